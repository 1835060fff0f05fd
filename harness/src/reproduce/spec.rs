//! Reproduction specs: one TOML file per table or figure of a paper (`paper/specs/*.toml`),
//! read with `deny_unknown_fields` and checked whole before anything runs. Every error
//! names the spec file and the field (`paper/specs/x.toml: measure 'near': path: …`).
//!
//! ```toml
//! id = "qsplat-fig6"                 # = the file's stem
//! paper = "QSplat (Rusinkiewicz & Levoy, SIGGRAPH 2000)"
//! title = "Fig. 6: structure and file size"
//! source = "§3.2 and Fig. 6, p. 7"  # where in the paper
//! notes = "…"                        # optional, printed under the table (markdown)
//!
//! [scenes.statue]                    # a generator (points and seed), or file = "…"
//! generator = "statue"
//! points = { quick = 1_000_000, full = 10_000_000, paper = 127_072_827 }  # may differ by profile
//! seed = 1
//! sampling = "even"                  # even (statue, isosurface default) | random; by profile
//! ```
//!
//! Any count, string or size may be `{ quick = …, full = …, paper = … }`; a table without
//! `paper` gives the `paper` profile its `full` value (the report's measure lines show the
//! sizes used).
//! `profiles = ["quick", "full"]` at the top keeps a spec out of the other profiles (our own
//! tables with no paper size to reproduce); every spec is checked for every profile.
//! `reference = "compute"` (by profile, default `quads`: the run's rasteriser) draws the
//! reference images of the spec's runs with the compute rasteriser, as square splats: ≈ 15×
//! faster on lavapipe, what the paper profile's references of 10⁸ samples need.
//!
//! ```toml
//!
//! [[measure]]
//! id = "build"
//! kind = "build"                     # build | run | sweep | plan
//! method = "qsplat"
//! scene = "statue"
//! params = { }                       # --param key = value (build and runtime keys; by profile)
//!
//! [[row]]
//! what = "interior / leaf"
//! paper = [0.40, 0.49]               # a number, [lo, hi] (inside) or a list (order)
//! ours = "build.interior_per_leaf"   # an expression (see `expr`), or a list of them (order)
//! rule = "inside"                    # exact | within (+ tolerance) | inside | at_most | at_least | order | report
//! reason = "… {build.leaves} …"      # shown when it differs; {expr} and {expr:%} are filled in
//! ```
//!
//! Measures (`kind`):
//! - `build`: the method on the scene with its build parameters; metrics are `build.json`'s
//!   fields and `extra` keys (`points_per_s`, `bits_per_sample`, `interior_per_leaf`, …).
//! - `run`: a build (shared with every measure of the same method, build parameters and
//!   scene, across specs) and one camera-path run: `path` (default `orbit`, or a keyframe
//!   file relative to the repository root), `frames`, `eps = PX` or `budget = POINTS`,
//!   `width`/`height` (512), `kernel` (`square`), `gpu_cache_mb` (512), `metrics` (true:
//!   FLIP, holes… against the reference), `skip` (frames left out of the statistics, e.g.
//!   while an out-of-core method loads), `isolate` (run in a child process, so that its
//!   memory figures are its own), `reference_kernel` (the references' kernel, default the
//!   run's: runs of several kernels against one image of the full cloud).
//! - `sweep`: as `run`, with lists `eps = [8, 4, 2, 1]` or `budget = [25_000, …]`.
//! - `plan`: `splatbench plan`'s tree shape (`method = "mwkd"`, `points`, `params`).
//!
//! Any measure may say `profiles = ["full", "paper"]` (a subset of the spec's): the other
//! profiles leave it out, with every row that reads it (the report lists those rows under the
//! table, with the profiles that measure them) and its sweeps in figures. For an experiment
//! too slow for `quick` (an item-5 sweep that moves a cause) beside rows that `quick` keeps.
//!
//! A row with `needs_gpu = true` is a GPU's figure (throughput): on a CPU adapter it is
//! listed as "needs a GPU" and the measures only it uses are not run. A row with
//! `judge_on_gpu = true` (a relative speed, whose ratio a CPU rasteriser's costs distort) is
//! measured on every adapter and judged only on a GPU ("CPU rasteriser: no verdict").
//! Rule `band` takes `band = [lo, hi]` and `band_reason` (see [`super::verdict`]). `[[figure]]` tables
//! (`name`, `title`, `sweeps = [ids]`) overlay sweeps in one plot.

use std::collections::BTreeMap;
use std::fmt;
use std::path::PathBuf;

use methods::{MethodKind, Params};
use scenes::SceneSpec;
use scenes::paths::PathSpec;

use super::expr::Expr;
use super::verdict::{Paper, Rule};
use crate::render::{Kernel, Raster};
use crate::sweep::SweepTarget;

/// Which sizes a reproduction uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Small scenes: the whole reproduction in minutes on 2 cores with lavapipe.
    Quick,
    /// The middle ground (10–100 M points).
    Full,
    /// The papers' own sizes and resolutions (127 M – 369 M samples; hours, out of core).
    Paper,
}

impl Profile {
    /// Every profile.
    pub const ALL: [Profile; 3] = [Profile::Quick, Profile::Full, Profile::Paper];

    /// `quick`, `full` or `paper`.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Quick => "quick",
            Profile::Full => "full",
            Profile::Paper => "paper",
        }
    }
}

impl fmt::Display for Profile {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

/// A spec that failed to load: the file, the field, what is wrong.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{}: {field}{}{message}", file.display(), if field.is_empty() { "" } else { ": " })]
pub struct SpecError {
    /// The spec file.
    pub file: PathBuf,
    /// The field (`measure 'near': path`), or empty for the whole file.
    pub field: String,
    /// What is wrong.
    pub message: String,
}

// ---------------------------------------------------------------------------------------
// The spec as checked, resolved for one profile.

#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
/// What a measure does.
pub enum MeasureKind {
    /// A build.
    Build,
    /// A build and one run.
    Run,
    /// A build and one run per target.
    Sweep,
    /// A tree shape without data.
    Plan,
}

/// How a row's numbers print.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Format {
    /// Integers with thousands separators when whole, else three significant digits.
    #[default]
    Auto,
    /// Rounded to an integer, thousands separators.
    Int,
    /// × 100, one decimal, `%`.
    Percent,
    /// Three significant digits with a k / M / G suffix.
    Si,
}

/// A checked spec.
#[derive(Debug, Clone)]
pub struct Spec {
    /// The file it came from.
    pub file: PathBuf,
    /// Its id (the file's stem).
    pub id: String,
    /// The paper.
    pub paper: String,
    /// The table or figure.
    pub title: String,
    /// Where in the paper.
    pub source: String,
    /// Notes printed under the table.
    pub notes: Option<String>,
    /// The profiles it belongs to (all unless the spec says).
    pub profiles: Vec<Profile>,
    /// Scenes by name, resolved for the profile.
    pub scenes: BTreeMap<String, SceneSpec>,
    /// Measures in file order.
    pub measures: Vec<Measure>,
    /// Rows in file order.
    pub rows: Vec<Row>,
    /// Rows this profile leaves out with a measure they read (its `profiles`).
    pub rows_elsewhere: Vec<RowElsewhere>,
    /// Figures.
    pub figures: Vec<Figure>,
}

/// One measure of a spec, resolved for a profile.
#[derive(Debug, Clone)]
pub struct Measure {
    /// Id, unique in the spec.
    pub id: String,
    /// Kind.
    pub kind: MeasureKind,
    /// Method.
    pub method: MethodKind,
    /// Scene name (a key of [`Spec::scenes`]); `None` for plans.
    pub scene: Option<String>,
    /// Parameters that change the build.
    pub build_params: Params,
    /// Parameters that only steer rendering ([`MethodKind::runtime_params`]).
    pub runtime_params: Params,
    /// Camera path (runs, sweeps).
    pub path: Option<PathSpec>,
    /// The path as `--path` takes it: a built-in name, or the keyframe file under the root.
    pub path_text: Option<String>,
    /// Frames along the path.
    pub frames: usize,
    /// Leading frames left out of the statistics.
    pub skip: usize,
    /// Targets: one for a run, one or more for a sweep.
    pub targets: Vec<SweepTarget>,
    /// Image width.
    pub width: u32,
    /// Image height.
    pub height: u32,
    /// Splat kernel.
    pub kernel: Kernel,
    /// GPU cache budget, MiB.
    pub gpu_cache_mb: u64,
    /// Image metrics against the reference.
    pub metrics: bool,
    /// Run in a child process.
    pub isolate: bool,
    /// Input points (plans).
    pub points: Option<u64>,
    /// The reference images' rasteriser (the spec's `reference`; `None`: the run's).
    pub reference_raster: Option<Raster>,
    /// The reference images' kernel (the measure's `reference_kernel`; `None`: the run's).
    pub reference_kernel: Option<Kernel>,
}

/// A row measured in other profiles only: a measure it reads has `profiles` without this one.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct RowElsewhere {
    /// The row's `what`.
    pub what: String,
    /// The profiles that measure it.
    pub profiles: Vec<Profile>,
}

/// Whether a metric key is a time or a rate (its last part `seconds`, `…_seconds`, `…_ms`
/// or `…_per_s`): what moves from one run to the next on the same input.
pub fn is_timing_key(key: &str) -> bool {
    let last = key.rsplit('.').next().unwrap_or(key);
    last == "seconds"
        || last.ends_with("_seconds")
        || last.ends_with("_ms")
        || last.ends_with("_per_s")
}

/// Which of a measure's timings verdict rows read ([`Spec::timed`]).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Timed {
    /// Its build's, by a row judged on any adapter.
    pub build: bool,
    /// Its build's, by a row judged on a GPU only.
    pub build_on_gpu: bool,
    /// Its frames', by a row judged on any adapter.
    pub frames: bool,
    /// Its frames', by a row judged on a GPU only.
    pub frames_on_gpu: bool,
}

/// One row of a spec's table.
#[derive(Debug, Clone)]
pub struct Row {
    /// What is compared.
    pub what: String,
    /// The paper's value(s).
    pub paper: Option<Paper>,
    /// How the paper's value prints (else from `paper`).
    pub paper_text: Option<String>,
    /// Our value(s).
    pub ours: Vec<Expr>,
    /// The rule.
    pub rule: Rule,
    /// `within`'s tolerance.
    pub tolerance: Option<f64>,
    /// How numbers print.
    pub format: Format,
    /// Why it differs: text with `{expr}` / `{expr:%}` placeholders.
    pub reason: Option<Vec<Piece>>,
    /// A GPU's figure.
    pub needs_gpu: bool,
    /// Rule `band`'s range.
    pub band: Option<(f64, f64)>,
    /// Why the band is what it is.
    pub band_reason: Option<String>,
    /// Measured on any adapter, judged on a GPU only (a relative speed: on a CPU rasteriser
    /// "CPU rasteriser: no verdict").
    pub judge_on_gpu: bool,
}

/// A piece of a reason template.
#[derive(Debug, Clone)]
pub enum Piece {
    /// Literal text.
    Text(String),
    /// A value, formatted.
    Value(Expr, Format),
}

/// A plot overlaying sweeps.
#[derive(Debug, Clone)]
pub struct Figure {
    /// File stem (`<spec id>-<name>.png`).
    pub name: String,
    /// Title.
    pub title: String,
    /// Sweep measure ids.
    pub sweeps: Vec<String>,
}

impl Spec {
    /// Every measure id the rows, reasons and figures refer to, with whether only
    /// `needs_gpu` rows use it.
    pub fn measure_uses(&self) -> BTreeMap<&str, bool> {
        let mut gpu_only: BTreeMap<&str, bool> = BTreeMap::new();
        for row in &self.rows {
            let mut refs: Vec<&str> = row.ours.iter().flat_map(Expr::measures).collect();
            for p in row.reason.iter().flatten() {
                if let Piece::Value(e, _) = p {
                    refs.extend(e.measures());
                }
            }
            for m in refs {
                let e = gpu_only.entry(m).or_insert(true);
                *e &= row.needs_gpu;
            }
        }
        for f in &self.figures {
            for s in &f.sweeps {
                gpu_only.insert(s, false);
            }
        }
        gpu_only
    }

    /// The measures whose timings a verdict rests on: those a row with a verdict rule
    /// (not `report`, not `by_construction`) reads a time or a rate of ([`is_timing_key`]),
    /// split by whether the time is its build's (`seconds`, `points_per_s`, … of a build
    /// measure; `build.…` of a run or sweep) or its frames', and by whether the row is judged
    /// on any adapter or on a GPU only (`needs_gpu`, `judge_on_gpu`). Such measures are timed
    /// as the median of repeats (`exec`): one timing of a short build or a few frames moves
    /// with whatever else the machine does, and a verdict should not.
    pub fn timed(&self) -> BTreeMap<&str, Timed> {
        let mut out: BTreeMap<&str, Timed> = BTreeMap::new();
        for row in self
            .rows
            .iter()
            .filter(|r| !matches!(r.rule, Rule::Report | Rule::ByConstruction))
        {
            let on_gpu = row.needs_gpu || row.judge_on_gpu;
            for (measure, key) in row.ours.iter().flat_map(Expr::refs) {
                if !is_timing_key(key) {
                    continue;
                }
                let of_build = key.starts_with("build.")
                    || self
                        .measure(measure)
                        .is_some_and(|m| m.kind == MeasureKind::Build);
                let t = out.entry(measure).or_default();
                let slot = match (of_build, on_gpu) {
                    (true, false) => &mut t.build,
                    (true, true) => &mut t.build_on_gpu,
                    (false, false) => &mut t.frames,
                    (false, true) => &mut t.frames_on_gpu,
                };
                *slot = true;
            }
        }
        out
    }

    /// Finds a measure by id.
    pub fn measure(&self, id: &str) -> Option<&Measure> {
        self.measures.iter().find(|m| m.id == id)
    }
}
