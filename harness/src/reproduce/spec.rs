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
//! points = { quick = 1_000_000, full = 10_000_000 }   # any count may differ by profile
//! seed = 1
//!
//! [[measure]]
//! id = "build"
//! kind = "build"                     # build | run | sweep | plan
//! method = "qsplat"
//! scene = "statue"
//! params = { }                       # --param key = value (build and runtime keys)
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
//!   memory figures are its own).
//! - `sweep`: as `run`, with lists `eps = [8, 4, 2, 1]` or `budget = [25_000, …]`.
//! - `plan`: `splatbench plan`'s tree shape (`method = "mwkd"`, `points`, `params`).
//!
//! A row with `needs_gpu = true` is a GPU's figure (throughput): on a CPU adapter it is
//! listed as "needs a GPU" and the measures only it uses are not run. `[[figure]]` tables
//! (`name`, `title`, `sweeps = [ids]`) overlay sweeps in one plot.

use std::collections::{BTreeMap, BTreeSet};
use std::fmt;
use std::path::{Path, PathBuf};

use methods::{MethodKind, Params};
use scenes::SceneSpec;
use scenes::generators::Generator;
use scenes::paths::PathSpec;

use super::expr::Expr;
use super::verdict::{Paper, Rule, check_shape};
use crate::render::Kernel;
use crate::sweep::SweepTarget;

/// Which sizes a reproduction uses.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Profile {
    /// Small scenes: the whole reproduction in minutes on 2 cores with lavapipe.
    Quick,
    /// The real sizes (10–100 M points).
    Full,
}

impl Profile {
    /// Both profiles.
    pub const ALL: [Profile; 2] = [Profile::Quick, Profile::Full];

    /// `quick` or `full`.
    pub fn name(self) -> &'static str {
        match self {
            Profile::Quick => "quick",
            Profile::Full => "full",
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
// The file as written.

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawSpec {
    id: String,
    paper: String,
    title: String,
    source: String,
    #[serde(default)]
    notes: Option<String>,
    #[serde(default)]
    scenes: BTreeMap<String, RawScene>,
    #[serde(default, rename = "measure")]
    measures: Vec<RawMeasure>,
    #[serde(default, rename = "row")]
    rows: Vec<RawRow>,
    #[serde(default, rename = "figure")]
    figures: Vec<RawFigure>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScene {
    generator: Option<String>,
    file: Option<PathBuf>,
    points: Option<toml::Value>,
    seed: Option<u64>,
    sample: Option<toml::Value>,
}

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

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawMeasure {
    id: String,
    kind: MeasureKind,
    method: String,
    scene: Option<String>,
    #[serde(default)]
    params: toml::Table,
    path: Option<String>,
    frames: Option<toml::Value>,
    skip: Option<u64>,
    eps: Option<toml::Value>,
    budget: Option<toml::Value>,
    width: Option<toml::Value>,
    height: Option<toml::Value>,
    kernel: Option<String>,
    gpu_cache_mb: Option<u64>,
    metrics: Option<bool>,
    isolate: Option<bool>,
    points: Option<toml::Value>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawRow {
    what: String,
    paper: Option<toml::Value>,
    paper_text: Option<String>,
    ours: toml::Value,
    rule: Rule,
    tolerance: Option<f64>,
    #[serde(default)]
    format: Format,
    reason: Option<String>,
    #[serde(default)]
    needs_gpu: bool,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct RawFigure {
    name: String,
    title: String,
    sweeps: Vec<String>,
}

// ---------------------------------------------------------------------------------------
// The spec as checked, resolved for one profile.

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
    /// Scenes by name, resolved for the profile.
    pub scenes: BTreeMap<String, SceneSpec>,
    /// Measures in file order.
    pub measures: Vec<Measure>,
    /// Rows in file order.
    pub rows: Vec<Row>,
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

    /// Finds a measure by id.
    pub fn measure(&self, id: &str) -> Option<&Measure> {
        self.measures.iter().find(|m| m.id == id)
    }
}

/// Loads every `*.toml` in `dir` (sorted by file name), paths inside them relative to
/// `root`, resolved for `profile`. Each spec is checked for both profiles.
pub fn load_dir(dir: &Path, root: &Path, profile: Profile) -> Result<Vec<Spec>, SpecError> {
    let err = |m: String| SpecError {
        file: dir.to_path_buf(),
        field: String::new(),
        message: m,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| err(format!("cannot read the spec directory: {e}")))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(err("no *.toml specs".into()));
    }
    let specs: Vec<Spec> = files
        .iter()
        .map(|f| load(f, root, profile))
        .collect::<Result<_, _>>()?;
    Ok(specs)
}

/// Loads one spec file for `profile` (checking it for both).
pub fn load(file: &Path, root: &Path, profile: Profile) -> Result<Spec, SpecError> {
    let text = std::fs::read_to_string(file).map_err(|e| SpecError {
        file: file.to_path_buf(),
        field: String::new(),
        message: format!("cannot read: {e}"),
    })?;
    parse(&text, file, root, profile)
}

/// Parses a spec's text (`file` names it in errors and gives the expected id).
pub fn parse(text: &str, file: &Path, root: &Path, profile: Profile) -> Result<Spec, SpecError> {
    let raw: RawSpec = toml::from_str(text).map_err(|e| SpecError {
        file: file.to_path_buf(),
        field: String::new(),
        message: e.to_string().trim_end().replace('\n', " "),
    })?;
    let mut out = None;
    for p in Profile::ALL {
        let s = Checker {
            file,
            root,
            profile: p,
        }
        .spec(&raw)?;
        if p == profile {
            out = Some(s);
        }
    }
    out.ok_or_else(|| SpecError {
        file: file.to_path_buf(),
        field: String::new(),
        message: "no profile".into(),
    })
}

struct Checker<'a> {
    file: &'a Path,
    root: &'a Path,
    profile: Profile,
}

impl Checker<'_> {
    fn err(&self, field: impl Into<String>, message: impl Into<String>) -> SpecError {
        let message = message.into();
        SpecError {
            file: self.file.to_path_buf(),
            field: field.into(),
            message: message.replace("{profile}", self.profile.name()),
        }
    }

    fn spec(&self, raw: &RawSpec) -> Result<Spec, SpecError> {
        let stem = self
            .file
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default();
        if raw.id != stem {
            return Err(self.err(
                "id",
                format!(
                    "'{}' must equal the file's name without .toml ('{stem}')",
                    raw.id
                ),
            ));
        }
        for (field, v) in [
            ("paper", &raw.paper),
            ("title", &raw.title),
            ("source", &raw.source),
        ] {
            if v.trim().is_empty() {
                return Err(self.err(field, "must not be empty"));
            }
        }
        let mut scenes = BTreeMap::new();
        for (name, s) in &raw.scenes {
            scenes.insert(name.clone(), self.scene(name, s)?);
        }
        let mut measures: Vec<Measure> = Vec::new();
        for m in &raw.measures {
            let checked = self.measure(m, &scenes)?;
            if measures.iter().any(|o| o.id == checked.id) {
                return Err(self.err(format!("measure '{}'", m.id), "id given twice"));
            }
            measures.push(checked);
        }
        if raw.rows.is_empty() {
            return Err(self.err("row", "a spec needs at least one [[row]]"));
        }
        let rows = raw
            .rows
            .iter()
            .enumerate()
            .map(|(i, r)| self.row(i, r, &measures))
            .collect::<Result<Vec<_>, _>>()?;
        let mut figures = Vec::new();
        for f in &raw.figures {
            let field = format!("figure '{}'", f.name);
            if f.name.is_empty()
                || !f
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-')
            {
                return Err(self.err(field, "name: letters, digits and '-' only"));
            }
            if f.sweeps.is_empty() {
                return Err(self.err(field, "sweeps: name at least one sweep measure"));
            }
            for s in &f.sweeps {
                match measures.iter().find(|m| &m.id == s) {
                    Some(m) if m.kind == MeasureKind::Sweep => {}
                    Some(_) => return Err(self.err(field, format!("sweeps: '{s}' is not a sweep"))),
                    None => {
                        return Err(self.err(field, format!("sweeps: no measure '{s}'")));
                    }
                }
            }
            figures.push(Figure {
                name: f.name.clone(),
                title: f.title.clone(),
                sweeps: f.sweeps.clone(),
            });
        }
        let spec = Spec {
            file: self.file.to_path_buf(),
            id: raw.id.clone(),
            paper: raw.paper.clone(),
            title: raw.title.clone(),
            source: raw.source.clone(),
            notes: raw.notes.clone(),
            scenes,
            measures,
            rows,
            figures,
        };
        let used = spec.measure_uses();
        if let Some(m) = spec
            .measures
            .iter()
            .find(|m| !used.contains_key(m.id.as_str()))
        {
            return Err(self.err(
                format!("measure '{}'", m.id),
                "no row, reason or figure uses it (remove it, or add a row)",
            ));
        }
        Ok(spec)
    }

    /// An integer that may differ by profile: `N` or `{ quick = N, full = M }`.
    fn count(&self, field: &str, v: &toml::Value) -> Result<u64, SpecError> {
        let int = |v: &toml::Value, what: &str| match v {
            toml::Value::Integer(i) if *i >= 0 => Ok(*i as u64),
            _ => Err(self.err(
                field,
                format!(
                    "{what}must be a non-negative integer or {{ quick = N, full = M }}, not {v}"
                ),
            )),
        };
        match v {
            toml::Value::Table(t) => {
                if let Some(k) = t.keys().find(|k| *k != "quick" && *k != "full") {
                    return Err(self.err(field, format!("unknown profile '{k}' (quick, full)")));
                }
                let Some(v) = t.get(self.profile.name()) else {
                    return Err(self.err(field, "gives no value for profile '{profile}'"));
                };
                int(v, &format!("{}: ", self.profile))
            }
            v => int(v, ""),
        }
    }

    fn scene(&self, name: &str, s: &RawScene) -> Result<SceneSpec, SpecError> {
        let field = format!("scenes.{name}");
        let sample = s
            .sample
            .as_ref()
            .map(|v| self.count(&format!("{field}.sample"), v))
            .transpose()?
            .map(|v| v as usize);
        let seed = s.seed.unwrap_or(1);
        let text = match (&s.generator, &s.file) {
            (Some(g), None) => {
                let generator = Generator::ALL
                    .iter()
                    .find(|x| x.name() == g)
                    .ok_or_else(|| {
                        let known: Vec<_> = Generator::ALL.iter().map(|x| x.name()).collect();
                        self.err(
                            format!("{field}.generator"),
                            format!("unknown generator '{g}' (known: {})", known.join(", ")),
                        )
                    })?;
                let Some(points) = &s.points else {
                    return Err(self.err(format!("{field}.points"), "a generator needs `points`"));
                };
                let n = self.count(&format!("{field}.points"), points)?;
                if n == 0 {
                    return Err(self.err(format!("{field}.points"), "must be at least 1"));
                }
                format!("{}:{n}:{seed}", generator.name())
            }
            (None, Some(f)) => {
                if s.points.is_some() {
                    return Err(self.err(
                        format!("{field}.points"),
                        "a file has its own points (use `sample` to resample a mesh)",
                    ));
                }
                let p = self.root.join(f);
                if !p.is_file() {
                    return Err(self.err(
                        format!("{field}.file"),
                        format!("{} does not exist", p.display()),
                    ));
                }
                p.to_string_lossy().into_owned()
            }
            _ => {
                return Err(self.err(field, "give exactly one of `generator` and `file`"));
            }
        };
        SceneSpec::parse(&text, sample, seed).map_err(|e| self.err(field, e.to_string()))
    }

    fn measure(
        &self,
        m: &RawMeasure,
        scenes: &BTreeMap<String, SceneSpec>,
    ) -> Result<Measure, SpecError> {
        let field = |f: &str| format!("measure '{}': {f}", m.id);
        if m.id.is_empty() || !m.id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(self.err(
                format!("measure '{}'", m.id),
                "id: letters, digits and '_' only (it is used in expressions)",
            ));
        }
        let method = MethodKind::from_name(&m.method)
            .map_err(|e| self.err(field("method"), param_message(&e)))?;
        let is_render = matches!(m.kind, MeasureKind::Run | MeasureKind::Sweep);
        let deny = |name: &str, given: bool| {
            if given {
                Err(self.err(
                    field(name),
                    format!("does not apply to a {:?} measure", m.kind).to_lowercase(),
                ))
            } else {
                Ok(())
            }
        };
        // Parameters: TOML values as `--param` text, split into build and runtime keys.
        let mut pairs = Vec::new();
        for (k, v) in &m.params {
            let text = match v {
                toml::Value::String(s) => s.clone(),
                toml::Value::Integer(_) | toml::Value::Float(_) | toml::Value::Boolean(_) => {
                    v.to_string()
                }
                _ => {
                    return Err(self.err(
                        field(&format!("params.{k}")),
                        "must be a string, number or boolean",
                    ));
                }
            };
            pairs.push(format!("{k}={text}"));
        }
        let all =
            Params::parse(&pairs).map_err(|e| self.err(field("params"), param_message(&e)))?;
        method
            .check_params(&all)
            .map_err(|e| self.err(field("params"), param_message(&e)))?;
        let (mut build_params, mut runtime_params) = (Params::default(), Params::default());
        for (k, v) in all.0 {
            if method.runtime_params().contains(&k.as_str()) {
                runtime_params.0.insert(k, v);
            } else {
                build_params.0.insert(k, v);
            }
        }
        if m.kind == MeasureKind::Build && !runtime_params.is_empty() {
            return Err(self.err(
                field("params"),
                format!(
                    "{} only steer rendering, not a build",
                    runtime_params
                        .0
                        .keys()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        // Scene.
        let scene = match (&m.scene, m.kind) {
            (None, MeasureKind::Plan) => None,
            (Some(_), MeasureKind::Plan) => {
                return Err(self.err(field("scene"), "a plan has no data: give `points`"));
            }
            (None, _) => return Err(self.err(field("scene"), "is required")),
            (Some(s), _) if !scenes.contains_key(s) => {
                let known: Vec<_> = scenes.keys().cloned().collect();
                return Err(self.err(
                    field("scene"),
                    format!(
                        "'{s}' is not defined in [scenes] (defined: {})",
                        if known.is_empty() {
                            "none".into()
                        } else {
                            known.join(", ")
                        }
                    ),
                ));
            }
            (Some(s), _) => Some(s.clone()),
        };
        // Plans.
        let points = match (&m.points, m.kind) {
            (Some(v), MeasureKind::Plan) => Some(self.count(&field("points"), v)?),
            (None, MeasureKind::Plan) => {
                return Err(self.err(field("points"), "a plan needs `points`"));
            }
            (Some(_), _) => return Err(self.err(field("points"), "belongs to plan measures")),
            (None, _) => None,
        };
        if m.kind == MeasureKind::Plan && method != MethodKind::Mwkd {
            return Err(self.err(field("method"), "only mwkd can plan a tree without data"));
        }
        if !is_render {
            for (name, given) in [
                ("path", m.path.is_some()),
                ("frames", m.frames.is_some()),
                ("skip", m.skip.is_some()),
                ("eps", m.eps.is_some()),
                ("budget", m.budget.is_some()),
                ("width", m.width.is_some()),
                ("height", m.height.is_some()),
                ("kernel", m.kernel.is_some()),
                ("gpu_cache_mb", m.gpu_cache_mb.is_some()),
                ("metrics", m.metrics.is_some()),
                ("isolate", m.isolate.is_some()),
            ] {
                deny(name, given)?;
            }
        }
        // Rendering.
        let (path, path_text) = if is_render {
            let text = m.path.as_deref().unwrap_or("orbit");
            let (spec, resolved) = if PathSpec::builtin(text).is_some() {
                (PathSpec::parse(text), text.to_string())
            } else {
                let p = self.root.join(text);
                if !p.is_file() {
                    return Err(self.err(
                        field("path"),
                        format!(
                            "'{text}' is neither a built-in path ({}) nor a file ({} does not exist)",
                            PathSpec::BUILTIN.iter().map(|b| b.0).collect::<Vec<_>>().join(", "),
                            p.display()
                        ),
                    ));
                }
                let resolved = p.to_string_lossy().into_owned();
                (PathSpec::parse(&resolved), resolved)
            };
            (
                Some(spec.map_err(|e| self.err(field("path"), e.to_string()))?),
                Some(resolved),
            )
        } else {
            (None, None)
        };
        if m.isolate == Some(true) && m.kind != MeasureKind::Run {
            return Err(self.err(field("isolate"), "only a run measure can be isolated"));
        }
        let frames = match &m.frames {
            Some(v) => self.count(&field("frames"), v)? as usize,
            None if is_render => return Err(self.err(field("frames"), "is required")),
            None => 0,
        };
        if is_render && frames == 0 {
            return Err(self.err(field("frames"), "must be at least 1"));
        }
        let skip = m.skip.unwrap_or(0) as usize;
        if is_render && skip >= frames {
            return Err(self.err(
                field("skip"),
                format!("{skip} leaves none of the {frames} frames"),
            ));
        }
        let targets = if is_render {
            self.targets(m, &field)?
        } else {
            Vec::new()
        };
        let size = |name: &str, v: &Option<toml::Value>| -> Result<u32, SpecError> {
            match v {
                None => Ok(512),
                Some(v) => {
                    let n = self.count(&field(name), v)?;
                    if (1..=16_384).contains(&n) {
                        Ok(n as u32)
                    } else {
                        Err(self.err(field(name), format!("{n} px is outside 1…16384")))
                    }
                }
            }
        };
        let kernel = match &m.kernel {
            None => Kernel::Square,
            Some(k) => *Kernel::ALL.iter().find(|x| x.name() == k).ok_or_else(|| {
                let known: Vec<_> = Kernel::ALL.iter().map(|x| x.name()).collect();
                self.err(
                    field("kernel"),
                    format!("unknown kernel '{k}' (known: {})", known.join(", ")),
                )
            })?,
        };
        Ok(Measure {
            id: m.id.clone(),
            kind: m.kind,
            method,
            scene,
            build_params,
            runtime_params,
            path,
            path_text,
            frames,
            skip,
            targets,
            width: size("width", &m.width)?,
            height: size("height", &m.height)?,
            kernel,
            gpu_cache_mb: m.gpu_cache_mb.unwrap_or(512),
            metrics: m.metrics.unwrap_or(true),
            isolate: m.isolate.unwrap_or(false),
            points,
        })
    }

    fn targets(
        &self,
        m: &RawMeasure,
        field: &dyn Fn(&str) -> String,
    ) -> Result<Vec<SweepTarget>, SpecError> {
        let (name, v) = match (&m.eps, &m.budget) {
            (Some(v), None) => ("eps", v),
            (None, Some(v)) => ("budget", v),
            _ => {
                return Err(self.err(
                    field("eps"),
                    "give exactly one of `eps` (pixels) and `budget` (points)",
                ));
            }
        };
        let v = match v {
            toml::Value::Table(t) if t.keys().all(|k| k == "quick" || k == "full") => t
                .get(self.profile.name())
                .ok_or_else(|| self.err(field(name), "gives no value for profile '{profile}'"))?,
            v => v,
        };
        let items: Vec<&toml::Value> = match (v, m.kind) {
            (toml::Value::Array(a), MeasureKind::Sweep) => a.iter().collect(),
            (toml::Value::Array(_), _) => {
                return Err(self.err(field(name), "a run has one target (a sweep takes a list)"));
            }
            (v, _) => vec![v],
        };
        if items.is_empty() {
            return Err(self.err(field(name), "the list is empty"));
        }
        let mut out: Vec<SweepTarget> = Vec::new();
        for it in items {
            let t = if name == "eps" {
                let px = match it {
                    toml::Value::Float(f) => *f,
                    toml::Value::Integer(i) => *i as f64,
                    _ => {
                        return Err(
                            self.err(field(name), format!("{it} is not a number of pixels"))
                        );
                    }
                };
                SweepTarget::tolerance(px as f32)
            } else {
                match it {
                    toml::Value::Integer(i) if *i > 0 => SweepTarget::budget(*i as u64),
                    _ => return Err(self.err(field(name), format!("{it} is not a budget ≥ 1"))),
                }
            }
            .map_err(|e| self.err(field(name), e.to_string()))?;
            if out.iter().any(|o| o.name == t.name) {
                return Err(self.err(field(name), format!("{} is given twice", t.value)));
            }
            out.push(t);
        }
        Ok(out)
    }

    fn row(&self, i: usize, r: &RawRow, measures: &[Measure]) -> Result<Row, SpecError> {
        let field = |f: &str| format!("row {} ('{}'): {f}", i + 1, r.what);
        let texts: Vec<&str> = match &r.ours {
            toml::Value::String(s) => vec![s.as_str()],
            toml::Value::Array(a) => a
                .iter()
                .map(|v| {
                    v.as_str()
                        .ok_or_else(|| self.err(field("ours"), "a list of expressions (strings)"))
                })
                .collect::<Result<_, _>>()?,
            _ => return Err(self.err(field("ours"), "an expression or a list of them")),
        };
        let ours: Vec<Expr> = texts
            .iter()
            .map(|t| Expr::parse(t).map_err(|e| self.err(field("ours"), e)))
            .collect::<Result<_, _>>()?;
        let number = |v: &toml::Value| match v {
            toml::Value::Float(f) => Some(*f),
            toml::Value::Integer(i) => Some(*i as f64),
            _ => None,
        };
        let paper = match &r.paper {
            None => None,
            Some(v) => Some(match (v, r.rule) {
                (toml::Value::Array(a), rule) => {
                    let nums: Vec<f64> = a
                        .iter()
                        .map(|x| number(x).ok_or_else(|| self.err(field("paper"), "numbers only")))
                        .collect::<Result<_, _>>()?;
                    if rule == Rule::Inside && nums.len() == 2 {
                        Paper::Range(nums[0], nums[1])
                    } else {
                        Paper::List(nums)
                    }
                }
                (v, _) => Paper::Value(
                    number(v).ok_or_else(|| self.err(field("paper"), "a number or a list"))?,
                ),
            }),
        };
        check_shape(r.rule, paper.as_ref(), ours.len(), r.tolerance)
            .map_err(|e| self.err(field("rule"), e))?;
        let reason = r
            .reason
            .as_deref()
            .map(|t| template(t).map_err(|e| self.err(field("reason"), e)))
            .transpose()?;
        let row = Row {
            what: r.what.clone(),
            paper,
            paper_text: r.paper_text.clone(),
            ours,
            rule: r.rule,
            tolerance: r.tolerance,
            format: r.format,
            reason,
            needs_gpu: r.needs_gpu,
        };
        // Every reference names a measure; points_at_flip names a sweep.
        let mut exprs: Vec<(&Expr, &str)> = row.ours.iter().map(|e| (e, "ours")).collect();
        for p in row.reason.iter().flatten() {
            if let Piece::Value(e, _) = p {
                exprs.push((e, "reason"));
            }
        }
        for (e, which) in exprs {
            for id in e.measures() {
                if !measures.iter().any(|m| m.id == id) {
                    let known: BTreeSet<&str> = measures.iter().map(|m| m.id.as_str()).collect();
                    return Err(self.err(
                        field(which),
                        format!(
                            "'{id}' is not a measure of this spec (measures: {})",
                            known.into_iter().collect::<Vec<_>>().join(", ")
                        ),
                    ));
                }
            }
            check_sweep_args(e, measures).map_err(|m| self.err(field(which), m))?;
        }
        Ok(row)
    }
}

/// A method error's message without the CLI's `--param:` prefix (a spec has no flags).
fn param_message(e: &methods::MethodError) -> String {
    match e {
        methods::MethodError::Param(m) => m.clone(),
        e => e.to_string(),
    }
}

fn check_sweep_args(e: &Expr, measures: &[Measure]) -> Result<(), String> {
    use super::expr::Func;
    match e {
        Expr::Call(Func::PointsAtFlip(m), args) => {
            if measures
                .iter()
                .any(|x| &x.id == m && x.kind != MeasureKind::Sweep)
            {
                return Err(format!("points_at_flip: '{m}' is not a sweep measure"));
            }
            args.iter().try_for_each(|a| check_sweep_args(a, measures))
        }
        Expr::Call(_, args) => args.iter().try_for_each(|a| check_sweep_args(a, measures)),
        Expr::Neg(a) => check_sweep_args(a, measures),
        Expr::Bin(a, _, b) => {
            check_sweep_args(a, measures)?;
            check_sweep_args(b, measures)
        }
        Expr::Num(_) | Expr::Ref { .. } => Ok(()),
    }
}

/// Splits a reason into text and `{expr}` / `{expr:%}` values (`{{` and `}}` are braces).
fn template(text: &str) -> Result<Vec<Piece>, String> {
    let mut out = Vec::new();
    let mut lit = String::new();
    let mut rest = text;
    while let Some(i) = rest.find(['{', '}']) {
        lit.push_str(&rest[..i]);
        let (c, after) = (rest.as_bytes()[i], &rest[i + 1..]);
        if after.as_bytes().first() == Some(&c) {
            lit.push(c as char);
            rest = &after[1..];
            continue;
        }
        if c == b'}' {
            return Err("an unmatched '}' (write '}}' for a brace)".into());
        }
        let end = after
            .find('}')
            .ok_or("an unclosed '{' (write '{{' for a brace)")?;
        let inner = &after[..end];
        let (expr, format) = match inner.rsplit_once(':') {
            Some((e, "%")) => (e, Format::Percent),
            Some((e, "si")) => (e, Format::Si),
            Some((e, "int")) => (e, Format::Int),
            Some((_, f)) => {
                return Err(format!("'{{{inner}}}': unknown format ':{f}' (%, si, int)"));
            }
            None => (inner, Format::Auto),
        };
        if !lit.is_empty() {
            out.push(Piece::Text(std::mem::take(&mut lit)));
        }
        out.push(Piece::Value(Expr::parse(expr.trim())?, format));
        rest = &after[end + 1..];
    }
    lit.push_str(rest);
    if !lit.is_empty() {
        out.push(Piece::Text(lit));
    }
    Ok(out)
}
