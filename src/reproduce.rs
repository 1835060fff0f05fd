//! `splatbench reproduce`: every table of the four papers regenerated from the specs in
//! `paper/specs/`, with the paper's numbers beside ours and a verdict
//! ([`harness::reproduce`]).

use std::path::PathBuf;

use anyhow::bail;
use clap::{Args, ValueEnum};
use harness::reproduce::{self, Options, Profile};

use crate::args::CacheArgs;

#[derive(Debug, Clone, Copy, ValueEnum)]
pub enum ProfileArg {
    /// Small scenes: every table in minutes on 2 cores with lavapipe.
    Quick,
    /// The real sizes (10–100 M points).
    Full,
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
    /// Load and check every spec for both profiles, list them, and run nothing.
    #[arg(long)]
    pub check: bool,
}

/// `splatbench reproduce`.
pub fn main(a: &ReproduceArgs) -> anyhow::Result<()> {
    let profile = match a.profile {
        ProfileArg::Quick => Profile::Quick,
        ProfileArg::Full => Profile::Full,
    };
    let opts = Options {
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
    let multi = indicatif::MultiProgress::new();
    let outcome = reproduce::reproduce(&opts, &multi)?;
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
