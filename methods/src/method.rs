//! The [`LodMethod`] trait and what builds and opened instances report.
//!
//! Building and opening are static, per method (functions `build` and `open` in each
//! method's module, dispatched by [`crate::MethodKind`]); an opened instance is a
//! `Box<dyn LodMethod>` that the runner drives frame by frame.

use std::path::Path;
use std::sync::Arc;

use scenes::{Attributes, View};

pub use crate::jsonfile::{read_json, write_json};
use crate::{ChunkId, DrawList, Feedback, MethodError, SplatBatch, Target};

/// An opened multiresolution representation.
pub trait LodMethod: Send {
    /// Which attributes its splats carry (a subset of the scene's, plus a derived radius).
    fn attributes(&self) -> Attributes;
    /// Number of input samples the representation was built from.
    fn input_points(&self) -> u64;
    /// Selects what to draw for `view` at `target`. Must not touch a GPU.
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        feedback: &Feedback,
    ) -> Result<DrawList, MethodError>;
    /// Decoded chunk `id`, for upload. Shared: a method that keeps decoded chunks in core
    /// (LPC, MWKD) hands out its copy without cloning it.
    fn chunk(&self, id: ChunkId) -> Result<Arc<SplatBatch>, MethodError>;
    /// Resident memory and structure counters.
    fn stats(&self) -> MethodStats;
    /// Names of the extra CSV columns this method appends (values in [`DrawList::counters`]).
    fn extra_columns(&self) -> &'static [&'static str] {
        &[]
    }
    /// True if the method's draw lists carry [`crate::DrawItem::Sequential`] items: the runner
    /// then appends `prefix_points,gpu_passed,gpu_culled_fraction` (counted on the GPU).
    fn interval_tested(&self) -> bool {
        false
    }
    /// Splats of `list` that are drawn for `view`: what `frames.csv` calls `points_drawn`.
    /// Without a vertex-stage test that is [`DrawList::points`]; for
    /// [`crate::DrawItem::Sequential`] items it is the splats of the prefix that pass the
    /// interval test, counted by its CPU mirror ([`crate::IntervalTest::passes`], the function
    /// the renderer's tests compare with the GPU counter). The default counts through
    /// [`LodMethod::chunk`] ([`count_drawn`]); a method may answer faster from its own data.
    fn drawn_points(&self, view: &View, list: &DrawList) -> Result<u64, MethodError> {
        count_drawn(self, view, list)
    }
    /// True if the method's draw lists may carry an [`crate::OcclusionPass`]: the runner then
    /// appends `clouds_queried,clouds_occluded` (counted by the renderer's queries).
    fn occlusion_culled(&self) -> bool {
        false
    }
    /// Bytes that must stay resident on the GPU for the method to work (SPT keeps its whole
    /// node list there); `None` when chunks may come and go. The runner refuses a GPU cache
    /// budget smaller than this rather than re-upload the model every frame.
    fn gpu_resident_bytes(&self) -> Option<u64> {
        None
    }
    /// The level in its hierarchy of the node or cloud whose chunk is `id` (0 = the root),
    /// for methods that draw chunks by node (LPC, MWKD, Potree); `None` for the others
    /// (QSplat and SPT draw splats of every level in one stream or list). The viewer
    /// colours drawn chunks by it.
    fn chunk_level(&self, id: ChunkId) -> Option<u32> {
        let _ = id;
        None
    }
    /// Chunks that failed to load and that the method renders on without (a coarser level, a
    /// stand-in), each with its error naming the file and the chunk. The runner reports them
    /// and fails the run unless told to accept them: frames missing data are not a faithful
    /// measurement.
    fn failed_chunks(&self) -> Vec<(ChunkId, String)> {
        Vec::new()
    }
    /// True if the method loads chunks from a repository as it renders (LPC, MWKD): the
    /// runner then appends `chunks_failed` ([`LodMethod::failed_chunks`] so far, counted
    /// after the frame was drawn).
    fn loads_chunks(&self) -> bool {
        false
    }
    /// What its data-access layer has fetched so far (methods that load chunks; zeros for
    /// the others): the runner writes each frame's share in `frames.csv`.
    fn traffic(&self) -> crate::store::access::Traffic {
        crate::store::access::Traffic::default()
    }
    /// The rate its data-access layer measured over recent responses
    /// ([`crate::store::access::DataAccess::throughput`]); `None` by default.
    fn throughput(&self) -> Option<crate::store::access::Throughput> {
        None
    }
}

/// [`LodMethod::drawn_points`] computed from the chunks: every item's
/// [`crate::DrawItem::points`], except that of a `Sequential` item's prefix only the splats
/// passing its interval test count (normals decoded as the GPU sees them; `Vec3::Z` without
/// normals, as the renderer's CPU mirror). Decodes only the chunks of `Sequential` items.
pub fn count_drawn<M: LodMethod + ?Sized>(
    method: &M,
    view: &View,
    list: &DrawList,
) -> Result<u64, MethodError> {
    let eye = view.camera.position;
    let mut drawn = 0;
    for item in &list.items {
        drawn += match item {
            crate::DrawItem::Sequential {
                id, prefix, test, ..
            } => {
                let c = method.chunk(*id)?;
                let lod = c.lod.as_deref().unwrap_or(&[]);
                (0..(*prefix as usize).min(c.len()))
                    .filter(|&i| {
                        let n = c
                            .normals
                            .as_ref()
                            .map_or(glam::Vec3::Z, |n| crate::octnormal::decode(n[i]));
                        let l = lod.get(i).copied().unwrap_or([0.0; 4]);
                        test.passes(glam::Vec3::from(c.positions[i]), n, l, eye)
                    })
                    .count() as u64
            }
            other => other.points(),
        };
    }
    Ok(drawn)
}

/// What `build` reports (written as `build.json`).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BuildStats {
    /// Input samples.
    pub points_in: u64,
    /// Nodes (or chunks) in the structure.
    pub nodes: u64,
    /// Levels of the hierarchy (1 for a flat structure).
    pub levels: u32,
    /// Bytes of the input columns.
    pub bytes_in: u64,
    /// Bytes written to the output directory.
    pub bytes_out: u64,
    /// `bytes_out · 8 / points_in`.
    pub bits_per_sample: f64,
    /// Wall-clock build time.
    pub seconds: f64,
    /// `points_in / seconds`.
    pub points_per_s: f64,
    /// Method-specific figures.
    #[serde(default)]
    pub extra: serde_json::Map<String, serde_json::Value>,
}

impl BuildStats {
    /// File name inside a build directory.
    pub const FILE: &'static str = "build.json";

    /// Writes `build.json` into `dir`.
    pub fn write(&self, dir: &Path) -> Result<(), MethodError> {
        write_json(&dir.join(Self::FILE), self)
    }

    /// Reads `build.json` from `dir`.
    pub fn read(dir: &Path) -> Result<Self, MethodError> {
        read_json(&dir.join(Self::FILE))
    }

    /// Fills the derived fields from the raw ones.
    pub fn finish(mut self) -> Self {
        self.bits_per_sample = if self.points_in > 0 {
            self.bytes_out as f64 * 8.0 / self.points_in as f64
        } else {
            0.0
        };
        self.points_per_s = if self.seconds > 0.0 {
            self.points_in as f64 / self.seconds
        } else {
            0.0
        };
        self
    }
}

/// Counters of an opened instance.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct MethodStats {
    /// Bytes the method holds in memory (index, decoded caches), excluding mapped files.
    pub resident_bytes: u64,
    /// Nodes or chunks.
    pub nodes: u64,
    /// Levels.
    pub levels: u32,
}

/// A documented effect that dominates a run's result, and the parameter that changes it
/// ([`crate::MethodKind::known_effect`]): a run's summary line and `summary.json` carry it,
/// so a result that looks broken says why and what to try.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct KnownEffect {
    /// What dominates the result, with the figure that shows it.
    pub effect: String,
    /// The parameter (`key=value`) that changes it.
    pub param: String,
    /// What that parameter is (a departure from the paper, say) and what it costs.
    pub cost: String,
    /// Where the effect is documented and measured.
    pub doc: String,
}

/// The figures of a run that a [`KnownEffect`] shows in (medians over its frames).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Observed {
    /// Median hole ratio: the share of the reference's covered pixels the run left bare.
    pub hole_ratio: Option<f64>,
}

/// `method.json`: what a build directory holds, read by `open`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Manifest {
    /// Registry name of the method.
    pub method: String,
    /// On-disk format version of that method.
    pub format_version: u32,
    /// Parameters used, as given.
    pub params: crate::Params,
    /// Attributes stored.
    pub attributes: Attributes,
    /// Input samples.
    pub points: u64,
    /// The scene's description (spec string and content hash).
    pub scene: String,
}

impl Manifest {
    /// File name inside a build directory.
    pub const FILE: &'static str = "method.json";

    /// Writes the manifest into `dir`.
    pub fn write(&self, dir: &Path) -> Result<(), MethodError> {
        write_json(&dir.join(Self::FILE), self)
    }

    /// Reads the manifest of `dir`.
    pub fn read(dir: &Path) -> Result<Self, MethodError> {
        read_json(&dir.join(Self::FILE))
    }
}

/// Refuses a point budget smaller than the root a method refines from (`what` with `root`
/// points): LPC and MWKD draw whole clouds / nodes, and below the root their selection is
/// empty — a black frame passed off as a result. Their papers always draw the root; we keep
/// the budget a hard bound and say instead which budget is the smallest that draws. `None`
/// (no nodes) and tolerance targets pass.
pub fn check_budget_above_root(
    method: &str,
    what: &str,
    target: Target,
    root: Option<u32>,
) -> Result<(), MethodError> {
    match (target, root) {
        (Target::Budget(b), Some(r)) if b < u64::from(r) => Err(MethodError::Target(format!(
            "method '{method}': a budget of {b} points is smaller than its {what} of {r} \
             points, the least it can draw (the papers refine from the root): give a budget of \
             {r} or more"
        ))),
        _ => Ok(()),
    }
}
