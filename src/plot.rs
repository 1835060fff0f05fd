//! `splatbench plot` and `splatbench plot-sweep`: plots from run and sweep directories.

use std::path::PathBuf;

use clap::Args;

#[derive(Args, Clone)]
pub struct PlotArgs {
    /// Run directories (each with frames.csv).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where the comparison plot goes (default: the first directory's parent).
    #[arg(long)]
    pub out: Option<PathBuf>,
}

#[derive(Args, Clone)]
pub struct PlotSweepArgs {
    /// Sweep directories (each with sweep.csv).
    #[arg(required = true)]
    pub dirs: Vec<PathBuf>,
    /// Where the comparison plot goes.
    #[arg(long)]
    pub out: PathBuf,
}

/// `splatbench plot`: a timeline per run, one comparison across them.
pub fn main(a: &PlotArgs) -> anyhow::Result<()> {
    for d in &a.dirs {
        harness::plot::plot_run(d)?;
    }
    let out = a.out.clone().unwrap_or_else(|| {
        a.dirs[0]
            .parent()
            .map(PathBuf::from)
            .unwrap_or_else(|| PathBuf::from("."))
    });
    let files = harness::plot::plot_comparison(&a.dirs, &out)?;
    for f in files {
        println!("{}", f.display());
    }
    Ok(())
}

/// `splatbench plot-sweep`: several sweeps' curves in one plot.
pub fn plot_sweep(a: &PlotSweepArgs) -> anyhow::Result<()> {
    for f in harness::plot::plot_sweeps(&a.dirs, &a.out)? {
        println!("{}", f.display());
    }
    Ok(())
}
