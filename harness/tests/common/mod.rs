//! Helpers shared by the render test binaries (`render.rs`, `compute.rs`).
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use harness::gpu::Gpu;
use harness::image::Image;
use harness::render::{Kernel, RenderSettings};
use methods::{DrawItem, DrawList, SplatBatch, SplatSize};
use methods::{LodMethod, MethodKind, Params};
use scenes::paths::PathSpec;
use scenes::{PointCloud, View};

/// The `full` method built on `cloud` in `dir`.
pub fn full(cloud: &PointCloud, dir: &Path) -> Box<dyn LodMethod> {
    MethodKind::Full
        .build(cloud, &Params::default(), "test", dir, &scenes::NoProgress)
        .unwrap();
    MethodKind::open(dir).unwrap()
}

/// Frame `frame` of an 8-frame orbit around `cloud` at `w` × `h`.
pub fn view(cloud: &PointCloud, w: u32, h: u32, frame: usize) -> View {
    View {
        camera: PathSpec::parse("orbit")
            .unwrap()
            .camera(frame, 8, &cloud.bounds()),
        width: w,
        height: h,
    }
}

/// Quads renderer settings at `w` × `h` with `kernel` and a 64 MiB cache.
pub fn settings(w: u32, h: u32, kernel: Kernel) -> RenderSettings {
    RenderSettings {
        width: w,
        height: h,
        kernel,
        cache_bytes: 64 << 20,
        shade: Default::default(),
        raster: Default::default(),
    }
}

/// Fraction of pixels whose coverage differs, and mean absolute colour difference over
/// pixels covered in both.
pub fn disagreement(a: &Image, b: &Image) -> (f64, f64) {
    let (mut cov, mut diff, mut both, mut sum) = (0u64, 0u64, 0u64, 0u64);
    for (pa, pb) in a.rgba.chunks(4).zip(b.rgba.chunks(4)) {
        let (ca, cb) = (pa[3] > 0, pb[3] > 0);
        cov += (ca || cb) as u64;
        diff += (ca != cb) as u64;
        if ca && cb {
            both += 1;
            sum += (0..3).map(|c| pa[c].abs_diff(pb[c]) as u64).sum::<u64>();
        }
    }
    (
        diff as f64 / cov.max(1) as f64,
        sum as f64 / (3 * both.max(1)) as f64,
    )
}

/// The committed golden images.
pub fn golden_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/golden")
}

/// The adapter that blessed a golden, beside it as `<name>.adapter.json`.
#[derive(Debug, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BlessedOn {
    pub name: String,
    pub driver: String,
    pub driver_info: String,
}

impl BlessedOn {
    pub fn of(gpu: &Gpu) -> Self {
        Self {
            name: gpu.adapter.name.clone(),
            driver: gpu.adapter.driver.clone(),
            driver_info: gpu.adapter.driver_info.clone(),
        }
    }
}

/// Per-pixel LDR-FLIP errors (NVIDIA's FLIP at its default 67 pixels per degree) of `test`
/// against `reference`, both composited on black, and which pixels either image covers.
pub fn flip_errors(reference: &Image, test: &Image) -> (Vec<f32>, Vec<bool>) {
    let rgb = |img: &Image| -> Vec<u8> {
        img.rgba
            .chunks_exact(4)
            .flat_map(|p| {
                let a = u16::from(p[3]);
                [0, 1, 2].map(|c| ((u16::from(p[c]) * a + 127) / 255) as u8)
            })
            .collect()
    };
    let (w, h) = (reference.width, reference.height);
    let e = nv_flip::flip(
        nv_flip::FlipImageRgb8::with_data(w, h, &rgb(reference)),
        nv_flip::FlipImageRgb8::with_data(w, h, &rgb(test)),
        nv_flip::DEFAULT_PIXELS_PER_DEGREE,
    )
    .to_vec();
    let covered = reference
        .rgba
        .chunks_exact(4)
        .zip(test.rgba.chunks_exact(4))
        .map(|(a, b)| a[3] > 0 || b[3] > 0)
        .collect();
    (e, covered)
}

/// Gates of [`cross_adapter_mismatch`], set on llvmpipe between what another rasteriser may
/// do and what a wrong kernel does, on the sparse kernel goldens (`render.rs`): the camera
/// moved a quarter of a pixel sideways gives a mean FLIP of 0.048 over the covered pixels
/// with 0.7 % of them above 0.3 (a tenth of a pixel: 0.024, 0.1 %); squares drawn for
/// circles give 0.085 and 4.7 %, ellipses 0.22 and 28 %, gaussians 0.18 and 19 % (QSplat's
/// spline, since 2026-12-06; 0.11 and 2.2 % with the former `exp(−2r²)` kernel).
pub const GOLDEN_MEAN_FLIP: f64 = 0.06;
/// The per-pixel FLIP error counted by [`GOLDEN_OVER_SHARE`].
pub const GOLDEN_PIXEL_FLIP: f32 = 0.3;
/// At most this share of the covered pixels may exceed [`GOLDEN_PIXEL_FLIP`].
pub const GOLDEN_OVER_SHARE: f64 = 0.02;

/// The comparison for a golden blessed on another adapter: over the pixels covered in
/// either image (the background would dilute any error: the statue covers a fifth of the
/// frame), the mean FLIP must stay within `max_mean` and at most [`GOLDEN_OVER_SHARE`] of
/// them may exceed [`GOLDEN_PIXEL_FLIP`] (a rasteriser's rounding moves splat edges by a
/// pixel; a wrong kernel moves a whole band of them). `Some(why)` on a mismatch.
pub fn cross_adapter_mismatch(golden: &Image, img: &Image, max_mean: f64) -> Option<String> {
    let (mean, share, n) = golden_stats(golden, img);
    (mean > max_mean || share > GOLDEN_OVER_SHARE).then(|| {
        format!(
            "mean FLIP {mean:.4} over {n} covered pixels (max {max_mean}), {:.2} % of them \
             above {GOLDEN_PIXEL_FLIP} (max {:.0} %)",
            100.0 * share,
            100.0 * GOLDEN_OVER_SHARE
        )
    })
}

/// Mean FLIP over the pixels either image covers, the share of them above
/// [`GOLDEN_PIXEL_FLIP`], and their count.
pub fn golden_stats(golden: &Image, img: &Image) -> (f64, f64, usize) {
    let (e, covered) = flip_errors(golden, img);
    let n = covered.iter().filter(|&&c| c).count().max(1);
    let sum: f64 = e
        .iter()
        .zip(&covered)
        .filter(|(_, c)| **c)
        .map(|(v, _)| f64::from(*v))
        .sum();
    let over = e
        .iter()
        .zip(&covered)
        .filter(|(v, c)| **c && **v > GOLDEN_PIXEL_FLIP)
        .count();
    (sum / n as f64, over as f64 / n as f64, n)
}

/// Compares with `tests/golden/<name>.png`. Blessed on this adapter (the sidecar
/// `<name>.adapter.json` names the same adapter, driver and driver info): the image must be
/// the golden byte for byte (same-adapter renders repeat exactly:
/// `results/baselines/quick.json`). Blessed elsewhere: [`cross_adapter_mismatch`] with mean
/// gate `max_mean`. Regenerate with `SPLATBENCH_BLESS=1` (writes the image and its sidecar).
pub fn check_golden(gpu: &Gpu, name: &str, img: &Image, max_mean: f64) {
    let path = golden_dir().join(format!("{name}.png"));
    let sidecar = golden_dir().join(format!("{name}.adapter.json"));
    if std::env::var("SPLATBENCH_BLESS").as_deref() == Ok("1") {
        img.save_png(&path).unwrap();
        let text = serde_json::to_string_pretty(&BlessedOn::of(gpu)).unwrap();
        std::fs::write(&sidecar, text + "\n").unwrap();
        eprintln!("blessed {}", path.display());
        return;
    }
    let golden = Image::load_png(&path)
        .unwrap_or_else(|e| panic!("{e:#}: run with SPLATBENCH_BLESS=1 to create it"));
    let blessed: BlessedOn = std::fs::read_to_string(&sidecar)
        .ok()
        .and_then(|t| serde_json::from_str(&t).ok())
        .unwrap_or_else(|| panic!("{}: missing or unreadable", sidecar.display()));
    let why = if blessed == BlessedOn::of(gpu) {
        let differ = golden
            .rgba
            .chunks_exact(4)
            .zip(img.rgba.chunks_exact(4))
            .filter(|(a, b)| a != b)
            .count();
        (differ > 0 || golden.width != img.width || golden.height != img.height)
            .then(|| format!("{differ} pixels differ from the golden blessed on this adapter"))
    } else {
        eprintln!(
            "{name}: blessed on {} ({} {}), running on {}: cross-adapter tolerance",
            blessed.name, blessed.driver, blessed.driver_info, gpu.adapter.name
        );
        cross_adapter_mismatch(&golden, img, max_mean)
    };
    if let Some(why) = why {
        let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/golden-failures");
        std::fs::create_dir_all(&out).unwrap();
        img.save_png(&out.join(format!("{name}-actual.png")))
            .unwrap();
        harness::metrics::flip_map(&golden, img)
            .unwrap()
            .save_png(&out.join(format!("{name}-difference.png")))
            .unwrap();
        panic!("{name}: {why}; see {}", out.display());
    }
}

/// A camera at +Z 5 looking at the origin, 60° vertical field of view, near 0.1, far 10.
pub fn front_view(w: u32, h: u32) -> View {
    View {
        camera: scenes::Camera {
            position: glam::Vec3::new(0.0, 0.0, 5.0),
            target: glam::Vec3::ZERO,
            up: glam::Vec3::Y,
            fov_y: 60f32.to_radians(),
            near: 0.1,
            far: 10.0,
        },
        width: w,
        height: h,
    }
}

/// One streamed batch of `size`-pixel splats with `colors` (packed RGBA8, little-endian).
pub fn stream(points: &[[f32; 3]], colors: Option<Vec<u32>>, size: f32) -> DrawList {
    DrawList {
        items: vec![DrawItem::Stream {
            batch: SplatBatch {
                positions: points.to_vec(),
                colors,
                ..Default::default()
            },
            size: SplatSize::Pixels(size),
        }],
        ..Default::default()
    }
}

/// Covered pixels (alpha > 0) of `img`, as (x, y).
pub fn covered(img: &Image) -> Vec<(u32, u32)> {
    (0..img.height)
        .flat_map(|y| (0..img.width).map(move |x| (x, y)))
        .filter(|&(x, y)| img.pixel(x, y)[3] > 0)
        .collect()
}

/// `list` with every cached chunk drawn at `px` pixels instead of its own size mode.
pub fn with_pixel_size(list: &DrawList, px: f32) -> DrawList {
    let mut l = list.clone();
    for it in &mut l.items {
        if let DrawItem::Chunk { size, .. } = it {
            *size = SplatSize::Pixels(px);
        }
    }
    l
}
