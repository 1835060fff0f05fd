//! `splatbench reproduce`: the papers' tables regenerated from specs.
//!
//! A spec (`paper/specs/<id>.toml`, [`spec`]) names a paper's table or figure, its numbers,
//! the scenes, camera paths, methods and parameters that measure ours, and the rule that
//! decides whether the paper's shape holds ([`verdict`]). [`reproduce`] loads and checks
//! every spec first (a typo fails before anything runs), then runs the selected specs' measures
//! in order ([`exec`]: builds shared across tables), evaluates their rows, and writes
//! `OUT/report.md` ([`report`]: per table the paper's value, ours, the ratio, the verdict and
//! — where it differs — the measured reason; the command, adapter, commit and date),
//! `OUT/results.json`, figures (PNG + SVG) under `OUT/figures/`, and the raw runs under
//! `OUT/runs/`. With `publish` (and no `only`), a complete, failure-free reproduction also
//! writes `report-<profile>.md`, `results-<profile>.json` and `figures-<profile>/` into that
//! directory (the committed `paper/`).
//!
//! Rows marked `needs_gpu` are listed as "needs a GPU" when the adapter is a CPU rasteriser
//! (lavapipe), and measured when a real GPU is present.

mod check;
mod check_rows;
pub mod claims;
pub mod evaluate;
pub mod exec;
pub mod expr;
pub mod inputs;
pub mod load;
mod raw;
pub mod report;
pub mod resume;
pub mod spec;
pub mod verdict;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, anyhow, bail};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};

pub use spec::{Profile, Spec, SpecError};
pub use verdict::Verdict;

use evaluate::{Results, RowResult};
use exec::{Context, MeasureResult, SweepLine};

/// What to reproduce, and where.
#[derive(Debug, Clone)]
pub struct Options {
    /// The spec directory (`paper/specs`).
    pub specs: PathBuf,
    /// Paths inside specs are relative to this (the repository root).
    pub root: PathBuf,
    /// Sizes.
    pub profile: Profile,
    /// Only these spec ids (all when `None`).
    pub only: Option<Vec<String>>,
    /// Output directory.
    pub out: PathBuf,
    /// Scene and reference cache.
    pub cache: PathBuf,
    /// The `splatbench` binary (for isolated runs).
    pub exe: Option<PathBuf>,
    /// Also write the report, results and figures here (`paper/`).
    pub publish: Option<PathBuf>,
    /// The command as typed, for the report.
    pub command: String,
    /// Take each measure that an earlier run of this commit finished from its checkpoint
    /// ([`resume`]) instead of running it again.
    pub resume: bool,
}

/// One table of the report.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct TableResult {
    /// Spec id.
    pub id: String,
    /// The spec file (as given).
    pub file: String,
    /// Paper.
    pub paper: String,
    /// Table or figure.
    pub title: String,
    /// Where in the paper.
    pub source: String,
    /// Notes.
    pub notes: Option<String>,
    /// Rows.
    pub rows: Vec<RowResult>,
    /// Rows measured in other profiles only (a measure they read has its own `profiles`).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub rows_elsewhere: Vec<spec::RowElsewhere>,
    /// The table's verdict (its worst row).
    pub verdict: Verdict,
    /// Wall seconds, including the builds it made.
    pub seconds: f64,
    /// What was measured.
    pub measures: Vec<MeasureLine>,
    /// Sweeps: measure id, label, per-target medians.
    pub sweeps: Vec<(String, String, Vec<SweepLine>)>,
    /// Figures: title and file names (under the figures directory).
    pub figures: Vec<(String, String, String)>,
}

/// One measure as the report describes it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct MeasureLine {
    /// Id.
    pub id: String,
    /// What it is, in words.
    pub what: String,
    /// `ok`, `needs a GPU (not run)` or `failed: …`.
    pub status: String,
    /// Wall seconds.
    pub seconds: f64,
}

/// What a reproduction produced.
#[derive(Debug)]
pub struct Outcome {
    /// The tables, in spec order.
    pub tables: Vec<TableResult>,
    /// `OUT/report.md`.
    pub report: PathBuf,
    /// Files written under `publish`.
    pub published: Vec<PathBuf>,
}

impl Outcome {
    /// Tables whose measures or rows failed.
    pub fn failed(&self) -> usize {
        self.tables
            .iter()
            .filter(|t| matches!(t.verdict, Verdict::Failed(_)))
            .count()
    }
}

/// Loads the specs and keeps those `only` names (an unknown id is an error listing them).
pub fn select(opts: &Options) -> anyhow::Result<Vec<Spec>> {
    let mut specs = load::load_dir(&opts.specs, &opts.root, opts.profile)?;
    // The papers in order of publication, then our own tables; by id within each.
    let rank = |id: &str| {
        ["qsplat-", "spt-", "lpc-", "mwkd-"]
            .iter()
            .position(|p| id.starts_with(p))
            .unwrap_or(4)
    };
    specs.sort_by(|a, b| (rank(&a.id), &a.id).cmp(&(rank(&b.id), &b.id)));
    let Some(only) = &opts.only else {
        return Ok(specs);
    };
    if only.is_empty() {
        bail!("--only: give one or more spec ids");
    }
    let known: Vec<&str> = specs.iter().map(|s| s.id.as_str()).collect();
    if let Some(bad) = only.iter().find(|id| !known.contains(&id.as_str())) {
        bail!(
            "--only: no spec '{bad}' in {} (specs: {})",
            opts.specs.display(),
            known.join(", ")
        );
    }
    Ok(specs.into_iter().filter(|s| only.contains(&s.id)).collect())
}

/// Runs the selected specs and writes the report (see the module docs).
pub fn reproduce(opts: &Options, multi: &MultiProgress) -> anyhow::Result<Outcome> {
    let t0 = Instant::now();
    if opts.publish.is_some() && opts.only.is_some() {
        bail!("--publish regenerates the whole report: it cannot be combined with --only");
    }
    let specs = select(opts)?;
    std::fs::create_dir_all(&opts.out)
        .with_context(|| format!("creating {}", opts.out.display()))?;
    for stale in ["report.md", "results.json"] {
        let p = opts.out.join(stale);
        if p.exists() {
            std::fs::remove_file(&p)
                .with_context(|| format!("removing the old {}", p.display()))?;
        }
    }
    let figures_dir = opts.out.join("figures");
    // The inputs as they are when the run starts: an edit made while it runs is not what
    // produced its numbers.
    let mut spec_hashes = BTreeMap::new();
    for spec in &specs {
        let h =
            inputs::spec_hash(spec).with_context(|| format!("hashing {}", spec.file.display()))?;
        spec_hashes.insert(spec.id.clone(), h);
    }
    let baseline_hash = baseline_hash(opts)?;
    let phase = crate::progress::Bar::under(multi);
    let mut ctx = Context::new(&opts.out, &opts.cache, opts.exe.clone(), &phase);
    let mut tables = Vec::new();
    let mut resumed_seconds = 0.0;
    for (i, spec) in specs.iter().enumerate() {
        let later = &specs[i + 1..];
        let run = SpecRun {
            spec,
            later,
            spec_hash: &spec_hashes[&spec.id],
        };
        let (table, resumed) = run_spec(&run, opts, &mut ctx, multi, &figures_dir)?;
        resumed_seconds += resumed;
        tables.push(table);
        if opts.profile == Profile::Paper && opts.only.is_none() {
            // The papers' sizes do not all fit the disk at once: a spec's scenes go once no
            // later spec needs them when this run is the whole profile (a run of some specs,
            // or a job's part, keeps the cached scenes for the others: making one takes up to
            // half an hour). Builds go measure by measure (`run_spec`).
            ctx.prune_scenes(spec, later)
                .with_context(|| format!("pruning the scenes after {}", spec.id))?;
        }
    }
    let meta = report::Meta {
        profile: opts.profile,
        command: opts.command.clone(),
        commit: crate::runner::GIT_COMMIT.to_string(),
        date: report::utc_now(),
        adapter: ctx.adapter().cloned(),
        cpus: std::thread::available_parallelism().map_or(1, |n| n.get()),
        // A resumed measure's time is the run's that measured it.
        seconds: t0.elapsed().as_secs_f64() + resumed_seconds,
        partial: opts.only.is_some(),
        spec_hashes,
        baseline_hash,
    };
    let report_path = opts.out.join("report.md");
    report::write(&report_path, &meta, &tables, "figures")?;
    crate::results::write_json(
        &opts.out.join("results.json"),
        &report::results(&meta, &tables),
    )?;
    let mut outcome = Outcome {
        tables,
        report: report_path,
        published: Vec::new(),
    };
    if let Some(dir) = &opts.publish {
        outcome.published = publish_complete(dir, &meta, &outcome, &figures_dir)?;
    }
    Ok(outcome)
}

/// A spec to run: the specs after it (whose builds and scenes must stay) and its hash.
struct SpecRun<'s> {
    spec: &'s Spec,
    later: &'s [Spec],
    spec_hash: &'s str,
}

/// Runs one spec: its measures ([`run_measures`]), then its rows, sweeps, figures and
/// verdict; prints its line and returns its table and the seconds of its resumed measures.
fn run_spec(
    run: &SpecRun<'_>,
    opts: &Options,
    ctx: &mut Context<'_>,
    multi: &MultiProgress,
    figures_dir: &Path,
) -> anyhow::Result<(TableResult, f64)> {
    let spec = run.spec;
    let t = Instant::now();
    let Measured {
        results,
        lines,
        resumed_seconds,
        real_gpu,
        bar,
    } = run_measures(run, opts, ctx, multi)?;
    let env = Results { by_id: &results };
    let rows: Vec<RowResult> = spec
        .rows
        .iter()
        .map(|r| evaluate::evaluate(r, &env, real_gpu))
        .collect();
    let sweeps = spec_sweeps(spec, &results);
    let (figures, figure_error) = plot_figures(spec, &results, figures_dir);
    let mut verdict = Verdict::of_table(rows.iter().map(|r| &r.verdict));
    if let (Some(e), false) = (figure_error, matches!(verdict, Verdict::Failed(_))) {
        verdict = Verdict::Failed(e);
    }
    let seconds = t.elapsed().as_secs_f64() + resumed_seconds;
    bar.finish_and_clear();
    multi.suspend(|| {
        println!(
            "{:<24} {:<12} {} rows, {:.1} s",
            spec.id,
            verdict.word(),
            rows.len(),
            seconds
        );
    });
    let table = TableResult {
        id: spec.id.clone(),
        file: spec.file.display().to_string(),
        paper: spec.paper.clone(),
        title: spec.title.clone(),
        source: spec.source.clone(),
        notes: spec.notes.clone(),
        rows,
        rows_elsewhere: spec.rows_elsewhere.clone(),
        verdict,
        seconds,
        measures: lines,
        sweeps,
        figures,
    };
    Ok((table, resumed_seconds))
}

/// What a spec's measures gave ([`run_measures`]).
struct Measured {
    /// By measure id.
    results: BTreeMap<String, MeasureResult>,
    /// As the report lists them.
    lines: Vec<MeasureLine>,
    /// Seconds the resumed measures took when they were measured.
    resumed_seconds: f64,
    /// A real GPU is present and some row wants one.
    real_gpu: bool,
    /// The spec's progress bar, still shown.
    bar: ProgressBar,
}

/// Runs, in order, the measures of `run.spec` that its rows use: each is skipped if it
/// serves GPU rows only and there is no real GPU, taken from its checkpoint with
/// `opts.resume`, else measured ([`measure_or_resume`]); in the paper profile, the builds no
/// later measure needs go after each ([`prune_after`]).
fn run_measures(
    run: &SpecRun<'_>,
    opts: &Options,
    ctx: &mut Context<'_>,
    multi: &MultiProgress,
) -> anyhow::Result<Measured> {
    let spec = run.spec;
    let uses = spec.measure_uses();
    let needed: Vec<&spec::Measure> = spec
        .measures
        .iter()
        .filter(|m| uses.contains_key(m.id.as_str()))
        .collect();
    let bar = measures_bar(multi, spec, needed.len());
    let needs_gpu_rows = spec.rows.iter().any(|r| r.needs_gpu || r.judge_on_gpu);
    let real_gpu = needs_gpu_rows && ctx.has_real_gpu().unwrap_or(false);
    // What a checkpoint of this spec's measures must match ([`resume`]): the same for all.
    let identity = resume::Identity::now(
        opts.profile,
        run.spec_hash,
        ctx.gpu().ok().flatten().map(|g| g.adapter.clone()),
    );
    let mut out = Measured {
        results: BTreeMap::new(),
        lines: Vec::new(),
        resumed_seconds: 0.0,
        real_gpu,
        bar,
    };
    for (j, m) in needed.iter().enumerate() {
        out.bar.set_message(m.id.clone());
        let gpu_only = uses.get(m.id.as_str()).copied().unwrap_or(false);
        let (mut r, resumed) = if gpu_only && !real_gpu {
            let skipped = MeasureResult {
                skipped_for_gpu: true,
                ..MeasureResult::default()
            };
            (skipped, None)
        } else {
            measure_or_resume(opts, ctx, multi, spec, m, &identity)?
        };
        if resumed.is_some() {
            out.resumed_seconds += r.seconds;
        }
        if opts.profile == Profile::Paper {
            prune_after(ctx, run, &needed[j + 1..], m, &mut r)?;
        }
        out.lines
            .push(measure_line(spec, m, &r, resumed.as_deref(), &opts.root));
        out.results.insert(m.id.clone(), r);
        out.bar.inc(1);
    }
    Ok(out)
}

/// A spec's progress bar over its `len` measures.
fn measures_bar(multi: &MultiProgress, spec: &Spec, len: usize) -> ProgressBar {
    let bar = multi.add(ProgressBar::new(len as u64));
    if let Ok(style) =
        ProgressStyle::with_template("{prefix:>28} [{bar:40}] {pos}/{len} measures {msg}")
    {
        bar.set_style(style.progress_chars("=> "));
    }
    bar.set_prefix(spec.id.clone());
    bar
}

/// Measure `m` of `spec`: from its checkpoint when `opts.resume` and the checkpoint matches
/// `identity` (with the date it was measured), else measured now and checkpointed if it
/// succeeded. A checkpoint that exists but is not taken is said why.
fn measure_or_resume(
    opts: &Options,
    ctx: &mut Context<'_>,
    multi: &MultiProgress,
    spec: &Spec,
    m: &spec::Measure,
    identity: &resume::Identity,
) -> anyhow::Result<(MeasureResult, Option<String>)> {
    let checkpoint = resume::path(&opts.out, &spec.id, &m.id);
    if let Some(done) = opts
        .resume
        .then(|| resume::load(&checkpoint, identity))
        .and_then(|loaded| {
            // Why a checkpoint that exists was not taken (a missing one needs no word).
            loaded
                .map_err(|why| {
                    if checkpoint.exists() {
                        multi.suspend(|| {
                            eprintln!("{}.{}: not resumed, measuring again: {why}", spec.id, m.id)
                        });
                    }
                })
                .ok()
        })
    {
        return Ok((done.result, Some(done.date)));
    }
    resume::forget(&checkpoint)?;
    let r = ctx.measure(spec, m);
    if r.error.is_none() {
        resume::save(&checkpoint, identity, &r)?;
    }
    Ok((r, None))
}

/// The papers' sizes do not all fit the disk at once: a build goes as soon as no measure
/// still to run (`rest` of this spec, or one of a later spec) needs it. A successful `r`
/// (measure `m`) notes what was deleted.
fn prune_after(
    ctx: &mut Context<'_>,
    run: &SpecRun<'_>,
    rest: &[&spec::Measure],
    m: &spec::Measure,
    r: &mut MeasureResult,
) -> anyhow::Result<()> {
    let spec = run.spec;
    let rest = rest.iter().map(|m| (spec, *m)).chain(
        run.later
            .iter()
            .flat_map(|s| s.measures.iter().map(move |m| (s, m))),
    );
    let freed = ctx
        .prune_builds(rest)
        .with_context(|| format!("pruning the builds after {}.{}", spec.id, m.id))?;
    if freed > 0 && r.error.is_none() {
        r.made
            .push(format!("build deleted after: {}", exec::gigabytes(freed)));
    }
    Ok(())
}

/// Measure `m` as the report lists it: `ok` (with what it made, and when it was measured if
/// `resumed`), `needs a GPU (not run)` or `failed: …`.
fn measure_line(
    spec: &Spec,
    m: &spec::Measure,
    r: &MeasureResult,
    resumed: Option<&str>,
    root: &Path,
) -> MeasureLine {
    MeasureLine {
        id: m.id.clone(),
        what: report::describe(spec, m, root),
        status: match (&r.error, r.skipped_for_gpu) {
            (Some(e), _) => format!("failed: {e}"),
            (None, true) => "needs a GPU (not run)".into(),
            (None, false) => {
                let mut notes = r.made.clone();
                if let Some(date) = resumed {
                    notes.insert(0, format!("resumed: measured {date} by an earlier run"));
                }
                if notes.is_empty() {
                    "ok".into()
                } else {
                    format!("ok; {}", notes.join("; "))
                }
            }
        },
        seconds: r.seconds,
    }
}

/// The spec's sweeps that ran: measure id, label, per-target medians.
fn spec_sweeps(
    spec: &Spec,
    results: &BTreeMap<String, MeasureResult>,
) -> Vec<(String, String, Vec<SweepLine>)> {
    let mut sweeps = Vec::new();
    for m in spec
        .measures
        .iter()
        .filter(|m| m.kind == spec::MeasureKind::Sweep)
    {
        if let Some(r) = results
            .get(&m.id)
            .filter(|r| r.error.is_none() && !r.sweep.is_empty())
        {
            sweeps.push((m.id.clone(), report::label(spec, m), r.sweep.clone()));
        }
    }
    sweeps
}

/// Plots the spec's figures into `figures_dir`: title, PNG and SVG file names of each
/// plotted, and the last error (a sweep it plots did not run, or plotting failed).
fn plot_figures(
    spec: &Spec,
    results: &BTreeMap<String, MeasureResult>,
    figures_dir: &Path,
) -> (Vec<(String, String, String)>, Option<String>) {
    let mut figures = Vec::new();
    let mut figure_error = None;
    for f in &spec.figures {
        let dirs: Vec<PathBuf> = f
            .sweeps
            .iter()
            .filter_map(|s| results.get(s).and_then(|r| r.dir.clone()))
            .collect();
        if dirs.len() != f.sweeps.len() {
            figure_error = Some(format!("figure '{}': a sweep it plots did not run", f.name));
            continue;
        }
        let stem = format!("{}-{}", spec.id, f.name);
        match plot_figure(&dirs, figures_dir, &stem) {
            Ok(()) => figures.push((
                f.title.clone(),
                format!("{stem}.png"),
                format!("{stem}.svg"),
            )),
            Err(e) => figure_error = Some(format!("figure '{}': {e:#}", f.name)),
        }
    }
    (figures, figure_error)
}

/// What a part of a reproduction run by an emitted job records (`reproduce-part.json`): the
/// reproduction (its command without `--part`, `--out` and `--emit-jobs`, its profile, the
/// specs it selected, where it publishes), the part (the index of its one spec) and whether
/// it finished.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PartRecord {
    /// The reproduction's command.
    pub command: String,
    /// Its profile.
    pub profile: Profile,
    /// Every spec it selected, in report order.
    pub specs: Vec<String>,
    /// The spec this part ran.
    pub part: usize,
    /// Whether the command picked specs with `--only` (the report is then partial).
    pub partial: bool,
    /// `--publish`, done by the merge.
    pub publish: Option<PathBuf>,
    /// False until the part's reproduction returned with no table failed.
    pub complete: bool,
    /// Commit of the binary.
    pub commit: String,
}

impl PartRecord {
    /// The file name.
    pub const FILE: &'static str = "reproduce-part.json";

    /// Reads `dir/reproduce-part.json`.
    pub fn read(dir: &Path) -> anyhow::Result<Self> {
        crate::results::read_json(&dir.join(Self::FILE))
    }

    /// Writes `dir/reproduce-part.json` atomically.
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        crate::results::write_json(&dir.join(Self::FILE), self)
    }
}

/// Assembles the parts in `dirs` (each a `reproduce … --part K` output) into `out` as the
/// local reproduction would have: one reproduction, every spec present once, on one adapter
/// and commit; `report.md` and `results.json` of all the tables in report order, their
/// figures, their runs (`runs/`; each part's builds stay in its directory), and the
/// publication when the command asked for one. The date is the merge's; `seconds` the sum
/// of the parts'.
pub fn merge(dirs: &[PathBuf], out: &Path) -> anyhow::Result<Outcome> {
    let parts = dirs
        .iter()
        .map(|d| PartRecord::read(d).map(|p| (d, p)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let Some((first_dir, first)) = parts.first() else {
        bail!("merge: no directories given");
    };
    let identity = |p: &PartRecord| {
        (
            p.command.clone(),
            p.profile,
            p.specs.clone(),
            p.partial,
            p.publish.clone(),
            p.commit.clone(),
        )
    };
    for (d, p) in &parts {
        if identity(p) != identity(first) {
            bail!(
                "{} is a part of another reproduction than {} (`{}` at {} against `{}` at {})",
                d.display(),
                first_dir.display(),
                p.command,
                p.commit,
                first.command,
                first.commit
            );
        }
    }
    let listed: Vec<_> = parts
        .iter()
        .map(|(d, p)| (*d, vec![p.part], p.complete))
        .collect();
    let by_spec = crate::results::cover(&listed, first.specs.len(), |k| first.specs[k].clone())?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut tables = Vec::new();
    let mut adapter: Option<crate::gpu::AdapterDesc> = None;
    let (mut seconds, mut cpus) = (0.0, 0);
    let mut spec_hashes = BTreeMap::new();
    let mut baseline = None;
    for (spec, d) in first.specs.iter().zip(&by_spec) {
        let path = d.join("results.json");
        let v: serde_json::Value = crate::results::read_json(&path)?;
        let meta: report::Meta = serde_json::from_value(v["meta"].clone())
            .with_context(|| format!("{}: field 'meta'", path.display()))?;
        let part_tables: Vec<TableResult> = serde_json::from_value(v["tables"].clone())
            .with_context(|| format!("{}: field 'tables'", path.display()))?;
        match (&adapter, &meta.adapter) {
            (Some(a), Some(b)) if a != b => bail!(
                "{} ran on {} ({}), another part on {} ({}): a report is of one adapter",
                d.display(),
                b.name,
                b.backend,
                a.name,
                a.backend
            ),
            (None, Some(b)) => adapter = Some(b.clone()),
            _ => {}
        }
        seconds += meta.seconds;
        cpus = cpus.max(meta.cpus);
        spec_hashes.extend(meta.spec_hashes.clone());
        baseline = baseline.or(meta.baseline_hash.clone());
        let t = part_tables
            .into_iter()
            .find(|t| &t.id == spec)
            .ok_or_else(|| anyhow!("{}: no table '{spec}'", path.display()))?;
        for sub in ["runs", "figures"] {
            if d.join(sub).is_dir() {
                crate::results::link_tree(&d.join(sub), &out.join(sub))?;
            }
        }
        tables.push(t);
    }
    let meta = report::Meta {
        profile: first.profile,
        command: first.command.clone(),
        commit: first.commit.clone(),
        date: report::utc_now(),
        adapter,
        cpus,
        seconds,
        partial: first.partial,
        spec_hashes,
        baseline_hash: baseline,
    };
    let report_path = out.join("report.md");
    report::write(&report_path, &meta, &tables, "figures")?;
    crate::results::write_json(&out.join("results.json"), &report::results(&meta, &tables))?;
    let mut outcome = Outcome {
        tables,
        report: report_path,
        published: Vec::new(),
    };
    if let Some(dir) = &first.publish {
        outcome.published = publish_complete(dir, &meta, &outcome, &out.join("figures"))?;
    }
    Ok(outcome)
}

/// The quick baseline's hash for a quick reproduction (`None` for other profiles, or where
/// the root has no baseline: a reproduction outside the repository).
fn baseline_hash(opts: &Options) -> anyhow::Result<Option<String>> {
    let path = opts.root.join(inputs::QUICK_BASELINE);
    if opts.profile != Profile::Quick || !path.is_file() {
        return Ok(None);
    }
    Ok(Some(
        inputs::file_hash(&path).with_context(|| format!("hashing {}", path.display()))?,
    ))
}

/// Overlays the sweeps of `dirs` into `out/<stem>.png` and `.svg`.
fn plot_figure(dirs: &[PathBuf], out: &Path, stem: &str) -> anyhow::Result<()> {
    let tmp = out.join(format!(".{stem}"));
    let files = crate::plot::plot_sweeps(dirs, &tmp)?;
    for f in files {
        let ext = f
            .extension()
            .and_then(|e| e.to_str())
            .unwrap_or("png")
            .to_string();
        let to = out.join(format!("{stem}.{ext}"));
        std::fs::rename(&f, &to)
            .with_context(|| format!("moving {} to {}", f.display(), to.display()))?;
    }
    std::fs::remove_dir_all(&tmp).ok();
    Ok(())
}

/// [`publish`]es a reproduction in which no table failed; with a failed table, publishes
/// nothing and says so.
fn publish_complete(
    dir: &Path,
    meta: &report::Meta,
    outcome: &Outcome,
    figures_dir: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    if outcome.failed() > 0 {
        bail!(
            "{} table(s) failed: nothing published to {} (see {})",
            outcome.failed(),
            dir.display(),
            outcome.report.display()
        );
    }
    publish(dir, meta, &outcome.tables, figures_dir)
}

/// Writes `report-<profile>.md`, `results-<profile>.json` and `figures-<profile>/` into `dir`.
fn publish(
    dir: &Path,
    meta: &report::Meta,
    tables: &[TableResult],
    figures_dir: &Path,
) -> anyhow::Result<Vec<PathBuf>> {
    let p = meta.profile.name();
    let figs = dir.join(format!("figures-{p}"));
    if figs.exists() {
        std::fs::remove_dir_all(&figs).with_context(|| format!("removing {}", figs.display()))?;
    }
    std::fs::create_dir_all(&figs).with_context(|| format!("creating {}", figs.display()))?;
    let mut out = Vec::new();
    for t in tables {
        for (_, png, svg) in &t.figures {
            for f in [png, svg] {
                let to = figs.join(f);
                std::fs::copy(figures_dir.join(f), &to)
                    .with_context(|| format!("copying {f} to {}", figs.display()))?;
                out.push(to);
            }
        }
    }
    let report = dir.join(format!("report-{p}.md"));
    report::write(&report, meta, tables, &format!("figures-{p}"))?;
    let results = dir.join(format!("results-{p}.json"));
    crate::results::write_json(&results, &report::results(meta, tables))?;
    out.push(report);
    out.push(results);
    Ok(out)
}
