//! `mwkd`: the multi-way kd-tree of Goswami, Erol, Mukhi, Pajarola and Gobbetti (~2010;
//! `/work/shared/papers/mwkd-multiway-kd-tree.txt`, `/work/shared/METHODS.md`).
//!
//! Build ([`build`](mod@build)): the fully balanced `N`-ary kd-tree ([`tree::Tree::split`];
//! [`tree::Plan`] gives its shape from `(n, N, s)` alone and reproduces the paper's Table
//! II), representatives bottom-up ([`reps`]), every node encoded by [`codec`] into one LZO
//! chunk with a checksum in `repo.bin`, and the index array `index.bin` ([`index`]). For the
//! paper's Table IV ablation, `tree=kd` (binary) or `tree=octree` build the same
//! representatives and files over another split. A cloud larger than `mem_mb` allows is
//! built in units ([`ooc`]), into the same files.
//!
//! Frame ([`Mwkd`]): the front from [`select`] (the paper's `LODSelection` on a budget, or
//! projected pixel size for `--eps`), then the frame-to-frame transitions of the paper's
//! asynchronous loading: a front node not in core yet is stood in for by what the previous
//! frame drew there (an ancestor, or descendants covering it), or, for a region new to the
//! front, by the parent of its sibling group read synchronously — never a hole. Splats carry
//! their radius, projected in the vertex stage.
//!
//! See `README.md` next to this file for the rules and what is faithful or deviating.

pub mod build;
pub mod codec;
pub mod index;
pub mod ooc;
mod params;
pub mod reps;
pub mod select;
pub mod tree;

use std::path::Path;
use std::sync::Arc;

use scenes::{Attributes, PointCloud, Progress, View};

use crate::store::access::{BuildFigures, DataAccess, Loader, LoaderOptions, RepoAt, open_figures};
use crate::{
    BuildStats, ChunkId, DrawItem, DrawList, Feedback, LodMethod, Manifest, MethodError,
    MethodStats, OcclusionCandidate, OcclusionPass, Params, SplatBatch, SplatSize, Target,
};
use index::IndexNode;
pub use params::{
    Clustering, LoadMode, MwkdParams, OCTREE_MAX_DEPTH, QueueOrder, RUNTIME_PARAMS, TreeKind,
};
use select::{Ctx, Front};

/// Registry name (and `splatbench plan --method` value).
pub const NAME: &str = "mwkd";
/// Version of the on-disk layout.
pub const FORMAT_VERSION: u32 = 1;
/// The index array.
pub const INDEX_FILE: &str = "index.bin";
/// Samples of one parallel task of the in-memory build: `mem_mb·2²⁰ / 64` (and at most
/// `n/16`); the output does not depend on it.
const TASK_BYTES_PER_SAMPLE: u64 = 64;
/// What `mwkd.json` records about a build (read at `open`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Info {
    /// Hierarchy built.
    pub tree: TreeKind,
    /// Fan-out used by the split.
    pub fanout: u32,
    /// VBO size `s`.
    pub vbo: u64,
    /// Nodes.
    pub nodes: u64,
    /// Levels (deepest leaf + 1).
    pub levels: u32,
    /// Input samples.
    pub points: u64,
    /// Splats stored in all nodes together.
    pub samples_stored: u64,
}

/// Build figures read at `open`.
pub const INFO_FILE: &str = "mwkd.json";

impl BuildFigures for Info {
    fn nodes(&self) -> u64 {
        self.nodes
    }
    fn points(&self) -> u64 {
        self.points
    }
}

/// What MWKD stores: the scene's normals and colours if it has them, and always a radius
/// per splat (representatives have their own, and every splat is drawn at its projected
/// radius).
pub fn mwkd_attributes(a: Attributes) -> Attributes {
    Attributes { radii: true, ..a }
}

/// Builds an MWKD (or, with `tree=`, an ablation tree) of `cloud` into `dir`: `repo.bin`,
/// `index.bin`, `mwkd.json`, then the manifest last, so a directory with a manifest is
/// complete.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let t0 = std::time::Instant::now();
    let p = MwkdParams::from_params(params)?;
    let n = cloud.len() as u64;
    let mem_bytes = p.mem_mb << 20;
    let depth = tree::leaf_depth(n, u64::from(p.effective_fanout()), p.vbo)?;
    let repo = dir.join(codec::REPO_FILE);
    // In units when the cloud exceeds one (the balanced trees; see `ooc`), else in memory.
    let in_units = p.tree != TreeKind::Octree && depth > 0 && n > ooc::unit_capacity(mem_bytes);
    let (written, nodes, depth, units, t_split, task_points) = if in_units {
        let shape = p.ooc_shape();
        let budget = crate::spill::Budget {
            mem_bytes,
            dir,
            hook: None,
        };
        let b = ooc::write_repository(cloud, shape, &repo, budget, progress)?;
        (b.written, b.nodes, b.depth, b.units, b.split_seconds, None)
    } else {
        progress.start("mwkd: split", n);
        let tree = p.split(cloud.positions())?;
        progress.finish();
        let t_split = t0.elapsed().as_secs_f64();
        // Parallel granularity only: the output does not depend on it.
        let task_points = ((mem_bytes / TASK_BYTES_PER_SAMPLE).min((n / 16).max(1))) as usize;
        let input = build::Input {
            cols: build::Columns::of(cloud),
            tree: &tree,
            reps: p.rep_config(),
        };
        let written =
            build::write_repository(&input, &repo, task_points, p.compression(), progress)?;
        (
            written,
            tree.nodes,
            tree.depth,
            1,
            t_split,
            Some(task_points),
        )
    };
    let index_path = dir.join(INDEX_FILE);
    let index_bytes = index::write(&index_path, &written.index)?;
    let levels = depth + 1;
    let samples_stored: u64 = written.index.iter().map(|n| u64::from(n.points)).sum();
    let info = Info {
        tree: p.tree,
        fanout: p.effective_fanout(),
        vbo: p.vbo,
        nodes: written.index.len() as u64,
        levels,
        points: cloud.len() as u64,
        samples_stored,
    };
    crate::method::write_json(&dir.join(INFO_FILE), &info)?;
    let mut extra = serde_json::Map::new();
    let mut put = |k: &str, v: serde_json::Value| {
        extra.insert(k.into(), v);
    };
    put("tree", serde_json::to_value(p.tree).unwrap_or_default());
    put("fanout", p.effective_fanout().into());
    put("vbo", p.vbo.into());
    put("grid", p.grid.into());
    put(
        "leaves",
        (nodes.iter().filter(|n| n.child_count == 0).count() as u64).into(),
    );
    put("samples_stored", samples_stored.into());
    // Fig. 1 and §3: leaves at one depth holding "almost the same number of points", inner
    // nodes of a constant output size s (the VBO size).
    let range = |it: &mut dyn Iterator<Item = u64>| {
        it.fold((u64::MAX, 0), |(lo, hi), x| (lo.min(x), hi.max(x)))
    };
    let leaves = || nodes.iter().filter(|n| n.child_count == 0);
    let (lmin, lmax) = range(&mut leaves().map(|n| n.len as u64));
    let (dmin, dmax) = range(&mut leaves().map(|n| u64::from(n.level)));
    put("leaf_points_min", lmin.into());
    put("leaf_points_max", lmax.into());
    put("leaf_level_min", dmin.into());
    put("leaf_level_max", dmax.into());
    let (imin, imax) = range(
        &mut written
            .index
            .iter()
            .zip(&nodes)
            .filter(|(_, n)| n.child_count > 0)
            .map(|(x, _)| u64::from(x.points)),
    );
    if imin <= imax {
        put("inner_points_min", imin.into());
        put("inner_points_max", imax.into());
    }
    put("raw_bytes", written.raw_bytes.into());
    put("repo_bytes", written.repo_bytes.into());
    put("index_bytes", index_bytes.into());
    put(
        "compression_ratio",
        (written.repo_bytes as f64 / written.raw_bytes.max(1) as f64).into(),
    );
    put("split_seconds", t_split.into());
    put("units", units.into());
    if let Some(t) = task_points {
        put("task_points", (t as u64).into());
    }
    let stats = BuildStats {
        points_in: cloud.len() as u64,
        nodes: written.index.len() as u64,
        levels,
        bytes_in: cloud.column_bytes(),
        bytes_out: index_bytes + written.repo_bytes,
        bits_per_sample: 0.0,
        seconds: t0.elapsed().as_secs_f64(),
        points_per_s: 0.0,
        extra,
    }
    .finish();
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: mwkd_attributes(cloud.attributes()),
        points: cloud.len() as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    Ok(stats)
}

/// Extra CSV columns of `mwkd`.
pub const COLUMNS: &[&str] = &[
    "front_nodes",
    "front_points",
    "nodes_culled",
    "nodes_waiting",
    "stand_ins",
    "sync_loads",
    "loader_pending",
];

/// Counters of one frame (the extra CSV columns).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameCounters {
    /// Nodes of the selected front.
    pub front_nodes: u64,
    /// Splats of the selected front.
    pub front_points: u64,
    /// Nodes culled by the selection (frustum, back-face).
    pub nodes_culled: u64,
    /// Front nodes not in core yet (requested from the loader).
    pub nodes_waiting: u64,
    /// Nodes drawn in place of waiting ones (ancestors or descendants drawn last frame, or
    /// parents read synchronously).
    pub stand_ins: u64,
    /// Nodes read synchronously this frame.
    pub sync_loads: u64,
}

/// An opened MWKD.
pub struct Mwkd {
    nodes: Vec<IndexNode>,
    parents: Vec<u32>,
    info: Info,
    params: MwkdParams,
    attributes: Attributes,
    access: Box<dyn DataAccess>,
    /// Nodes drawn last frame (`prev_mark[id] == frame_no`).
    prev: Vec<u32>,
    prev_mark: Vec<u64>,
    frame_no: u64,
    last: FrameCounters,
}

impl Mwkd {
    /// Opens a build directory with the local data-access layer (loader thread).
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        Self::open_at(dir, manifest, &RepoAt::Local(dir.join(codec::REPO_FILE)))
    }

    /// Opens the index and figures of `dir` with the repository at `repo`, local or served
    /// over HTTP (a remote build: `dir` holds copies of its small files).
    pub fn open_at(dir: &Path, manifest: Manifest, repo: &RepoAt) -> Result<Self, MethodError> {
        let p = MwkdParams::from_params(&manifest.params)?;
        let nodes = index::read(&dir.join(INDEX_FILE))?;
        let refs = nodes.iter().map(|n| n.chunk).collect();
        let options = LoaderOptions::new(p.core_mb, p.delay_frames, p.in_flight, repo);
        let access = Loader::at(repo, refs, "node", Arc::new(codec::decode), options)?;
        Self::with_access(dir, manifest, nodes, Box::new(access))
    }

    /// Opens with a given data-access layer (the local loader from [`Mwkd::open`], or another
    /// [`DataAccess`]).
    pub fn with_access(
        dir: &Path,
        manifest: Manifest,
        nodes: Vec<IndexNode>,
        access: Box<dyn DataAccess>,
    ) -> Result<Self, MethodError> {
        let params = MwkdParams::from_params(&manifest.params)?;
        let Some(root) = nodes.first() else {
            return Err(MethodError::corrupt(dir.join(INDEX_FILE), "no nodes"));
        };
        // `open_figures` reads the root now: here it is also the stand-in of last resort.
        let info: Info = open_figures(
            &dir.join(INFO_FILE),
            nodes.len(),
            Some(root.subtree_points),
            manifest.points,
            access.as_ref(),
        )?;
        Ok(Self {
            parents: index::parents(&nodes),
            prev_mark: vec![0; nodes.len()],
            prev: Vec::new(),
            frame_no: 0,
            nodes,
            info,
            params,
            attributes: manifest.attributes,
            access,
            last: FrameCounters::default(),
        })
    }

    /// The index array.
    pub fn nodes(&self) -> &[IndexNode] {
        &self.nodes
    }
    /// Build figures.
    pub fn info(&self) -> &Info {
        &self.info
    }
    /// Counters of the last frame.
    pub fn counters(&self) -> FrameCounters {
        self.last
    }
    /// Nodes drawn by the last frame.
    pub fn drawn(&self) -> &[u32] {
        &self.prev
    }

    /// The front for `view` and `target` (pure; see [`select`]).
    pub fn front(&self, view: &View, target: Target, held_back: &dyn Fn(u32) -> bool) -> Front {
        let ctx = Ctx::new(&self.nodes, view, self.params.metric());
        select_front(&ctx, target, held_back)
    }

    fn in_prev(&self, id: u32) -> bool {
        self.frame_no > 0 && self.prev_mark[id as usize] == self.frame_no
    }

    /// Nodes drawn last frame that cover `id`'s visible part (`id` itself excluded): true
    /// with them appended to `out` if every unculled branch under `id` reaches one that is
    /// still available.
    fn prev_cover(
        &self,
        ctx: &Ctx<'_>,
        id: u32,
        avail: &dyn Fn(u32) -> bool,
        out: &mut Vec<u32>,
    ) -> bool {
        let n = &self.nodes[id as usize];
        if n.is_leaf() {
            return false;
        }
        for c in n.children() {
            if ctx.culled(c) {
                continue;
            }
            let ok = if self.in_prev(c) {
                avail(c) && {
                    out.push(c);
                    true
                }
            } else {
                self.prev_cover(ctx, c, avail, out)
            };
            if !ok {
                return false;
            }
        }
        true
    }

    /// The paper's four transitions from the last drawn set to `front` (see [`Mwkd::frame`]):
    /// what to draw, how many stand-ins that includes, which front nodes wait (to request)
    /// and which nodes to read now.
    fn transitions(
        &self,
        ctx: &Ctx<'_>,
        front: &Front,
        target: Target,
        avail: &dyn Fn(u32) -> bool,
    ) -> Transitions {
        // The four transitions, per front node: available → draw it; else request it and
        // stand in for it with (3) the ancestor drawn last frame, (4) the descendants drawn
        // last frame, or (2) the parent of its sibling group, read now. (1) nodes of the last
        // front that nothing needs are simply not drawn.
        let mut draws: Vec<u32> = Vec::with_capacity(front.nodes.len());
        let mut stand_ins: Vec<u32> = Vec::new();
        let mut waiting: Vec<u32> = Vec::new();
        let mut sync = Vec::new();
        for &id in &front.nodes {
            if avail(id) {
                draws.push(id);
                continue;
            }
            waiting.push(id);
            // (3) An ancestor was drawn last frame: the deepest available node on the way
            // up to it stands in (it, or a finer one loaded since).
            if let Some(a) = self.ancestors(id).find(|&a| self.in_prev(a))
                && let Some(s) = self
                    .ancestors(id)
                    .take_while(|&x| x != a)
                    .chain([a])
                    .find(|&x| avail(x))
            {
                stand_ins.push(s);
                continue;
            }
            let mut cover = Vec::new();
            if self.prev_cover(ctx, id, avail, &mut cover) && !cover.is_empty() {
                draws.extend(cover);
                continue;
            }
            let p = self.parents[id as usize];
            let p = if p == u32::MAX { id } else { p };
            if !avail(p) {
                sync.push(p);
            }
            stand_ins.push(p);
        }
        // A stand-in replaces everything under it: drop nested stand-ins and drawn nodes
        // below one.
        stand_ins.sort_unstable();
        stand_ins.dedup();
        let all = stand_ins.clone();
        stand_ins.retain(|&s| !self.ancestors(s).any(|a| all.binary_search(&a).is_ok()));
        // Only stand-ins still drawn need reading (a parent nested under another stand-in
        // was queued for a synchronous read it does not need).
        sync.retain(|p| stand_ins.binary_search(p).is_ok());
        if !stand_ins.is_empty() {
            draws.retain(|&d| {
                !self
                    .ancestors(d)
                    .any(|a| stand_ins.binary_search(&a).is_ok())
            });
        }
        draws.extend(&stand_ins);
        draws.sort_unstable();
        draws.dedup();
        // Budget: stand-ins (ancestors, or descendants drawn last frame) may hold more
        // splats than the nodes they replace; if the frame would exceed B, read the waiting
        // nodes now instead (never over the budget). `load=sync` always does.
        let drawn_points: u64 = draws
            .iter()
            .map(|&i| u64::from(self.nodes[i as usize].points))
            .sum();
        let over_budget = target.budget_points().is_some_and(|b| drawn_points > b);
        if !waiting.is_empty() && (self.params.load == LoadMode::Sync || over_budget) {
            draws = front.nodes.clone();
            draws.sort_unstable();
            stand_ins.clear();
            sync = std::mem::take(&mut waiting);
        }
        sync.sort_unstable();
        sync.dedup();
        Transitions {
            draws,
            stand_ins: stand_ins.len() as u64,
            waiting,
            sync,
        }
    }

    fn ancestors(&self, id: u32) -> impl Iterator<Item = u32> + '_ {
        std::iter::successors(Some(id), |&i| {
            let p = self.parents[i as usize];
            (p != u32::MAX).then_some(p)
        })
        .skip(1)
    }
}

/// What a frame draws after the transitions ([`Mwkd::transitions`]).
struct Transitions {
    /// Nodes to draw, sorted.
    draws: Vec<u32>,
    /// How many of them stand in for waiting nodes.
    stand_ins: u64,
    /// Front nodes not available yet (requested from the loader).
    waiting: Vec<u32>,
    /// Nodes to read synchronously, sorted.
    sync: Vec<u32>,
}

/// The front for `target` in the frame `ctx` describes.
fn select_front(ctx: &Ctx<'_>, target: Target, held_back: &dyn Fn(u32) -> bool) -> Front {
    match target {
        Target::Tolerance(eps) => select::eps_front(ctx, eps, held_back),
        Target::Budget(b) => select::budget_front(ctx, b, held_back),
    }
}

impl LodMethod for Mwkd {
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
            "root node",
            target,
            self.nodes.first().map(|n| n.points),
        )?;
        self.access.begin_frame();
        let occlusion = self.params.occlusion;
        let held = |id: u32| occlusion && feedback.occluded.contains(&(id as ChunkId));
        let ctx = Ctx::new(&self.nodes, view, self.params.metric());
        let front = select_front(&ctx, target, &held);
        let access = &self.access;
        let avail = |id: u32| feedback.cached.contains(&(id as ChunkId)) || access.available(id);
        let mut c = FrameCounters {
            front_nodes: front.nodes.len() as u64,
            front_points: front.points,
            nodes_culled: u64::from(front.culled),
            ..Default::default()
        };
        let Transitions {
            draws,
            stand_ins,
            waiting,
            sync,
        } = self.transitions(&ctx, &front, target, &avail);
        for &id in &sync {
            self.access.get(id)?;
        }
        for &id in &waiting {
            self.access.request(id);
        }
        c.stand_ins = stand_ins;
        c.sync_loads = sync.len() as u64;
        c.nodes_waiting = waiting.len() as u64;
        // Held-back nodes (occluded last frame) are drawn in phase 3 if visible: read them now.
        for &id in &front.held_back {
            if !avail(id) {
                self.access.get(id)?;
                c.sync_loads += 1;
            }
        }
        // Remember what was drawn.
        self.frame_no += 1;
        for &id in draws.iter().chain(&front.held_back) {
            self.prev_mark[id as usize] = self.frame_no;
        }
        self.last = c;
        let size = SplatSize::Radius {
            scale: 1.0,
            min_px: 1.0,
        };
        let item = |id: u32| DrawItem::Chunk {
            id: id as ChunkId,
            first: 0,
            points: self.nodes[id as usize].points,
            size,
        };
        let mut list = DrawList {
            counters: vec![
                c.front_nodes as f64,
                c.front_points as f64,
                c.nodes_culled as f64,
                c.nodes_waiting as f64,
                c.stand_ins as f64,
                c.sync_loads as f64,
                self.access.pending() as f64,
            ],
            fetch: waiting.iter().map(|&i| i as ChunkId).collect(),
            ..Default::default()
        };
        if occlusion {
            let mut candidates = Vec::with_capacity(draws.len() + front.held_back.len());
            for &id in draws.iter().chain(&front.held_back) {
                let (center, radius) = self.nodes[id as usize].sphere();
                let phase1 = feedback.visible.contains(&(id as ChunkId));
                if phase1 {
                    list.items.push(item(id));
                }
                candidates.push(OcclusionCandidate {
                    id: id as ChunkId,
                    center: center.to_array(),
                    radius,
                    item: (!phase1).then(|| item(id)),
                });
            }
            list.occlusion = Some(OcclusionPass {
                candidates,
                threshold: self.params.occlusion_threshold,
            });
        } else {
            list.items = draws.iter().map(|&id| item(id)).collect();
        }
        self.prev = draws;
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
                + (self.parents.len() * 4 + self.prev_mark.len() * 8 + self.prev.len() * 4) as u64
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
