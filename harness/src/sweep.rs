//! Sweeps: one build, then one ordinary run per target (a budget or a tolerance) into a
//! directory of its own, `sweep.csv` with one row of medians per target, and its plot.
//! `splatbench sweep` and `splatbench reproduce` both run sweeps through [`run_targets`].

use std::path::Path;

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

/// Runs `base` once per target, each into `dir/<target name>` with `base`'s `build_dir`
/// (which must be set: a sweep runs one build), calling `each` with every run's summary;
/// then writes `dir/sweep.csv` and `dir/sweep.png/.svg`. Returns the rows in target order.
pub fn run_targets(
    base: &RunConfig,
    targets: &[SweepTarget],
    dir: &Path,
    gpu: &Gpu,
    progress: &dyn scenes::Progress,
    mut each: impl FnMut(&Summary),
) -> anyhow::Result<Vec<SweepRow>> {
    anyhow::ensure!(
        base.build_dir.is_some(),
        "a sweep runs every target on one build: its build directory must be given"
    );
    anyhow::ensure!(!targets.is_empty(), "a sweep needs at least one target");
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    remove_stale(dir)?;
    let mut rows = Vec::with_capacity(targets.len());
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
        let frames = read_frames(&cfg.out.join("frames.csv"))?;
        let params = s
            .params
            .0
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ");
        rows.push(SweepRow::of_run(&frames, &params, t.value)?);
    }
    write_sweep(&dir.join("sweep.csv"), &rows)?;
    plot_sweep(dir)?;
    Ok(rows)
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
