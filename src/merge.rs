//! `splatbench merge DIR… --out DIR`: the parts that jobs emitted by `--emit-jobs` wrote
//! (`sweep`, `tune` or `reproduce`), assembled into the output a local run of the same
//! command writes.

use std::path::PathBuf;

use anyhow::bail;
use clap::Args;

use crate::jobs;

#[derive(Args, Clone)]
pub struct MergeArgs {
    /// The parts' directories (`OUT/parts/part-*`), in any order.
    #[arg(required = true, value_name = "DIR")]
    pub dirs: Vec<PathBuf>,
    /// Where to assemble them (the emitting command's --out).
    #[arg(long)]
    pub out: PathBuf,
}

/// `splatbench merge`.
pub fn main(a: &MergeArgs) -> anyhow::Result<()> {
    let kind = |d: &PathBuf| {
        if d.join("tune.json").is_file() {
            Some("tune")
        } else {
            None
        }
    };
    let kinds: Vec<Option<&str>> = a.dirs.iter().map(kind).collect();
    if let Some((d, _)) = a.dirs.iter().zip(&kinds).find(|(_, k)| k.is_none()) {
        bail!(
            "{}: not a part written by an emitted job (no tune.json, sweep-part.json or \
             reproduce-part.json)",
            d.display()
        );
    }
    match kinds[0] {
        Some("tune") => {
            if let Some((d, _)) = a.dirs.iter().zip(&kinds).find(|(_, k)| **k != Some("tune")) {
                bail!(
                    "{}: not a part of a tune, as {} is",
                    d.display(),
                    a.dirs[0].display()
                );
            }
            jobs::prepare_out(&a.out, "tune.json", None)?;
            let done = harness::tune::merge(&a.dirs, &a.out)?;
            print!("{}", done.recommendation);
            println!(
                "merged {} parts into {}: tune.csv ({} rows), recommendation.md, tune.png, tune.svg",
                a.dirs.len(),
                a.out.display(),
                done.rows.len()
            );
        }
        _ => bail!("unreachable: every directory has a kind"),
    }
    Ok(())
}
