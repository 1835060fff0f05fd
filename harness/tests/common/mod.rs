//! Helpers shared by the render test binaries (`render.rs`, `compute.rs`).
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};

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

/// Compares with `tests/golden/<name>.png`; FLIP mean ≤ `max_flip` (thresholds set on
/// llvmpipe (LLVM 15.0.6, 256 bits), Vulkan; the GPU/CPU agreement test above bounds what a
/// different rasteriser may change).
pub fn check_golden(name: &str, img: &Image, max_flip: f64) {
    let path = golden_dir().join(format!("{name}.png"));
    if std::env::var("SPLATBENCH_BLESS").as_deref() == Ok("1") {
        img.save_png(&path).unwrap();
        eprintln!("blessed {}", path.display());
        return;
    }
    let golden = Image::load_png(&path)
        .unwrap_or_else(|e| panic!("{e:#}: run with SPLATBENCH_BLESS=1 to create it"));
    let flip = harness::metrics::flip_mean(&golden, img).unwrap();
    let holes = harness::metrics::hole_ratio(&golden, img).unwrap();
    if flip > max_flip || holes > 0.01 {
        let out = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/golden-failures");
        std::fs::create_dir_all(&out).unwrap();
        img.save_png(&out.join(format!("{name}-actual.png")))
            .unwrap();
        harness::metrics::flip_map(&golden, img)
            .unwrap()
            .save_png(&out.join(format!("{name}-difference.png")))
            .unwrap();
        panic!(
            "{name}: FLIP {flip:.4} (max {max_flip}), holes {holes:.4}; see {}",
            out.display()
        );
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
