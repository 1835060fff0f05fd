//! `spt`: Sequential Point Trees (Dachsbacher, Vogelgsang, Stamminger, SIGGRAPH 2003).
//!
//! Build ([`build`]): a point tree over the samples ([`build`](mod@build) module: octree,
//! node disks, errors from [`errors`]), flattened into one list sorted by the parent's error
//! descending (per normal cluster when `normal_clusters=true`), written quantised
//! ([`quant`] says what is rounded which way and why the selection keeps its guarantees;
//! [`files`] has the layouts) as
//! - `nodes.bin`: one record per node in list order: the centre on the build's position
//!   grid, a 24-bit octahedral normal and an sRGB colour where the scene has them, the radius
//!   `d/2` as a 16-bit code on the build's scale, rounded up;
//! - `lod.bin`: the per-node `lod` entries ([`select`] documents the four floats): `e` and
//!   `e_par` exact (coded losslessly), `δ` as a 16-bit code (rounded up), and the `φ`/`γ` word
//!   only in split mode;
//! - `index.json`: clusters (list range, normal cone, bounding sphere) and chunks (≤
//!   [`CHUNK_NODES`] consecutive nodes of one cluster, with max `e_par` and a bounding sphere).
//!
//! Frame ([`Spt`]): per cluster, `r_lo` = lower bound of the eye distance over its bounding
//! sphere (with `bound=box`, also its box of node centres: [`Spt::r_lo`]); binary search of the prefix that can pass ([`select::prefix_len`]); one
//! [`DrawItem::Sequential`] per chunk with a non-empty prefix, the test `IntervalTest { mode,
//! scale: ε/k, overlap }` for the vertex stage ([`select::interval_pass`] is its CPU mirror),
//! splat size `2·(d/2)·k/z`. CPU work is O(clusters · log n).
//!
//! Budget `B`: the smallest scale `s` (largest ε) whose total prefix is ≤ B, by bisection on
//! `log s` (the prefix is non-increasing in `s`). When no `s` gets there (the eye inside a
//! cluster's sphere makes `r_lo = 0`), each cluster's prefix is cut proportionally to fit B
//! (coarse nodes first; holes possible, documented in the README). `points()` (the prefixes)
//! never exceeds B.
//!
//! Limits: the whole list is resident on the GPU (the paper's limitation); `open` refuses a
//! model whose GPU bytes exceed `gpu_limit_mb`.

pub mod build;
pub mod errors;
pub mod files;
mod inner;
pub mod list;
pub mod ooc;
mod params;
pub mod quant;
pub mod select;
mod write;

pub use files::{ChunkInfo, ClusterInfo, Index};
use files::{NodeFile, read_lod};
pub use params::{SptBound, SptMode, SptParams};
pub use write::{build, build_with_budget};

use std::path::Path;

use glam::Vec3;
use rayon::prelude::*;
use scenes::{Attributes, View};

use crate::{
    ChunkId, DrawItem, DrawList, Feedback, IntervalTest, LodMethod, Manifest, MethodError,
    MethodStats, Params, SplatBatch, SplatSize, SplatTest, Target,
};
use build::NO_PARENT;
pub(crate) use inner::InnerNodes;
use select::{MODE_SPLIT, MODE_UNIFIED, ROOT_PARENT_ERROR};

/// Registry name.
pub const NAME: &str = "spt";
/// Largest chunk (nodes): 3 MiB of positions fit every storage binding.
pub const CHUNK_NODES: usize = 1 << 18;
/// Parameters read at `open` only (a run of an existing build may change them): the
/// bounding volume of `r_lo` is computed from the index when the build is opened.
pub const RUNTIME_PARAMS: &[&str] = &["bound"];
/// Version of the on-disk layout (2: quantised `nodes.bin` and `lod.bin`; 1 had a column
/// file and `f32` entries).
pub const FORMAT_VERSION: u32 = 2;
/// The node records.
pub const NODES_FILE: &str = "nodes.bin";
/// The `lod` entries.
pub const LOD_FILE: &str = "lod.bin";
const INDEX_FILE: &str = "index.json";

pub(crate) fn sphere_of(points: impl Iterator<Item = (Vec3, f32)> + Clone) -> ([f32; 3], f32) {
    let (lo, hi) = points.clone().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), (p, _)| (lo.min(p), hi.max(p)),
    );
    let c = (lo + hi) * 0.5;
    let r = points
        .map(|(p, r)| p.distance(c) + r)
        .fold(0.0f32, f32::max);
    (c.to_array(), r * (1.0 + 1e-5))
}

/// Bytes one node takes on the GPU with these attributes (position, normal, colour, radius,
/// lod).
pub fn gpu_bytes_per_node(attrs: Attributes) -> u64 {
    12 + 4 * attrs.normals as u64 + 4 * attrs.colors as u64 + 4 + 16
}

/// The `lod` entry of every node of a tree, in tree order ([`select`] documents the layout):
/// `[e_g, parent e_g (ROOT_PARENT_ERROR at the root), δ = |p − p_parent|·(1 + 1e-5), packed φ,
/// φ_par, γ]`.
pub fn lod_entries(nodes: &[build::Node]) -> Vec<[f32; 4]> {
    nodes
        .par_iter()
        .map(|nd| {
            let parent = (nd.parent != NO_PARENT).then(|| &nodes[nd.parent as usize]);
            lod_entry(nd, parent)
        })
        .collect()
}

/// The `lod` entry of `nd` whose parent is `parent` (`None` at the root), for the exact
/// centres: `e` and `e_par` are stored exactly; `δ` is the writer's to raise for the
/// rounding of the centres and round up ([`list::ListWriter`]); `γ` bounds the angles
/// between both the exact and the stored normals.
pub fn lod_entry(nd: &build::Node, parent: Option<&build::Node>) -> [f32; 4] {
    match parent {
        None => select::pack_lod(
            nd.e_g,
            ROOT_PARENT_ERROR,
            0.0,
            nd.phi_q,
            select::PHI_STEPS as u32,
            select::GAMMA_UNBOUNDED,
        ),
        Some(par) => {
            let delta = nd.p.distance(par.p) * (1.0 + 1e-5) + f32::MIN_POSITIVE;
            // Without normals every node's normal is `Vec3::Z`: the same γ for all, computed
            // once by the same function (it was most of this function's time there).
            static GAMMA_Z: std::sync::LazyLock<u32> =
                std::sync::LazyLock::new(|| gamma_code(Vec3::Z, Vec3::Z));
            let gamma = if nd.n == Vec3::Z && par.n == Vec3::Z {
                *GAMMA_Z
            } else {
                gamma_code(nd.n, par.n)
            };
            select::pack_lod(nd.e_g, par.e_g, delta, nd.phi_q, par.phi_q, gamma)
        }
    }
}

/// The quantised γ of a node of normal `n` whose parent's normal is `par`: the larger of the
/// angles between the exact and between the stored normals, plus 1e-3.
fn gamma_code(n: Vec3, par: Vec3) -> u32 {
    let angle = |a: Vec3, b: Vec3| a.dot(b).clamp(-1.0, 1.0).acos();
    let stored = |n: Vec3| quant::decode_normal(quant::normal_code(n));
    select::quantize_gamma(angle(n, par).max(angle(stored(n), stored(par))) + 1e-3)
}

/// The list's sort key of node `id` with `lod` entry `lod` in normal cluster `cluster`:
/// cluster ascending, then parent error descending, then own error descending, then node
/// index (a total order, so the list is unique).
pub fn list_key(cluster: u32, lod: &[f32; 4], id: u32) -> u128 {
    let descending = |x: f32| u128::from(!crate::sortkey::f32_total_order(x));
    (u128::from(cluster) << 96)
        | (descending(lod[1]) << 64)
        | (descending(lod[0]) << 32)
        | id as u128
}

/// What writing the list reports to [`build`].
pub(crate) struct Listed {
    /// `index.json`'s contents.
    pub index: Index,
    /// Inner nodes, with their errors against the paper's bound.
    pub inner: InnerNodes,
    /// Leaf radii capped as isolated.
    pub radii_capped: u64,
    /// Seconds until the tree was built.
    pub tree_seconds: f64,
    /// Units built one at a time (1: in memory).
    pub units: u64,
}

/// The normal cluster of a node of normal `n`.
pub(crate) fn cluster_of(p: &SptParams, has_normals: bool, n: Vec3) -> u32 {
    if p.normal_clusters && has_normals {
        select::cluster_of(n) as u32
    } else {
        0
    }
}

/// The error for a node whose `lod` entry is not finite.
pub(crate) fn non_finite(id: u64, lod: &[f32; 4], nd: &build::Node) -> MethodError {
    MethodError::Limit(format!(
        "spt: node {id} got a non-finite lod entry {lod:?} (centre {}, radius {})",
        nd.p, nd.r
    ))
}

/// An opened SPT build.
pub struct Spt {
    nodes: NodeFile,
    attrs: Attributes,
    params: SptParams,
    index: Index,
    lod: Vec<[f32; 4]>,
    /// Suffix maximum of `δ` within each cluster (for the prefix search).
    d_suffix: Vec<f32>,
    /// `lod[i][1]` as a contiguous column (for the prefix search).
    e_par: Vec<f32>,
    /// Per cluster, the axis-aligned box `(min, max)` of its node centres (`bound=box`).
    boxes: Vec<(Vec3, Vec3)>,
    input_points: u64,
}

/// What one frame selected (before turning into draw items).
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The test sent with every item.
    pub test: IntervalTest,
    /// Prefix per cluster (0 for skipped clusters).
    pub prefixes: Vec<u64>,
    /// Clusters skipped as back-facing.
    pub clusters_skipped: u32,
    /// Nodes at the start of the prefixes that a left bound could skip ([`Spt::left_bounds`]).
    pub left_skippable: u64,
}

impl Spt {
    /// Opens a build directory; refuses a model larger than `gpu_limit_mb`.
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        manifest.expect_version(dir, FORMAT_VERSION)?;
        let params = SptParams::parse(&manifest.params, manifest.attributes)?;
        let index_path = dir.join(INDEX_FILE);
        let text =
            std::fs::read_to_string(&index_path).map_err(|e| MethodError::io(&index_path, e))?;
        let index: Index = serde_json::from_str(&text)
            .map_err(|e| MethodError::corrupt(&index_path, e.to_string()))?;
        // index.json is not checksummed: its counts are any u64, and must not overflow.
        let bytes = index
            .nodes
            .saturating_mul(gpu_bytes_per_node(manifest.attributes));
        let limit = params.gpu_limit_mb.saturating_mul(1 << 20);
        if bytes > limit {
            return Err(MethodError::Limit(format!(
                "spt: the model needs {:.1} MiB of GPU memory ({} nodes × {} bytes, all resident), \
                 more than gpu_limit_mb = {} MiB",
                bytes as f64 / (1u64 << 20) as f64,
                index.nodes,
                gpu_bytes_per_node(manifest.attributes),
                params.gpu_limit_mb
            )));
        }
        let nodes = NodeFile::read(&dir.join(NODES_FILE), index.nodes, manifest.attributes)?;
        let mut next = 0u64;
        for (i, c) in index.clusters.iter().enumerate() {
            if c.start != next || c.count == 0 {
                return Err(MethodError::corrupt(
                    &index_path,
                    format!(
                        "cluster {i} covers {}..+{}, expected start {next}",
                        c.start, c.count
                    ),
                ));
            }
            next = next.saturating_add(c.count);
        }
        let mut cnext = 0u64;
        for (i, c) in index.chunks.iter().enumerate() {
            let in_cluster = index.clusters.get(c.cluster as usize).is_some_and(|cl| {
                c.start >= cl.start
                    && c.start.saturating_add(u64::from(c.count))
                        <= cl.start.saturating_add(cl.count)
            });
            if c.start != cnext || c.count == 0 || !in_cluster {
                return Err(MethodError::corrupt(
                    &index_path,
                    format!(
                        "chunk {i} ({}..+{}) does not tile its cluster",
                        c.start, c.count
                    ),
                ));
            }
            cnext = cnext.saturating_add(u64::from(c.count));
        }
        if next != index.nodes || cnext != index.nodes {
            return Err(MethodError::corrupt(
                &index_path,
                format!(
                    "clusters/chunks cover {next}/{cnext} of {} nodes",
                    index.nodes
                ),
            ));
        }
        let lod = read_lod(
            &dir.join(LOD_FILE),
            index.nodes,
            params.mode == SptMode::Split,
        )?;
        let e_par: Vec<f32> = lod.iter().map(|l| l[1]).collect();
        let mut d_suffix = vec![0f32; lod.len()];
        for c in &index.clusters {
            let mut m = 0f32;
            for i in (c.start as usize..(c.start + c.count) as usize).rev() {
                m = m.max(lod[i][2]);
                d_suffix[i] = m;
                if i + 1 < (c.start + c.count) as usize && e_par[i] < e_par[i + 1] {
                    return Err(MethodError::corrupt(
                        dir.join(LOD_FILE),
                        format!("node {i}: list not sorted by parent error"),
                    ));
                }
            }
        }
        let boxes = index
            .clusters
            .iter()
            .map(|c| {
                (c.start as usize..(c.start + c.count) as usize).fold(
                    (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                    |(lo, hi), i| {
                        let p = nodes.position(i);
                        (lo.min(p), hi.max(p))
                    },
                )
            })
            .collect();
        Ok(Self {
            attrs: manifest.attributes,
            nodes,
            params,
            index,
            lod,
            d_suffix,
            e_par,
            boxes,
            input_points: manifest.points,
        })
    }

    /// The index (clusters and chunks).
    pub fn index(&self) -> &Index {
        &self.index
    }

    /// The `lod` entries of all nodes, in list order.
    pub fn lod(&self) -> &[[f32; 4]] {
        &self.lod
    }

    /// Node `i`'s centre (list order) as decoded from `nodes.bin`: the one the GPU draws.
    pub fn position(&self, i: usize) -> Vec3 {
        self.nodes.position(i)
    }

    /// Node `i`'s radius as decoded from `nodes.bin`.
    pub fn radius(&self, i: usize) -> f32 {
        self.nodes.radius(i)
    }

    /// The node records (`nodes.bin`, decoded on demand).
    pub fn nodes(&self) -> &NodeFile {
        &self.nodes
    }

    /// The normal the GPU sees for node `i` (the stored octahedral code decoded; `Vec3::Z`
    /// without normals).
    pub fn gpu_normal(&self, i: usize) -> Vec3 {
        self.nodes.normal(i)
    }

    /// The interval test at tolerance `eps` px for `view` (mode and overlap from the params).
    pub fn test_for(&self, view: &View, eps: f32) -> IntervalTest {
        self.test_with_scale(eps / view.proj_scale())
    }

    fn test_with_scale(&self, scale: f32) -> IntervalTest {
        IntervalTest {
            mode: match self.params.mode {
                SptMode::Unified => MODE_UNIFIED,
                SptMode::Split => MODE_SPLIT,
            },
            scale,
            overlap: self.params.overlap,
        }
    }

    fn passes(&self, i: usize, eye: Vec3, test: &IntervalTest) -> bool {
        select::interval_pass(
            self.nodes.position(i),
            self.gpu_normal(i),
            self.lod[i],
            eye,
            test,
        )
    }

    /// CPU mirror over the whole list: the indices (list order) of nodes passing the interval
    /// test at tolerance `eps` px (no cluster culling, no prefix).
    pub fn cpu_select(&self, view: &View, eps: f32) -> Vec<u32> {
        let test = self.test_for(view, eps);
        let eye = view.camera.position;
        (0..self.lod.len())
            .filter(|&i| self.passes(i, eye, &test))
            .map(|i| i as u32)
            .collect()
    }

    /// CPU mirror of a draw list: the nodes of its `Sequential` prefixes that pass their test.
    pub fn cpu_passed_in(&self, view: &View, list: &DrawList) -> Vec<u32> {
        let eye = view.camera.position;
        let mut out = Vec::new();
        for item in &list.items {
            if let DrawItem::Sequential {
                id,
                prefix,
                test: SplatTest::Interval(test),
                ..
            } = item
                && let Some(c) = self.index.chunks.get(*id as usize)
            {
                let s = c.start as usize;
                out.extend(
                    (s..s + *prefix as usize)
                        .filter(|&i| self.passes(i, eye, test))
                        .map(|i| i as u32),
                );
            }
        }
        out
    }

    fn cluster_skipped(&self, eye: Vec3) -> Vec<bool> {
        self.index
            .clusters
            .iter()
            .map(|c| {
                self.params.normal_clusters
                    && crate::cull::cone_backfacing(
                        Vec3::from(c.axis),
                        c.half_angle,
                        Vec3::from(c.center),
                        c.radius,
                        eye,
                    )
            })
            .collect()
    }

    /// The lower bound `r_lo` of the view distance over cluster `ci`'s node centres that the
    /// prefix search uses (`bound` parameter).
    pub fn r_lo(&self, ci: usize, eye: Vec3) -> f64 {
        let c = &self.index.clusters[ci];
        let sphere = select::sphere_distance_lower_bound(eye, Vec3::from(c.center), c.radius);
        match self.params.bound {
            SptBound::Sphere => sphere,
            SptBound::Box => {
                let (lo, hi) = self.boxes[ci];
                sphere.max(select::box_distance_lower_bound(eye, lo, hi))
            }
        }
    }

    /// §3.4: the list could be bounded on the left too: "The benefit is small, because the
    /// number of inner nodes in a tree of average branching factor 4 is small relative to
    /// the children." Not used for drawing; counted: in each cluster, the nodes at the start
    /// of its prefix whose own error fails the interval test's lower bound (too coarse) at
    /// every distance the cluster's node centres can have (`r ≤ |eye − centre| + radius`)
    /// and at every view angle (split errors: the least factor `min(sin φ, cos φ)`), up to
    /// the first that might pass. A left bound would skip exactly these: their count per
    /// cluster.
    pub fn left_bounds(&self, s: f32, eye: Vec3, prefixes: &[u64]) -> Vec<u64> {
        let split = self.params.mode == SptMode::Split;
        self.index
            .clusters
            .iter()
            .zip(prefixes)
            .map(|(c, &len)| {
                let r_hi = eye.distance(Vec3::from(c.center)) + c.radius;
                let start = c.start as usize;
                self.lod[start..start + len as usize]
                    .iter()
                    .take_while(|l| {
                        let g = if split {
                            let hi = (l[3] / 256.0).floor();
                            let phi = (hi / 256.0).floor()
                                * (std::f32::consts::FRAC_PI_2 / select::PHI_STEPS);
                            phi.sin().min(phi.cos())
                        } else {
                            1.0
                        };
                        l[0] * g > s * r_hi
                    })
                    .count() as u64
            })
            .collect()
    }

    fn prefixes(&self, s: f32, eye: Vec3, skipped: &[bool]) -> Vec<u64> {
        self.index
            .clusters
            .iter()
            .zip(skipped)
            .enumerate()
            .map(|(ci, (c, &skip))| {
                if skip {
                    return 0;
                }
                let r = c.start as usize..(c.start + c.count) as usize;
                let r_lo = self.r_lo(ci, eye);
                select::prefix_len(
                    &self.e_par[r.clone()],
                    &self.d_suffix[r],
                    s,
                    self.params.overlap,
                    r_lo,
                ) as u64
            })
            .collect()
    }

    /// Selects the prefixes for `view` at `target` (validated).
    pub fn select(&self, view: &View, target: Target) -> Result<Selection, MethodError> {
        let target = target.validate()?;
        let eye = view.camera.position;
        let skipped = self.cluster_skipped(eye);
        let clusters_skipped = skipped.iter().filter(|&&s| s).count() as u32;
        let (scale, prefixes) = match target {
            Target::Tolerance(eps) => {
                let s = (eps / view.proj_scale()).min(f32::MAX);
                (s, self.prefixes(s, eye, &skipped))
            }
            Target::Budget(b) => self.budget(b, eye, &skipped),
        };
        let left_skippable = self.left_bounds(scale, eye, &prefixes).iter().sum();
        Ok(Selection {
            test: self.test_with_scale(scale),
            prefixes,
            clusters_skipped,
            left_skippable,
        })
    }

    fn budget(&self, b: u64, eye: Vec3, skipped: &[bool]) -> (f32, Vec<u64>) {
        let total = |p: &[u64]| p.iter().sum::<u64>();
        let p0 = self.prefixes(0.0, eye, skipped);
        if total(&p0) <= b {
            return (0.0, p0);
        }
        // Find hi with total ≤ b by doubling, then bisect log s.
        let (mut lo, mut hi) = (0.0f32, 2f32.powi(-40));
        let mut p_hi = self.prefixes(hi, eye, skipped);
        while total(&p_hi) > b && hi < 2f32.powi(100) {
            lo = hi;
            hi *= 2.0;
            p_hi = self.prefixes(hi, eye, skipped);
        }
        if total(&p_hi) > b {
            // Unreachable by the tolerance alone: cut every prefix proportionally.
            let t = total(&p_hi) as u128;
            let cut = p_hi
                .iter()
                .map(|&p| (p as u128 * b as u128 / t) as u64)
                .collect();
            return (hi, cut);
        }
        for _ in 0..32 {
            let mid = if lo > 0.0 { (lo * hi).sqrt() } else { hi * 0.5 };
            if !(mid > lo && mid < hi) {
                break;
            }
            let p = self.prefixes(mid, eye, skipped);
            if total(&p) <= b {
                hi = mid;
                p_hi = p;
            } else {
                lo = mid;
            }
        }
        (hi, p_hi)
    }
}

/// Extra CSV columns of `spt`.
pub const EXTRA_COLUMNS: &[&str] = &[
    "prefix_points",
    "cpu_passed",
    "clusters_skipped",
    "left_bound_points",
];

impl LodMethod for Spt {
    fn attributes(&self) -> Attributes {
        self.attrs
    }
    fn input_points(&self) -> u64 {
        self.input_points
    }
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        _feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let sel = self.select(view, target)?;
        let size = SplatSize::Radius {
            scale: 1.0,
            min_px: 1.0,
        };
        let mut items = Vec::new();
        for (id, c) in self.index.chunks.iter().enumerate() {
            let cl = &self.index.clusters[c.cluster as usize];
            let into = c.start - cl.start;
            let prefix = sel.prefixes[c.cluster as usize]
                .saturating_sub(into)
                .min(c.count as u64);
            if prefix > 0 {
                items.push(DrawItem::Sequential {
                    id: id as ChunkId,
                    prefix: prefix as u32,
                    test: sel.test.into(),
                    size,
                });
            }
        }
        let mut list = DrawList {
            items,
            ..Default::default()
        };
        let cpu = if self.params.cpu_mirror {
            self.cpu_passed_in(view, &list).len() as f64
        } else {
            f64::NAN
        };
        list.counters = vec![
            sel.prefixes.iter().sum::<u64>() as f64,
            cpu,
            sel.clusters_skipped as f64,
            sel.left_skippable as f64,
        ];
        Ok(list)
    }
    fn chunk(&self, id: ChunkId) -> Result<std::sync::Arc<SplatBatch>, MethodError> {
        let c = usize::try_from(id)
            .ok()
            .and_then(|i| self.index.chunks.get(i))
            .ok_or(MethodError::NoChunk(id))?;
        let range = c.start as usize..(c.start as usize + c.count as usize);
        let mut batch = self.nodes.batch(range.clone());
        batch.lod = Some(self.lod[range].to_vec());
        Ok(std::sync::Arc::new(batch))
    }
    fn stats(&self) -> MethodStats {
        MethodStats {
            resident_bytes: (self.lod.len() * 16 + self.e_par.len() * 8) as u64
                + self.nodes.bytes(),
            nodes: self.index.nodes,
            levels: self.index.levels,
        }
    }
    fn interval_tested(&self) -> bool {
        true
    }
    /// The splats passing the interval test ([`Spt::cpu_passed_in`]; equals
    /// [`crate::method::count_drawn`], without copying chunks).
    fn drawn_points(&self, view: &View, list: &DrawList) -> Result<u64, MethodError> {
        Ok(self.cpu_passed_in(view, list).len() as u64)
    }
    fn gpu_resident_bytes(&self) -> Option<u64> {
        Some(self.index.nodes * gpu_bytes_per_node(self.attrs))
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        EXTRA_COLUMNS
    }
}
