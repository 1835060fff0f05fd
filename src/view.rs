//! `splatbench view`: the interactive viewer (keys in `harness::viewer::command`).

use std::path::PathBuf;

use anyhow::Context as _;
use clap::Args;
use harness::viewer::command::Script;
use harness::viewer::session::{Session, SessionConfig};
use harness::viewer::window::{self, LoopConfig, WindowSystem};
use methods::{MethodKind, Params};
use scenes::paths::PathSpec;

use crate::args::{CacheArgs, RenderArgs, SceneArgs, TargetArgs};

#[derive(Args, Clone)]
pub struct ViewArgs {
    /// Method to view.
    #[arg(
        long,
        value_parser = crate::args::method_parser(),
        conflicts_with = "methods",
        required_unless_present = "methods"
    )]
    pub method: Option<MethodKind>,
    /// Several methods, comma-separated: keys 1 to 9 switch between them.
    #[arg(long, value_name = "M1,M2,...")]
    pub methods: Option<String>,
    /// Method parameter, `key=value` (repeatable; with --method only).
    #[arg(long = "param", value_name = "KEY=VALUE", requires = "method")]
    pub params: Vec<String>,
    #[command(flatten)]
    pub scene: SceneArgs,
    #[command(flatten)]
    pub render: RenderArgs,
    #[command(flatten)]
    pub target: TargetArgs,
    #[command(flatten)]
    pub cache: CacheArgs,
    /// View an existing build of --method (ours, or PotreeConverter's output for potree)
    /// instead of building.
    #[arg(long, requires = "method")]
    pub build_dir: Option<PathBuf>,
    /// Where builds (reused by the next start), screenshots and recorded paths go (default:
    /// splatbench/view in the user's data directory, e.g. ~/.local/share/splatbench/view).
    #[arg(long, default_value_os_t = crate::shared::default_view_dir())]
    pub out: PathBuf,
    /// Timed key and mouse events (one per line, `FRAME EVENT [ARGS]`; see the README),
    /// played on a virtual clock of 30 frames per second.
    #[arg(long, value_name = "FILE")]
    pub script: Option<PathBuf>,
    /// Quit after this many frames.
    #[arg(long, allow_negative_numbers = true)]
    pub frames: Option<u64>,
    /// The camera path `P` plays: orbit, zoom, flythrough, extremes or a keyframe .toml
    /// (default: the last path saved with Enter).
    #[arg(long, value_name = "PATH")]
    pub play: Option<String>,
    /// On quitting, save the window's picture (frame and HUD, as presented) to this PNG.
    #[arg(long, value_name = "FILE")]
    pub window_shot: Option<PathBuf>,
    /// Frames a played path takes; `run --path P --frames N` draws the same poses.
    #[arg(long, default_value_t = 60, allow_negative_numbers = true)]
    pub play_frames: usize,
}

fn methods_of(a: &ViewArgs) -> anyhow::Result<Vec<(MethodKind, Params)>> {
    if let Some(m) = a.method {
        return Ok(vec![(m, crate::args::method_params(m, &a.params)?)]);
    }
    let list = a.methods.as_deref().unwrap_or_default();
    list.split(',')
        .map(|name| {
            let name = name.trim();
            name.to_ascii_lowercase()
                .parse::<MethodKind>()
                .map(|m| (m, Params::default()))
                .map_err(|_| {
                    let all: Vec<&str> = MethodKind::ALL.iter().map(|m| m.name()).collect();
                    anyhow::anyhow!(
                        "--methods: unknown method '{name}' (one of {})",
                        all.join(", ")
                    )
                })
        })
        .collect()
}

/// The flags that name the same scene to `run`.
fn scene_flags(s: &SceneArgs) -> String {
    let mut f = format!("--scene {}", s.scene);
    if let Some(n) = s.sample {
        f.push_str(&format!(" --sample {n}"));
    }
    if s.seed != 1 {
        f.push_str(&format!(" --seed {}", s.seed));
    }
    if let Some(up) = s.up {
        f.push_str(&format!(" --up {up}"));
    }
    if s.keep_attributes {
        f.push_str(" --keep-attributes");
    }
    f
}

/// `splatbench view`.
pub fn main(a: &ViewArgs) -> anyhow::Result<()> {
    // Flags and files first: a bad value is reported before any window or build.
    let methods = methods_of(a)?;
    let script = match &a.script {
        Some(f) => {
            let text =
                std::fs::read_to_string(f).with_context(|| format!("--script {}", f.display()))?;
            Some(
                Script::parse(&text)
                    .map_err(|e| anyhow::anyhow!("--script {}: {e}", f.display()))?,
            )
        }
        None => None,
    };
    if a.frames == Some(0) {
        anyhow::bail!("--frames must be at least 1");
    }
    let play = a
        .play
        .as_deref()
        .map(PathSpec::parse)
        .transpose()
        .context("--play")?;
    let target = a.target.target()?;
    let spec = a.scene.spec()?;
    let render = a.render.settings(a.scene.shading)?;
    let display = WindowSystem::open()?;
    let gpu = display.gpu()?.context(
        "no GPU adapter found: install Mesa's software Vulkan driver (scripts/setup.sh) or run \
         on a machine with a GPU",
    )?;
    eprintln!(
        "adapter: {} ({}, {})",
        gpu.adapter.name, gpu.adapter.backend, gpu.adapter.device_type
    );
    let bar = harness::progress::Bar::new();
    let scene = harness::runner::load_scene(&spec, render, &a.cache.dir, &bar)?;
    let mut session = Session::new(
        &gpu,
        &scene,
        SessionConfig {
            methods,
            build_dir: a.build_dir.clone(),
            target,
            cache: a.cache.dir.clone(),
            out: a.out.clone(),
            play,
            play_frames: a.play_frames,
            scene_flags: scene_flags(&a.scene),
        },
        &bar,
    )?;
    eprintln!(
        "view: builds, screenshots and paths go to {}",
        a.out.display()
    );
    let title = format!("splatbench view: {}", scene.label);
    let times = window::run(
        display,
        &gpu,
        &mut session,
        LoopConfig {
            script,
            frames: a.frames,
            title,
            window_shot: a.window_shot.clone(),
        },
        &bar,
    )?;
    let median = |v: &[f64]| {
        let mut v = v.to_vec();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(f64::NAN)
    };
    println!(
        "view: {} frames on '{}' ({}x{}): median frame {:.2} ms (select + draw + overlays), \
         present {:.2} ms (HUD text {:.2} ms)",
        times.frame_ms.len(),
        gpu.adapter.name,
        render.width,
        render.height,
        median(&times.frame_ms),
        median(&times.present_ms),
        median(&times.hud_ms)
    );
    for s in &session.shots {
        println!(
            "screenshot: {} (reference {}, pose {})",
            s.frame.display(),
            s.reference.display(),
            s.sidecar.display()
        );
    }
    for p in session.saved_paths() {
        println!("path: {}", p.display());
    }
    Ok(())
}
