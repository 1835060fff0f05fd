//! Parameter choice (`splatbench tune`): a grid over a method's parameters, one ordinary run
//! per setting and target, the Pareto front over (error, cost) and a recommendation.
//!
//! A [`Plan`] is everything a tune does, as data: the method, the [`grid::Grid`] (build and
//! runtime keys told apart), the targets, the cost measure, the repeats, and the command
//! lines' shared arguments. It is carried out in **parts**, one per distinct build (the
//! build, then every run on it): each build and run is a child process of the `splatbench`
//! binary (`build`, then `run --build-dir`), so a run's peak RSS is its own and the build's
//! is the build's, and a part is exactly the job line `--emit-jobs` writes
//! (`splatbench tune … --part K`). A local tune runs every part and then [`assemble`]s;
//! `splatbench merge` assembles the parts that jobs wrote elsewhere, with the same code.
//!
//! Layout of `OUT/`: `tune.json` (the plan, the parts done, `"complete"`), `builds/<b>/`
//! (`m-512`; `default` when only runtime keys vary; absent with `--build-dir`),
//! `runs/<setting>/<target>/` (ordinary run directories), `repeats/<setting>/<target>/rep-K/`
//! (the same runs again, for run-to-run noise), then from [`assemble`]: `tune.csv`,
//! `recommendation.md` and `tune.png/.svg`.
//!
//! `tune.csv`, one row per setting × target, in grid order (the first `--grid` varies
//! slowest) then target order: [`TUNE_FIXED_COLUMNS`] with the grid's keys after `setting`.
//! Medians are over the run's frames (as `sweep.csv`); `cost` is the median of what
//! `--cost` names; `flip_noise` / `cost_noise` the largest change of the median FLIP / cost
//! between the run and its repeats (empty without repeats); `pareto` whether the row is on
//! the front of (cost, FLIP) over all rows.

pub mod grid;
pub mod pareto;
mod report;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use anyhow::{Context as _, anyhow, bail};
use methods::MethodKind;

use crate::plot::{FrameRecord, SweepRow, read_frames};
pub use crate::sweep::TargetRecord;
pub use grid::{Axis, Grid, Setting};
pub use report::recommendation;

/// What the recommendation compares settings at: a frame's time or its points.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize, clap::ValueEnum,
)]
#[serde(rename_all = "lowercase")]
pub enum Cost {
    /// Median GPU ms per frame (wall ms on an adapter without timestamp queries).
    Time,
    /// Median points drawn per frame.
    Points,
}

impl Cost {
    /// The cost's name in files and plots.
    pub fn describe(self) -> &'static str {
        match self {
            Cost::Time => "median GPU ms per frame (wall ms without timestamps)",
            Cost::Points => "median points drawn per frame",
        }
    }

    /// The axis label.
    pub fn axis(self) -> &'static str {
        match self {
            Cost::Time => "frame time, ms (median)",
            Cost::Points => "points drawn per frame (median)",
        }
    }
}

/// A tune, as data (written to `tune.json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plan {
    /// Method (registry name).
    pub method: String,
    /// Scene label.
    pub scene: String,
    /// Camera path name.
    pub path: String,
    /// The grid.
    pub grid: Grid,
    /// Targets, in the order given.
    pub targets: Vec<TargetRecord>,
    /// What "equal cost" compares.
    pub cost: Cost,
    /// Runs per setting and target (≥ 2 measures run-to-run noise).
    pub repeats: usize,
    /// Scene flags of every child command (`--scene …`).
    pub scene_args: Vec<String>,
    /// Path and render flags of every run (`--path … --frames … --width …`).
    pub run_args: Vec<String>,
    /// An existing build every setting runs on (`--build-dir`), else one build per part.
    pub build_dir: Option<PathBuf>,
    /// A build served over HTTP every setting runs on (`--build-url`; its runs' flags carry
    /// `--remote-timeout`).
    #[serde(default)]
    pub build_url: Option<String>,
    /// The cache directory.
    pub cache: PathBuf,
    /// The command as typed (without `--part`/`--emit-jobs`).
    pub command: String,
}

impl Plan {
    /// The method.
    pub fn kind(&self) -> anyhow::Result<MethodKind> {
        Ok(MethodKind::from_name(&self.method)?)
    }

    /// True if every setting runs on one existing build (`--build-dir` or `--build-url`).
    pub fn on_existing_build(&self) -> bool {
        self.build_dir.is_some() || self.build_url.is_some()
    }

    /// Number of parts: one per distinct build (one in all over an existing build).
    pub fn parts(&self) -> usize {
        if self.on_existing_build() {
            1
        } else {
            self.grid.builds().len()
        }
    }

    /// The settings of part `k`.
    fn settings_of(&self, k: usize) -> Vec<Setting> {
        self.grid
            .settings()
            .into_iter()
            .filter(|s| self.on_existing_build() || s.build == k)
            .collect()
    }

    /// The build directory of part `k` under `out`.
    pub fn build_dir_of(&self, out: &Path, k: usize) -> PathBuf {
        match &self.build_dir {
            Some(d) => d.clone(),
            None => out
                .join("builds")
                .join(Grid::build_folder(&self.grid.builds()[k])),
        }
    }

    /// The run directory of setting `s`, target `t`, repeat `rep` (0: the run itself).
    pub fn run_dir(out: &Path, s: &Setting, t: &TargetRecord, rep: usize) -> PathBuf {
        if rep == 0 {
            out.join("runs").join(s.folder()).join(&t.name)
        } else {
            out.join("repeats")
                .join(s.folder())
                .join(&t.name)
                .join(format!("rep-{rep}"))
        }
    }
}

/// The record at the top of a tune's output directory (`tune.json`).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Record {
    /// The plan.
    pub plan: Plan,
    /// The parts this directory holds (all of them for a local tune or a merge).
    pub parts: Vec<usize>,
    /// False until every part listed has run (and, for a whole tune, been assembled).
    pub complete: bool,
    /// The commit of the binary.
    pub commit: String,
}

impl Record {
    /// Reads `dir/tune.json`.
    pub fn read(dir: &Path) -> anyhow::Result<Self> {
        let p = dir.join("tune.json");
        let text =
            std::fs::read_to_string(&p).with_context(|| format!("reading {}", p.display()))?;
        serde_json::from_str(&text).with_context(|| format!("parsing {}", p.display()))
    }

    /// Writes `dir/tune.json` atomically.
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        crate::results::write_json(&dir.join("tune.json"), self)
    }
}

/// Runs `exe` with `args`; an error carries the command and the end of its stderr.
fn child(exe: &Path, args: &[String]) -> anyhow::Result<()> {
    let out = Command::new(exe)
        .args(args)
        .args(crate::memory::check_skipped().then_some("--skip-memory-check"))
        .stdin(std::process::Stdio::null())
        .output()
        .with_context(|| format!("starting {}", exe.display()))?;
    if !out.status.success() {
        let err = String::from_utf8_lossy(&out.stderr);
        let tail: Vec<&str> = err.lines().rev().take(6).collect();
        bail!(
            "`splatbench {}` failed ({}): {}",
            args.join(" "),
            out.status,
            tail.into_iter().rev().collect::<Vec<_>>().join("\n")
        );
    }
    Ok(())
}

/// The `splatbench build` arguments of part `k`.
pub fn build_args(plan: &Plan, out: &Path, k: usize) -> anyhow::Result<Vec<String>> {
    let kind = plan.kind()?;
    let mut a = vec!["build".to_string(), "--method".into(), plan.method.clone()];
    a.extend(plan.scene_args.iter().cloned());
    for (key, v) in &plan.grid.build_params(kind, &plan.grid.builds()[k]).0 {
        a.extend(["--param".to_string(), format!("{key}={v}")]);
    }
    a.push("--out".into());
    a.push(path_arg(&plan.build_dir_of(out, k)));
    a.extend(["--cache".to_string(), path_arg(&plan.cache)]);
    Ok(a)
}

/// The `splatbench run` arguments of setting `s`, target `t`, repeat `rep`.
pub fn run_args(
    plan: &Plan,
    out: &Path,
    s: &Setting,
    t: &TargetRecord,
    rep: usize,
) -> anyhow::Result<Vec<String>> {
    let kind = plan.kind()?;
    let mut a = vec!["run".to_string(), "--method".into(), plan.method.clone()];
    a.extend(plan.scene_args.iter().cloned());
    a.extend(plan.run_args.iter().cloned());
    for (key, v) in &plan.grid.runtime_params(kind, s).0 {
        a.extend(["--param".to_string(), format!("{key}={v}")]);
    }
    a.extend(t.flag.iter().cloned());
    match &plan.build_url {
        Some(url) => a.extend(["--build-url".to_string(), url.clone()]),
        None => {
            a.push("--build-dir".into());
            a.push(path_arg(&plan.build_dir_of(out, s.build)));
        }
    }
    a.push("--out".into());
    a.push(path_arg(&Plan::run_dir(out, s, t, rep)));
    a.extend(["--cache".to_string(), path_arg(&plan.cache)]);
    Ok(a)
}

fn path_arg(p: &Path) -> String {
    p.display().to_string()
}

/// Carries out part `k` of `plan` into `out` with the `splatbench` binary `exe`: its build
/// (unless the plan runs on `--build-dir`), then every run of its settings × targets ×
/// repeats. `say` is told each step. Earlier output of the same runs is replaced.
pub fn run_part(
    plan: &Plan,
    k: usize,
    out: &Path,
    exe: &Path,
    say: &mut dyn FnMut(&str),
) -> anyhow::Result<()> {
    anyhow::ensure!(
        k < plan.parts(),
        "part {k} of a tune of {} parts",
        plan.parts()
    );
    if !plan.on_existing_build() {
        let dir = plan.build_dir_of(out, k);
        if dir.exists() {
            std::fs::remove_dir_all(&dir)
                .with_context(|| format!("removing the old {}", dir.display()))?;
        }
        let t = Instant::now();
        say(&format!("build {}", dir.display()));
        child(exe, &build_args(plan, out, k)?)?;
        say(&format!("  built in {:.1} s", t.elapsed().as_secs_f64()));
    }
    for s in plan.settings_of(k) {
        for t in &plan.targets {
            for rep in 0..plan.repeats {
                let dir = Plan::run_dir(out, &s, t, rep);
                if dir.exists() {
                    std::fs::remove_dir_all(&dir)
                        .with_context(|| format!("removing the old {}", dir.display()))?;
                }
                let started = Instant::now();
                child(exe, &run_args(plan, out, &s, t, rep)?)?;
                say(&format!(
                    "run {} · {}{} ({:.1} s)",
                    if s.values.is_empty() {
                        "default".into()
                    } else {
                        s.label()
                    },
                    t.label(),
                    if rep > 0 {
                        format!(" · repeat {rep}")
                    } else {
                        String::new()
                    },
                    started.elapsed().as_secs_f64()
                ));
            }
        }
    }
    Ok(())
}

/// The fixed columns of `tune.csv`; the grid's keys go after `setting`.
pub const TUNE_FIXED_COLUMNS: [&str; 24] = [
    "setting",
    "target",
    "value",
    "frames",
    "points_drawn_median",
    "flip_mean_median",
    "hole_ratio_median",
    "psnr_db_median",
    "popping_flip_median",
    "popping_warped_l1_median",
    "popping_warped_l1_p95",
    "popping_warped_l7_median",
    "popping_warped_l7_p95",
    "gpu_ms_median",
    "wall_ms_median",
    "cpu_select_ms_median",
    "cost",
    "flip_noise",
    "cost_noise",
    "build_seconds",
    "bytes_per_sample",
    "build_peak_rss_bytes",
    "peak_rss_bytes",
    "pareto",
];

/// One row of `tune.csv`.
#[derive(Debug, Clone, PartialEq)]
pub struct TuneRow {
    /// The setting's index in the grid.
    pub setting: usize,
    /// Its label (`m=512`).
    pub label: String,
    /// Its values, in axis order.
    pub values: Vec<String>,
    /// The target's index in the plan.
    pub target: usize,
    /// The target as its run directory names it.
    pub target_name: String,
    /// Pixels or points.
    pub value: f64,
    /// Medians over the run's frames.
    pub sweep: SweepRow,
    /// Median wall ms.
    pub wall_ms_median: f64,
    /// The cost.
    pub cost: f64,
    /// Largest change of the median FLIP between the run and its repeats.
    pub flip_noise: Option<f64>,
    /// Largest change of the cost between the run and its repeats.
    pub cost_noise: Option<f64>,
    /// `(cost, FLIP)` of each repeat.
    pub repeats: Vec<(f64, Option<f64>)>,
    /// Build seconds.
    pub build_seconds: Option<f64>,
    /// Bytes written per input sample.
    pub bytes_per_sample: Option<f64>,
    /// Peak RSS of the build's process (`splatbench build`).
    pub build_peak_rss_bytes: Option<f64>,
    /// Peak RSS of the run's process.
    pub peak_rss_bytes: Option<f64>,
    /// On the Pareto front of (cost, FLIP).
    pub pareto: bool,
}

/// A run's `(row medians, wall median, cost, summary)`.
fn read_run(
    dir: &Path,
    cost: Cost,
    value: f64,
) -> anyhow::Result<(SweepRow, f64, f64, serde_json::Value)> {
    let frames: Vec<FrameRecord> = read_frames(&dir.join("frames.csv"))?;
    let row = SweepRow::of_run(&frames, "", value)?;
    let wall = crate::results::median(frames.iter().map(|f| f.wall_ms))
        .ok_or_else(|| anyhow!("{}: no wall time", dir.display()))?;
    let summary = crate::results::read_complete_summary(dir)?;
    let c = match cost {
        Cost::Time => row.gpu_ms_median.unwrap_or(wall),
        Cost::Points => row.points_drawn_median,
    };
    Ok((row, wall, c, summary))
}

/// Reads the runs of a complete tune in `out` into rows (grid order, then target order),
/// with the Pareto front marked.
pub fn rows(plan: &Plan, out: &Path) -> anyhow::Result<Vec<TuneRow>> {
    let mut rows = Vec::new();
    for s in plan.grid.settings() {
        for (ti, t) in plan.targets.iter().enumerate() {
            let dir = Plan::run_dir(out, &s, t, 0);
            let (sweep, wall, cost, summary) = read_run(&dir, plan.cost, t.value)
                .with_context(|| format!("setting {} at {}", s.label(), t.label()))?;
            let mut repeats = Vec::new();
            for rep in 1..plan.repeats {
                let d = Plan::run_dir(out, &s, t, rep);
                let (r, _, c, _) = read_run(&d, plan.cost, t.value).with_context(|| {
                    format!("setting {} at {}, repeat {rep}", s.label(), t.label())
                })?;
                repeats.push((c, r.flip_mean_median));
            }
            // The largest change of a figure between the run and its repeats.
            let spread = |values: Vec<Option<f64>>, base: Option<f64>| {
                let base = base?;
                values
                    .iter()
                    .map(|v| v.map_or(f64::INFINITY, |x| (x - base).abs()))
                    .reduce(f64::max)
            };
            let flip_noise = spread(
                repeats.iter().map(|r| r.1).collect(),
                sweep.flip_mean_median,
            );
            let cost_noise = spread(repeats.iter().map(|r| Some(r.0)).collect(), Some(cost));
            let build = &summary["build"];
            let num = |v: &serde_json::Value| v.as_f64();
            rows.push(TuneRow {
                setting: s.index,
                label: s.label(),
                values: s.values.iter().map(|(_, v)| v.clone()).collect(),
                target: ti,
                target_name: t.name.clone(),
                value: t.value,
                flip_noise,
                cost_noise,
                sweep,
                wall_ms_median: wall,
                cost,
                repeats,
                build_seconds: num(&build["seconds"]),
                bytes_per_sample: num(&build["bits_per_sample"]).map(|b| b / 8.0),
                build_peak_rss_bytes: num(&build["extra"]["peak_rss_bytes"]),
                peak_rss_bytes: num(&summary["peak_rss_bytes"]),
                pareto: false,
            });
        }
    }
    let pts: Vec<(f64, f64)> = rows
        .iter()
        .map(|r| (r.cost, r.sweep.flip_mean_median.unwrap_or(f64::NAN)))
        .collect();
    for (r, on) in rows.iter_mut().zip(pareto::front(&pts)) {
        r.pareto = on;
    }
    Ok(rows)
}

/// Writes `tune.csv` (see the module docs) atomically.
pub fn write_csv(plan: &Plan, rows: &[TuneRow], path: &Path) -> anyhow::Result<()> {
    let mut w = csv::Writer::from_writer(Vec::new());
    let mut header: Vec<String> = vec![TUNE_FIXED_COLUMNS[0].to_string()];
    header.extend(plan.grid.axes.iter().map(|a| a.key.clone()));
    header.extend(TUNE_FIXED_COLUMNS[1..].iter().map(|s| s.to_string()));
    w.write_record(&header)?;
    let opt = |v: Option<f64>| v.map(|x| x.to_string()).unwrap_or_default();
    for r in rows {
        let mut rec = vec![r.label.clone()];
        rec.extend(r.values.iter().cloned());
        rec.extend([
            r.target_name.clone(),
            r.value.to_string(),
            r.sweep.frames.to_string(),
            r.sweep.points_drawn_median.to_string(),
            opt(r.sweep.flip_mean_median),
            opt(r.sweep.hole_ratio_median),
            opt(r.sweep.psnr_db_median),
            opt(r.sweep.popping_flip_median),
            opt(r.sweep.popping_warped_l1_median),
            opt(r.sweep.popping_warped_l1_p95),
            opt(r.sweep.popping_warped_l7_median),
            opt(r.sweep.popping_warped_l7_p95),
            opt(r.sweep.gpu_ms_median),
            r.wall_ms_median.to_string(),
            r.sweep.cpu_select_ms_median.to_string(),
            r.cost.to_string(),
            opt(r.flip_noise),
            opt(r.cost_noise),
            opt(r.build_seconds),
            opt(r.bytes_per_sample),
            opt(r.build_peak_rss_bytes),
            opt(r.peak_rss_bytes),
            r.pareto.to_string(),
        ]);
        w.write_record(&rec)?;
    }
    let bytes = w
        .into_inner()
        .map_err(|e| anyhow!("cannot format {}: {e}", path.display()))?;
    crate::image::write_atomically(path, &bytes)
        .with_context(|| format!("writing {}", path.display()))
}

/// The tune's figure: FLIP against the cost, one line per setting, the front ringed.
pub fn figure(plan: &Plan, rows: &[TuneRow]) -> crate::plot::TuneFigure {
    let flip = |r: &TuneRow| r.sweep.flip_mean_median.map(|f| (r.cost, f));
    crate::plot::TuneFigure {
        title: format!("tune {} · {} · {}", plan.method, plan.scene, plan.path),
        x_desc: plan.cost.axis().into(),
        lines: plan
            .grid
            .settings()
            .iter()
            .map(|s| {
                let pts = rows
                    .iter()
                    .filter(|r| r.setting == s.index)
                    .filter_map(flip)
                    .collect();
                (s.label(), pts)
            })
            .collect(),
        front: rows.iter().filter(|r| r.pareto).filter_map(flip).collect(),
        labels: rows
            .iter()
            .filter_map(|r| Some((flip(r)?, plan.targets[r.target].label())))
            .collect(),
    }
}

/// Assembles the parts in `dirs` (each a `tune … --part K` output) into `out`, exactly as
/// a local tune would have: the plans must be one plan, every part present once and
/// complete; their builds, runs and repeats are put under `out` (hard links where
/// possible), then [`assemble`]d. Errors name the directory and what is wrong.
pub fn merge(dirs: &[PathBuf], out: &Path) -> anyhow::Result<Assembled> {
    let records = dirs
        .iter()
        .map(|d| Record::read(d).map(|r| (d, r)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let Some((first_dir, first)) = records.first() else {
        bail!("merge: no directories given");
    };
    let plan = first.plan.clone();
    for (d, r) in &records {
        if r.plan != plan {
            let (a, b) = (serde_json::to_value(&plan)?, serde_json::to_value(&r.plan)?);
            let fields: Vec<String> = a
                .as_object()
                .map(|a| {
                    a.iter()
                        .filter(|(k, v)| b.get(k.as_str()) != Some(v))
                        .map(|(k, _)| format!("'{k}'"))
                        .collect()
                })
                .unwrap_or_default();
            bail!(
                "{} is a part of another tune than {} (they differ in {})",
                d.display(),
                first_dir.display(),
                fields.join(", ")
            );
        }
    }
    let listed: Vec<_> = records
        .iter()
        .map(|(d, r)| (*d, r.parts.clone(), r.complete))
        .collect();
    crate::results::cover(&listed, plan.parts(), |k| format!("build {k}"))?;
    let mut record = Record {
        plan: plan.clone(),
        parts: (0..plan.parts()).collect(),
        complete: false,
        commit: first.commit.clone(),
    };
    record.write(out)?;
    for (d, _) in &records {
        for sub in ["builds", "runs", "repeats"] {
            if d.join(sub).is_dir() {
                crate::results::link_tree(&d.join(sub), &out.join(sub))?;
            }
        }
    }
    let done = assemble(&plan, out)?;
    record.complete = true;
    record.write(out)?;
    Ok(done)
}

/// What [`assemble`] wrote.
#[derive(Debug)]
pub struct Assembled {
    /// The rows of `tune.csv`.
    pub rows: Vec<TuneRow>,
    /// The text of `recommendation.md`.
    pub recommendation: String,
}

/// Reads a tune's runs in `out` and writes `tune.csv`, `recommendation.md` and
/// `tune.png/.svg` (the adapter and commit the recommendation names are the first run's).
pub fn assemble(plan: &Plan, out: &Path) -> anyhow::Result<Assembled> {
    for stale in ["tune.csv", "recommendation.md", "tune.png", "tune.svg"] {
        let p = out.join(stale);
        if p.exists() {
            std::fs::remove_file(&p)
                .with_context(|| format!("removing the old {}", p.display()))?;
        }
    }
    let rows = rows(plan, out)?;
    write_csv(plan, &rows, &out.join("tune.csv"))?;
    let first = plan
        .grid
        .settings()
        .first()
        .map(|s| Plan::run_dir(out, s, &plan.targets[0], 0))
        .context("a tune without settings")?;
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(first.join("summary.json")).unwrap_or_default(),
    )
    .unwrap_or_default();
    let adapter = format!(
        "{} ({})",
        summary["adapter"]["name"].as_str().unwrap_or("?"),
        summary["adapter"]["backend"].as_str().unwrap_or("?")
    );
    let commit = summary["git_commit"].as_str().unwrap_or("?").to_string();
    let text = recommendation(plan, &rows, &adapter, &commit)?;
    crate::image::write_atomically(&out.join("recommendation.md"), text.as_bytes())
        .with_context(|| format!("writing {}", out.join("recommendation.md").display()))?;
    crate::plot::plot_tune(&figure(plan, &rows), out)?;
    Ok(Assembled {
        rows,
        recommendation: text,
    })
}
