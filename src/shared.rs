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

pub fn print_summary(s: &Summary) {
    let f = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
    println!(
        "{:<8} {:<22} frames {:>4}  points {:>10}  {} ms {:>8}  splats/s {:>12}  flip {:>7}  holes {:>7}",
        s.method,
        s.scene.label,
        s.frames,
        f(s.medians.points_drawn),
        s.splats_per_s_basis,
        f(s.medians.gpu_ms.or(s.medians.wall_ms)),
        f(s.medians.splats_per_s),
        f(s.medians.flip_mean),
        f(s.medians.hole_ratio),
    );
}
