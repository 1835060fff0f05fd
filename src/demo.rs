//! `splatbench demo`: every registered method on the embedded scene along a short orbit, and
//! beside a method whose result a documented effect dominates, the departure that changes it
//! ([`methods::MethodKind::known_effect`]).

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use harness::render::RenderSettings;
use harness::runner::RunConfig;
use methods::{MethodKind, Params, Target};
use scenes::SceneSpec;
use scenes::paths::PathSpec;

use crate::shared::{open_gpu, print_summary};

/// The scene the demo uses: generated, so it needs no download.
const DEMO_SCENE: &str = "statue:60000:1";

#[derive(Args, Clone)]
pub struct DemoArgs {
    /// Output directory.
    #[arg(long, default_value = "results/demo")]
    pub out: PathBuf,
    /// Frames along the orbit.
    #[arg(long, default_value_t = 24, allow_negative_numbers = true)]
    pub frames: usize,
}

/// `splatbench demo`: CSV + plots per method, one comparison plot.
pub fn main(a: &DemoArgs) -> anyhow::Result<()> {
    demo(&a.out, a.frames)
}

fn demo(out: &std::path::Path, frames: usize) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let gpu = open_gpu()?;
    let bar = harness::progress::Bar::new();
    let mut dirs = Vec::new();
    println!(
        "demo: every method on the embedded scene {DEMO_SCENE}, {frames} frames of orbit, 512x512, eps 1 px"
    );
    let run = |method: MethodKind, params: Params, dir: PathBuf| -> anyhow::Result<_> {
        let cfg = RunConfig {
            method,
            params,
            scene: SceneSpec::parse(DEMO_SCENE, None, 1)?,
            path: PathSpec::parse("orbit")?,
            frames,
            target: Target::tolerance(1.0)?,
            render: RenderSettings::default(),
            seed: 1,
            save_images: false,
            metrics: true,
            out: dir.clone(),
            cache: out.join("cache"),
            build_dir: None,
            build_url: None,
            allow_missing_chunks: false,
            reference_raster: None,
            reference_kernel: None,
        };
        let s = harness::runner::run(&cfg, &gpu, &bar)?;
        harness::plot::plot_run(&dir)?;
        print_summary(&s);
        Ok(s)
    };
    for m in MethodKind::ALL {
        let dir = out.join(m.name());
        let s = run(*m, Params::default(), dir.clone())?;
        dirs.push(dir);
        // A result dominated by a documented effect: the departure that changes it runs
        // next, so the paper's row and the departure's stand side by side (issue 37).
        if let Some(e) = s.known_effect {
            let dir = out.join(format!("{}-{}", m.name(), e.param.replace('=', "-")));
            run(*m, Params::parse(&[&e.param])?, dir.clone())?;
            dirs.push(dir);
        }
    }
    let files = harness::plot::plot_comparison(&dirs, out)?;
    println!(
        "demo done in {:.1} s: {} run directories, comparison plots {}",
        t0.elapsed().as_secs_f64(),
        dirs.len(),
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
