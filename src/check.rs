//! `splatbench check`: a run, sweep, tune or reproduction directory (or a regression suite,
//! run first) compared with a baseline; `--bless` writes the baseline instead
//! ([`harness::check`]).
//!
//! Exit status: 0 when every figure holds (or the baseline was written), 1 on a regression,
//! 2 on input that cannot be compared (a missing or unreadable file, a baseline of another
//! scene, resolution or experiment), each named.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use harness::check::{self, Baseline, Unusable, suite::Suite};

use crate::args::CacheArgs;
use crate::shared::open_gpu;

#[derive(Args, Clone)]
pub struct CheckArgs {
    /// The directory to check: a run, a sweep, a tune, a reproduction, or any directory of
    /// runs (every folder holding summary.json and frames.csv is a run, keyed by its path).
    #[arg(value_name = "DIR")]
    pub input: Option<PathBuf>,
    /// The baseline file (JSON). With --suite, default: the suite's `baseline`.
    #[arg(long)]
    pub baseline: Option<PathBuf>,
    /// Write the baseline from the directory (atomically), keeping the tolerances of the
    /// baseline it replaces; prints what changed first when there was one.
    #[arg(long)]
    pub bless: bool,
    /// Fail when a median time (GPU, wall, selection, build) grows by more than this factor;
    /// without it times are reported as ratios and never fail.
    #[arg(long, value_name = "FACTOR")]
    pub timing_gate: Option<f64>,
    /// Run a regression suite (a TOML file, e.g. results/baselines/quick.toml) into --out
    /// first, then check that.
    #[arg(long)]
    pub suite: Option<PathBuf>,
    /// Where --suite writes its runs.
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// Print every row of the table (default: the first 60, failures first).
    #[arg(long)]
    pub all: bool,
    /// Compare runs that are not the same experiment as their baseline's (another
    /// parameter, kernel, shading, resolution…) instead of refusing them: checks a change's
    /// effect against a baseline; exit 1 on a figure outside its allowance.
    #[arg(long)]
    pub compare_across: bool,
    #[command(flatten)]
    pub cache: CacheArgs,
}

/// `splatbench check`: the process's exit status (errors printed here).
pub fn main(a: &CheckArgs) -> u8 {
    match check(a) {
        Ok(code) => code,
        // Input the check cannot use: a file missing or unreadable, another experiment.
        Err(e) => {
            eprintln!("Error: {e:#}");
            2
        }
    }
}

fn check(a: &CheckArgs) -> anyhow::Result<u8> {
    if let Some(g) = a.timing_gate
        && !(g.is_finite() && g >= 1.0)
    {
        return Err(Unusable(format!(
            "--timing-gate {g}: give a factor ≥ 1 (e.g. 1.5 fails a time that grew by half)"
        ))
        .into());
    }
    let (dir, baseline_path, command) = match (&a.suite, &a.input) {
        (Some(_), Some(d)) => {
            return Err(Unusable(format!(
                "give a directory ({}) or --suite, not both: --suite runs into --out and checks \
                 that",
                d.display()
            ))
            .into());
        }
        (Some(file), None) => {
            let suite = Suite::load(file).map_err(|e| Unusable(format!("--suite {e:#}")))?;
            let out = a
                .out
                .clone()
                .ok_or_else(|| Unusable("--suite needs --out".into()))?;
            let command = harness::results::invocation();
            eprintln!(
                "suite {}: {} sweeps into {}",
                file.display(),
                suite.sweeps(),
                out.display()
            );
            let gpu = open_gpu()?;
            let bar = harness::progress::Bar::new();
            if let Err(e) = check::suite::run(&suite, &out, &a.cache.dir, &gpu, &command, &bar) {
                // A build or run of the suite that fails is a regression of the code under
                // test, not unusable input.
                eprintln!("Error: {e:#}");
                println!("REGRESSION: the suite did not run to the end (see the error above)");
                return Ok(1);
            }
            let baseline = a.baseline.clone().unwrap_or(suite.baseline.clone());
            (out, baseline, Some(command))
        }
        (None, Some(dir)) => {
            if a.out.is_some() {
                return Err(Unusable(
                    "--out is where --suite writes its runs: give --suite".into(),
                )
                .into());
            }
            let baseline = a
                .baseline
                .clone()
                .ok_or_else(|| Unusable("give --baseline FILE".into()))?;
            (dir.clone(), baseline, None)
        }
        (None, None) => return Err(Unusable("give a directory or --suite FILE".into()).into()),
    };
    let now = check::snapshot(&dir, command)?;
    let max_rows = if a.all { None } else { Some(60) };
    if a.bless {
        let mut blessed = now;
        if baseline_path.exists() {
            match Baseline::read(&baseline_path) {
                Ok(old) => {
                    blessed.tolerances = old.tolerances.clone();
                    match check::compare(&old, &blessed, check::Options::default()) {
                        Ok(report) => {
                            println!("what changed since {}:", baseline_path.display());
                            print!("{}", check::render_table(&report, max_rows));
                        }
                        Err(e) => println!("the old baseline does not compare: {e:#}"),
                    }
                }
                Err(e) => println!("replacing an unreadable baseline ({e:#})"),
            }
        }
        blessed.write(&baseline_path)?;
        println!(
            "blessed {} ({} runs from {}, commit {}, adapter {})",
            baseline_path.display(),
            blessed.runs.len(),
            dir.display(),
            blessed.commit,
            blessed
                .adapter
                .as_ref()
                .map_or_else(|| "-".into(), check::adapter_text)
        );
        return Ok(0);
    }
    let baseline = Baseline::read(&baseline_path)?;
    let report = check::compare(
        &baseline,
        &now,
        check::Options {
            timing_gate: a.timing_gate,
            compare_across: a.compare_across,
        },
    )
    .with_context(|| dir.display().to_string())?;
    println!(
        "{} against {} (blessed {} at {} on {})",
        dir.display(),
        baseline_path.display(),
        baseline.date,
        baseline.commit,
        baseline
            .adapter
            .as_ref()
            .map_or_else(|| "-".into(), check::adapter_text)
    );
    print!("{}", check::render_table(&report, max_rows));
    Ok(if report.holds() { 0 } else { 1 })
}
