//! Regression checks (`splatbench check`): a run, sweep, tune or reproduction directory
//! compared with a committed baseline.
//!
//! A **baseline** ([`Baseline`], JSON) records every run found under the directory it was
//! blessed from ([`record::find_runs`]), keyed by the run's path inside it, with the run's
//! identity (method, parameters, scene, path, frames, target, resolution, kernel, shading)
//! and its figures per frame ([`RunRecord`]); plus the adapter, commit, date and command
//! that produced it, and the image tolerances ([`Tolerances`]).
//!
//! [`compare`] matches runs by key and compares each figure by its class
//! ([`figures::Class`]): selection counts, build sizes and scene facts exactly; image
//! metrics within the tolerance for the same adapter or another; figures counted on the
//! GPU exactly on the same adapter and not at all on another; times as ratios of medians
//! that fail only beyond a `--timing-gate`. What makes a comparison meaningless is
//! [`Unusable`] (exit 2): a baseline from another scene, resolution, path, target, method,
//! parameter set, kernel or shading for the same key, no run in common, a file missing or
//! unreadable. What fails it (exit 1): any figure outside its allowance, a frame or a run of
//! the baseline missing, a run that did not complete.

mod figures;
mod format;
mod interval;
mod numbers;
mod record;
pub mod suite;
mod table;
mod tolerance;

use std::collections::{BTreeMap, BTreeSet};
use std::path::Path;

use anyhow::Context as _;

pub use figures::{Class, RunTraits, build_class, column_class, is_rate, process_class};
pub use record::{DirKind, RunRecord, adapter_text, find_runs};
pub use table::render_table;
pub use tolerance::{ImageTolerance, Tolerances};

use crate::gpu::AdapterDesc;
use numbers::{fmt, show, show_pair};

/// Version of the baseline file format.
pub const FORMAT: u32 = 1;

/// A baseline file.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Baseline {
    /// [`FORMAT`].
    pub format: u32,
    /// What was blessed: `run`, `sweep`, `tune`, `reproduce`, `suite` or `runs`.
    pub what: String,
    /// The commands that produced the runs (distinct, in key order), or the suite's command.
    pub commands: Vec<String>,
    /// Commit of the binary that blessed it.
    pub commit: String,
    /// When (UTC).
    pub date: String,
    /// The adapter of the runs (the first run's; each run records its own).
    pub adapter: Option<AdapterDesc>,
    /// Image tolerances.
    pub tolerances: Tolerances,
    /// The runs, by their path inside the blessed directory.
    pub runs: BTreeMap<String, RunRecord>,
}

/// Input that cannot be compared (exit status 2): the message names the file, the run and
/// the field.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct Unusable(pub String);

/// The verdict of one row of the check's table.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Verdict {
    /// Outside its allowance.
    Fails,
    /// In the baseline, absent now.
    Missing,
    /// Slower than the timing gate allows.
    Slower,
    /// Changed within its allowance.
    Within,
    /// Not compared: counted on the GPU, and the adapters differ.
    OtherAdapter,
    /// Not in the baseline (a new run or figure): shown, not failing.
    New,
    /// A time, reported as a ratio.
    Ratio,
    /// Identical.
    Same,
}

impl Verdict {
    /// The word printed in the table.
    pub fn word(self) -> &'static str {
        match self {
            Self::Fails => "FAILS",
            Self::Missing => "MISSING",
            Self::Slower => "SLOWER",
            Self::Within => "within",
            Self::OtherAdapter => "other adapter",
            Self::New => "new",
            Self::Ratio => "ratio",
            Self::Same => "same",
        }
    }

    /// Whether this row makes the check fail.
    pub fn fails(self) -> bool {
        matches!(self, Self::Fails | Self::Missing | Self::Slower)
    }
}

/// One row of the table.
#[derive(Debug, Clone, PartialEq)]
pub struct Row {
    /// The figure (`points_drawn`, `build.bytes_out`, `run`, `frame`…).
    pub figure: String,
    /// The run's key.
    pub run: String,
    /// Method and parameters.
    pub method: String,
    /// Scene label.
    pub scene: String,
    /// Target, and the frame or `build`.
    pub at: String,
    /// The baseline's value.
    pub old: String,
    /// The value now.
    pub new: String,
    /// What is allowed.
    pub allowed: String,
    /// The verdict.
    pub verdict: Verdict,
    /// For a time: new / old.
    pub ratio: Option<f64>,
}

/// Options of a comparison.
#[derive(Debug, Clone, Copy, Default)]
pub struct Options {
    /// Fail a time whose median grew by more than this factor.
    pub timing_gate: Option<f64>,
    /// Compare runs whose identity differs (another parameter, kernel, shading…) instead of
    /// refusing them: a parameter's effect checked against a baseline. The differences are
    /// listed in [`Report::across`].
    pub compare_across: bool,
}

/// What a comparison found.
#[derive(Debug, Clone, Default)]
pub struct Report {
    /// Every compared figure that is not identical, plus one timing row per run and figure.
    pub rows: Vec<Row>,
    /// With [`Options::compare_across`]: how each run differs from its baseline's experiment.
    pub across: Vec<String>,
    /// Figures recorded but never compared: they follow the machine or thread timing
    /// ([`figures::Class::Machine`]).
    pub recorded: BTreeSet<String>,
    /// Figures compared (identical ones included).
    pub compared: usize,
    /// Runs compared.
    pub runs: usize,
}

impl Report {
    /// Rows that make the check fail.
    pub fn failures(&self) -> usize {
        self.rows.iter().filter(|r| r.verdict.fails()).count()
    }
    /// True if every figure holds.
    pub fn holds(&self) -> bool {
        self.failures() == 0
    }
}

/// Reads the runs under `dir` into a baseline (not written): what `--bless` records.
/// Incomplete runs are [`Unusable`]: a baseline is never blessed from half a run.
pub fn snapshot(dir: &Path, command: Option<String>) -> anyhow::Result<Baseline> {
    let found = find_runs(dir).map_err(|e| Unusable(format!("{e:#}")))?;
    if found.is_empty() {
        return Err(Unusable(format!(
            "{}: no run directory (summary.json + frames.csv) under it",
            dir.display()
        ))
        .into());
    }
    let mut runs = BTreeMap::new();
    for (key, d) in found {
        let r = RunRecord::read(&d).map_err(|e| Unusable(format!("{e:#}")))?;
        runs.insert(key, r);
    }
    let suite = dir.join("suite.json");
    let suite: Option<serde_json::Value> = std::fs::read_to_string(&suite)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok());
    if let Some(s) = &suite
        && s.get("complete") != Some(&serde_json::Value::Bool(true))
    {
        return Err(Unusable(format!(
            "{}: the suite did not run to the end (suite.json says \"complete\": false)",
            dir.display()
        ))
        .into());
    }
    let suite_command =
        || -> Option<String> { suite.as_ref()?.get("command")?.as_str().map(String::from) };
    let commands = match command.or_else(suite_command) {
        Some(c) => vec![c],
        None => {
            let mut seen = BTreeSet::new();
            runs.values()
                .filter_map(|r| r.command.clone())
                .filter(|c| seen.insert(c.clone()))
                .collect()
        }
    };
    Ok(Baseline {
        format: FORMAT,
        what: DirKind::of(dir).name().into(),
        commands,
        commit: crate::runner::GIT_COMMIT.into(),
        date: crate::reproduce::report::utc_now(),
        adapter: runs.values().next().map(|r| r.adapter.clone()),
        tolerances: Tolerances::default(),
        runs,
    })
}

impl Baseline {
    /// Reads a baseline file; a missing or malformed file is [`Unusable`], naming it.
    pub fn read(path: &Path) -> anyhow::Result<Self> {
        let text = std::fs::read_to_string(path)
            .map_err(|e| Unusable(format!("baseline {}: {e}", path.display())))?;
        let b: Self = serde_json::from_str(&text)
            .map_err(|e| Unusable(format!("baseline {}: {e}", path.display())))?;
        if b.format != FORMAT {
            return Err(Unusable(format!(
                "baseline {}: format {} (this splatbench reads format {FORMAT}): re-bless it",
                path.display(),
                b.format
            ))
            .into());
        }
        Ok(b)
    }

    /// Writes the baseline atomically (temporary file, then rename), one figure per line.
    pub fn write(&self, path: &Path) -> anyhow::Result<()> {
        let value = serde_json::to_value(self)?;
        let text = format::json(&value);
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        }
        crate::image::write_atomically(path, text.as_bytes())
            .with_context(|| format!("writing {}", path.display()))
    }
}

/// Compares `now` (a [`snapshot`] of the checked directory) with `baseline`.
pub fn compare(baseline: &Baseline, now: &Baseline, opts: Options) -> anyhow::Result<Report> {
    let common: Vec<&String> = baseline
        .runs
        .keys()
        .filter(|k| now.runs.contains_key(*k))
        .collect();
    if common.is_empty() {
        let list = |b: &Baseline| {
            let mut v: Vec<&str> = b.runs.keys().map(String::as_str).take(4).collect();
            if b.runs.len() > 4 {
                v.push("…");
            }
            v.join(", ")
        };
        return Err(Unusable(format!(
            "no run in common: the baseline holds {} ({}), the directory {} ({})",
            baseline.runs.len(),
            list(baseline),
            now.runs.len(),
            list(now)
        ))
        .into());
    }
    let mut report = Report::default();
    for key in &common {
        let differs = identity(key, &baseline.runs[*key], &now.runs[*key]);
        if opts.compare_across {
            report.across.extend(differs);
        } else if let Some(first) = differs.into_iter().next() {
            return Err(Unusable(format!(
                "{first}: the two are not the same experiment (--compare-across compares them \
                 anyway)"
            ))
            .into());
        }
    }
    for (key, old) in &baseline.runs {
        let Some(new) = now.runs.get(key) else {
            report.rows.push(Row {
                figure: "run".into(),
                run: key.clone(),
                method: old.method_label(),
                scene: old.scene.clone(),
                at: old.target.clone(),
                old: "present".into(),
                new: "absent".into(),
                allowed: "present".into(),
                verdict: Verdict::Missing,
                ratio: None,
            });
            continue;
        };
        report.runs += 1;
        compare_run(key, old, new, &baseline.tolerances, opts, &mut report);
    }
    for (key, new) in now
        .runs
        .iter()
        .filter(|(k, _)| !baseline.runs.contains_key(*k))
    {
        report.rows.push(Row {
            figure: "run".into(),
            run: key.clone(),
            method: new.method_label(),
            scene: new.scene.clone(),
            at: new.target.clone(),
            old: "absent".into(),
            new: "present".into(),
            allowed: "-".into(),
            verdict: Verdict::New,
            ratio: None,
        });
    }
    report
        .rows
        .sort_by(|a, b| (a.verdict, &a.run).cmp(&(b.verdict, &b.run)));
    Ok(report)
}

/// The fields that make two runs the same experiment: each that differs, in words naming the
/// run (`.`: the directory checked is the run).
fn identity(key: &str, old: &RunRecord, new: &RunRecord) -> Vec<String> {
    let fields: [(&str, String, String); 9] = [
        ("scene", old.scene.clone(), new.scene.clone()),
        (
            "resolution",
            format!("{}×{}", old.width, old.height),
            format!("{}×{}", new.width, new.height),
        ),
        ("method", old.method.clone(), new.method.clone()),
        ("parameters", old.method_label(), new.method_label()),
        ("path", old.path.clone(), new.path.clone()),
        ("frames", old.frames.to_string(), new.frames.to_string()),
        ("target", old.target.clone(), new.target.clone()),
        ("kernel", old.kernel.clone(), new.kernel.clone()),
        ("shading", old.shading.clone(), new.shading.clone()),
    ];
    let run = if key == "." {
        "the run".to_string()
    } else {
        format!("run '{key}'")
    };
    fields
        .into_iter()
        .filter(|(_, a, b)| a != b)
        .map(|(what, a, b)| format!("{run}: {what} {b}, the baseline's {a}"))
        .collect()
}

/// Compares run `key` of this run (`new`) with the baseline's (`old`) within `tol`: the run's
/// facts, its build figures, its frames' columns, and its times; a row that is not the same
/// goes into `report`.
fn compare_run(
    key: &str,
    old: &RunRecord,
    new: &RunRecord,
    tol: &Tolerances,
    opts: Options,
    report: &mut Report,
) {
    let same_adapter = old.adapter_text() == new.adapter_text();
    let tolerance = if same_adapter {
        &tol.same_adapter
    } else {
        &tol.other_adapter
    };
    let mut run = RunCompare {
        key,
        old,
        new,
        opts,
        report,
    };
    run.facts();
    run.build_figures();
    run.frames(same_adapter, tolerance);
    run.new_columns();
    run.times();
}

/// The rows of run `key` (method and scene as the baseline's `old` names them): a row from
/// figure, where, old and new value, what is allowed and the verdict.
fn rows_of<'a>(
    key: &'a str,
    old: &'a RunRecord,
) -> impl Fn(String, String, String, String, String, Verdict) -> Row + 'a {
    move |figure: String, at: String, old_v: String, new_v: String, allowed: String, v| Row {
        figure,
        run: key.to_string(),
        method: old.method_label(),
        scene: old.scene.clone(),
        at,
        old: old_v,
        new: new_v,
        allowed,
        verdict: v,
        ratio: None,
    }
}

/// One run's comparison in progress.
struct RunCompare<'a> {
    key: &'a str,
    old: &'a RunRecord,
    new: &'a RunRecord,
    opts: Options,
    report: &'a mut Report,
}

impl RunCompare<'_> {
    /// Counts a compared figure; keeps its row unless it is the same.
    fn push(&mut self, r: Row) {
        self.report.compared += 1;
        if r.verdict != Verdict::Same {
            self.report.rows.push(r);
        }
    }

    /// Run-level facts: complete, the scene's points and content hash.
    fn facts(&mut self) {
        let (old, new) = (self.old, self.new);
        let row = rows_of(self.key, old);
        self.push(row(
            "complete".into(),
            old.target.clone(),
            old.complete.to_string(),
            new.complete.to_string(),
            "true".into(),
            if new.complete || !old.complete {
                Verdict::Same
            } else {
                Verdict::Fails
            },
        ));
        for (figure, a, b) in [
            (
                "scene.points",
                old.scene_points.to_string(),
                new.scene_points.to_string(),
            ),
            (
                "scene.content_hash",
                old.content_hash.clone(),
                new.content_hash.clone(),
            ),
        ] {
            let v = if a == b {
                Verdict::Same
            } else {
                Verdict::Fails
            };
            self.push(row(
                figure.into(),
                old.target.clone(),
                a,
                b,
                "exact".into(),
                v,
            ));
        }
    }

    /// Build figures: timings as ratios, machine figures not at all, the others exactly.
    fn build_figures(&mut self) {
        let (old, new, opts) = (self.old, self.new, self.opts);
        let row = rows_of(self.key, old);
        let keys: BTreeSet<&String> = old.build.keys().chain(new.build.keys()).collect();
        for k in keys {
            let (a, b) = (old.build.get(k).copied(), new.build.get(k).copied());
            let at = format!("{} · build", old.target);
            let fig = format!("build.{k}");
            match build_class(k) {
                Class::Timing => {
                    if let (Some(a), Some(b)) = (a, b) {
                        self.push(timing_row(&row, fig, at, a, b, opts, is_rate(k)));
                    }
                }
                Class::Machine => {
                    self.report.recorded.insert(fig);
                }
                _ => self.push(exact_row(&row, fig, at, a, b)),
            }
        }
    }

    /// Frames, aligned by frame number: each baseline column's value by its class (exact,
    /// the adapter's, an image metric within `tolerance`; timings and machine figures not
    /// here).
    fn frames(&mut self, same_adapter: bool, tolerance: &ImageTolerance) {
        let (old, new) = (self.old, self.new);
        let row = rows_of(self.key, old);
        let traits = RunTraits::of(&new.method, &new.params, &new.column_names());
        let (old_frames, new_frames) = (old.frame_numbers(), new.frame_numbers());
        let new_index: BTreeMap<u64, usize> = new_frames
            .iter()
            .enumerate()
            .map(|(i, f)| (*f, i))
            .collect();
        for (i, f) in old_frames.iter().enumerate() {
            let at = format!("{} · frame {f}", old.target);
            let Some(&j) = new_index.get(f) else {
                self.push(row(
                    "frame".into(),
                    at,
                    "present".into(),
                    "absent".into(),
                    "present".into(),
                    Verdict::Missing,
                ));
                continue;
            };
            for (c, values) in &old.columns {
                if c == "frame" {
                    continue;
                }
                let a = values.get(i).copied().flatten();
                let Some(new_values) = new.columns.get(c) else {
                    self.push(row(
                        c.clone(),
                        at.clone(),
                        show(a),
                        "no column".into(),
                        "present".into(),
                        Verdict::Missing,
                    ));
                    continue;
                };
                let b = new_values.get(j).copied().flatten();
                let class = column_class(c, traits);
                let r = match class {
                    Class::Exact => exact_row(&row, c.clone(), at.clone(), a, b),
                    Class::Adapter if same_adapter => exact_row(&row, c.clone(), at.clone(), a, b),
                    Class::Adapter => row(
                        c.clone(),
                        at.clone(),
                        show(a),
                        show(b),
                        "same adapter only".into(),
                        if a == b {
                            Verdict::Same
                        } else {
                            Verdict::OtherAdapter
                        },
                    ),
                    Class::Image => image_row(&row, c, at.clone(), a, b, tolerance.of(c)),
                    Class::Machine => {
                        self.report.recorded.insert(c.clone());
                        continue;
                    }
                    Class::Timing => continue,
                };
                self.push(r);
            }
        }
    }

    /// Columns this run has and the baseline has not.
    fn new_columns(&mut self) {
        let (old, new) = (self.old, self.new);
        let row = rows_of(self.key, old);
        for c in new.columns.keys().filter(|c| !old.columns.contains_key(*c)) {
            self.push(row(
                c.clone(),
                old.target.clone(),
                "no column".into(),
                "present".into(),
                "-".into(),
                Verdict::New,
            ));
        }
    }

    /// Times: the medians over the frames, as ratios; then the process's timings.
    fn times(&mut self) {
        let (old, new, opts) = (self.old, self.new, self.opts);
        let row = rows_of(self.key, old);
        for c in ["gpu_ms", "wall_ms", "cpu_select_ms"] {
            let med = |r: &RunRecord| {
                r.columns
                    .get(c)
                    .and_then(|v| crate::results::median(v.iter().flatten().copied()))
            };
            if let (Some(a), Some(b)) = (med(old), med(new)) {
                let frames = |r: &RunRecord| -> Vec<f64> {
                    r.columns
                        .get(c)
                        .map(|v| v.iter().flatten().copied().collect())
                        .unwrap_or_default()
                };
                let ci = interval::ratio_interval(&frames(old), &frames(new));
                self.push(gated_frames_row(
                    timing_row(
                        &row,
                        format!("{c} (median)"),
                        old.target.clone(),
                        a,
                        b,
                        opts,
                        false,
                    ),
                    ci,
                    opts,
                ));
            }
        }
        for (k, a) in &old.process {
            if let (Class::Timing, Some(b)) = (process_class(k), new.process.get(k)) {
                self.push(timing_row(
                    &row,
                    k.clone(),
                    old.target.clone(),
                    *a,
                    *b,
                    opts,
                    false,
                ));
            }
        }
    }
}

/// A per-frame time's row with the 95 % interval of its ratio ([`interval`]), where the
/// frames give one: the gate then fails it only when the whole interval lies beyond the
/// gate (a slowdown the frames show), and passes one whose interval reaches below it
/// however far its median moved.
fn gated_frames_row(mut r: Row, ci: Option<(f64, f64)>, opts: Options) -> Row {
    let Some((lo, hi)) = ci else {
        return r;
    };
    r.new = format!("{} [95 % ×{lo:.3}–×{hi:.3}]", r.new);
    if let Some(g) = opts.timing_gate {
        r.verdict = if lo > g {
            Verdict::Slower
        } else {
            Verdict::Ratio
        };
        r.allowed = format!("slowdown ≤ ×{g} (95 % interval)");
    }
    r
}

/// An exactly compared figure's row.
fn exact_row(
    row: &impl Fn(String, String, String, String, String, Verdict) -> Row,
    figure: String,
    at: String,
    a: Option<f64>,
    b: Option<f64>,
) -> Row {
    let v = if a == b {
        Verdict::Same
    } else if b.is_none() {
        Verdict::Missing
    } else if a.is_none() {
        Verdict::New
    } else {
        Verdict::Fails
    };
    let (sa, sb) = show_pair(a, b);
    row(figure, at, sa, sb, "exact".into(), v)
}

/// An image metric's row: `|new − old| ≤ tol`; `None` tolerance: shown, not compared.
fn image_row(
    row: &impl Fn(String, String, String, String, String, Verdict) -> Row,
    figure: &str,
    at: String,
    a: Option<f64>,
    b: Option<f64>,
    tol: Option<f64>,
) -> Row {
    let (v, allowed) = match (a, b, tol) {
        _ if a == b => (Verdict::Same, tol.map_or("-".into(), |t| format!("± {t}"))),
        (_, _, None) => (Verdict::OtherAdapter, "not compared".into()),
        (Some(x), Some(y), Some(t)) if (x - y).abs() <= t => (Verdict::Within, format!("± {t}")),
        (Some(_), None, Some(t)) => (Verdict::Missing, format!("± {t}")),
        (_, _, Some(t)) => (Verdict::Fails, format!("± {t}")),
    };
    let (sa, sb) = show_pair(a, b);
    row(figure.to_string(), at, sa, sb, allowed, v)
}

/// A time's row: the ratio new/old (for a rate, old/new: larger is slower either way).
fn timing_row(
    row: &impl Fn(String, String, String, String, String, Verdict) -> Row,
    figure: String,
    at: String,
    a: f64,
    b: f64,
    opts: Options,
    rate: bool,
) -> Row {
    let slowdown = if rate { a / b } else { b / a };
    let ratio = if a > 0.0 && b > 0.0 {
        format!("×{:.3}", b / a)
    } else {
        "-".into()
    };
    let (v, allowed) = match opts.timing_gate {
        Some(g) if slowdown.is_finite() && slowdown > g => {
            (Verdict::Slower, format!("slowdown ≤ ×{g}"))
        }
        Some(g) => (Verdict::Ratio, format!("slowdown ≤ ×{g}")),
        None => (Verdict::Ratio, "any (no --timing-gate)".into()),
    };
    Row {
        ratio: (a > 0.0 && b > 0.0).then(|| b / a),
        ..row(
            figure,
            at,
            fmt(a),
            format!("{} ({ratio})", fmt(b)),
            allowed,
            v,
        )
    }
}
