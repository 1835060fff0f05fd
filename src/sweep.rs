//! `splatbench sweep`: one build, one run per budget or tolerance, `sweep.csv` and its plot.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use harness::sweep::SweepTarget;

use crate::args::{
    BuildSourceArgs, CacheArgs, JobArgs, MethodArgs, RenderArgs, SceneArgs, SweepTargetArgs,
    TargetArgs,
};
use crate::build::build;
use crate::run::{RunArgs, run_config};
use crate::shared::{check_scene_file, open_gpu, print_summary};

#[derive(Args, Clone)]
pub struct SweepArgs {
    #[command(flatten)]
    pub method: MethodArgs,
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub render: RenderArgs,
    #[command(flatten)]
    pub targets: SweepTargetArgs,
    /// Output directory: build/ (unless --build-dir), one run directory per target
    /// (budget-25000/, eps-2/, …), sweep.csv, sweep.png and sweep.svg.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub cache: CacheArgs,
    #[command(flatten)]
    pub source: BuildSourceArgs,
    #[command(flatten)]
    pub jobs: JobArgs,
}

/// `splatbench sweep`: targets, parameters, scene spec, path and frames are checked before
/// anything is built or rendered; then one build (or `--build-dir`, checked by the runner at
/// the first target), one ordinary run per target ([`harness::sweep::run_targets`] on a
/// [`run_config`] with `build_dir` set, so the runner's `--build-dir` path opens it), then
/// `sweep.csv` and its plot.
pub fn main(a: &SweepArgs) -> anyhow::Result<()> {
    let all = a.targets.list()?;
    if let Some(file) = a.jobs.emit()? {
        // Checks every flag as a sweep would, without running.
        base_config(a, &all)?;
        let n = crate::jobs::emit(file, &a.out, all.len())?;
        println!(
            "wrote {} ({} jobs: one per target, each {}its run); run them, then: \
             splatbench merge {}/parts/part-* --out {}",
            file.display(),
            n,
            if a.source.given() {
                ""
            } else {
                "making its own (identical) build, then "
            },
            a.out.display(),
            a.out.display()
        );
        return Ok(());
    }
    let targets = match a.jobs.part {
        None => all.clone(),
        Some(k) => vec![
            all.get(k)
                .ok_or_else(|| {
                    anyhow::anyhow!(
                        "--part {k}: this sweep has {} targets (parts 0 to {})",
                        all.len(),
                        all.len() - 1
                    )
                })?
                .clone(),
        ],
    };
    let (base, build_dir) = base_config(a, &targets)?;
    check_scene_file(&base.scene)?;
    let gpu = open_gpu()?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    // A sweep.csv (or plot) of an earlier sweep must not outlive a failure of this one.
    harness::sweep::remove_stale(&a.out)?;
    if !a.source.given() {
        eprintln!("building {} into {}", a.method.method, build_dir.display());
        build(&a.method, &a.scene, &build_dir, &a.cache.dir)?;
    }
    let bar = harness::progress::Bar::new();
    let mut part = a.jobs.part.map(|k| harness::sweep::SweepPart {
        command: crate::jobs::command_without(&crate::jobs::PART_FLAGS),
        targets: all.iter().map(harness::sweep::TargetRecord::of).collect(),
        part: k,
        builds: !a.source.given(),
        complete: false,
        commit: harness::runner::GIT_COMMIT.into(),
    });
    if let Some(p) = &part {
        p.write(&a.out)?;
    }
    let rows = harness::sweep::run_targets(&base, &targets, &a.out, &gpu, &bar, print_summary)?;
    if let Some(p) = part.as_mut() {
        p.complete = true;
        p.write(&a.out)?;
    }
    let csv = a.out.join("sweep.csv");
    let plots = [a.out.join("sweep.png"), a.out.join("sweep.svg")];
    println!(
        "wrote {} ({} targets), {} and {} run directories",
        csv.display(),
        rows.len(),
        plots
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        targets.len()
    );
    Ok(())
}

/// The runner's configuration shared by the sweep's targets (the first target's), and the
/// build directory: every flag checked, nothing run.
fn base_config(
    a: &SweepArgs,
    targets: &[SweepTarget],
) -> anyhow::Result<(harness::runner::RunConfig, PathBuf)> {
    anyhow::ensure!(a.targets.frames >= 1, "--frames must be at least 1");
    crate::args::method_params(a.method.method, &a.method.params)?;
    let build_dir = a
        .source
        .build_dir
        .clone()
        .unwrap_or_else(|| a.out.join("build"));
    let first = targets.first().map(|t| t.target);
    let base = run_config(&RunArgs {
        method: MethodArgs {
            method: a.method.method,
            // A build of our own already holds every --param (its method.json records
            // them); the runner lets a run of a build change runtime parameters only.
            params: if a.source.given() {
                a.method.params.clone()
            } else {
                Vec::new()
            },
        },
        scene: a.scene.clone(),
        render: a.render.clone(),
        target: TargetArgs {
            eps: first.and_then(|t| t.eps_px()).map(f64::from),
            budget: first.and_then(|t| t.budget_points()),
        },
        path: a.targets.path.clone(),
        frames: a.targets.frames,
        save_images: false,
        no_metrics: false,
        out: a.out.clone(),
        cache: a.cache.clone(),
        source: BuildSourceArgs {
            build_dir: a.source.build_url.is_none().then(|| build_dir.clone()),
            ..a.source.clone()
        },
        allow_missing_chunks: false,
    })?;
    Ok((base, build_dir))
}
