//! `splatbench reproduce`: every table of the four papers regenerated from the specs in
//! `paper/specs/`, with the paper's numbers beside ours and a verdict
//! ([`harness::reproduce`]).

use std::path::PathBuf;

use anyhow::{Context as _, bail};
use clap::{Args, ValueEnum};
use harness::reproduce::{self, Options, Profile};

use crate::args::CacheArgs;

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ProfileArg {
    /// Small scenes: every table in minutes on 2 cores with lavapipe.
    Quick,
    /// The middle ground (10–100 M points).
    Full,
    /// The papers' own sizes and resolutions (127–369 M samples, out of core: hours; see
    /// paper/README.md for the time and disk it takes).
    Paper,
}

#[derive(Args, Clone)]
pub struct ReproduceArgs {
    /// Scene sizes.
    #[arg(long, value_enum, default_value = "quick")]
    pub profile: ProfileArg,
    /// Only these specs (ids, comma-separated), e.g. `--only mwkd-table2,qsplat-fig6`.
    #[arg(long, value_delimiter = ',')]
    pub only: Option<Vec<String>>,
    /// Output directory: report.md, results.json, figures/, runs/, builds/ (default
    /// results/reproduce-PROFILE).
    #[arg(long)]
    pub out: Option<PathBuf>,
    /// The spec directory; paths inside specs are relative to the current directory (the
    /// repository root).
    #[arg(long, default_value = "paper/specs")]
    pub specs: PathBuf,
    /// Also write report-PROFILE.md, results-PROFILE.json and figures-PROFILE/ into this
    /// directory (e.g. `paper`) — only for a complete reproduction (no --only) in which no
    /// table failed.
    #[arg(long)]
    pub publish: Option<PathBuf>,
    #[command(flatten)]
    pub cache: CacheArgs,
    /// Load and check every spec for every profile, list them, and run nothing.
    #[arg(long)]
    pub check: bool,
    #[command(flatten)]
    pub jobs: crate::args::JobArgs,
    /// Take every measure that an earlier run of this same commit, profile and spec finished
    /// (its checkpoint under OUT/measures/ and its runs under OUT/runs/) instead of running it
    /// again: how a part killed mid-way goes on. A measure whose checkpoint does not match
    /// runs, and stderr says why (another commit, an edited spec, its runs gone, …). Without
    /// it, every measure runs.
    #[arg(long)]
    pub resume: bool,
}

/// `splatbench reproduce`.
pub fn main(a: &ReproduceArgs) -> anyhow::Result<()> {
    let profile = match a.profile {
        ProfileArg::Quick => Profile::Quick,
        ProfileArg::Full => Profile::Full,
        ProfileArg::Paper => Profile::Paper,
    };
    let mut opts = Options {
        specs: a.specs.clone(),
        root: PathBuf::from("."),
        profile,
        only: a.only.clone(),
        out: a
            .out
            .clone()
            .unwrap_or_else(|| PathBuf::from(format!("results/reproduce-{profile}"))),
        cache: a.cache.dir.clone(),
        exe: std::env::current_exe().ok(),
        publish: a.publish.clone(),
        command: std::iter::once("splatbench".to_string())
            .chain(std::env::args().skip(1))
            .collect::<Vec<_>>()
            .join(" "),
        resume: a.resume,
    };
    if a.check {
        for s in reproduce::select(&opts)? {
            println!(
                "{:<24} {} — {} ({} measures, {} rows)",
                s.id,
                s.paper,
                s.title,
                s.measures.len(),
                s.rows.len()
            );
        }
        return Ok(());
    }
    if opts.publish.is_some() && opts.only.is_some() {
        bail!("--publish regenerates the whole report: it cannot be combined with --only");
    }
    let specs: Vec<String> = reproduce::select(&opts)?
        .into_iter()
        .map(|s| s.id)
        .collect();
    if let Some(file) = a.jobs.emit()? {
        let n = crate::jobs::emit(file, &opts.out, specs.len())?;
        println!(
            "wrote {} ({} jobs: one per spec, {}); run them from this directory, then: \
             splatbench merge {}/parts/part-* --out {}",
            file.display(),
            n,
            specs.join(", "),
            opts.out.display(),
            opts.out.display()
        );
        return Ok(());
    }
    let mut part = None;
    if let Some(k) = a.jobs.part {
        let spec = specs.get(k).ok_or_else(|| {
            anyhow::anyhow!("--part {k}: this reproduction has {} specs", specs.len())
        })?;
        let record = reproduce::PartRecord {
            command: crate::jobs::command_without_switches(&crate::jobs::PART_FLAGS, &["--resume"]),
            profile,
            specs: specs.clone(),
            part: k,
            partial: opts.only.is_some(),
            publish: opts.publish.take(),
            complete: false,
            commit: harness::runner::GIT_COMMIT.into(),
        };
        opts.only = Some(vec![spec.clone()]);
        std::fs::create_dir_all(&opts.out)
            .with_context(|| format!("creating {}", opts.out.display()))?;
        record.write(&opts.out)?;
        part = Some(record);
    }
    let multi = indicatif::MultiProgress::new();
    let outcome = reproduce::reproduce(&opts, &multi)?;
    if let Some(mut record) = part {
        // A part in which a table failed did not finish: it stays pending, so that a driver
        // that skips finished parts runs it again (`--resume` keeps its finished measures)
        // and `merge` refuses it rather than merging a failure.
        record.complete = outcome.failed() == 0;
        record.write(&opts.out)?;
    }
    report(&outcome)
}

/// Says what a reproduction (or the merge of one) wrote and published; an error when a
/// table failed.
pub fn report(outcome: &reproduce::Outcome) -> anyhow::Result<()> {
    println!("wrote {}", outcome.report.display());
    for p in &outcome.published {
        println!("published {}", p.display());
    }
    if outcome.failed() > 0 {
        bail!(
            "{} of {} tables failed (see {})",
            outcome.failed(),
            outcome.tables.len(),
            outcome.report.display()
        );
    }
    Ok(())
}
