//! What a run's images will hold in memory, checked before anything is allocated: a frame
//! too large for the machine is refused with the estimate, what is available and the flags
//! that change it, instead of growing until the kernel kills the process without a word
//! (a 16384² run with image metrics grew to 24 GB and died with exit 137).
//!
//! **The estimate** is per pixel of the frame, measured as the growth of peak RSS between
//! runs of 1024², 2048² and 4096² (`/usr/bin/time -f %M splatbench run --method lpc --scene
//! statue:20000:1 --frames 2 --width S --height S`, lavapipe on a 2-core machine, where the
//! render targets live in host memory too): with image metrics 151–155 bytes per pixel
//! (square kernel), 164 (`--raster compute`), 172 (`--kernel gaussian`: its accumulation
//! target); with `--no-metrics` about 7. The warped popping metric (issue 38) keeps the
//! last 7 frames' reference depth, reference and test images (84 bytes per pixel) and FLIP's
//! planes of the warped frames: with it, 9 frames (lag 7 reached) of 1024² and 2048², 326
//! bytes per pixel (square) and 341 (gaussian), measured 2026-12-07. The estimate takes
//! [`METRICS_BYTES_PER_PIXEL`] = 360 and [`PLAIN_BYTES_PER_PIXEL`] = 16, the largest
//! measured plus 5 % and twice the measured respectively: the colour, depth and
//! accumulation targets, their readbacks, the reference image and depth, FLIP's feature
//! planes of both images and of the warped ones, and the popping history. It leaves out the scene and the
//! method's own memory (their sizes are the method's `core_mb`, `gpu_cache_mb` and the
//! scene's columns), so it refuses only what the frame alone cannot hold.
//!
//! **Available**: `SPLATBENCH_MEMORY_LIMIT_MB` if set (a cap for a shared machine, and how
//! the tests inject a small limit), else Linux's `MemAvailable`; where neither is known
//! nothing is refused. `--skip-memory-check` runs anyway.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::render::RenderSettings;

/// Bytes per pixel a run with image metrics holds (see the module docs).
pub const METRICS_BYTES_PER_PIXEL: u64 = 360;
/// Bytes per pixel a run without image metrics holds (see the module docs).
pub const PLAIN_BYTES_PER_PIXEL: u64 = 16;
/// The environment variable that caps the memory a run may count on, MiB.
pub const LIMIT_ENV: &str = "SPLATBENCH_MEMORY_LIMIT_MB";

static SKIP: AtomicBool = AtomicBool::new(false);

/// `--skip-memory-check`: refuse nothing in this process (children are given the flag).
pub fn skip_check(skip: bool) {
    SKIP.store(skip, Ordering::Relaxed);
}

/// Whether `--skip-memory-check` was given.
pub fn check_skipped() -> bool {
    SKIP.load(Ordering::Relaxed)
}

/// Estimated bytes a run's images hold at `render`'s size (see the module docs).
pub fn frame_bytes(render: &RenderSettings, metrics: bool) -> u64 {
    let pixels = u64::from(render.width) * u64::from(render.height);
    let per_pixel = if metrics {
        METRICS_BYTES_PER_PIXEL
    } else {
        PLAIN_BYTES_PER_PIXEL
    };
    // One figure for every kernel and rasteriser: the largest measured (module docs).
    pixels.saturating_mul(per_pixel)
}

/// Bytes a run may count on: [`LIMIT_ENV`], else `MemAvailable`; `None` if neither is known.
/// A malformed [`LIMIT_ENV`] is an error naming it.
pub fn available_bytes() -> anyhow::Result<Option<u64>> {
    if let Ok(v) = std::env::var(LIMIT_ENV) {
        let mb: u64 = v
            .trim()
            .parse()
            .map_err(|_| anyhow::anyhow!("{LIMIT_ENV}={v}: not a whole number of MiB"))?;
        return Ok(Some(mb.saturating_mul(1 << 20)));
    }
    Ok(std::fs::read_to_string("/proc/meminfo")
        .ok()
        .and_then(|s| meminfo_available(&s)))
}

/// `MemAvailable` of a `/proc/meminfo` text, bytes.
fn meminfo_available(text: &str) -> Option<u64> {
    text.lines()
        .find(|l| l.starts_with("MemAvailable:"))
        .and_then(|l| l.split_whitespace().nth(1))
        .and_then(|kb| kb.parse::<u64>().ok())
        .map(|kb| kb * 1024)
}

/// Refuses a frame whose estimated images exceed the memory available: the error names the
/// size flags, the estimate, what is available and what to change.
pub fn check_frame(render: &RenderSettings, metrics: bool) -> anyhow::Result<()> {
    if check_skipped() {
        return Ok(());
    }
    let Some(available) = available_bytes()? else {
        return Ok(());
    };
    let need = frame_bytes(render, metrics);
    if need <= available {
        return Ok(());
    }
    let size = |b: u64| {
        if b >= 1_000_000_000 {
            format!("{:.1} GB", b as f64 / 1e9)
        } else {
            format!("{:.1} MB", b as f64 / 1e6)
        }
    };
    let source = if std::env::var_os(LIMIT_ENV).is_some() {
        LIMIT_ENV
    } else {
        "MemAvailable"
    };
    let per_pixel = if metrics {
        format!("{METRICS_BYTES_PER_PIXEL} bytes per pixel with image metrics")
    } else {
        format!("{PLAIN_BYTES_PER_PIXEL} bytes per pixel without image metrics")
    };
    let fewer = if metrics { ", give --no-metrics" } else { "" };
    anyhow::bail!(
        "--width {} --height {}: the frame's images need an estimated {} ({per_pixel}: \
         render targets, readbacks, the reference and FLIP's planes), more than the {} \
         available ({source}): lower --width/--height{fewer}, or give --skip-memory-check to \
         run anyway",
        render.width,
        render.height,
        size(need),
        size(available)
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn meminfo_available_is_read_in_bytes() {
        let text = "MemTotal:       24000000 kB\nMemFree:  100 kB\nMemAvailable:   20000000 kB\n";
        assert_eq!(meminfo_available(text), Some(20_000_000 * 1024));
        assert_eq!(meminfo_available("MemTotal: 1 kB\n"), None);
    }

    #[test]
    fn the_estimate_is_the_measured_bytes_per_pixel() {
        let r = RenderSettings {
            width: 16384,
            height: 16384,
            ..Default::default()
        };
        assert_eq!(frame_bytes(&r, true), 16384 * 16384 * 360);
        assert_eq!(frame_bytes(&r, false), 16384 * 16384 * 16);
    }
}
