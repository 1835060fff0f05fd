//! `potree`: the octree of Potree 2.0 (Schütz, Ohrhallinger, Wimmer, "Fast Out-of-Core
//! Octree Generation for Massive Point Clouds", CGF 2020; Schütz, "Potree: Rendering Large
//! Point Clouds in Web Browsers", TU Wien 2016), the level-of-detail structure practitioners
//! use today, as a fifth baseline beside the four papers' methods.
//!
//! - [`format`]: the three files PotreeConverter 2.0 writes (`metadata.json`,
//!   `hierarchy.bin`, `octree.bin`), read and written by the same code.
//! - [`hierarchy`]: the octree as far as its chunks have been read; proxies expanded on
//!   demand.
//! - [`select`]: the viewer's traversal (priority by projected node size, point budget,
//!   frustum culling).
//! - [`build`](mod@build): our converter from a scene into the same format ([`octree`]:
//!   the tree and its sampling; [`ooc`]: the same in units for clouds beyond `mem_mb`;
//!   [`write`]: the files).
//!
//! A directory written by PotreeConverter opens with [`Potree::open_dir`] (no conversion,
//! no `method.json`); one written by [`build()`] opens through the registry like any build.
//! See `README.md` next to this file for what is faithful and what deviates.

pub mod adaptive;
pub mod build;
pub mod format;
pub mod hierarchy;
pub mod octree;
pub mod ooc;
mod params;
pub mod select;
pub mod write;

use std::path::Path;
use std::sync::Arc;

use glam::DVec3;
use scenes::{Attributes, View};

use crate::store::access::{ChunkSource, DataAccess, Decoder, Loader, LoaderOptions, RepoAt};
use crate::{
    ChunkId, DrawItem, DrawList, Feedback, LodMethod, Manifest, MethodError, MethodStats,
    SplatBatch, SplatSize, Target,
};
pub use build::build;
use format::{Decoding, Metadata};
use hierarchy::{Hierarchy, LocalFile, RangeRead, Spans};
pub use params::{LoadMode, PotreeParams, RUNTIME_PARAMS, Sampling};

/// Registry name.
pub const NAME: &str = "potree";
/// Version of what [`build()`] writes besides the Potree files (`potree.json`).
pub const FORMAT_VERSION: u32 = 1;
/// What a build by splatbench records beside the Potree files: the scene's origin.
pub const INFO_FILE: &str = "potree.json";
/// Potree's adaptive point size: a splat is `1.7 · size · spacing` across (the viewer's
/// `uOctreeSpacing * 1.7`), `spacing` its node's.
pub const ADAPTIVE_FACTOR: f32 = 1.7;
/// Traversals a `load=sync` frame makes at most (each loads what the last one found
/// missing; a level per traversal, so the octree's depth bounds it).
const SYNC_ROUNDS: usize = format::MAX_LEVEL as usize + 2;

/// `potree.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Info {
    /// World origin of the scene's local frame (subtracted from decoded positions).
    pub origin: [f64; 3],
    /// Nodes written.
    pub nodes: u64,
    /// Levels (deepest + 1).
    pub levels: u32,
}

/// Extra CSV columns of `potree`.
pub const COLUMNS: &[&str] = &[
    "visible_nodes",
    "visible_points",
    "nodes_culled",
    "nodes_waiting",
    "hierarchy_chunks_read",
    "loader_pending",
];

/// Counters of one frame.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameCounters {
    /// Nodes drawn.
    pub visible_nodes: u64,
    /// Points of the visible nodes, loaded or not (Potree's `numVisiblePoints`).
    pub visible_points: u64,
    /// Nodes dropped by the frustum test.
    pub nodes_culled: u64,
    /// Visible nodes not loaded yet (requested).
    pub nodes_waiting: u64,
    /// Hierarchy chunks read this frame (proxies expanded).
    pub hierarchy_chunks_read: u64,
}

/// The points of `octree.bin`, node by node, for the loader.
struct OctreeSource {
    file: Box<dyn RangeRead>,
    spans: Spans,
    read: std::sync::atomic::AtomicU64,
}

impl OctreeSource {
    fn span(&self, id: u32) -> Result<hierarchy::Span, MethodError> {
        let spans = self.spans.read().unwrap_or_else(|e| e.into_inner());
        spans
            .get(id as usize)
            .copied()
            .ok_or(MethodError::NoChunk(u64::from(id)))
    }
}

impl ChunkSource for OctreeSource {
    fn len(&self) -> usize {
        self.spans.read().unwrap_or_else(|e| e.into_inner()).len()
    }
    fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError> {
        let s = self.span(id)?;
        let bytes = self
            .file
            .read(s.offset, s.size, &format!("node {}", s.name()))?;
        self.read
            .fetch_add(s.size, std::sync::atomic::Ordering::Relaxed);
        Ok(bytes)
    }
    fn bytes_read(&self) -> u64 {
        self.read.load(std::sync::atomic::Ordering::Relaxed)
    }
    fn stored_bytes(&self, id: u32) -> u64 {
        self.span(id).map_or(0, |s| s.size)
    }
}

/// `octree.bin` served elsewhere (`--build-url`), read a node at a time by range requests,
/// as Potree's viewer reads it. Its size is not asked for: a node's span past the end fails
/// its request, naming the URL (the hierarchy's spans are checked against the size locally).
struct RemoteRange {
    file: Arc<dyn crate::store::remote::RemoteFile>,
    url: std::path::PathBuf,
}

impl RangeRead for RemoteRange {
    fn read(&self, offset: u64, len: u64, what: &str) -> Result<Vec<u8>, MethodError> {
        self.file.get_range(offset, len).map_err(|e| match e {
            MethodError::Remote { url, msg } => MethodError::Remote {
                url,
                msg: format!("{what}: {msg}"),
            },
            other => other,
        })
    }
    fn len(&self) -> u64 {
        u64::MAX
    }
    fn path(&self) -> &Path {
        &self.url
    }
}

/// How the drawn nodes of an octree in the Potree format combine into a frame.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refinement {
    /// Potree's: a node adds points to its ancestors' (none is stored twice); every drawn
    /// node is drawn whole, a point sized by the deepest drawn node over it ([`adaptive`]).
    Additive,
    /// `voxel`'s (Schütz et al. 2023): a drawn child *replaces* its parent's samples in its
    /// octant, so a node is drawn only where no child of it is; a sample is sized by the
    /// radius its chunk carries.
    Replacing,
}

/// What a method reading the Potree format decides at open: its name (errors), how drawn
/// nodes combine, and the splat radii of a decoded node.
#[derive(Clone, Copy)]
pub struct Mode {
    /// Registry name, for messages.
    pub name: &'static str,
    /// How drawn nodes combine.
    pub refinement: Refinement,
    /// Fills the radii of a decoded node (its span, the root's spacing, the batch sorted by
    /// [`adaptive::sort`]).
    pub radii: fn(&hierarchy::Span, f64, &mut SplatBatch),
}

impl Mode {
    /// Potree's: additive, every point's radius half its node's spacing (the draw scales it).
    pub const POTREE: Mode = Mode {
        name: NAME,
        refinement: Refinement::Additive,
        radii: level_radius,
    };
}

/// Half the spacing of the node's level for every point ([`Mode::POTREE`]).
fn level_radius(s: &hierarchy::Span, spacing: f64, b: &mut SplatBatch) {
    let radius = (spacing / f64::from(1u32 << s.level.min(31)) * 0.5) as f32;
    if let Some(r) = b.radii.as_mut() {
        r.fill(radius);
    }
}

/// An opened Potree octree.
pub struct Potree {
    hierarchy: Hierarchy,
    meta: Metadata,
    params: PotreeParams,
    attributes: Attributes,
    access: Box<dyn DataAccess>,
    last: FrameCounters,
    mode: Mode,
}

impl Potree {
    /// Opens a build written by [`build()`] (`method.json`, `potree.json` and the Potree
    /// files in `dir`).
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        let octree = RepoAt::Local(dir.join(format::OCTREE_FILE));
        Self::open_at(dir, manifest, &octree)
    }

    /// [`Potree::open`] with `octree.bin` read at `octree` (served elsewhere: `--build-url`,
    /// whose small files, `hierarchy.bin` among them, were copied into `dir`).
    pub fn open_at(dir: &Path, manifest: Manifest, octree: &RepoAt) -> Result<Self, MethodError> {
        let params = PotreeParams::from_params(&manifest.params)?;
        Self::open_build(dir, &manifest, INFO_FILE, &params, Mode::POTREE, octree)
    }

    /// Opens a build of a method in the Potree format (`potree`, `voxel`): its info file
    /// `info` (an [`Info`]) gives the origin, and the metadata's point count must be the
    /// manifest's.
    pub fn open_build(
        dir: &Path,
        manifest: &Manifest,
        info: &str,
        params: &PotreeParams,
        mode: Mode,
        octree: &RepoAt,
    ) -> Result<Self, MethodError> {
        let info: Info = crate::method::read_json(&dir.join(info))?;
        let p = Self::open_from(dir, DVec3::from(info.origin), params, mode, octree)?;
        if p.meta.points != manifest.points {
            return Err(MethodError::corrupt(
                dir.join(format::METADATA_FILE),
                format!(
                    "{} points, but method.json says {}",
                    p.meta.points, manifest.points
                ),
            ));
        }
        Ok(p)
    }

    /// Opens a Potree 2.0 directory as PotreeConverter wrote it, positions relative to
    /// `origin` (the scene's), with `params` (their runtime part matters).
    pub fn open_dir(dir: &Path, origin: DVec3, params: &PotreeParams) -> Result<Self, MethodError> {
        Self::open_as(dir, origin, params, Mode::POTREE)
    }

    /// [`Potree::open_dir`] for a method in the Potree format (`mode`: Potree's or
    /// `voxel`'s).
    pub fn open_as(
        dir: &Path,
        origin: DVec3,
        params: &PotreeParams,
        mode: Mode,
    ) -> Result<Self, MethodError> {
        let octree = RepoAt::Local(dir.join(format::OCTREE_FILE));
        Self::open_from(dir, origin, params, mode, &octree)
    }

    /// [`Potree::open_as`] with `octree.bin` at `octree`, the other files in `dir`.
    fn open_from(
        dir: &Path,
        origin: DVec3,
        params: &PotreeParams,
        mode: Mode,
        at: &RepoAt,
    ) -> Result<Self, MethodError> {
        params.validate()?;
        let meta = Metadata::read(dir)?;
        let meta_path = dir.join(format::METADATA_FILE);
        let layout = meta.layout(&meta_path)?;
        let octree: Box<dyn RangeRead> = match at {
            RepoAt::Local(path) => Box::new(LocalFile::open(path)?),
            RepoAt::Remote(file) => Box::new(RemoteRange {
                url: std::path::PathBuf::from(file.url()),
                file: Arc::clone(file),
            }),
        };
        let hierarchy = Hierarchy::open(
            &meta,
            Box::new(LocalFile::open(&dir.join(format::HIERARCHY_FILE))?),
            octree.len(),
            layout.bytes_per_point as u64,
            origin,
        )?;
        let decoding = Decoding {
            layout,
            scale: DVec3::from(meta.scale),
            offset: DVec3::from(meta.offset),
            origin,
        };
        let attributes = decoding.attributes();
        let spans = hierarchy.spans();
        let octree_path = octree.path().to_owned();
        let spacing = meta.spacing;
        let decode_spans = Arc::clone(&spans);
        let radii = mode.radii;
        let decoder: Decoder = Arc::new(move |id: u32, bytes: &[u8]| {
            let s = decode_spans.read().unwrap_or_else(|e| e.into_inner())[id as usize];
            let mut b = decoding.decode(bytes, s.points, 0.0).map_err(|m| {
                MethodError::corrupt(&octree_path, format!("node {}: {m}", s.name()))
            })?;
            adaptive::sort(&mut b, glam::Vec3::from(s.lo), glam::Vec3::from(s.hi));
            radii(&s, spacing, &mut b);
            Ok(b)
        });
        let source = OctreeSource {
            file: octree,
            spans,
            read: Default::default(),
        };
        let options = LoaderOptions::new(params.core_mb, params.delay_frames, params.in_flight, at);
        let access = Loader::spawn(Arc::new(source), decoder, options);
        // The root is what every frame draws first: read (and checked) now.
        if hierarchy.nodes()[0].points > 0 {
            access.get(0)?;
        }
        Ok(Self {
            hierarchy,
            meta,
            params: params.clone(),
            attributes,
            access: Box::new(access),
            last: FrameCounters::default(),
            mode,
        })
    }

    /// What `build.json` would say of a directory PotreeConverter wrote (it has none): the
    /// point count, nodes (non-proxy records of `hierarchy.bin`), levels and bytes of the
    /// three files; no build time.
    pub fn foreign_stats(dir: &Path) -> Result<crate::BuildStats, MethodError> {
        let meta = Metadata::read(dir)?;
        let h = dir.join(format::HIERARCHY_FILE);
        let records = std::fs::read(&h).map_err(|e| MethodError::io(&h, e))?;
        let nodes = records
            .chunks_exact(format::RECORD_BYTES)
            .filter(|r| r[0] != 2)
            .count() as u64;
        let mut bytes_out = 0;
        for f in [
            format::METADATA_FILE,
            format::HIERARCHY_FILE,
            format::OCTREE_FILE,
        ] {
            let p = dir.join(f);
            bytes_out += std::fs::metadata(&p)
                .map_err(|e| MethodError::io(&p, e))?
                .len();
        }
        let mut extra = serde_json::Map::new();
        extra.insert(
            "source".into(),
            "a Potree 2.0 directory written by another tool (no build.json)".into(),
        );
        extra.insert("spacing".into(), meta.spacing.into());
        extra.insert(
            "levels_from".into(),
            "metadata.json hierarchy.depth + 1 (PotreeConverter writes 0 for some multi-level \
             octrees)"
                .into(),
        );
        Ok(crate::BuildStats {
            points_in: meta.points,
            nodes,
            levels: meta.hierarchy.depth + 1,
            bytes_out,
            extra,
            ..Default::default()
        }
        .finish())
    }

    /// The metadata.
    pub fn metadata(&self) -> &Metadata {
        &self.meta
    }
    /// The nodes known so far.
    pub fn hierarchy(&self) -> &Hierarchy {
        &self.hierarchy
    }
    /// Counters of the last frame.
    pub fn counters(&self) -> FrameCounters {
        self.last
    }

    /// Reads every hierarchy chunk (tests and tools that walk the whole octree).
    pub fn expand_all(&mut self) -> Result<(), MethodError> {
        let mut id = 0;
        while id < self.hierarchy.nodes().len() as u32 {
            self.hierarchy.expand(id)?;
            id += 1;
        }
        Ok(())
    }

    /// The draw items of the drawn nodes `draw`: each node in ranges of its points (sorted
    /// at decode, [`adaptive`]), each range sized by the deepest drawn node holding it, as
    /// the viewer's adaptive point size.
    fn adaptive_items(&self, draw: &[u32]) -> Result<Vec<DrawItem>, MethodError> {
        let nodes = self.hierarchy.nodes();
        let mut drawn = vec![false; nodes.len()];
        for &id in draw {
            drawn[id as usize] = true;
        }
        // The descendant `depth` levels below `id` along the digits `path`, if drawn.
        let below = |id: u32, depth: u32, path: u64| {
            let mut at = id;
            for d in (0..depth).rev() {
                at = nodes[at as usize].children[((path >> (3 * d)) & 7) as usize];
                if at == hierarchy::NONE {
                    return false;
                }
            }
            drawn[at as usize]
        };
        let mut items = Vec::with_capacity(draw.len());
        for &id in draw {
            let n = &nodes[id as usize];
            if n.points == 0 {
                continue;
            }
            let batch = self.access.get(id)?;
            let ranges = adaptive::ranges(&batch.positions, (n.lo, n.hi), n.level, &|d, p| {
                below(id, d, p)
            });
            for r in ranges {
                items.push(DrawItem::Chunk {
                    id: ChunkId::from(id),
                    first: r.first,
                    points: r.len,
                    size: SplatSize::Radius {
                        scale: ADAPTIVE_FACTOR * self.params.point_size
                            / (1u64 << (r.lod - n.level).min(63)) as f32,
                        min_px: self.params.min_px,
                    },
                });
            }
        }
        Ok(items)
    }

    /// The draw items of the drawn nodes `draw` when children replace their parent
    /// ([`Refinement::Replacing`]): each node's points outside its drawn children (sorted
    /// by octant at decode, so the rest is a few ranges), at the radius they carry.
    fn replacing_items(&self, draw: &[u32]) -> Result<Vec<DrawItem>, MethodError> {
        let nodes = self.hierarchy.nodes();
        let mut drawn = vec![false; nodes.len()];
        for &id in draw {
            drawn[id as usize] = true;
        }
        let mut items = Vec::with_capacity(draw.len());
        for &id in draw {
            let n = &nodes[id as usize];
            if n.points == 0 {
                continue;
            }
            let batch = self.access.get(id)?;
            // Only the children matter (a drawn grandchild's parent is drawn): the walk
            // stops one level down.
            let child_drawn = |depth: u32, path: u64| {
                let c = n.children[(path & 7) as usize];
                depth == 1 && c != hierarchy::NONE && drawn[c as usize]
            };
            let ranges = adaptive::ranges(&batch.positions, (n.lo, n.hi), n.level, &child_drawn);
            for r in ranges.into_iter().filter(|r| r.lod == n.level) {
                items.push(DrawItem::Chunk {
                    id: ChunkId::from(id),
                    first: r.first,
                    points: r.len,
                    size: SplatSize::Radius {
                        scale: self.params.point_size,
                        min_px: self.params.min_px,
                    },
                });
            }
        }
        Ok(items)
    }

    fn loaded(&self, id: u32, feedback: &Feedback) -> bool {
        !self.hierarchy.is_proxy(id)
            && (self.hierarchy.nodes()[id as usize].points == 0
                || feedback.cached.contains(&ChunkId::from(id))
                || self.access.available(id))
    }

    fn selection(&self, view: &View, target: Target, feedback: &Feedback) -> select::Selection {
        select::select(
            self.hierarchy.nodes(),
            view,
            target,
            self.meta.spacing,
            self.params.min_node_px,
            &|id| self.loaded(id, feedback),
        )
    }
}

impl LodMethod for Potree {
    fn chunk_level(&self, id: ChunkId) -> Option<u32> {
        self.hierarchy
            .nodes()
            .get(usize::try_from(id).ok()?)
            .map(|n| n.level)
    }
    fn attributes(&self) -> Attributes {
        self.attributes
    }
    fn input_points(&self) -> u64 {
        self.meta.points
    }
    crate::loads_through_access!(access);
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let target = target.validate()?;
        crate::method::check_budget_above_root(
            self.mode.name,
            "root node",
            target,
            Some(self.hierarchy.nodes()[0].points),
        )?;
        self.access.begin_frame();
        let chunks_before = self.hierarchy.chunks_read();
        let mut sel = self.selection(view, target, feedback);
        if self.params.load == LoadMode::Sync {
            for _ in 0..SYNC_ROUNDS {
                if sel.waiting.is_empty() {
                    break;
                }
                for &id in &sel.waiting {
                    self.hierarchy.expand(id)?;
                    if self.hierarchy.nodes()[id as usize].points > 0 {
                        self.access.get(id)?;
                    }
                }
                sel = self.selection(view, target, feedback);
            }
        }
        // Waiting nodes, best first: a proxy's chunk is read now (a few hundred bytes per
        // four levels), its points are requested.
        for &id in &sel.waiting {
            self.hierarchy.expand(id)?;
            if self.hierarchy.nodes()[id as usize].points > 0 {
                self.access.request(id);
            }
        }
        let c = FrameCounters {
            visible_nodes: sel.draw.len() as u64,
            visible_points: sel.visible_points,
            nodes_culled: u64::from(sel.culled),
            nodes_waiting: sel.waiting.len() as u64,
            hierarchy_chunks_read: self.hierarchy.chunks_read() - chunks_before,
        };
        self.last = c;
        let items = match self.mode.refinement {
            Refinement::Additive => self.adaptive_items(&sel.draw)?,
            Refinement::Replacing => self.replacing_items(&sel.draw)?,
        };
        Ok(DrawList {
            items,
            fetch: sel.waiting.iter().map(|&id| ChunkId::from(id)).collect(),
            counters: vec![
                c.visible_nodes as f64,
                c.visible_points as f64,
                c.nodes_culled as f64,
                c.nodes_waiting as f64,
                c.hierarchy_chunks_read as f64,
                self.access.pending() as f64,
            ],
            ..Default::default()
        })
    }
    fn chunk(&self, id: ChunkId) -> Result<Arc<SplatBatch>, MethodError> {
        let id = u32::try_from(id)
            .ok()
            .filter(|&i| (i as usize) < self.hierarchy.nodes().len() && !self.hierarchy.is_proxy(i))
            .ok_or(MethodError::NoChunk(id))?;
        self.access.get(id)
    }
    fn stats(&self) -> MethodStats {
        let nodes = self.hierarchy.nodes();
        MethodStats {
            resident_bytes: (std::mem::size_of_val(nodes)
                + nodes.len() * std::mem::size_of::<hierarchy::Span>())
                as u64
                + self.access.resident_bytes(),
            nodes: nodes.len() as u64,
            // The deepest node known so far, or the metadata's depth if deeper (the
            // converter writes 0 for some multi-level octrees).
            levels: nodes
                .iter()
                .map(|n| n.level)
                .max()
                .unwrap_or(0)
                .max(self.meta.hierarchy.depth)
                + 1,
        }
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        COLUMNS
    }
}
