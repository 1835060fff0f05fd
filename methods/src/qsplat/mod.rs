//! `qsplat`: QSplat (Rusinkiewicz & Levoy, SIGGRAPH 2000), a quantised bounding-sphere
//! hierarchy traversed on the CPU every frame. See `README.md` beside this file.
//!
//! Contract:
//! - [`build`] writes `tree.qs` ([`format`]) and `method.json`: a breadth-first file of 4-byte
//!   nodes (6 with colour) plus one 32-bit pointer per sibling group that has children.
//! - [`Qsplat::open`] memory-maps and validates the file; a corrupt file is
//!   [`MethodError::Corrupt`] naming it.
//! - [`LodMethod::frame`] traverses the mapped file ([`select`]) and returns one
//!   [`DrawItem::Stream`] of splats sized per splat by their radius. Tolerance `ε`: splats
//!   whose projected diameter is ≤ ε (or leaves); budget `B`: coarse-first refinement, never
//!   more than `B` splats. [`LodMethod::chunk`] is [`MethodError::NoChunk`]: QSplat draws
//!   streams only.
//! - Frame-rate control (`--param target_ms=…`, off by default) and progressive refinement:
//!   see [`FrameControl`]. Off ⇒ the frame is exactly what the target says.

pub mod build;
mod forest;
pub mod format;
mod node;
pub mod ooc;
pub mod quant;
pub mod select;
pub mod stats;

use std::path::Path;
use std::time::Instant;

use scenes::{Attributes, PointCloud, Progress, View};

use crate::{
    BuildStats, ChunkId, DrawItem, DrawList, Feedback, LodMethod, Manifest, MethodError,
    MethodStats, Params, SplatBatch, SplatShape, SplatSize, Target,
};

/// Version of the build directory layout (the file's own version is [`format::VERSION`]).
pub const FORMAT_VERSION: u32 = 1;
/// Name of the tree file in the build directory.
pub const TREE_FILE: &str = "tree.qs";
/// Registry name.
pub const NAME: &str = "qsplat";
/// Extra CSV columns (values from [`select::Counters`], in this order).
pub const COLUMNS: &[&str] = &[
    "nodes_visited",
    "splats_emitted",
    "culled_frustum",
    "culled_backface",
    "threshold_px",
    "dropped_empty",
    "file_drawn_fraction",
    "file_read_fraction",
];

/// Parameters of `qsplat`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct QsplatParams {
    /// Splat kernel asked of the renderer (`square|circle|ellipse|gaussian`); none = the
    /// run's `--kernel`.
    pub kernel: Option<SplatShape>,
    /// Desired frame time in ms: turns on frame-rate control and progressive refinement.
    pub target_ms: Option<f64>,
    /// Split rule of the build (`midpoint`, the paper's; or `median`).
    pub split: build::Split,
    /// Combine rule of the build (`fewest`, the default: the fewest interior nodes, the
    /// purpose the paper states; or `pairs`, binary levels paired from the top).
    pub combine: build::Combine,
    /// How each child's sphere code is chosen: `nearest` (the paper's §3.1: nearest centre,
    /// radius rounded up) or `smallest` (a departure: the smallest enclosing sphere of the
    /// centres around, tighter spheres).
    pub fit: quant::Fit,
    /// Draw back faces too (`two_sided=true`, a departure): no normal-cone culling. The
    /// paper culls back-facing subtrees (§3.2), which from inside a closed model — the last
    /// frames of `zoom`, the `extremes` and `flythrough` paths — culls every node, since all
    /// the surface seen from inside faces away; and for scans whose normals are not
    /// oriented, culls half of the samples. The reference draws both sides.
    pub two_sided: bool,
    /// Working memory of the build in MiB (≥ 16; default [`crate::params::BUILD_MEM_MB`]).
    /// A larger cloud is built in units of at most `mem_mb·2²⁰ / 256` samples
    /// ([`ooc::UNIT_BYTES_PER_SAMPLE`]); the file is the same for any value.
    pub mem_mb: u64,
}

impl Default for QsplatParams {
    fn default() -> Self {
        Self {
            kernel: None,
            target_ms: None,
            split: build::Split::default(),
            combine: build::Combine::default(),
            fit: quant::Fit::default(),
            two_sided: false,
            mem_mb: crate::params::BUILD_MEM_MB,
        }
    }
}

impl QsplatParams {
    /// Parses and validates. A value that does not parse is an error naming its key
    /// (serde's own message names only the value, e.g. "unknown variant `midpt`").
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: Self = params.to_typed(NAME).map_err(|e| {
            params
                .0
                .iter()
                .find_map(|(k, v)| {
                    let one = Params([(k.clone(), v.clone())].into_iter().collect());
                    match one.to_typed::<Self>(NAME) {
                        Err(MethodError::Param(m)) => Some(MethodError::Param(m.replacen(
                            &format!("method '{NAME}': "),
                            &format!("method '{NAME}': {k}={v}: "),
                            1,
                        ))),
                        _ => None,
                    }
                })
                .unwrap_or(e)
        })?;
        crate::params::check_mb(NAME, "mem_mb", p.mem_mb, 16)?;
        if let Some(t) = p.target_ms
            && !(t.is_finite() && t > 0.0)
        {
            return Err(MethodError::Param(format!(
                "method '{NAME}': target_ms must be a positive number of milliseconds, got {t}"
            )));
        }
        Ok(p)
    }
}

/// Writes the build directory.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let p = QsplatParams::from_params(params)?;
    let opt = build::BuildOptions {
        split: p.split,
        combine: p.combine,
        fit: p.fit,
    };
    let t0 = Instant::now();
    let n = cloud.len();
    let path = dir.join(TREE_FILE);
    let budget = ooc::Budget {
        mem_bytes: p.mem_mb << 20,
        dir,
        hook: None,
    };
    let t = ooc::build_file(cloud, opt, &path, budget, progress)?;
    let fs = t.file;
    let attrs = Attributes {
        radii: true,
        ..cloud.attributes()
    };
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: attrs,
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    let (nodes, leaves) = (t.nodes, t.leaves);
    let interior = nodes - leaves;
    let nb = format::node_bytes(cloud.colors().is_some()) as u64;
    let mut extra = serde_json::Map::new();
    let mut put = |k: &str, v: serde_json::Value| {
        extra.insert(k.into(), v);
    };
    put("split", serde_json::to_value(opt.split).unwrap_or_default());
    put("leaf_radii_capped", t.radii_capped.into());
    put(
        "combine",
        serde_json::to_value(opt.combine).unwrap_or_default(),
    );
    put("fit", serde_json::to_value(opt.fit).unwrap_or_default());
    put("leaves", leaves.into());
    put("units", t.units.into());
    put("interior", interior.into());
    put(
        "interior_per_leaf",
        (interior as f64 / leaves as f64).into(),
    );
    put("bytes_per_node", nb.into());
    put("pointer_bytes", (fs.pointers * 4).into());
    put(
        "pointer_share",
        ((fs.pointers * 4) as f64 / fs.bytes as f64).into(),
    );
    put(
        "table_entries",
        (quant::sphere_table().entries.len() as u64).into(),
    );
    for (k, v) in t.quant.extras() {
        put(k, v);
    }
    Ok(BuildStats {
        points_in: n as u64,
        nodes,
        levels: t.levels,
        bytes_in: cloud.column_bytes(),
        bytes_out: fs.bytes,
        seconds: t0.elapsed().as_secs_f64(),
        extra,
        ..Default::default()
    }
    .finish())
}

/// Frame-rate control and progressive refinement, active only with `target_ms`.
///
/// State: the threshold `t` used last frame (starts at `max(ε, 1)`). Each tolerance frame:
/// - camera still (`feedback.camera_still`): progressive refinement, `t ← t/2`; once `t/2`
///   would fall below `max(ε, 1 px)`, `t ← ε` (the requested tolerance, reached exactly);
/// - camera moving and a previous frame time `m` known (`last_gpu_ms`, else `last_wall_ms`):
///   `t ← clamp(t·√(m/target_ms), max(ε, 1), max(64, ε))` — splat count goes as `1/t²`, so
///   the square root makes the frame time proportional to the correction;
/// - otherwise `t` is unchanged.
///
/// The threshold is a deterministic function of the sequence of feedbacks. Budget frames
/// ignore frame-rate control (the budget already fixes the work).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameControl {
    /// Desired frame time, ms.
    pub target_ms: f64,
    /// Threshold of the last frame, px (`None` before the first).
    pub threshold: Option<f32>,
}

/// Largest threshold frame-rate control uses, px.
pub const MAX_THRESHOLD_PX: f32 = 64.0;

impl FrameControl {
    /// The threshold for this frame given the requested tolerance `eps` and `feedback`.
    pub fn next(&mut self, eps: f32, feedback: &Feedback) -> f32 {
        let floor = eps.max(1.0);
        let ceil = MAX_THRESHOLD_PX.max(eps);
        let t = match self.threshold {
            None => floor,
            Some(t) if feedback.camera_still => {
                if t * 0.5 < floor {
                    eps
                } else {
                    t * 0.5
                }
            }
            Some(t) => match feedback.last_gpu_ms.or(feedback.last_wall_ms) {
                Some(ms) if ms.is_finite() && ms > 0.0 => {
                    (t.max(floor) * (ms / self.target_ms).sqrt() as f32).clamp(floor, ceil)
                }
                _ => t,
            },
        };
        self.threshold = Some(t);
        t
    }
}

/// An opened `qsplat` build.
pub struct Qsplat {
    file: format::QsFile,
    attrs: Attributes,
    points: u64,
    params: QsplatParams,
    control: Option<FrameControl>,
    last_len: usize,
}

impl Qsplat {
    /// Opens a build directory (the tree file is memory-mapped and validated).
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        manifest.expect_version(dir, FORMAT_VERSION)?;
        let params = QsplatParams::from_params(&manifest.params)?;
        let file = format::QsFile::open(&dir.join(TREE_FILE))?;
        if file.header.leaves != manifest.points {
            return Err(MethodError::corrupt(
                &file.path,
                format!(
                    "{} leaves, manifest says {} samples",
                    file.header.leaves, manifest.points
                ),
            ));
        }
        let control = params.target_ms.map(|target_ms| FrameControl {
            target_ms,
            threshold: None,
        });
        Ok(Self {
            attrs: manifest.attributes,
            points: manifest.points,
            file,
            params,
            control,
            last_len: 0,
        })
    }

    /// The mapped file.
    pub fn file(&self) -> &format::QsFile {
        &self.file
    }
}

impl LodMethod for Qsplat {
    fn attributes(&self) -> Attributes {
        self.attrs
    }
    fn input_points(&self) -> u64 {
        self.points
    }
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let body = self.file.body();
        let body_len = body.len();
        let h = &self.file.header;
        let cull = !self.params.two_sided;
        let (batch, c) = match target.validate()? {
            Target::Tolerance(eps) => {
                let thr = match self.control.as_mut() {
                    Some(fc) => fc.next(eps, feedback),
                    None => eps,
                };
                select::select_threshold(body, h, view, thr, self.last_len, cull)?
            }
            Target::Budget(b) => select::select_budget(body, h, view, b, self.last_len, cull)?,
        };
        self.last_len = batch.len();
        Ok(DrawList {
            shape: self.params.kernel,
            items: vec![DrawItem::Stream {
                batch,
                size: SplatSize::Radius {
                    scale: 1.0,
                    min_px: 1.0,
                },
            }],
            fetch: Vec::new(),
            counters: vec![
                c.nodes_visited as f64,
                c.splats_emitted as f64,
                c.culled_frustum as f64,
                c.culled_backface as f64,
                c.threshold_px,
                c.dropped_empty as f64,
                c.draw_end as f64 / body_len.max(1) as f64,
                c.read_end as f64 / body_len.max(1) as f64,
            ],
            occlusion: None,
        })
    }
    fn chunk(&self, id: ChunkId) -> Result<std::sync::Arc<SplatBatch>, MethodError> {
        Err(MethodError::NoChunk(id))
    }
    fn stats(&self) -> MethodStats {
        MethodStats {
            resident_bytes: (quant::sphere_table().entries.len() * 16 + quant::NORMAL_CODES * 16)
                as u64,
            nodes: self.file.header.nodes,
            levels: self.file.header.levels,
        }
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        COLUMNS
    }
}
