//! Helpers several subcommands use: opening the GPU and printing a run's summary line.

use anyhow::bail;
use harness::gpu::Gpu;
use harness::runner::Summary;

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
