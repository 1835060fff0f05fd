//! `splatbench run`: build (or reuse a build), run a camera path, write `frames.csv`,
//! `summary.json` and the timeline plot.

use std::path::PathBuf;

use clap::Args;
use harness::runner::RunConfig;
use scenes::paths::PathSpec;

use crate::args::{BuildSourceArgs, CacheArgs, MethodArgs, RenderArgs, SceneArgs, TargetArgs};
use crate::shared::{check_scene_file, open_gpu, print_summary};

#[derive(Args, Clone)]
pub struct RunArgs {
    #[command(flatten)]
    pub method: MethodArgs,
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub render: RenderArgs,
    #[command(flatten)]
    pub target: TargetArgs,
    /// Camera path: a built-in (orbit, zoom, flythrough, extremes; `splatbench list` says what
    /// each does) or a keyframe .toml file.
    #[arg(long, default_value = "orbit")]
    pub path: String,
    /// Frames along the path.
    #[arg(long, default_value_t = 60, allow_negative_numbers = true)]
    pub frames: usize,
    /// Save every frame and its reference as PNG under images/.
    #[arg(long)]
    pub save_images: bool,
    /// Skip the reference and the image metrics (speed only).
    #[arg(long)]
    pub no_metrics: bool,
    /// Output directory.
    #[arg(long)]
    pub out: PathBuf,
    #[command(flatten)]
    pub cache: CacheArgs,
    #[command(flatten)]
    pub source: BuildSourceArgs,
    /// Exit 0 although chunks of an LPC or MWKD repository failed to load (a corrupted or
    /// truncated repo.bin). They are reported either way: on stderr, in frames.csv
    /// (`chunks_failed`) and in summary.json (`failed_chunks`); without this flag the run
    /// fails and summary.json says "complete": false.
    #[arg(long)]
    pub allow_missing_chunks: bool,
}

/// The runner's configuration for `run`'s arguments (`sweep` makes one per target).
pub fn run_config(a: &RunArgs) -> anyhow::Result<RunConfig> {
    let params = crate::args::method_params(a.method.method, &a.method.params)?;
    let target = a.target.target()?;
    Ok(RunConfig {
        method: a.method.method,
        params,
        scene: a.scene.spec()?,
        path: PathSpec::parse(&a.path)?,
        frames: a.frames,
        target,
        render: a.render.settings(a.scene.shading)?,
        seed: a.scene.seed,
        save_images: a.save_images,
        metrics: !a.no_metrics,
        out: a.out.clone(),
        cache: a.cache.dir.clone(),
        build_dir: a.source.build_dir.clone(),
        build_url: a.source.remote()?,
        allow_missing_chunks: a.allow_missing_chunks,
        reference_raster: a.render.reference_raster,
        reference_kernel: a.render.reference_kernel()?,
    })
}

/// `splatbench run`.
pub fn main(args: &RunArgs) -> anyhow::Result<()> {
    // Flags first: a bad value is reported without waiting for an adapter.
    let cfg = run_config(args)?;
    check_scene_file(&cfg.scene)?;
    harness::memory::check_frame(&cfg.render, cfg.metrics)?;
    let gpu = open_gpu()?;
    let s = harness::runner::run(&cfg, &gpu, &harness::progress::Bar::new())?;
    let plots = harness::plot::plot_run(&cfg.out)?;
    print_summary(&s);
    let images = if cfg.save_images {
        // Every frame and, with metrics, its reference (`frame_NNNN.png`, `ref_NNNN.png`).
        let n = std::fs::read_dir(cfg.out.join("images")).map_or(0, |d| d.count());
        format!(", {n} images under images/")
    } else {
        String::new()
    };
    println!(
        "wrote {}/frames.csv, summary.json, {} plot files{images}",
        cfg.out.display(),
        plots.len()
    );
    Ok(())
}
