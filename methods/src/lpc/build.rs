//! Out-of-core LPC build (paper §5), in two phases.
//!
//! **Phase 1, recursive partitioning.** A node is a set of samples (as 20-byte
//! [`Sample`] records: position, 16-bit normal, colour) with the tight bounding box of those
//! samples and the sum of their (quantised) normals, both accumulated by the parent's scan.
//! One linear scan of the node's samples:
//! - `N_j < M`: a leaf, its cloud holds all its samples;
//! - otherwise each sample is kept by Russian roulette with probability `K·M/N_j` (all when
//!   that is ≥ 1); of the samples not kept, the first `M` in scan order are held back, the
//!   others go straight to the child on their side of the midpoint of the box's longest axis
//!   (`p[axis] < mid` → child 0, else child 1). After the scan: if fewer than `M` were kept, the
//!   first held-back samples top the cloud up to `M` (deterministic, documented in the
//!   README); the kept samples are shuffled (partial Fisher–Yates with the node's seeded
//!   [`scenes::rng::Pcg32`]), the first `M` form the cloud, and the other kept samples, then the rest of
//!   the held-back ones, are given back to the children. An empty child is omitted; a node
//!   with `N_j ≥ M` whose remainder is empty (`N_j = M`) is a leaf with exactly `M` samples.
//! - The same scan computes the node's bounding sphere (centre of the box, radius = largest
//!   distance of any subtree sample from it) and normal cone (axis = normalised normal sum,
//!   half-angle = largest angle to any subtree normal as the renderer decodes it), exactly
//!   over every sample of the subtree.
//!
//! Each node's random stream is `Pcg32::stream(seed, key)` with `key` derived from the path
//! from the root, and nodes are processed depth-first (child 0 first) on an explicit stack
//! (degenerate inputs make deep trees: no recursion). A subtree whose samples fit the memory
//! budget (`2 × 20` bytes per sample: a source and a destination buffer) is loaded and
//! partitioned in memory, by stable partitioning into the other buffer; a larger one is
//! streamed. Streamed levels are simulated in read-only passes over their source (the scene's
//! columns, read sequentially in blocks with their pages released behind the cursor, or a
//! temporary file), and each sample is written once, to the file of the subtree that fits
//! (or, past the limits of [`super::multilevel`], to a file that starts the next group): the
//! temporary-file traffic is linear in `N`, not `N` times the number of streamed levels. Both
//! paths visit the samples in the same order and draw the same random numbers, so they give
//! the same tree and clouds. Clouds are appended to a temporary cloud file.
//!
//! **Parallelism** (the current rayon pool; the output is byte-identical for any number of
//! threads). Streamed subtrees are taken one at a time, so at most one in-core subtree is
//! loaded and the `2 × 20` bytes per sample bound holds for the whole build. Inside an in-core
//! subtree (`part`), a node whose two children both hold ≥ [`PAR_MIN`] samples and
//! ≥ 1/16 of the node's runs the two child subtrees in [`rayon::join`] on their disjoint
//! ranges of the two buffers (no extra sample memory; each worker has its own scan buffers
//! of ≈ `K·M + M` samples, counted per pool thread in `peak_bytes_held`). Each node's cloud is
//! left in its destination buffer, in the gap between its children's ranges; the workers
//! return their nodes in depth-first order (child 0 first), and the subtree's nodes are then
//! given their ids and their clouds appended in that order, which is the single-threaded
//! processing order. A streamed scan fetches (converts or reads) its next block while
//! scanning the current one; the scene's columns are converted (normal encoding) in parallel
//! per block,
//! and the probe k-NN ([`probe_knn`]) scans its subtree in parallel chunks, alongside the
//! partition of the subtree's root (which only reads the source buffer too). Sums of `f64`
//! (normal sums) are always accumulated in scan order.
//!
//! **Phase 2, structure construction.** Nodes are sorted by level, then by the Morton code
//! of their sphere centre quantised in the root box (ties: processing order); node index =
//! cloud id. The spacings of eqs. (1)–(2) are computed top-down ([`hierarchical_spacing`]);
//! clouds are read back in repository order in batches, encoded ([`cloud::encode`]) and
//! LZO-compressed in parallel, then appended in order.
//!
//! **Input spacing** `r` (when not given): from the distance to the
//! [`crate::leaf::LEAF_K`]-th nearest neighbour by the `spacing_rule` ([`spacing_estimates`]:
//! the paper's average spacing by default) over a seeded probe (each sample with
//! probability `min(1, 16 384 / N)`), each probe measured exactly against all the scene's
//! samples: by the in-core root ([`probe_knn`], alongside its first split) or, when the root
//! is streamed, by one scan of the position column before the partition
//! ([`column_probe_knn`]: the same values in the same order), so that `r`, and with it the
//! files, do not depend on `mem_mb`.
//!
//! **Temporary files** (`temp_bytes` in `build.json`): the cloud file (`20·N` bytes) plus
//! `20` bytes for each sample written to a streamed group's frontier file. With no group
//! past its limits (balanced trees up to 64 in-core subtrees), that is each sample outside
//! the streamed nodes' clouds once, `20·(N + Σ n_j)` over the in-core subtrees `j` whose
//! parent is streamed, plus once more the samples of each speculated child that did not fit
//! (see [`super::multilevel`]).
//!
//! Files: phase 1 is in [`super::partition`] (in-core path, processing order), the streamed
//! levels in [`super::multilevel`], their sources in [`super::source`], the input and
//! per-node spacings in [`super::spacing`]; this file runs the two phases and writes the
//! build.

use std::fs::File;
use std::io::{BufWriter, Read, Seek, SeekFrom};
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use scenes::{Aabb, Attributes, PointCloud, Progress};

use super::cloud::{self, Sample};
use super::index::{self, NONE, Node};
use super::partition::PNode;
use super::sizes::SizeCheck;
use super::{INDEX_FILE, INFO_FILE, Info, LpcParams, Quantise, REPO_FILE, SpacingRule};
use crate::store::{self, RepoWriter};
use crate::{BuildStats, MethodError};

pub use super::multilevel::{MAX_FILES, MAX_LEVELS, MAX_SIMULATED, WRITE_BUF};
pub use super::partition::PAR_MIN;
use super::partition::{Cfg, Phase1, Temps};
pub use super::spacing::{
    KNN_CHUNK, MEAN_SPACING_FACTOR, SPACING_QUANTILE, column_probe_knn, hierarchical_spacing,
    probe_knn, spacing_estimates,
};

use super::layout::IO_BUF;
pub use super::layout::{CONE_MARGIN, IN_CORE_BYTES_PER_SAMPLE, PROBES, RECORD_BYTES};

/// Builds the index tree and the repository of `cloud` into `dir` with the memory budget
/// `params.mem_mb`.
pub fn build(
    cloud: &PointCloud,
    params: &LpcParams,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    build_with_budget(cloud, params, scene, dir, progress, params.mem_mb << 20)
}

/// [`build`] with an explicit working-memory budget in bytes (tests force the out-of-core
/// path with a tiny one). Subtrees of up to `mem_bytes / 40` samples are partitioned in
/// memory; the fixed I/O buffers (≈ 13 MiB, with the 64 frontier-file writers) come on top.
pub fn build_with_budget(
    cloud: &PointCloud,
    params: &LpcParams,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
    mem_bytes: u64,
) -> Result<BuildStats, MethodError> {
    let _ = scene;
    let t0 = Instant::now();
    let mut temps = Temps(Vec::new());
    let attrs = super::lpc_attributes(cloud.attributes());
    let Partitioned {
        nodes,
        clouds_path,
        mut probes,
        mut peak,
        temp_bytes,
    } = partition(cloud, params, dir, progress, mem_bytes, attrs, &mut temps)?;

    let n = cloud.len() as u64;
    let bounds = cloud.bounds();
    // Positions quantised in the model's box (the paper's) or in each cloud's own.
    let frame = match params.quantise {
        Quantise::Model => Some((bounds.min.to_array(), bounds.max.to_array())),
        Quantise::Cloud => None,
    };
    let probe_count = probes.len() as u64;
    let (r, nn) = input_spacings(cloud, params, &mut probes);

    // Phase 2: repository order, spacing, clouds.
    let phase2 = Phase2::new(&nodes, &clouds_path, bounds);
    let (mut out, spacing) = phase2.index_nodes(r);
    // §4: the clouds' spacings against their samples (`super::sizes`), read from the cloud
    // file while it exists.
    let sizes = phase2.cloud_spacing(params.m, &spacing)?;
    let batch_samples = (mem_bytes / (4 * RECORD_BYTES)).max(params.m as u64) as usize;
    let encoding = Encoding { attrs, nn, frame };
    let repo = phase2.write_repository(
        &mut out,
        dir,
        &mut temps,
        progress,
        batch_samples,
        &encoding,
    )?;
    peak = peak.max(repo.peak);

    let index_path = dir.join(INDEX_FILE);
    let index_bytes = index::write(&index_path, &out)?;
    let levels = out.iter().map(|n| n.level).max().unwrap_or(0) + 1;
    let info = Info {
        input_spacing: r,
        nn_spacing: nn,
        m: params.m,
        nodes: out.len() as u64,
        levels,
        points: n,
    };
    crate::method::write_json(&dir.join(INFO_FILE), &info)?;
    drop(temps);
    let extra = Report {
        params,
        attrs,
        r,
        nn,
        probe_count,
        bits: (repo.bits_min, repo.bits_max),
        temp_bytes,
        mem_bytes,
        peak,
        out: &out,
        sizes,
        index_bytes,
        repo_bytes: repo.bytes,
    }
    .extra();
    let stats = BuildStats {
        points_in: n,
        nodes: out.len() as u64,
        levels,
        bytes_in: cloud.column_bytes(),
        bytes_out: index_bytes + repo.bytes,
        bits_per_sample: 0.0,
        seconds: t0.elapsed().as_secs_f64(),
        points_per_s: 0.0,
        extra,
    }
    .finish();
    Ok(stats)
}

/// What phase 1 leaves for phase 2.
struct Partitioned {
    /// The nodes, in processing order.
    nodes: Vec<PNode>,
    /// The temporary cloud file, complete and closed.
    clouds_path: PathBuf,
    /// `[nearest, LEAF_K-th nearest]` distances of the measured probes.
    probes: Vec<[f32; 2]>,
    /// Peak bytes held so far.
    peak: u64,
    /// Temporary-file bytes, the cloud file's included.
    temp_bytes: u64,
}

/// Phase 1: partitions `cloud` into nodes and writes their clouds to the temporary cloud
/// file (registered in `temps`), then closes the progress bar and flushes the file.
fn partition(
    cloud: &PointCloud,
    params: &LpcParams,
    dir: &Path,
    progress: &dyn Progress,
    mem_bytes: u64,
    attrs: Attributes,
    temps: &mut Temps,
) -> Result<Partitioned, MethodError> {
    let clouds_path = dir.join("lpc-clouds.tmp");
    temps.0.push(clouds_path.clone());
    let clouds_file = File::create(&clouds_path).map_err(|e| MethodError::io(&clouds_path, e))?;
    let mut p1 = Phase1 {
        cfg: Cfg {
            m: params.m as usize,
            k: params.k,
            seed: params.seed,
            normals: attrs.normals,
        },
        budget: mem_bytes,
        estimate: params.spacing.is_none() || params.nn_spacing.is_none(),
        dir: dir.to_owned(),
        nodes: Vec::new(),
        clouds: BufWriter::with_capacity(IO_BUF, clouds_file),
        clouds_path: clouds_path.clone(),
        clouds_len: 0,
        pool: Vec::new(),
        probes: Vec::new(),
        peak: 0,
        temp_bytes: 0,
        files: 0,
        progress,
    };
    p1.run(cloud, temps)?;
    progress.finish();
    let Phase1 {
        nodes,
        clouds,
        probes,
        peak,
        mut temp_bytes,
        ..
    } = p1;
    clouds
        .into_inner()
        .map_err(|e| MethodError::io(&clouds_path, e.into_error()))?;
    temp_bytes += cloud.len() as u64 * RECORD_BYTES;
    Ok(Partitioned {
        nodes,
        clouds_path,
        probes,
        peak,
        temp_bytes,
    })
}

/// The input spacing `r` and the quantisation spacing: given in `params`, else estimated
/// from the probes (by `params.spacing_rule`), else derived from the bounding box.
fn input_spacings(cloud: &PointCloud, params: &LpcParams, probes: &mut [[f32; 2]]) -> (f32, f32) {
    let n = cloud.len() as u64;
    let bounds = cloud.bounds();
    let (r_est, nn_est) = spacing_estimates(probes, params.spacing_rule);
    let r_est = match params.spacing_rule {
        SpacingRule::Area => {
            let framed = scenes::framing::inlier_box(cloud).unwrap_or(bounds);
            scenes::spacing::area_spacing(cloud.positions(), framed)
        }
        _ => r_est,
    };
    let r = match params.spacing {
        Some(r) => r,
        None => {
            if r_est.is_finite() && r_est > 0.0 {
                r_est
            } else {
                let d = bounds.size().length() / (n as f32).sqrt();
                if d.is_finite() && d > 0.0 { d } else { 1.0 }
            }
        }
    };
    // Quantisation spacing: the mean nearest-neighbour distance (the paper's "average
    // sample spacing"); without an estimate, a quarter of the splat spacing (the ratio
    // measured on uniformly sampled surfaces is 3.5–4).
    let nn = match params.nn_spacing {
        Some(v) => v,
        None if nn_est.is_finite() && nn_est > 0.0 => nn_est,
        None => r / 4.0,
    };
    (r, nn)
}

/// How the clouds are encoded: attributes, quantisation spacing and frame.
struct Encoding {
    attrs: Attributes,
    nn: f32,
    frame: Option<([f32; 3], [f32; 3])>,
}

/// What [`Phase2::write_repository`] reports.
struct RepoWritten {
    /// Bytes of the repository file.
    bytes: u64,
    /// Smallest and largest position bits of any cloud (`u8::MAX` and 0 with no cloud).
    bits_min: u8,
    bits_max: u8,
    /// Peak bytes held by a batch (raw, encoded and compressed).
    peak: u64,
}

/// Phase 2 over the nodes of phase 1 and their cloud file, in repository order.
struct Phase2<'a> {
    nodes: &'a [PNode],
    clouds_path: &'a Path,
    /// Phase-1 node ids in repository order.
    order: Vec<u32>,
    /// Repository id of each phase-1 node.
    new_id: Vec<u32>,
}

impl<'a> Phase2<'a> {
    /// Repository order: by level, then by the Morton code of the sphere centre quantised
    /// in `bounds` (ties: processing order).
    fn new(nodes: &'a [PNode], clouds_path: &'a Path, bounds: Aabb) -> Self {
        let size = bounds.size().max_element().max(f32::MIN_POSITIVE);
        let cells = (1u32 << 21) as f32;
        let code = |c: Vec3| {
            let q =
                |v: f32, lo: f32| (((v - lo) / size * cells).max(0.0) as u32).min((1 << 21) - 1);
            crate::morton::morton96([
                q(c.x, bounds.min.x),
                q(c.y, bounds.min.y),
                q(c.z, bounds.min.z),
            ])
        };
        let mut order: Vec<(u32, u128, u32)> = nodes
            .iter()
            .enumerate()
            .map(|(i, nd)| (nd.level, code(nd.center), i as u32))
            .collect();
        order.sort_unstable();
        let order: Vec<u32> = order.into_iter().map(|(_, _, i)| i).collect();
        let mut new_id = vec![0u32; nodes.len()];
        for (new, &old) in order.iter().enumerate() {
            new_id[old as usize] = new as u32;
        }
        Phase2 {
            nodes,
            clouds_path,
            order,
            new_id,
        }
    }

    /// The index nodes in repository order (their chunks still unset) and their spacings
    /// (eqs. (1)–(2), top-down from the input spacing `r`).
    fn index_nodes(&self, r: f32) -> (Vec<Node>, Vec<f64>) {
        let (nodes, order, new_id) = (self.nodes, &self.order, &self.new_id);
        let parents: Vec<u32> = order
            .iter()
            .map(|&o| {
                let p = nodes[o as usize].parent;
                if p == NONE { NONE } else { new_id[p as usize] }
            })
            .collect();
        let subtree: Vec<u64> = order.iter().map(|&o| nodes[o as usize].n).collect();
        let points: Vec<u32> = order.iter().map(|&o| nodes[o as usize].m).collect();
        let spacing = hierarchical_spacing(r as f64, &parents, &subtree, &points);
        // Decoded positions may move by up to half a step (< 0.45 r) per axis.
        let quant_margin = (cloud::STEP_FRACTION * 0.5 * 3f64.sqrt() * 1.001) as f32 * r;
        let out: Vec<Node> = order
            .iter()
            .enumerate()
            .map(|(new, &old)| {
                let nd = &nodes[old as usize];
                Node {
                    center: nd.center.to_array(),
                    radius: nd.radius + quant_margin,
                    cone_axis: nd.axis.to_array(),
                    cone_half_angle: nd.half,
                    spacing: spacing[new] as f32,
                    children: nd
                        .children
                        .map(|c| if c == NONE { NONE } else { new_id[c as usize] }),
                    cloud: new as u32,
                    points: nd.m,
                    level: nd.level,
                    subtree: nd.n,
                    chunk: Default::default(),
                }
            })
            .collect();
        (out, spacing)
    }

    /// Reads the cloud of phase-1 node `old` from the cloud file `f`.
    fn read_cloud(&self, f: &mut File, old: usize) -> Result<Vec<Sample>, MethodError> {
        let nd = &self.nodes[old];
        let mut v = vec![Sample::default(); nd.m as usize];
        f.seek(SeekFrom::Start(nd.cloud_off * RECORD_BYTES))
            .and_then(|_| f.read_exact(bytemuck::cast_slice_mut(&mut v)))
            .map_err(|e| MethodError::io(self.clouds_path, e))?;
        Ok(v)
    }

    /// §4: the clouds' spacings against their samples (`super::sizes`), `spacing` being the
    /// nodes' spacings in repository order.
    fn cloud_spacing(&self, m: u32, spacing: &[f64]) -> Result<Option<SizeCheck>, MethodError> {
        let mut f =
            File::open(self.clouds_path).map_err(|e| MethodError::io(self.clouds_path, e))?;
        super::sizes::cloud_spacing(
            self.nodes,
            m,
            |old| spacing[self.new_id[old] as usize],
            |old| self.read_cloud(&mut f, old),
        )
    }

    /// Writes the repository: reads the clouds back in repository order in batches of up
    /// to `batch_samples` samples (at least one cloud), encodes and compresses each batch in
    /// parallel, appends the clouds in order and sets each node's chunk in `out`.
    fn write_repository(
        &self,
        out: &mut [Node],
        dir: &Path,
        temps: &mut Temps,
        progress: &dyn Progress,
        batch_samples: usize,
        encoding: &Encoding,
    ) -> Result<RepoWritten, MethodError> {
        let (nodes, order) = (self.nodes, &self.order);
        progress.start("lpc: clouds", out.len() as u64);
        let repo_path = dir.join(REPO_FILE);
        let mut repo = RepoWriter::create(&repo_path)?;
        temps.0.push(scenes::colfile::temp_path(&repo_path));
        let mut reader =
            File::open(self.clouds_path).map_err(|e| MethodError::io(self.clouds_path, e))?;
        let mut bits_min = u8::MAX;
        let mut bits_max = 0u8;
        let mut peak = 0u64;
        let mut i = 0;
        while i < order.len() {
            let mut j = i;
            let mut total = 0usize;
            while j < order.len()
                && (j == i || total + nodes[order[j] as usize].m as usize <= batch_samples)
            {
                total += nodes[order[j] as usize].m as usize;
                j += 1;
            }
            let mut raw: Vec<Vec<Sample>> = Vec::with_capacity(j - i);
            for &old in &order[i..j] {
                raw.push(self.read_cloud(&mut reader, old as usize)?);
            }
            peak = peak.max(total as u64 * RECORD_BYTES * 3);
            let enc: Vec<(Vec<u8>, usize, [u8; 3])> = raw
                .par_iter()
                .map(|c| {
                    let (bytes, bits) =
                        cloud::encode_in(c, encoding.attrs, encoding.nn, encoding.frame);
                    (store::compress(&bytes), bytes.len(), bits)
                })
                .collect();
            for (k, (stored, raw_len, bits)) in enc.iter().enumerate() {
                out[i + k].chunk = repo.append_compressed(stored, *raw_len)?;
                for &b in bits {
                    bits_min = bits_min.min(b);
                    bits_max = bits_max.max(b);
                }
            }
            progress.inc((j - i) as u64);
            i = j;
        }
        drop(reader);
        let bytes = repo.finish()?;
        progress.finish();
        Ok(RepoWritten {
            bytes,
            bits_min,
            bits_max,
            peak,
        })
    }
}

/// The figures of `build.json`'s method-specific fields, gathered over the build.
struct Report<'a> {
    params: &'a LpcParams,
    attrs: Attributes,
    /// Input spacing `r` and quantisation spacing.
    r: f32,
    nn: f32,
    probe_count: u64,
    /// Smallest and largest position bits of any cloud.
    bits: (u8, u8),
    temp_bytes: u64,
    mem_bytes: u64,
    peak: u64,
    /// The index nodes, in repository order.
    out: &'a [Node],
    sizes: Option<SizeCheck>,
    index_bytes: u64,
    repo_bytes: u64,
}

impl Report<'_> {
    /// The fields, in the order `build.json` lists them.
    fn extra(self) -> serde_json::Map<String, serde_json::Value> {
        let Report {
            params,
            attrs,
            r,
            nn,
            probe_count,
            bits: (bits_min, bits_max),
            temp_bytes,
            mem_bytes,
            peak,
            out,
            sizes,
            index_bytes,
            repo_bytes,
        } = self;
        let mut extra = serde_json::Map::new();
        let mut put = |k: &str, v: serde_json::Value| {
            extra.insert(k.into(), v);
        };
        put("m", params.m.into());
        put("k", (params.k as f64).into());
        put(
            "spacing_rule",
            serde_json::to_value(params.spacing_rule).unwrap_or_default(),
        );
        put("input_spacing", (r as f64).into());
        put("nn_spacing", (nn as f64).into());
        put("input_spacing_probes", probe_count.into());
        put(
            "quantise",
            serde_json::to_value(params.quantise).unwrap_or_default(),
        );
        put("position_bits_min", bits_min.min(bits_max).into());
        put("position_bits_max", bits_max.into());
        put("normal_bits", (if attrs.normals { 16 } else { 0 }).into());
        put("color_bits", (if attrs.colors { 24 } else { 0 }).into());
        put("temp_bytes", temp_bytes.into());
        put("memory_budget_bytes", mem_bytes.into());
        put("peak_bytes_held", peak.into());
        put("clouds", (out.len() as u64).into());
        if let Some(z) = sizes {
            put("spacing_clouds_measured", z.clouds.into());
            put("spacing_ratio_median", z.ratio_median.into());
            put("spacing_ratio_p10", z.ratio_p10.into());
            put("spacing_ratio_p90", z.ratio_p90.into());
            put("spacing_cv_median", z.cv_median.into());
        }
        // §3: the model keeps exactly the input samples; an inner cloud holds `M`, a leaf at
        // most `M` (`N_j < M`, or `N_j = M` with nothing left to split).
        let stored: u64 = out.iter().map(|nd| u64::from(nd.points)).sum();
        put("samples_stored", stored.into());
        put(
            "inner_clouds_not_m",
            (out.iter()
                .filter(|nd| !nd.is_leaf() && nd.points != params.m)
                .count() as u64)
                .into(),
        );
        put(
            "leaf_clouds_over_m",
            (out.iter()
                .filter(|nd| nd.is_leaf() && nd.points > params.m)
                .count() as u64)
                .into(),
        );
        put("index_bytes", index_bytes.into());
        put("repo_bytes", repo_bytes.into());
        extra
    }
}
