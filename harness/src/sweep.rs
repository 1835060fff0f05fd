//! Sweeps: one build, then one ordinary run per target (a budget or a tolerance) into a
//! directory of its own, `sweep.csv` with one row of medians per target, and its plot.
//! `splatbench sweep` and `splatbench reproduce` both run sweeps through [`run_targets`].

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use methods::{MethodError, Target};

use crate::gpu::Gpu;
use crate::plot::{SweepRow, plot_sweep, read_frames, write_sweep};
use crate::runner::{RunConfig, Summary, run};

/// One target of a sweep.
#[derive(Debug, Clone, PartialEq)]
pub struct SweepTarget {
    /// The target.
    pub target: Target,
    /// Its value as `sweep.csv` records it (a budget's points, a tolerance's pixels).
    pub value: f64,
    /// Its run directory's name: `budget-25000`, `eps-2`.
    pub name: String,
}

impl SweepTarget {
    /// A budget of `points` per frame (0 is an error).
    pub fn budget(points: u64) -> Result<Self, MethodError> {
        Ok(Self {
            target: Target::budget(points)?,
            value: points as f64,
            name: format!("budget-{points}"),
        })
    }

    /// A tolerance of `px` pixels (finite, ≥ 0; −0 is 0). The value and the directory name
    /// use `f32`'s shortest text, so 0.1 is recorded as 0.1, not 0.10000000149.
    pub fn tolerance(px: f32) -> Result<Self, MethodError> {
        let px = if px == 0.0 { 0.0 } else { px };
        let target = Target::tolerance(px)?;
        let text = px.to_string();
        Ok(Self {
            target,
            value: text.parse().unwrap_or(f64::from(px)),
            name: format!("eps-{text}"),
        })
    }
}

/// A sweep target as plans and part records keep it (JSON).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct TargetRecord {
    /// `eps` or `budget`.
    pub kind: String,
    /// Pixels or points.
    pub value: f64,
    /// Run directory name (`budget-25000`).
    pub name: String,
    /// The run flag and its value (`--budget 25000`).
    pub flag: [String; 2],
}

impl TargetRecord {
    /// The plan's record of a sweep target.
    pub fn of(t: &SweepTarget) -> Self {
        let (kind, flag) = match (t.target.eps_px(), t.target.budget_points()) {
            (_, Some(b)) => ("budget", ["--budget".to_string(), b.to_string()]),
            (e, None) => ("eps", ["--eps".to_string(), e.unwrap_or(1.0).to_string()]),
        };
        Self {
            kind: kind.into(),
            value: t.value,
            name: t.name.clone(),
            flag,
        }
    }

    /// `budget 25000`, `eps 2`.
    pub fn label(&self) -> String {
        format!("{} {}", self.kind, self.flag[1])
    }

    /// The sweep target again.
    pub fn target(&self) -> Result<SweepTarget, MethodError> {
        if self.kind == "budget" {
            SweepTarget::budget(self.value as u64)
        } else {
            SweepTarget::tolerance(self.value as f32)
        }
    }
}

/// Removes an earlier sweep's `sweep.csv` and plot from `dir`, so that they cannot outlive a
/// failure of this one.
pub fn remove_stale(dir: &Path) -> anyhow::Result<()> {
    for stale in ["sweep.csv", "sweep.png", "sweep.svg"] {
        let p = dir.join(stale);
        match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(e).with_context(|| format!("removing the old {}", p.display()));
            }
            _ => {}
        }
    }
    Ok(())
}

/// Runs `base` once per target, each into `dir/<target name>` with `base`'s `build_dir` or
/// `build_url` (one must be set: a sweep runs one build), calling `each` with every run's summary;
/// then [`assemble`]s `dir/sweep.csv` and its plot. Returns the rows in target order.
pub fn run_targets(
    base: &RunConfig,
    targets: &[SweepTarget],
    dir: &Path,
    gpu: &Gpu,
    progress: &dyn scenes::Progress,
    mut each: impl FnMut(&Summary),
) -> anyhow::Result<Vec<SweepRow>> {
    anyhow::ensure!(
        base.build_dir.is_some() || base.build_url.is_some(),
        "a sweep runs every target on one build: its build directory or URL must be given"
    );
    anyhow::ensure!(!targets.is_empty(), "a sweep needs at least one target");
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    remove_stale(dir)?;
    for t in targets {
        let cfg = RunConfig {
            target: t.target,
            out: dir.join(&t.name),
            ..base.clone()
        };
        let s = run(&cfg, gpu, progress)
            .and_then(|s| crate::plot::plot_run(&cfg.out).map(|_| s))
            .with_context(|| format!("sweep target {}", t.name))?;
        each(&s);
    }
    assemble(dir, targets)
}

/// Writes `dir/sweep.csv` and `dir/sweep.png/.svg` from the run directories
/// `dir/<target name>/` (their `frames.csv` and the parameters in their `summary.json`):
/// what a sweep does once its runs are done, and what `merge` does with runs that jobs made.
pub fn assemble(dir: &Path, targets: &[SweepTarget]) -> anyhow::Result<Vec<SweepRow>> {
    remove_stale(dir)?;
    let mut rows = Vec::with_capacity(targets.len());
    for t in targets {
        let run = dir.join(&t.name);
        let frames = read_frames(&run.join("frames.csv"))?;
        let summary = crate::results::read_complete_summary(&run)?;
        let params = summary["params"]
            .as_object()
            .map(|p| {
                p.iter()
                    .map(|(k, v)| format!("{k}={}", v.as_str().unwrap_or_default()))
                    .collect::<Vec<_>>()
                    .join(" ")
            })
            .unwrap_or_default();
        rows.push(SweepRow::of_run(&frames, &params, t.value)?);
    }
    write_sweep(&dir.join("sweep.csv"), &rows)?;
    plot_sweep(dir)?;
    Ok(rows)
}

/// What a part of a sweep run by an emitted job records (`sweep-part.json`): the sweep (its
/// command without `--part`, `--out` and `--emit-jobs`, and every target), the part (the
/// index of its one target) and whether it finished.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SweepPart {
    /// The sweep's command.
    pub command: String,
    /// Every target of the sweep, in order.
    pub targets: Vec<TargetRecord>,
    /// The target this part ran.
    pub part: usize,
    /// Whether the sweep builds (no `--build-dir`): the part then holds `build/`.
    pub builds: bool,
    /// False until the part's run finished.
    pub complete: bool,
    /// Commit of the binary.
    pub commit: String,
}

impl SweepPart {
    /// The file name.
    pub const FILE: &'static str = "sweep-part.json";

    /// Reads `dir/sweep-part.json`.
    pub fn read(dir: &Path) -> anyhow::Result<Self> {
        crate::results::read_json(&dir.join(Self::FILE))
    }

    /// Writes `dir/sweep-part.json` atomically.
    pub fn write(&self, dir: &Path) -> anyhow::Result<()> {
        crate::results::write_json(&dir.join(Self::FILE), self)
    }
}

/// Assembles the parts in `dirs` (each a `sweep … --part K` output) into `out` as the local
/// sweep would have: one sweep, every target present once and complete; the run
/// directories (and the first part's build) put under `out`, then [`assemble`]d. Errors
/// name the directory and what is wrong.
pub fn merge(dirs: &[PathBuf], out: &Path) -> anyhow::Result<Vec<SweepRow>> {
    let parts = dirs
        .iter()
        .map(|d| SweepPart::read(d).map(|p| (d, p)))
        .collect::<anyhow::Result<Vec<_>>>()?;
    let Some((first_dir, first)) = parts.first() else {
        anyhow::bail!("merge: no directories given");
    };
    for (d, p) in &parts {
        if (&p.command, &p.targets) != (&first.command, &first.targets) {
            anyhow::bail!(
                "{} is a part of another sweep than {} (`{}` against `{}`)",
                d.display(),
                first_dir.display(),
                p.command,
                first.command
            );
        }
    }
    let listed: Vec<_> = parts
        .iter()
        .map(|(d, p)| (*d, vec![p.part], p.complete))
        .collect();
    let by_target = crate::results::cover(&listed, first.targets.len(), |k| {
        format!("target {}", first.targets[k].name)
    })?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    for (t, d) in first.targets.iter().zip(&by_target) {
        crate::results::link_tree(&d.join(&t.name), &out.join(&t.name))?;
    }
    if first.builds
        && let Some(d) = by_target.first()
    {
        crate::results::link_tree(&d.join("build"), &out.join("build"))?;
    }
    let targets = first
        .targets
        .iter()
        .map(TargetRecord::target)
        .collect::<Result<Vec<_>, _>>()?;
    assemble(out, &targets)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn target_names_and_values() {
        let b = SweepTarget::budget(25_000).unwrap();
        assert_eq!((b.name.as_str(), b.value), ("budget-25000", 25_000.0));
        let e = SweepTarget::tolerance(0.1).unwrap();
        assert_eq!((e.name.as_str(), e.value), ("eps-0.1", 0.1));
        assert_eq!(SweepTarget::tolerance(-0.0).unwrap().name, "eps-0");
        assert!(SweepTarget::budget(0).is_err());
        assert!(SweepTarget::tolerance(f32::NAN).is_err());
        assert!(SweepTarget::tolerance(-1.0).is_err());
    }
}
