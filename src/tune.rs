//! `splatbench tune`: a grid over a method's build and runtime parameters, one ordinary run
//! per setting and target, `tune.csv`, the Pareto front, `recommendation.md` and its plot
//! ([`harness::tune`]). With `--emit-jobs FILE` it writes one command line per part (a
//! build and its runs) for GNU parallel or a Slurm array instead, which `splatbench merge`
//! assembles.

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use harness::tune::{self, Cost, Grid, Plan, Record, TargetRecord};
use scenes::paths::PathSpec;

use crate::args::{
    BuildSourceArgs, CacheArgs, JobArgs, MethodArgs, RenderArgs, SceneArgs, SweepTargetArgs,
};
use crate::jobs;

#[derive(Args, Clone)]
pub struct TuneArgs {
    #[command(flatten)]
    pub method: MethodArgs,
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub render: RenderArgs,
    /// A parameter and its values, `KEY=V1,V2,…` (repeatable; build and runtime parameters
    /// alike). The settings are the product of the grids; each distinct build is made once.
    #[arg(
        long = "grid",
        value_name = "KEY=V1,V2,...",
        allow_hyphen_values = true
    )]
    pub grids: Vec<String>,
    #[command(flatten)]
    pub targets: SweepTargetArgs,
    /// What settings are compared at: `time` (median GPU ms per frame, wall ms without
    /// timestamps) or `points` (median points drawn).
    #[arg(long, value_enum, default_value = "time")]
    pub cost: Cost,
    /// Runs per setting and target: 2 or more measure run-to-run noise, which says whether
    /// the recommendation's margin is real; 1 skips that.
    #[arg(long, default_value_t = 2, allow_negative_numbers = true)]
    pub repeats: usize,
    /// Output directory: tune.json, builds/, runs/, repeats/, tune.csv, recommendation.md,
    /// tune.png/.svg.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub cache: CacheArgs,
    #[command(flatten)]
    pub source: BuildSourceArgs,
    #[command(flatten)]
    pub jobs: JobArgs,
}

/// The most repeats of one run.
const MAX_REPEATS: usize = 20;

/// The plan of `a`: every flag checked before anything runs.
pub fn plan(a: &TuneArgs) -> anyhow::Result<Plan> {
    let targets = a.targets.list()?;
    anyhow::ensure!(a.targets.frames >= 1, "--frames must be at least 1");
    anyhow::ensure!(
        (1..=MAX_REPEATS).contains(&a.repeats),
        "--repeats {}: give 1 to {MAX_REPEATS}",
        a.repeats
    );
    let kind = a.method.method;
    let fixed = crate::args::method_params(kind, &a.method.params)?;
    let remote = a.source.remote()?;
    let grid = Grid::parse(
        kind,
        &a.grids,
        &fixed,
        a.source.build_dir.is_some() || remote.is_some(),
    )?;
    let spec = a.scene.spec()?;
    let path = PathSpec::parse(&a.targets.path)?;
    if let Some(d) = &a.source.build_dir {
        let m =
            methods::Manifest::read(d).with_context(|| format!("--build-dir {}", d.display()))?;
        anyhow::ensure!(
            m.method == kind.name(),
            "--build-dir {}: holds {}, not {kind}",
            d.display(),
            m.method
        );
    }
    let mut scene_args = vec!["--scene".to_string(), a.scene.scene.clone()];
    scene_args.extend(["--seed".into(), a.scene.seed.to_string()]);
    if let Some(n) = a.scene.sample {
        scene_args.extend(["--sample".into(), n.to_string()]);
    }
    if a.scene.keep_attributes {
        scene_args.push("--keep-attributes".into());
    }
    if let Some(up) = a.scene.up {
        scene_args.extend(["--up".into(), up.to_string()]);
    }
    scene_args.extend(["--shading".into(), a.scene.shading.name().into()]);
    let mut run_args = vec![
        "--path".to_string(),
        a.targets.path.clone(),
        "--frames".into(),
        a.targets.frames.to_string(),
        "--width".into(),
        a.render.width.to_string(),
        "--height".into(),
        a.render.height.to_string(),
        "--kernel".into(),
        a.render.kernel.name().into(),
        "--gpu-cache-mb".into(),
        a.render.gpu_cache_mb.to_string(),
        "--raster".into(),
        a.render.raster.name().into(),
    ];
    if let Some(r) = &remote {
        run_args.extend([
            "--remote-timeout".into(),
            r.timeout.as_secs_f64().to_string(),
        ]);
    }
    Ok(Plan {
        method: kind.name().into(),
        scene: spec.label(),
        path: path.name(),
        grid,
        targets: targets.iter().map(TargetRecord::of).collect(),
        cost: a.cost,
        repeats: a.repeats,
        scene_args,
        run_args,
        build_dir: a.source.build_dir.clone(),
        build_url: remote.map(|r| r.url),
        cache: a.cache.dir.clone(),
        command: jobs::command_without(&jobs::PART_FLAGS),
    })
}

/// `splatbench tune`.
pub fn main(a: &TuneArgs) -> anyhow::Result<()> {
    let plan = plan(a)?;
    let exe = std::env::current_exe().context("finding the splatbench binary")?;
    if let Some(file) = a.jobs.emit()? {
        let n = jobs::emit(file, &a.out, plan.parts())?;
        println!(
            "wrote {} ({} jobs: one per build, each building then running its {} runs); run \
             them, then: splatbench merge {}/parts/part-* --out {}",
            file.display(),
            n,
            plan.targets.len() * plan.repeats,
            a.out.display(),
            a.out.display()
        );
        return Ok(());
    }
    jobs::prepare_out(&a.out, "tune.json", a.source.build_dir.as_deref())?;
    let mut say = |s: &str| eprintln!("{s}");
    if let Some(k) = a.jobs.part {
        anyhow::ensure!(
            k < plan.parts(),
            "--part {k}: this tune has {} parts (0 to {})",
            plan.parts(),
            plan.parts() - 1
        );
        let mut record = Record {
            plan: plan.clone(),
            parts: vec![k],
            complete: false,
            commit: harness::runner::GIT_COMMIT.into(),
        };
        record.write(&a.out)?;
        tune::run_part(&plan, k, &a.out, &exe, &mut say)?;
        record.complete = true;
        record.write(&a.out)?;
        println!("part {k} of {} done in {}", plan.parts(), a.out.display());
        return Ok(());
    }
    let mut record = Record {
        plan: plan.clone(),
        parts: (0..plan.parts()).collect(),
        complete: false,
        commit: harness::runner::GIT_COMMIT.into(),
    };
    record.write(&a.out)?;
    eprintln!(
        "tune {}: {} settings × {} targets × {} repeats on {} build(s)",
        plan.method,
        plan.grid.settings().len(),
        plan.targets.len(),
        plan.repeats,
        plan.parts()
    );
    for k in 0..plan.parts() {
        tune::run_part(&plan, k, &a.out, &exe, &mut say)?;
    }
    let done = tune::assemble(&plan, &a.out)?;
    record.complete = true;
    record.write(&a.out)?;
    print!("{}", done.recommendation);
    println!(
        "wrote {}: tune.csv ({} rows), recommendation.md, tune.png, tune.svg",
        a.out.display(),
        done.rows.len()
    );
    Ok(())
}
