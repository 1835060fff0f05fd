//! `lpc`: Layered Point Clouds (Gobbetti & Marton, SPBG 2004).
//!
//! Build ([`build`](mod@build)): a binary tree of clouds of about `M` samples, out of core —
//! `M` uniform samples per node by Russian roulette over one linear scan, the remainder split
//! at the midpoint of the longest axis — then the spacing `r_j` of eqs. (1)–(2), a bounding
//! sphere and a normal cone per node. Written as
//! - `index.bin` ([`index`]): the index tree, nodes in repository order (level, then Morton
//!   code of the sphere centre), loaded whole at `open`;
//! - `repo.bin` ([`crate::store`]): one LZO-compressed, checksummed chunk per cloud, each
//!   spatially sorted, quantised and delta-encoded by [`cloud`];
//! - `lpc.json` ([`Info`]): the input spacing `r` and the build's figures.
//!
//! Frame ([`Lpc`], [`traverse`]): the paper's stateless coarse-to-fine traversal. Per node:
//! frustum and normal-cone culling on its sphere; projected spacing = apparent size of a
//! sphere of diameter `r_j` at the sphere point closest to the eye. Below the tolerance: draw
//! the cloud with splat size = tolerance and stop. Above: refine into the (unculled) children
//! if all of them are available now (GPU cache or in core), else draw this cloud with splat
//! size = its projected spacing and queue fetch requests by node index; at the end of the
//! frame the first requests go to the loader, as many as the measured bandwidth delivers in
//! a frame (the paper's rule, [`Lpc::requests_this_frame`]; `fetch_per_frame` overrides
//! it), the rest are forgotten.
//!
//! Budget `B`: bisection of the tolerance with the same traversal counting points, then a
//! fill step that refines single children while they fit (so the count is within one cloud
//! of `B`), never above `B` (README: "Budget").
//!
//! Occlusion culling (`occlusion=true`): the three phases of §4 as an
//! [`crate::OcclusionPass`]: phase 1 draws the clouds visible last frame; the renderer
//! queries every candidate's sphere and draws the visible rest.

pub mod build;
pub mod cloud;
mod effects;
pub mod index;
mod layout;
mod multilevel;
mod partition;
mod sizes;
mod source;
pub mod spacing;
pub mod traverse;

pub use effects::{SPACING_HOLES, known_effect};

use std::path::Path;
use std::sync::Arc;
use std::time::Instant;

use scenes::{Attributes, PointCloud, Progress, View};

use crate::store::access::{BuildFigures, DataAccess, Loader, LoaderOptions, RepoAt, open_figures};
use crate::{
    BuildStats, ChunkId, DrawItem, DrawList, Feedback, LodMethod, Manifest, MethodError,
    MethodStats, OcclusionCandidate, OcclusionPass, Params, SplatBatch, Target,
};
use index::Node;
use traverse::{Selection, Traversal};

/// Registry name.
pub const NAME: &str = "lpc";
/// Version of the on-disk layout.
pub const FORMAT_VERSION: u32 = 1;
/// The index tree.
pub const INDEX_FILE: &str = "index.bin";
/// The cloud repository.
pub const REPO_FILE: &str = "repo.bin";
/// Build figures read at `open`.
pub const INFO_FILE: &str = "lpc.json";

/// Parameters read at `open` only (rendering, data access): a run of an existing build may
/// change them ([`crate::MethodKind::open_with`]).
pub const RUNTIME_PARAMS: &[&str] = &[
    "fetch_per_frame",
    "core_mb",
    "delay_frames",
    "in_flight",
    "occlusion",
    "occlusion_threshold",
    "enlarge",
];

/// How the input spacing `r` of eqs. (1)–(2) is estimated from the samples (README,
/// "Spacings").
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SpacingRule {
    /// The paper's "average spacing between samples": `r = √(A/N)`, the side of the square
    /// each sample owns on the surface, estimated from the mean `LEAF_K`-th-neighbour
    /// distance (`r = c_k · mean d_k`, unbiased for uniformly random samples).
    Mean,
    /// `2 ×` the 90th percentile of the `LEAF_K`-th-neighbour distance: the diameter that
    /// covers 90 % of the reference renderer's per-sample discs.
    Cover90,
    /// The paper's `√(A/N)` with `A` measured as an occupancy area
    /// ([`scenes::spacing::area_spacing`] over the camera framing's inlier box): for scans
    /// sampled in lines or clusters, where nearest neighbours see only the spacing along a
    /// line (README, "Real aerial LiDAR").
    Area,
}

/// Parameters of `lpc` (`--param key=value`).
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct LpcParams {
    /// Samples per cloud `M` (paper: 512–8192, tables with 2048).
    pub m: u32,
    /// Russian-roulette oversampling `K > 1`: about `K·M` samples are kept in one scan,
    /// shuffled, `M` taken and the rest given back to the children.
    pub k: f32,
    /// Seed of the roulette and the shuffle.
    pub seed: u64,
    /// Working memory of the build, MiB: subtrees larger than this are partitioned through
    /// temporary files, smaller ones in memory.
    pub mem_mb: u64,
    /// Input spacing `r` of eqs. (1)–(2) (object units); estimated from the samples by
    /// `spacing_rule` when absent.
    pub spacing: Option<f32>,
    /// How `r` is estimated when `spacing` is not given: `mean` (default, the paper's
    /// "average spacing between samples") or a departure: `cover90` (the splat diameter
    /// that covers 90 % of the reference's per-sample discs; fewer holes, more points) or
    /// `area` (the area per sample from the occupancy area, for line-scanned tiles).
    pub spacing_rule: SpacingRule,
    /// Average sample spacing (mean nearest-neighbour distance) that bounds the position
    /// quantisation error (< half of it); estimated when absent.
    pub nn_spacing: Option<f32>,
    /// Fetch requests issued per frame, overriding the paper's rule (as many as the
    /// measured bandwidth delivers in a frame; see [`Lpc::requests_this_frame`]).
    pub fetch_per_frame: Option<u32>,
    /// Decoded clouds kept in core, MiB.
    pub core_mb: u64,
    /// Frames between a request and the moment its cloud counts as available: simulated
    /// latency, exact for d ≥ 1 (the frame waits for a late decode, so counts repeat); 0 = as
    /// soon as the loader thread has decoded it.
    pub delay_frames: u32,
    /// Requests in flight at once (loader threads); 1 for a local repository, 4 for one
    /// served over HTTP when absent ([`RepoAt::in_flight`]).
    pub in_flight: Option<u32>,
    /// Three-phase occlusion culling with occlusion queries.
    pub occlusion: bool,
    /// Fragments a cloud's sphere must pass to count as visible.
    pub occlusion_threshold: u64,
    /// Which clouds take the enlarged size of a node whose refinement stops above ε:
    /// `layers` (default, the node and its drawn ancestors: the layers whose merged density
    /// its spacing `r_j` is) or `cloud` (the literal reading: the node's cloud alone).
    pub enlarge: traverse::Enlarge,
    /// The box positions are quantised in: `model` (the paper's: "a position quantization
    /// ensuring a quantization error inferior to half of the input sampling distance" over
    /// the model, 3 × 13–15 bits) or `cloud` (a departure, the paper's future work:
    /// "quantizing attributes relative to each cluster's contents"; fewer bits per sample).
    pub quantise: Quantise,
}

/// The box an LPC cloud's positions are quantised in (`--param quantise=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Quantise {
    /// The model's bounding box (the paper's, §6).
    #[default]
    Model,
    /// Each cloud's own bounding box (a departure; the paper's §6 future work).
    Cloud,
}

impl Default for LpcParams {
    fn default() -> Self {
        Self {
            m: 2048,
            k: 2.0,
            seed: 1,
            mem_mb: crate::params::BUILD_MEM_MB,
            spacing: None,
            spacing_rule: SpacingRule::Mean,
            nn_spacing: None,
            fetch_per_frame: None,
            core_mb: 64,
            delay_frames: 0,
            in_flight: None,
            occlusion: false,
            occlusion_threshold: 0,
            enlarge: traverse::Enlarge::Layers,
            quantise: Quantise::Model,
        }
    }
}

impl LpcParams {
    /// Parses and checks `--param` values.
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: LpcParams = params.to_typed(NAME)?;
        let bad = |msg: String| Err(MethodError::Param(format!("method 'lpc': {msg}")));
        if p.m < 1 {
            return bad("m must be ≥ 1".into());
        }
        if !(p.k.is_finite() && p.k > 1.0) {
            return bad(format!("k must be a finite number > 1, got {}", p.k));
        }
        crate::params::check_mb(NAME, "mem_mb", p.mem_mb, 16)?;
        for (name, v) in [("spacing", p.spacing), ("nn_spacing", p.nn_spacing)] {
            if let Some(r) = v
                && !(r.is_finite() && r > 0.0)
            {
                return bad(format!("{name} must be a finite number > 0, got {r}"));
            }
        }
        if p.fetch_per_frame == Some(0) {
            return bad("fetch_per_frame must be ≥ 1".into());
        }
        crate::store::access::check_in_flight(NAME, p.in_flight)?;
        crate::params::check_mb(NAME, "core_mb", p.core_mb, 1)?;
        Ok(p)
    }
}

/// `lpc.json`: figures of a build needed at `open` and reported by `build`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Info {
    /// Splat spacing `r` of eqs. (1)–(2) (object units).
    pub input_spacing: f32,
    /// Mean nearest-neighbour distance: quantisation errors stay below half of it.
    pub nn_spacing: f32,
    /// `M`.
    pub m: u32,
    /// Nodes (= clouds).
    pub nodes: u64,
    /// Levels.
    pub levels: u32,
    /// Input samples.
    pub points: u64,
}

impl BuildFigures for Info {
    fn nodes(&self) -> u64 {
        self.nodes
    }
    fn points(&self) -> u64 {
        self.points
    }
}

/// Builds an LPC into `dir` (see [`build::build`]).
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let p = LpcParams::from_params(params)?;
    // `build::build` writes index, repository and info (the registry adds build.json); the manifest goes
    // last, so a directory with a manifest is complete.
    let stats = build::build(cloud, &p, scene, dir, progress)?;
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: lpc_attributes(cloud.attributes()),
        points: cloud.len() as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    Ok(stats)
}

/// LPC stores what the scene has except radii: every cloud is drawn with one screen-space
/// splat size (the paper's), so a per-sample radius would be stored and never used.
pub fn lpc_attributes(a: Attributes) -> Attributes {
    Attributes { radii: false, ..a }
}

/// An opened LPC.
pub struct Lpc {
    nodes: Vec<Node>,
    info: Info,
    params: LpcParams,
    attributes: Attributes,
    access: Box<dyn DataAccess>,
    traversal: Traversal,
    /// Start of the previous frame.
    last_frame: Option<Instant>,
}

/// Requests per frame when there is no bandwidth to go by (and no `fetch_per_frame`): before
/// the first response and the first frame interval (the warm-up frame), and with a simulated
/// latency (`delay_frames ≥ 1`), whose simulation has no link to measure and whose counts
/// must not depend on the machine's speed. 32 is the fixed count of earlier versions: a
/// first frame that asked for one cloud only would draw its first views coarser than before
/// (measured: `tests/quality.rs` `a_far_stray_changes_neither_the_framing_nor_the_holes`,
/// LPC frame 0 hole ratio 0.0424 against 0.0014, when the warm-up frame asked for one).
pub const UNMEASURED_FETCH_PER_FRAME: u32 = 32;

impl Lpc {
    /// Opens a build directory with the local data-access layer (loader thread).
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        Self::open_at(dir, manifest, &RepoAt::Local(dir.join(REPO_FILE)))
    }

    /// Opens the index and figures of `dir` with the repository at `repo`, local or served
    /// over HTTP (a remote build: `dir` holds copies of its small files).
    pub fn open_at(dir: &Path, manifest: Manifest, repo: &RepoAt) -> Result<Self, MethodError> {
        let p = LpcParams::from_params(&manifest.params)?;
        let nodes = index::read(&dir.join(INDEX_FILE))?;
        let refs = nodes.iter().map(|n| n.chunk).collect();
        let options = LoaderOptions::new(p.core_mb, p.delay_frames, p.in_flight, repo);
        let access = Loader::at(repo, refs, "cloud", Arc::new(cloud::decode), options)?;
        Self::with_access(dir, manifest, nodes, Box::new(access))
    }

    /// Opens with a given data-access layer (the local loader from [`Lpc::open`], or another
    /// [`DataAccess`] such as a future remote source).
    pub fn with_access(
        dir: &Path,
        manifest: Manifest,
        nodes: Vec<Node>,
        access: Box<dyn DataAccess>,
    ) -> Result<Self, MethodError> {
        let params = LpcParams::from_params(&manifest.params)?;
        let info: Info = open_figures(
            &dir.join(INFO_FILE),
            nodes.len(),
            None,
            manifest.points,
            access.as_ref(),
        )?;
        Ok(Self {
            traversal: Traversal::with_enlarge(nodes.len(), params.enlarge),
            nodes,
            info,
            params,
            attributes: manifest.attributes,
            access,
            last_frame: None,
        })
    }

    /// Fetch requests the current frame may issue: `fetch_per_frame` if given; with a
    /// simulated latency [`UNMEASURED_FETCH_PER_FRAME`]; else the paper's rule, "only as many
    /// requests as the estimated bandwidth allows": the chunks per second the source
    /// delivered over its recent responses ([`DataAccess::throughput`]) times the last
    /// frame's duration, rounded up, at least one. Before the first answer and the first
    /// frame interval, [`UNMEASURED_FETCH_PER_FRAME`] too.
    /// `frame_s` is the last frame's duration (`None` in the first frame).
    pub fn requests_this_frame(&self, frame_s: Option<f64>) -> usize {
        if let Some(n) = self.params.fetch_per_frame {
            return n as usize;
        }
        if self.params.delay_frames > 0 {
            return UNMEASURED_FETCH_PER_FRAME as usize;
        }
        match (self.access.throughput(), frame_s) {
            (Some(t), Some(dt)) => ((t.chunks_per_s * dt).ceil() as usize).max(1),
            _ => UNMEASURED_FETCH_PER_FRAME as usize,
        }
    }

    /// The index tree.
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    /// Build figures.
    pub fn info(&self) -> &Info {
        &self.info
    }
    /// Selection for `view` at `target` with the given availability (no fetch, no side
    /// effects): what [`LodMethod::frame`] draws.
    pub fn select(
        &mut self,
        view: &View,
        target: Target,
        cached: &dyn Fn(u32) -> bool,
    ) -> Selection {
        let access = &self.access;
        let avail = |id: u32| cached(id) || access.available(id);
        self.traversal.select(&self.nodes, view, target, &avail)
    }
}

/// Extra CSV columns of `lpc`.
pub const COLUMNS: &[&str] = &[
    "eps_used_px",
    "clouds_coarse",
    "fetch_issued",
    "fetch_dropped",
    "loader_pending",
];

impl LodMethod for Lpc {
    fn chunk_level(&self, id: ChunkId) -> Option<u32> {
        self.nodes.get(usize::try_from(id).ok()?).map(|n| n.level)
    }
    fn attributes(&self) -> Attributes {
        self.attributes
    }
    crate::loads_through_access!(access);
    fn input_points(&self) -> u64 {
        self.info.points
    }
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let target = target.validate()?;
        crate::method::check_budget_above_root(
            NAME,
            "root cloud",
            target,
            self.nodes.first().map(|n| n.points),
        )?;
        self.access.begin_frame();
        let now = Instant::now();
        let frame_s = self
            .last_frame
            .replace(now)
            .map(|t| now.duration_since(t).as_secs_f64());
        let cached = |id: u32| feedback.cached.contains(&(id as ChunkId));
        let sel = self.select(view, target, &cached);
        // End of frame: the queue in priority order (node index), as many requests as the
        // bandwidth allows, the rest forgotten.
        let issue = sel.fetch.len().min(self.requests_this_frame(frame_s));
        for &id in &sel.fetch[..issue] {
            self.access.request(id);
        }
        let items: Vec<(u32, DrawItem)> = sel
            .draws
            .iter()
            .map(|d| {
                (
                    d.node,
                    DrawItem::Chunk {
                        id: d.node as ChunkId,
                        first: 0,
                        points: d.points,
                        size: crate::SplatSize::Pixels(d.size_px),
                    },
                )
            })
            .collect();
        let mut list = DrawList {
            counters: vec![
                sel.eps_px as f64,
                sel.coarse as f64,
                issue as f64,
                (sel.fetch.len() - issue) as f64,
                self.access.pending() as f64,
            ],
            // Everything this selection would refine into but could not: empty once the
            // data it needs are all available (tests settle a view by repeating frames
            // until it is).
            fetch: sel.fetch.iter().map(|&id| id as ChunkId).collect(),
            ..Default::default()
        };
        if self.params.occlusion {
            let mut candidates = Vec::with_capacity(items.len());
            for (node, item) in items {
                let n = &self.nodes[node as usize];
                // Phase 1 draws the clouds visible last frame; the others wait for their query.
                let item = if feedback.visible.contains(&(node as ChunkId)) {
                    list.items.push(item);
                    None
                } else {
                    Some(item)
                };
                candidates.push(OcclusionCandidate {
                    id: node as ChunkId,
                    center: n.center,
                    radius: n.radius,
                    item,
                });
            }
            list.occlusion = Some(OcclusionPass {
                candidates,
                threshold: self.params.occlusion_threshold,
            });
        } else {
            list.items = items.into_iter().map(|(_, i)| i).collect();
        }
        Ok(list)
    }
    fn chunk(&self, id: ChunkId) -> Result<Arc<SplatBatch>, MethodError> {
        let id = u32::try_from(id)
            .ok()
            .filter(|&i| (i as usize) < self.nodes.len())
            .ok_or(MethodError::NoChunk(id))?;
        self.access.get(id)
    }
    fn stats(&self) -> MethodStats {
        MethodStats {
            resident_bytes: std::mem::size_of_val(self.nodes.as_slice()) as u64
                + self.access.resident_bytes(),
            nodes: self.nodes.len() as u64,
            levels: self.info.levels,
        }
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        COLUMNS
    }
    fn occlusion_culled(&self) -> bool {
        self.params.occlusion
    }
}
