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
//!   [`Pcg32`]), the first `M` form the cloud, and the other kept samples, then the rest of
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
//! streamed from a temporary file into two child files. Both paths visit the samples in the
//! same order and draw the same random numbers, so they give the same tree and clouds. The
//! root reads the scene's columns sequentially in blocks and releases their pages behind
//! the cursor. Clouds are appended to a temporary cloud file in processing order.
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
//! probability `min(1, 16 384 / N)`), each probe measured against the full-density samples of
//! the in-core subtree that contains it when that subtree is loaded ([`probe_knn`]). Probes
//! that end up in the cloud of an out-of-core node are not measured.

use std::collections::HashMap;
use std::fs::File;
use std::hash::{BuildHasherDefault, Hasher};
use std::io::{BufReader, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use scenes::rng::{Pcg32, splitmix64};
use scenes::{Aabb, PointCloud, Progress};

use super::cloud::{self, Sample};
use super::index::{self, NONE, Node};
use super::{INDEX_FILE, INFO_FILE, Info, LpcParams, REPO_FILE, SpacingRule};
use crate::leaf::LEAF_K;
use crate::store::{self, RepoWriter};
use crate::{BuildStats, MethodError};

/// Flag of a probe sample (spacing estimate).
const PROBE: u16 = 1;
/// Expected number of probe samples of the spacing estimate.
pub const PROBES: u64 = 16_384;
/// Bytes of one sample record.
pub const RECORD_BYTES: u64 = std::mem::size_of::<Sample>() as u64;
/// Bytes per sample of a subtree partitioned in memory (source and destination buffers).
pub const IN_CORE_BYTES_PER_SAMPLE: u64 = 2 * RECORD_BYTES;
/// Samples per block when reading the scene or a temporary file.
const BLOCK: usize = 1 << 16;
/// Samples per parallel chunk when converting the scene's columns.
const CONVERT_CHUNK: usize = 1 << 13;
/// Capacity of each buffered reader / writer.
const IO_BUF: usize = 1 << 20;
/// Added to every cone half-angle (radians): covers `f32` rounding of the dot products.
pub const CONE_MARGIN: f32 = 1e-3;

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
/// memory; the fixed I/O buffers (≈ 6 MiB) come on top.
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
        spare: (Vec::new(), Vec::new()),
        probes: Vec::new(),
        peak: 0,
        temp_bytes: 0,
        files: 0,
        progress,
    };
    progress.start("lpc: partition", cloud.len() as u64);
    p1.run(cloud, &mut temps)?;
    progress.finish();
    let Phase1 {
        nodes,
        clouds,
        mut probes,
        mut peak,
        mut temp_bytes,
        ..
    } = p1;
    clouds
        .into_inner()
        .map_err(|e| MethodError::io(&clouds_path, e.into_error()))?;
    temp_bytes += cloud.len() as u64 * RECORD_BYTES;

    let n = cloud.len() as u64;
    let bounds = cloud.bounds();
    let probe_count = probes.len() as u64;
    let (r_est, nn_est) = spacing_estimates(&mut probes, params.spacing_rule);
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

    // Phase 2: repository order, spacing, clouds.
    let size = bounds.size().max_element().max(f32::MIN_POSITIVE);
    let cells = (1u32 << 21) as f32;
    let code = |c: Vec3| {
        let q = |v: f32, lo: f32| (((v - lo) / size * cells).max(0.0) as u32).min((1 << 21) - 1);
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
    let mut out: Vec<Node> = order
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

    progress.start("lpc: clouds", out.len() as u64);
    let repo_path = dir.join(REPO_FILE);
    let mut repo = RepoWriter::create(&repo_path)?;
    temps.0.push(scenes::colfile::temp_path(&repo_path));
    let mut reader = File::open(&clouds_path).map_err(|e| MethodError::io(&clouds_path, e))?;
    let batch_samples = (mem_bytes / (4 * RECORD_BYTES)).max(params.m as u64) as usize;
    let mut bits_min = u8::MAX;
    let mut bits_max = 0u8;
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
            let nd = &nodes[old as usize];
            let mut v = vec![Sample::default(); nd.m as usize];
            reader
                .seek(SeekFrom::Start(nd.cloud_off * RECORD_BYTES))
                .and_then(|_| reader.read_exact(bytemuck::cast_slice_mut(&mut v)))
                .map_err(|e| MethodError::io(&clouds_path, e))?;
            raw.push(v);
        }
        peak = peak.max(total as u64 * RECORD_BYTES * 3);
        let enc: Vec<(Vec<u8>, usize, [u8; 3])> = raw
            .par_iter()
            .map(|c| {
                let (bytes, bits) = cloud::encode(c, attrs, nn);
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
    let repo_bytes = repo.finish()?;
    progress.finish();

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
    put("position_bits_min", bits_min.min(bits_max).into());
    put("position_bits_max", bits_max.into());
    put("normal_bits", (if attrs.normals { 16 } else { 0 }).into());
    put("color_bits", (if attrs.colors { 24 } else { 0 }).into());
    put("temp_bytes", temp_bytes.into());
    put("memory_budget_bytes", mem_bytes.into());
    put("peak_bytes_held", peak.into());
    put("clouds", (out.len() as u64).into());
    put("index_bytes", index_bytes.into());
    put("repo_bytes", repo_bytes.into());
    let stats = BuildStats {
        points_in: n,
        nodes: out.len() as u64,
        levels,
        bytes_in: cloud.column_bytes(),
        bytes_out: index_bytes + repo_bytes,
        bits_per_sample: 0.0,
        seconds: t0.elapsed().as_secs_f64(),
        points_per_s: 0.0,
        extra,
    }
    .finish();
    Ok(stats)
}

/// The spacing `r_j` of every node by eqs. (1)–(2): `r_0 = r·sqrt(N/M_0)`,
/// `M_j^tot = N_j/(N_p − M_p)·M_p^tot + M_j` (`M_0^tot = M_0`),
/// `r_j = r_p·sqrt(N_j·M_p^tot / ((N_p − M_p)·M_j^tot))`. Nodes are given parents first
/// (`parent[0] = NONE`), with their subtree sizes `N_j` and cloud sizes `M_j`.
pub fn hierarchical_spacing(r: f64, parent: &[u32], subtree: &[u64], points: &[u32]) -> Vec<f64> {
    let n = parent.len();
    let mut r_j = vec![0f64; n];
    let mut m_tot = vec![0f64; n];
    for j in 0..n {
        let (nj, mj) = (subtree[j] as f64, points[j] as f64);
        if parent[j] == NONE {
            m_tot[j] = mj;
            r_j[j] = r * (nj / mj).sqrt();
        } else {
            let p = parent[j] as usize;
            let rest = subtree[p] as f64 - points[p] as f64;
            m_tot[j] = nj / rest * m_tot[p] + mj;
            r_j[j] = r_j[p] * (nj * m_tot[p] / (rest * m_tot[j])).sqrt();
        }
    }
    r_j
}

/// Deletes the temporary files on drop (also on error).
struct Temps(Vec<PathBuf>);

impl Drop for Temps {
    fn drop(&mut self) {
        for p in &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// A node of phase 1 (index = processing order).
#[derive(Debug, Clone, Copy)]
struct PNode {
    parent: u32,
    children: [u32; 2],
    level: u32,
    n: u64,
    m: u32,
    cloud_off: u64,
    center: Vec3,
    radius: f32,
    axis: Vec3,
    half: f32,
}

/// A node waiting to be partitioned.
#[derive(Debug, Clone, Copy)]
struct Task {
    id: u32,
    key: u64,
    n: u64,
    bbox: Aabb,
    nsum: DVec3,
}

/// Samples, box and normal sum gathered for a child during its parent's scan.
#[derive(Debug, Clone, Copy)]
struct Acc {
    n: u64,
    bbox: Aabb,
    nsum: DVec3,
}

impl Acc {
    const EMPTY: Acc = Acc {
        n: 0,
        bbox: Aabb::EMPTY,
        nsum: DVec3::ZERO,
    };
    /// Adds `s`, whose decoded normal is `d` (ignored without normals).
    #[inline]
    fn add(&mut self, s: &Sample, d: [f32; 3], normals: bool) {
        self.n += 1;
        self.bbox = self.bbox.grow(Vec3::from(s.p));
        if normals {
            self.nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
        }
    }
}

/// The constants of phase 1's scans, shared by the workers.
#[derive(Debug, Clone, Copy)]
struct Cfg {
    m: usize,
    k: f32,
    seed: u64,
    normals: bool,
}

impl Cfg {
    fn scan_for(&self, task: &Task, spare: &mut (Vec<Sample>, Vec<Sample>)) -> Scan {
        let m = self.m;
        let p = self.k as f64 * m as f64 / task.n as f64;
        let axis = task.bbox.longest_axis();
        let naxis = if self.normals {
            let l = task.nsum.length();
            if l > 0.0 {
                (task.nsum / l).as_vec3()
            } else {
                Vec3::Z
            }
        } else {
            Vec3::ZERO
        };
        let (mut res, mut hold) = std::mem::take(spare);
        res.clear();
        hold.clear();
        Scan {
            m,
            leaf: task.n < m as u64,
            keep_all: p >= 1.0,
            p: p as f32,
            axis,
            mid: task.bbox.center()[axis],
            center: task.bbox.center(),
            naxis,
            normals: self.normals,
            max_d2: 0.0,
            min_dot: 1.0,
            rng: Pcg32::stream(self.seed, task.key),
            table: cloud::normal_table(),
            res,
            hold,
            kids: [Acc::EMPTY; 2],
        }
    }
}

/// A scanned node, before it gets its id and its place in the cloud file.
#[derive(Debug, Clone, Copy)]
struct Closed {
    key: u64,
    center: Vec3,
    radius: f32,
    axis: Vec3,
    half: f32,
    acc: [Acc; 2],
}

impl Closed {
    /// The child tasks (`None`: empty child), with id `id`.
    fn kids(&self, id: u32) -> [Option<Task>; 2] {
        std::array::from_fn(|side| {
            let acc = self.acc[side];
            (acc.n > 0).then(|| Task {
                id,
                key: child_key(self.key, side),
                n: acc.n,
                bbox: acc.bbox,
                nsum: acc.nsum,
            })
        })
    }
}

/// A node closed by [`part`]: its cloud lies in `bufs[buf][start..start + mc]`.
#[derive(Debug, Clone, Copy)]
struct Entry {
    closed: Closed,
    buf: usize,
    start: usize,
    mc: usize,
}

/// Subtrees smaller than this are never split between workers.
pub const PAR_MIN: u64 = 1 << 15;

/// One node partitioned in memory by [`split_node`].
#[derive(Debug, Clone, Copy)]
struct Split {
    closed: Closed,
    /// Child 0 is `dst[..f]`, the cloud `dst[f..bk]`, child 1 `dst[bk..]`.
    f: usize,
    bk: usize,
    mc: usize,
    /// Scan-buffer capacity used (samples).
    cap: usize,
}

/// Scans the node `task` whose samples are `src` and partitions them into `dst`: child 0
/// first, then the cloud, then child 1 (both children in scan order).
fn split_node(
    cfg: &Cfg,
    task: &Task,
    src: &[Sample],
    dst: &mut [Sample],
    spare: &mut (Vec<Sample>, Vec<Sample>),
) -> Result<Split, MethodError> {
    let mut scan = cfg.scan_for(task, spare);
    let (mut f, mut bk) = (0usize, dst.len());
    // Child 0 fills `dst` from the front, child 1 from the back (reversed below).
    let mut place = |side: usize, s: &Sample| {
        if side == 0 {
            dst[f] = *s;
            f += 1;
        } else {
            bk -= 1;
            dst[bk] = *s;
        }
    };
    for s in src {
        if let Some(side) = scan.step(*s) {
            place(side, s);
        }
    }
    let mc = scan.select();
    scan.give_back(mc, &mut |side, s| {
        place(side, s);
        Ok(())
    })?;
    dst[bk..].reverse();
    // The children took all but the cloud: it fills the gap `f..bk`.
    dst[f..bk].copy_from_slice(&scan.res[..mc]);
    let cap = scan.res.capacity() + scan.hold.capacity();
    let closed = scan.closed(task.key);
    *spare = (scan.res, scan.hold);
    Ok(Split {
        closed,
        f,
        bk,
        mc,
        cap,
    })
}

/// Partitions, in memory, the subtree of `root` whose samples are in `bufs[buf]` (`a` is
/// buffer 0 and `b` buffer 1, both restricted to the subtree's range, which starts at
/// `base` in the full buffers). Each node's cloud is left in the gap between its
/// children's ranges in the buffer it was partitioned into; the nodes are appended to `log`
/// depth-first, child 0 first (the order of the single-threaded build). When both children
/// of a node are large (≥ [`PAR_MIN`] and ≥ 1/16 of the node: the nesting depth stays
/// logarithmic), their subtrees run in [`rayon::join`] on disjoint ranges. Returns the
/// largest scan-buffer capacity (samples) used.
#[allow(clippy::too_many_arguments)]
fn part(
    cfg: &Cfg,
    root: Task,
    a: &mut [Sample],
    b: &mut [Sample],
    base: usize,
    buf: usize,
    log: &mut Vec<Entry>,
    mut first: Option<Split>,
) -> Result<usize, MethodError> {
    let mut spare = (Vec::new(), Vec::new());
    let mut cap = 0usize;
    // (task, buffer holding the samples, range)
    let mut stack = vec![(root, buf, 0usize, a.len())];
    while let Some((task, buf, lo, hi)) = stack.pop() {
        let (src, dst) = if buf == 1 {
            (&b[lo..hi], &mut a[lo..hi])
        } else {
            (&a[lo..hi], &mut b[lo..hi])
        };
        let Split {
            closed,
            f,
            bk,
            mc,
            cap: c,
        } = match first.take() {
            Some(sp) => sp,
            None => split_node(cfg, &task, src, dst, &mut spare)?,
        };
        cap = cap.max(c);
        log.push(Entry {
            closed,
            buf: 1 - buf,
            start: base + lo + f,
            mc,
        });
        let kids = closed.kids(NONE);
        match kids {
            [Some(t0), Some(t1)] if t0.n.min(t1.n) >= PAR_MIN.max(task.n / 16) => {
                let (a0, a1) = a[lo..hi].split_at_mut(bk);
                let (b0, b1) = b[lo..hi].split_at_mut(bk);
                let (a0, b0) = (&mut a0[..f], &mut b0[..f]);
                let (mut l0, mut l1) = (Vec::new(), Vec::new());
                let (c0, c1) = rayon::join(
                    || part(cfg, t0, a0, b0, base + lo, 1 - buf, &mut l0, None),
                    || part(cfg, t1, a1, b1, base + lo + bk, 1 - buf, &mut l1, None),
                );
                cap = cap.max(c0?).max(c1?);
                log.append(&mut l0);
                log.append(&mut l1);
            }
            _ => {
                if let Some(t) = kids[1] {
                    stack.push((t, 1 - buf, lo + bk, hi));
                }
                if let Some(t) = kids[0] {
                    stack.push((t, 1 - buf, lo, lo + f));
                }
            }
        }
    }
    Ok(cap)
}

/// The state of one node's scan.
struct Scan {
    m: usize,
    leaf: bool,
    keep_all: bool,
    p: f32,
    axis: usize,
    mid: f32,
    center: Vec3,
    naxis: Vec3,
    normals: bool,
    max_d2: f32,
    min_dot: f32,
    rng: Pcg32,
    table: &'static [(u32, [f32; 3])],
    res: Vec<Sample>,
    hold: Vec<Sample>,
    kids: [Acc; 2],
}

impl Scan {
    #[inline]
    fn step(&mut self, s: Sample) -> Option<usize> {
        let d2 = (Vec3::from(s.p) - self.center).length_squared();
        self.max_d2 = self.max_d2.max(d2);
        let mut d = [0.0; 3];
        if self.normals {
            d = self.table[s.normal as usize].1;
            self.min_dot = self.min_dot.min(Vec3::from(d).dot(self.naxis));
        }
        if self.leaf || self.keep_all || self.rng.f32() < self.p {
            self.res.push(s);
            return None;
        }
        if self.hold.len() < self.m {
            self.hold.push(s);
            return None;
        }
        Some(self.route(&s, d))
    }
    /// Adds `s` (decoded normal `d`) to its child; returns the side.
    #[inline]
    fn route(&mut self, s: &Sample, d: [f32; 3]) -> usize {
        let side = (s.p[self.axis] >= self.mid) as usize;
        self.kids[side].add(s, d, self.normals);
        side
    }
    /// Arranges `res` so that `res[..returned]` is the cloud; the give-back samples are
    /// `res[returned..]` then `hold`.
    fn select(&mut self) -> usize {
        if self.leaf {
            return self.res.len();
        }
        if self.res.len() < self.m {
            let d = self.m - self.res.len();
            self.res.extend(self.hold.drain(..d));
        }
        let len = self.res.len();
        if len > self.m {
            for i in 0..self.m {
                let j = i + self.rng.below((len - i) as u32) as usize;
                self.res.swap(i, j);
            }
        }
        self.m
    }
    /// Routes the give-back samples, calling `out(side, sample)` in a fixed order.
    fn give_back(
        &mut self,
        mc: usize,
        out: &mut dyn FnMut(usize, &Sample) -> Result<(), MethodError>,
    ) -> Result<(), MethodError> {
        let res = std::mem::take(&mut self.res);
        let hold = std::mem::take(&mut self.hold);
        for s in res[mc..].iter().chain(&hold) {
            let side = self.route(s, self.table[s.normal as usize].1);
            out(side, s)?;
        }
        self.res = res;
        self.hold = hold;
        Ok(())
    }
    /// The node's sphere, cone and children once its scan is complete.
    fn closed(&self, key: u64) -> Closed {
        Closed {
            key,
            center: self.center,
            radius: self.max_d2.sqrt() * (1.0 + 1e-6),
            axis: self.naxis,
            half: self.half_angle(),
            acc: self.kids,
        }
    }
    fn half_angle(&self) -> f32 {
        if self.normals {
            (self.min_dot.clamp(-1.0, 1.0).acos() + CONE_MARGIN).min(std::f32::consts::PI)
        } else {
            std::f32::consts::PI
        }
    }
}

/// Phase 1 state.
struct Phase1<'a> {
    cfg: Cfg,
    budget: u64,
    estimate: bool,
    dir: PathBuf,
    nodes: Vec<PNode>,
    clouds: BufWriter<File>,
    clouds_path: PathBuf,
    clouds_len: u64,
    spare: (Vec<Sample>, Vec<Sample>),
    /// `[nearest, LEAF_K-th nearest]` distances of the measured probes.
    probes: Vec<[f32; 2]>,
    peak: u64,
    temp_bytes: u64,
    files: u64,
    progress: &'a dyn Progress,
}

fn child_key(key: u64, side: usize) -> u64 {
    let mut s = key
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(side as u64 + 1);
    splitmix64(&mut s)
}

/// A temporary file of samples with its task.
struct FileTask {
    task: Task,
    path: PathBuf,
}

impl<'a> Phase1<'a> {
    fn fits(&self, n: u64) -> bool {
        n.saturating_mul(IN_CORE_BYTES_PER_SAMPLE) <= self.budget
    }

    /// Writes the cloud of a node scanned by [`Phase1::stream`], fills the node and creates
    /// its children; returns the child tasks.
    fn close(
        &mut self,
        task: &Task,
        mut scan: Scan,
        mc: usize,
    ) -> Result<[Option<Task>; 2], MethodError> {
        self.peak = self
            .peak
            .max((scan.res.capacity() + scan.hold.capacity()) as u64 * RECORD_BYTES);
        let closed = scan.closed(task.key);
        let kids = self.commit(task.id, &closed, &scan.res[..mc])?;
        self.spare = (
            std::mem::take(&mut scan.res),
            std::mem::take(&mut scan.hold),
        );
        Ok(kids)
    }

    /// Appends the node `id`'s cloud to the cloud file, fills the node and creates its
    /// children (the next ids, child 0 first); returns the child tasks.
    fn commit(
        &mut self,
        id: u32,
        c: &Closed,
        cloud: &[Sample],
    ) -> Result<[Option<Task>; 2], MethodError> {
        let off = self.clouds_len;
        self.clouds
            .write_all(bytemuck::cast_slice(cloud))
            .map_err(|e| MethodError::io(&self.clouds_path, e))?;
        self.clouds_len += cloud.len() as u64;
        self.progress.inc(cloud.len() as u64);
        let level = self.nodes[id as usize].level;
        let mut kids = [None, None];
        let mut ids = [NONE; 2];
        for (side, t) in c.kids(NONE).into_iter().enumerate() {
            let Some(mut t) = t else { continue };
            t.id = self.nodes.len() as u32;
            self.nodes.push(PNode {
                parent: id,
                children: [NONE; 2],
                level: level + 1,
                n: t.n,
                m: 0,
                cloud_off: 0,
                center: Vec3::ZERO,
                radius: 0.0,
                axis: Vec3::ZERO,
                half: 0.0,
            });
            ids[side] = t.id;
            kids[side] = Some(t);
        }
        let nd = &mut self.nodes[id as usize];
        nd.children = ids;
        nd.m = cloud.len() as u32;
        nd.cloud_off = off;
        nd.center = c.center;
        nd.radius = c.radius;
        nd.axis = c.axis;
        nd.half = c.half;
        Ok(kids)
    }

    fn run(&mut self, cloud: &PointCloud, temps: &mut Temps) -> Result<(), MethodError> {
        let n = cloud.len();
        self.nodes.push(PNode {
            parent: NONE,
            children: [NONE; 2],
            level: 0,
            n: n as u64,
            m: 0,
            cloud_off: 0,
            center: Vec3::ZERO,
            radius: 0.0,
            axis: Vec3::ZERO,
            half: 0.0,
        });
        let threshold = if n as u64 <= PROBES {
            u64::MAX
        } else {
            (PROBES as f64 / n as f64 * u64::MAX as f64) as u64
        };
        let seed = self.cfg.seed;
        // Appends the samples of `range` to `out` (converted in parallel) and adds their
        // quantised normals to `nsum` (in order: the same sum for any thread count).
        let convert = |range: std::ops::Range<usize>, out: &mut Vec<Sample>, nsum: &mut DVec3| {
            let pos = &cloud.positions()[range.clone()];
            let nrm = cloud.normals().map(|v| &v[range.clone()]);
            let col = cloud.colors().map(|v| &v[range.clone()]);
            let start = out.len();
            out.resize(start + range.len(), Sample::default());
            out[start..]
                .par_chunks_mut(CONVERT_CHUNK)
                .enumerate()
                .for_each(|(c, chunk)| {
                    for (jj, s) in chunk.iter_mut().enumerate() {
                        let j = c * CONVERT_CHUNK + jj;
                        let i = range.start + j;
                        let mut h = seed ^ (i as u64).wrapping_mul(0xA24B_AED4_963E_E407);
                        let probe = splitmix64(&mut h) <= threshold;
                        *s = Sample {
                            p: pos[j],
                            normal: nrm.map_or(0, |nv| cloud::oct16_encode(Vec3::from(nv[j]))),
                            flags: if probe { PROBE } else { 0 },
                            color: col.map_or([0; 4], |c| [c[j][0], c[j][1], c[j][2], 0]),
                        };
                    }
                });
            if nrm.is_some() {
                let table = cloud::normal_table();
                for s in &out[start..] {
                    let d = table[s.normal as usize].1;
                    *nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
                }
            }
            cloud.release_pages(range);
        };
        let root = |nsum: DVec3| Task {
            id: 0,
            key: seed,
            n: n as u64,
            bbox: cloud.bounds(),
            nsum,
        };
        let mut bufs: [Vec<Sample>; 2] = [Vec::new(), Vec::new()];
        let mut stack: Vec<FileTask> = Vec::new();
        if self.fits(n as u64) {
            let mut nsum = DVec3::ZERO;
            bufs[0].reserve_exact(n);
            for lo in (0..n).step_by(BLOCK) {
                convert(lo..(lo + BLOCK).min(n), &mut bufs[0], &mut nsum);
            }
            self.in_core(root(nsum), &mut bufs)?;
        } else {
            // The root streams the scene: a first pass for the normal sum (the cone axis).
            // Blocks are encoded in parallel while the previous one is summed (in order).
            let mut nsum = DVec3::ZERO;
            if let Some(nv) = cloud.normals() {
                let table = cloud::normal_table();
                let (mut codes, mut prev) = (vec![0u16; BLOCK], vec![0u16; BLOCK]);
                let mut prev_len = 0;
                let sum = |codes: &[u16], nsum: &mut DVec3| {
                    for &c in codes {
                        let d = table[c as usize].1;
                        *nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
                    }
                };
                for lo in (0..n).step_by(BLOCK) {
                    let hi = (lo + BLOCK).min(n);
                    rayon::join(
                        || sum(&prev[..prev_len], &mut nsum),
                        || {
                            codes[..hi - lo]
                                .par_chunks_mut(CONVERT_CHUNK)
                                .zip(nv[lo..hi].par_chunks(CONVERT_CHUNK))
                                .for_each(|(c, v)| {
                                    for (c, v) in c.iter_mut().zip(v) {
                                        *c = cloud::oct16_encode(Vec3::from(*v));
                                    }
                                });
                            cloud.release_pages(lo..hi);
                        },
                    );
                    std::mem::swap(&mut codes, &mut prev);
                    prev_len = hi - lo;
                }
                sum(&prev[..prev_len], &mut nsum);
            }
            let task = root(nsum);
            let mut lo = 0;
            let kids = self.stream(&task, temps, &mut |block| {
                block.clear();
                if lo >= n {
                    return Ok(false);
                }
                let hi = (lo + BLOCK).min(n);
                let mut unused = DVec3::ZERO;
                convert(lo..hi, block, &mut unused);
                lo = hi;
                Ok(true)
            })?;
            stack.extend(kids.into_iter().rev().flatten());
        }
        while let Some(ft) = stack.pop() {
            if self.fits(ft.task.n) {
                let len = ft.task.n as usize;
                bufs[0].clear();
                bufs[0].resize(len, Sample::default());
                read_samples(&ft.path, &mut bufs[0])?;
                let _ = std::fs::remove_file(&ft.path);
                self.in_core(ft.task, &mut bufs)?;
            } else {
                let file = File::open(&ft.path).map_err(|e| MethodError::io(&ft.path, e))?;
                let mut reader = BufReader::with_capacity(IO_BUF, file);
                let mut left = ft.task.n as usize;
                let path = ft.path.clone();
                let kids = self.stream(&ft.task, temps, &mut |block| {
                    let len = left.min(BLOCK);
                    block.clear();
                    if len == 0 {
                        return Ok(false);
                    }
                    block.resize(len, Sample::default());
                    reader
                        .read_exact(bytemuck::cast_slice_mut(block))
                        .map_err(|e| MethodError::io(&path, e))?;
                    left -= len;
                    Ok(true)
                })?;
                let _ = std::fs::remove_file(&ft.path);
                stack.extend(kids.into_iter().rev().flatten());
            }
        }
        Ok(())
    }

    /// Partitions one node out of core: samples come in blocks from `next`, the children
    /// go to new temporary files.
    fn stream(
        &mut self,
        task: &Task,
        temps: &mut Temps,
        next: &mut (dyn FnMut(&mut Vec<Sample>) -> Result<bool, MethodError> + Send),
    ) -> Result<[Option<FileTask>; 2], MethodError> {
        let mut scan = self.cfg.scan_for(task, &mut self.spare);
        let mut paths = Vec::with_capacity(2);
        let mut writers = Vec::with_capacity(2);
        for _ in 0..2 {
            let path = self.dir.join(format!("lpc-part-{}.tmp", self.files));
            self.files += 1;
            temps.0.push(path.clone());
            let f = File::create(&path).map_err(|e| MethodError::io(&path, e))?;
            writers.push(BufWriter::with_capacity(IO_BUF, f));
            paths.push(path);
        }
        let mut block = Vec::with_capacity(BLOCK);
        let mut ahead = Vec::with_capacity(BLOCK);
        self.peak = self
            .peak
            .max(2 * (BLOCK as u64) * RECORD_BYTES + 4 * IO_BUF as u64);
        let mut write = |side: usize, s: &Sample| -> Result<(), MethodError> {
            writers[side]
                .write_all(bytemuck::bytes_of(s))
                .map_err(|e| MethodError::io(&paths[side], e))
        };
        // The next block is fetched (converted / read) while this one is scanned.
        let mut more = next(&mut block)?;
        while more {
            let (scanned, fetched) = rayon::join(
                || -> Result<(), MethodError> {
                    for s in &block {
                        if let Some(side) = scan.step(*s) {
                            write(side, s)?;
                        }
                    }
                    Ok(())
                },
                || next(&mut ahead),
            );
            scanned?;
            more = fetched?;
            std::mem::swap(&mut block, &mut ahead);
        }
        let mc = scan.select();
        scan.give_back(mc, &mut write)?;
        for (w, p) in writers.into_iter().zip(&paths) {
            w.into_inner()
                .map_err(|e| MethodError::io(p, e.into_error()))?;
        }
        let kids = self.close(task, scan, mc)?;
        let mut out = [None, None];
        for side in 0..2 {
            match kids[side] {
                Some(t) => {
                    self.temp_bytes += t.n * RECORD_BYTES;
                    out[side] = Some(FileTask {
                        task: t,
                        path: paths[side].clone(),
                    });
                }
                None => {
                    let _ = std::fs::remove_file(&paths[side]);
                }
            }
        }
        Ok(out)
    }

    /// Partitions the subtree of `root`, whose samples are `bufs[0][..root.n]`, in memory
    /// ([`part`], on the current rayon pool), then commits its nodes in depth-first order.
    fn in_core(&mut self, root: Task, bufs: &mut [Vec<Sample>; 2]) -> Result<(), MethodError> {
        let n = root.n as usize;
        bufs[1].clear();
        bufs[1].resize(n, Sample::default());
        let mut log = Vec::new();
        let (a, b) = bufs.split_at_mut(1);
        let (a, b) = (&mut a[0][..n], &mut b[0][..n]);
        // The probe k-NN reads buffer 0 while the root is partitioned into buffer 1.
        let (probes, first) = rayon::join(
            || {
                if self.estimate {
                    probe_knn(a, root.bbox, LEAF_K)
                } else {
                    Vec::new()
                }
            },
            || split_node(&self.cfg, &root, a, b, &mut (Vec::new(), Vec::new())),
        );
        self.probes.extend(probes);
        let cap = part(&self.cfg, root, a, b, 0, 0, &mut log, Some(first?))?;
        // Each worker holds its own scan buffers.
        let workers = rayon::current_num_threads() as u64;
        self.peak = self.peak.max(
            (bufs[0].capacity() + bufs[1].capacity()) as u64 * RECORD_BYTES
                + workers * cap as u64 * RECORD_BYTES,
        );
        let mut ids = vec![root.id];
        for e in &log {
            let Some(id) = ids.pop() else { break };
            let cloud = &bufs[e.buf][e.start..e.start + e.mc];
            let kids = self.commit(id, &e.closed, cloud)?;
            ids.extend(kids.iter().rev().flatten().map(|t| t.id));
        }
        debug_assert!(ids.is_empty());
        Ok(())
    }
}

fn read_samples(path: &Path, out: &mut [Sample]) -> Result<(), MethodError> {
    let file = File::open(path).map_err(|e| MethodError::io(path, e))?;
    let mut r = BufReader::with_capacity(IO_BUF, file);
    r.read_exact(bytemuck::cast_slice_mut(out))
        .map_err(|e| MethodError::io(path, e))
}

/// Samples per parallel chunk of [`probe_knn`]'s scan.
pub const KNN_CHUNK: usize = 1 << 16;

/// Sorted squared distances of a probe's nearest samples (itself included).
type Best = [f32; LEAF_K + 1];

/// Merges the sorted `b[..k]` into the sorted `a[..k]`, keeping the `k` smallest.
fn merge_best(a: &mut Best, b: &Best, k: usize) {
    let mut out = [f32::INFINITY; LEAF_K + 1];
    let (mut i, mut j) = (0, 0);
    for o in &mut out[..k] {
        // `i + j < k`: both indices stay in range.
        if a[i] <= b[j] {
            *o = a[i];
            i += 1;
        } else {
            *o = b[j];
            j += 1;
        }
    }
    *a = out;
}

/// Bits of the probe-cell filter of [`probe_knn`].
const FILTER_BITS: usize = 1 << 20;

#[inline]
fn filter_bit(key: u64) -> usize {
    (key.wrapping_mul(0xD6E8_FEB8_6659_FD93) >> 44) as usize
}

#[derive(Default)]
struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for b in bytes {
            self.0 = (self.0 ^ *b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    fn write_u64(&mut self, v: u64) {
        let h = v.wrapping_mul(0x9E37_79B9_7F4A_7C15);
        self.0 = h ^ (h >> 29);
    }
}

/// `[nearest, k-th nearest]` neighbour distances of each probe sample of `s`
/// (flagged at load), measured exactly against all of `s` (the probe itself excluded once).
///
/// Linear in `s.len()`: the probes are hashed into a grid of cell size `h` (each into the
/// 27 cells around it); one scan of `s` (in parallel chunks of [`KNN_CHUNK`], whose nearest
/// lists are then merged: the same result for any split) collects, for each probe, the
/// samples within `h`.
/// A probe with fewer than `k` of them is measured again with `2h`. The first `h` is
/// `sqrt(A/n)` with `A` the surface area of the box. A 128 KiB bit filter of the cells that
/// hold probe entries spares most samples the (cache-missing) hash lookup.
pub fn probe_knn(s: &[Sample], bbox: Aabb, k: usize) -> Vec<[f32; 2]> {
    let probes: Vec<[f32; 3]> = s
        .iter()
        .filter(|x| x.flags & PROBE != 0)
        .map(|x| x.p)
        .collect();
    if probes.is_empty() || s.len() < 2 {
        return Vec::new();
    }
    let k = k.clamp(1, s.len() - 1);
    let size = bbox.size();
    let ext = size.max_element();
    if ext <= 0.0 || !ext.is_finite() {
        // Every sample coincides: every distance is 0.
        return vec![[0.0; 2]; probes.len()];
    }
    let area = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
    let mut h = (1.0 * (area / s.len() as f32).sqrt()).max(ext / (1u32 << 19) as f32);
    let mut pending: Vec<u32> = (0..probes.len() as u32).collect();
    let mut out = Vec::with_capacity(probes.len());
    let min = bbox.min;
    while !pending.is_empty() {
        let inv = 1.0 / h;
        let cell = |p: [f32; 3]| {
            let c = (Vec3::from(p) - min) * inv;
            [c.x.floor() as i64, c.y.floor() as i64, c.z.floor() as i64]
        };
        let key = |c: [i64; 3]| {
            ((c[0] + 1) as u64) | ((c[1] + 1) as u64) << 21 | ((c[2] + 1) as u64) << 42
        };
        let mut entries: Vec<(u64, u32)> = Vec::with_capacity(pending.len() * 27);
        for (j, &pi) in pending.iter().enumerate() {
            let c = cell(probes[pi as usize]);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        entries.push((key([c[0] + dx, c[1] + dy, c[2] + dz]), j as u32));
                    }
                }
            }
        }
        entries.sort_unstable();
        let mut filter = vec![0u64; FILTER_BITS / 64];
        let mut map: HashMap<u64, (u32, u32), BuildHasherDefault<KeyHasher>> =
            HashMap::with_capacity_and_hasher(entries.len(), Default::default());
        let mut a = 0;
        while a < entries.len() {
            let mut b = a + 1;
            while b < entries.len() && entries[b].0 == entries[a].0 {
                b += 1;
            }
            map.insert(entries[a].0, (a as u32, b as u32));
            let f = filter_bit(entries[a].0);
            filter[f >> 6] |= 1 << (f & 63);
            a = b;
        }
        // The `k + 1` nearest of every probe, itself included (at distance 0): per chunk of
        // `s`, in parallel, then merged (the same values for any split).
        let kk = k + 1;
        let h2 = h * h;
        let fresh = || vec![[f32::INFINITY; LEAF_K + 1]; pending.len()];
        let scan = |mut best: Vec<Best>, chunk: &[Sample]| {
            for x in chunk {
                let kx = key(cell(x.p));
                let f = filter_bit(kx);
                if filter[f >> 6] & (1 << (f & 63)) == 0 {
                    continue;
                }
                let Some(&(a, b)) = map.get(&kx) else {
                    continue;
                };
                for &(_, j) in &entries[a as usize..b as usize] {
                    let j = j as usize;
                    let q = probes[pending[j] as usize];
                    let d2 = (Vec3::from(x.p) - Vec3::from(q)).length_squared();
                    let bj = &mut best[j][..kk];
                    if d2 <= h2 && d2 < bj[kk - 1] {
                        let mut i = kk - 1;
                        while i > 0 && bj[i - 1] > d2 {
                            bj[i] = bj[i - 1];
                            i -= 1;
                        }
                        bj[i] = d2;
                    }
                }
            }
            best
        };
        let best = s
            .par_chunks(KNN_CHUNK)
            .fold(fresh, scan)
            .reduce_with(|mut x, y| {
                for (u, v) in x.iter_mut().zip(&y) {
                    merge_best(u, v, kk);
                }
                x
            })
            .unwrap_or_else(fresh);
        let mut next = Vec::new();
        for (j, &pi) in pending.iter().enumerate() {
            // `best[j][0]` is the probe itself.
            let d = best[j][k];
            if d <= h2 {
                out.push([best[j][1].sqrt(), d.sqrt()]);
            } else {
                next.push(pi);
            }
        }
        pending = next;
        h *= 2.0;
    }
    out
}

/// Quantile of the `LEAF_K`-th-neighbour distance that sets the splat spacing of
/// [`SpacingRule::Cover90`].
pub const SPACING_QUANTILE: f64 = 0.9;

/// `c_k = √π · Γ(k) / Γ(k + ½)` for `k = LEAF_K` (= 6): for samples placed uniformly at
/// random on a surface with `λ` samples per unit area, the `k`-th-neighbour distance has
/// mean `Γ(k + ½) / (Γ(k) √(πλ))`, so `c_k · mean d_k = 1/√λ = √(A/N)` exactly.
/// `Γ(6) = 120`, `Γ(6.5) = 10395 √π / 64`, so `c_6 = 120 · 64 / 10395 = 0.73882`.
pub const MEAN_SPACING_FACTOR: f64 = 120.0 * 64.0 / 10395.0;

/// `(r, r_nn)` from the probes' `[nearest, LEAF_K-th]` distances. `r` by `rule`:
/// [`SpacingRule::Mean`] `= MEAN_SPACING_FACTOR × mean d_k` (the paper's average spacing
/// `√(A/N)`), [`SpacingRule::Cover90`] `= 2 ×` the [`SPACING_QUANTILE`] of `d_k` (the splat
/// diameter that covers 90 % of the samples' own reference discs); NaN for [`SpacingRule::Area`],
/// which `build` measures on the samples. `r_nn` = the mean
/// nearest-neighbour distance (quantisation). NaN when there are no probes.
pub fn spacing_estimates(probes: &mut [[f32; 2]], rule: SpacingRule) -> (f32, f32) {
    if probes.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    let mean = |i: usize| probes.iter().map(|p| p[i] as f64).sum::<f64>() / probes.len() as f64;
    let nn = mean(0);
    let r = match rule {
        SpacingRule::Mean => (MEAN_SPACING_FACTOR * mean(1)) as f32,
        SpacingRule::Cover90 => {
            probes.sort_unstable_by(|a, b| a[1].total_cmp(&b[1]));
            let at = ((probes.len() - 1) as f64 * SPACING_QUANTILE).round() as usize;
            2.0 * probes[at][1]
        }
        // Measured on the samples, not the probes (`build`).
        SpacingRule::Area => f32::NAN,
    };
    (r, nn as f32)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probe_knn_matches_brute_force() {
        let mut rng = Pcg32::new(2);
        let s: Vec<Sample> = (0..5000)
            .map(|i| Sample {
                p: [rng.f32() * 4.0, rng.f32(), (rng.f32() * 6.0).sin() * 0.2],
                flags: if i % 97 == 0 { PROBE } else { 0 },
                ..Default::default()
            })
            .collect();
        let bbox = Aabb::from_points(&s.iter().map(|x| x.p).collect::<Vec<_>>());
        let got = probe_knn(&s, bbox, LEAF_K);
        let (sum, sum1) = got
            .iter()
            .fold((0f64, 0f64), |(a, b), d| (a + d[1] as f64, b + d[0] as f64));
        let count = got.len();
        let (mut want, mut want1) = (0f64, 0f64);
        let mut wc = 0;
        for (i, q) in s.iter().enumerate().filter(|(_, x)| x.flags & PROBE != 0) {
            let mut d: Vec<f32> = s
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, x)| (Vec3::from(x.p) - Vec3::from(q.p)).length())
                .collect();
            d.sort_by(f32::total_cmp);
            want += d[LEAF_K - 1] as f64;
            want1 += d[0] as f64;
            wc += 1;
        }
        assert_eq!(count, wc);
        assert!((sum - want).abs() < 1e-4 * want, "{sum} vs {want}");
        assert!((sum1 - want1).abs() < 1e-4 * want1, "{sum1} vs {want1}");
    }

    #[test]
    fn spacing_of_a_single_child_chain() {
        // Root N=10, M=4; child N=6, M=4; grandchild N=2, M=2.
        let r = hierarchical_spacing(1.0, &[NONE, 0, 1], &[10, 6, 2], &[4, 4, 2]);
        let r0 = (10.0f64 / 4.0).sqrt();
        // M1tot = 6/6·4 + 4 = 8; r1 = r0·sqrt(6·4/(6·8)).
        let r1 = r0 * (6.0 * 4.0 / (6.0 * 8.0f64)).sqrt();
        // M2tot = 2/2·8 + 2 = 10; r2 = r1·sqrt(2·8/(2·10)).
        let r2 = r1 * (2.0 * 8.0 / (2.0 * 10.0f64)).sqrt();
        assert_eq!(r, vec![r0, r1, r2]);
    }
}
