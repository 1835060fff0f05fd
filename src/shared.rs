//! Helpers several subcommands use: the cache directory, opening the GPU and printing a
//! run's summary line.

use std::path::PathBuf;

use anyhow::bail;
use harness::gpu::Gpu;
use harness::runner::Summary;

/// The default `--cache`: `$SPLATBENCH_CACHE` when set, else `splatbench/` in the platform's
/// user cache directory (`$XDG_CACHE_HOME` or `~/.cache` on Linux, `~/Library/Caches` on
/// macOS, `%LOCALAPPDATA%` on Windows), else `splatbench-cache/` in the temporary directory
/// (a machine with no home directory).
pub fn default_cache() -> PathBuf {
    match std::env::var_os("SPLATBENCH_CACHE") {
        Some(p) if !p.is_empty() => PathBuf::from(p),
        _ => dirs::cache_dir()
            .map(|d| d.join("splatbench"))
            .unwrap_or_else(|| std::env::temp_dir().join("splatbench-cache")),
    }
}

/// The viewer's folder unless `--out` is given: `splatbench/view` in the user's data
/// directory (`~/.local/share` on Linux), not the current directory (issue 37: a
/// `splatbench-view/` appeared wherever the viewer was started); the system's temporary
/// directory when there is no data directory.
pub fn default_view_dir() -> PathBuf {
    dirs::data_dir()
        .map(|d| d.join("splatbench").join("view"))
        .unwrap_or_else(|| std::env::temp_dir().join("splatbench-view"))
}

/// The scene's file, when it is read from one, exists: checked before the adapter is opened,
/// so a mistyped path fails at once, naming the flag, not after the adapter line.
pub fn check_scene_file(scene: &scenes::SceneSpec) -> anyhow::Result<()> {
    match scene.file() {
        Some(f) if !f.is_file() => bail!("--scene {}: no such file", f.display()),
        _ => Ok(()),
    }
}

pub fn open_gpu() -> anyhow::Result<Gpu> {
    match Gpu::new()? {
        Some(g) => {
            eprintln!(
                "adapter: {} ({}, {})",
                g.adapter.name, g.adapter.backend, g.adapter.device_type
            );
            Ok(g)
        }
        None => bail!(
            "no GPU adapter found: install Mesa's software Vulkan driver (scripts/setup.sh: \
             mesa-vulkan-drivers libvulkan1) or run on a machine with a GPU"
        ),
    }
}

/// One line per run, medians over its frames: points drawn (thousands grouped), the frame
/// time splats/s divides by (GPU or wall, with its unit once), splats/s, FLIP and holes (%).
pub fn print_summary(s: &Summary) {
    use harness::reproduce::evaluate::thousands;
    let m = &s.medians;
    let show = |v: Option<f64>, f: &dyn Fn(f64) -> String| v.map(f).unwrap_or_else(|| "-".into());
    // The time splats/s divides by: the GPU's where the adapter has timestamps, else the wall.
    let (clock, ms) = match s.splats_per_s_basis {
        "gpu_ms" => ("gpu", m.gpu_ms),
        _ => ("wall", m.wall_ms),
    };
    // The parameters as given follow the method's name: a departure's row reads apart from
    // the paper's (the demo prints both).
    let method: Vec<String> = std::iter::once(s.method.clone())
        .chain(s.params.0.iter().map(|(k, v)| format!("{k}={v}")))
        .collect();
    println!(
        "{:<8} {:<22} frames {:>4}  points {:>11}  {clock} {:>9} ms  splats/s {:>13}  flip {:>6}  holes {:>7}",
        method.join(" "),
        s.scene.label,
        s.frames,
        show(m.points_drawn, &thousands),
        show(ms, &|v| format!("{v:.1}")),
        show(m.splats_per_s, &thousands),
        show(m.flip_mean, &|v| format!("{v:.4}")),
        show(m.hole_ratio, &|v| format!("{:.2} %", v * 100.0)),
    );
    if let Some(e) = &s.known_effect {
        println!(
            "  known effect: {}; `--param {}` changes it ({}; {})",
            e.effect, e.param, e.cost, e.doc
        );
    }
}
