//! `splatbench merge DIR… --out DIR`: the parts that jobs emitted by `--emit-jobs` wrote
//! (`sweep`, `tune` or `reproduce`), assembled into the output a local run of the same
//! command writes: the same files, laid out the same way, every figure that does not depend
//! on timing equal byte for byte.

use std::path::{Path, PathBuf};

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

/// What a part is, by the record it holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Sweep,
    Tune,
    Reproduce,
}

impl Kind {
    fn of(dir: &Path) -> Option<Self> {
        [
            (Kind::Sweep, harness::sweep::SweepPart::FILE),
            (Kind::Tune, "tune.json"),
            (Kind::Reproduce, harness::reproduce::PartRecord::FILE),
        ]
        .into_iter()
        .find(|(_, f)| dir.join(f).is_file())
        .map(|(k, _)| k)
    }

    fn name(self) -> &'static str {
        match self {
            Kind::Sweep => "sweep",
            Kind::Tune => "tune",
            Kind::Reproduce => "reproduction",
        }
    }
}

/// `splatbench merge`.
pub fn main(a: &MergeArgs) -> anyhow::Result<()> {
    let mut kinds = Vec::new();
    for d in &a.dirs {
        match Kind::of(d) {
            Some(k) => kinds.push(k),
            None => bail!(
                "{}: not a part written by an emitted job (no {}, tune.json or {})",
                d.display(),
                harness::sweep::SweepPart::FILE,
                harness::reproduce::PartRecord::FILE
            ),
        }
    }
    let kind = kinds[0];
    if let Some((d, k)) = a.dirs.iter().zip(&kinds).find(|(_, k)| **k != kind) {
        bail!(
            "{} is a part of a {}, {} of a {}: merge the parts of one command",
            d.display(),
            k.name(),
            a.dirs[0].display(),
            kind.name()
        );
    }
    match kind {
        Kind::Sweep => {
            jobs::prepare_out(&a.out, "sweep.csv", None)?;
            let rows = harness::sweep::merge(&a.dirs, &a.out)?;
            println!(
                "merged {} parts into {}: sweep.csv ({} targets), sweep.png, sweep.svg",
                a.dirs.len(),
                a.out.display(),
                rows.len()
            );
        }
        Kind::Tune => {
            jobs::prepare_out(&a.out, "tune.json", None)?;
            let done = harness::tune::merge(&a.dirs, &a.out)?;
            print!("{}", done.recommendation);
            println!(
                "merged {} parts into {}: tune.csv ({} rows), recommendation.md, tune.png, \
                 tune.svg",
                a.dirs.len(),
                a.out.display(),
                done.rows.len()
            );
        }
        Kind::Reproduce => {
            jobs::prepare_out(&a.out, "report.md", None)?;
            crate::reproduce::report(&harness::reproduce::merge(&a.dirs, &a.out)?)?;
        }
    }
    Ok(())
}
