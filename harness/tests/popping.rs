//! Popping against exact motion (issue 38), with known answers, on whatever adapter exists
//! ("skipped: no adapter" printed loudly when there is none, a failure when
//! `SPLATBENCH_REQUIRE_GPU=1`):
//!
//! - a still camera gives exactly 0 for `full` at both lags, and every covered pixel valid;
//! - a camera stepping sideways by whole pixels in front of a textured wall gives `full`
//!   a warped FLIP of (almost) 0 where the unwarped frame-to-frame FLIP is large;
//! - the reference's depth read back from the GPU agrees with the CPU mirror's for every
//!   kernel and both rasterisers, and so do the warps made from them.
#![allow(clippy::unwrap_used)]

mod common;
use common::{full, settings};

use glam::Vec3;
use harness::gpu::{Gpu, gpu_for_test};
use harness::image::Image;
use harness::metrics::PathMetrics;
use harness::metrics::popping::{DepthImage, LAGS};
use harness::metrics::warp::Warp;
use harness::render::{Kernel, Raster, RenderSettings, Renderer, Shade, Shading, cpu};
use methods::{Feedback, LodMethod, Target};
use scenes::generators::Generator;
use scenes::paths::PathSpec;
use scenes::{Camera, PointCloud, View};

/// `full`'s image and the depth of `view` (the reference's, since `full` is the reference).
fn draw(r: &mut Renderer<'_>, m: &mut dyn LodMethod, view: &View) -> (Image, DepthImage) {
    let list = m
        .frame(view, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    let (_, img) = r.draw(view, &list, &*m, true).unwrap();
    (img.unwrap(), r.read_depth(view).unwrap())
}

fn renderer<'g>(gpu: &'g Gpu, s: RenderSettings) -> Renderer<'g> {
    let mut r = Renderer::new(gpu, s).unwrap();
    r.keep_depth(true);
    r
}

#[test]
fn a_still_camera_gives_full_exactly_zero_at_both_lags() {
    let Some(gpu) = gpu_for_test("a_still_camera_gives_full_exactly_zero_at_both_lags") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(20_000, 1).unwrap();
    let mut m = full(&cloud, tmp.path());
    let view = View {
        camera: PathSpec::parse("orbit")
            .unwrap()
            .camera(1, 8, &cloud.bounds()),
        width: 128,
        height: 96,
    };
    let mut r = renderer(&gpu, settings(128, 96, Kernel::Circle));
    let mut metrics = PathMetrics::new();
    for i in 0..9 {
        let (img, depth) = draw(&mut r, m.as_mut(), &view);
        let covered = img.rgba.chunks(4).filter(|p| p[3] > 0).count() as f64;
        let f = metrics
            .frame_warped(&view, depth, img.clone(), img)
            .unwrap();
        for (lag, w) in LAGS.iter().zip(f.warped) {
            if i < *lag {
                assert_eq!(w, None, "frame {i}, lag {lag}");
                continue;
            }
            let w = w.unwrap();
            assert_eq!((w.method, w.reference, w.pops), (0.0, 0.0, 0), "frame {i}");
            // Every pixel the reference covers maps to itself.
            assert_eq!(w.valid, covered / (128.0 * 96.0), "frame {i}, lag {lag}");
        }
    }
}

/// A wall at y = 0, x in ±1.3, z in ±0.8, sampled every 0.01 with a colour per sample
/// from a hash (a texture that changes at every pixel).
fn textured_wall() -> PointCloud {
    let (nx, nz) = (261, 161);
    let mut p = Vec::with_capacity(nx * nz);
    let mut c = Vec::with_capacity(nx * nz);
    for i in 0..nx {
        for k in 0..nz {
            p.push([-1.3 + 0.01 * i as f32, 0.0, -0.8 + 0.01 * k as f32]);
            let h = (i as u32).wrapping_mul(73_856_093) ^ (k as u32).wrapping_mul(19_349_663);
            c.push([(h >> 3) as u8, (h >> 11) as u8, (h >> 19) as u8]);
        }
    }
    PointCloud::new(glam::DVec3::ZERO, p.into(), None, Some(c.into()), None).unwrap()
}

/// The wall seen from `x` along −y at distance 2, 128 × 96, fov 40°.
fn wall_view(x: f32) -> View {
    View {
        camera: Camera {
            position: Vec3::new(x, 2.0, 0.0),
            target: Vec3::new(x, 0.0, 0.0),
            up: Vec3::Z,
            fov_y: 40f32.to_radians(),
            near: 0.1,
            far: 10.0,
        },
        width: 128,
        height: 96,
    }
}

#[test]
fn a_sideways_step_of_whole_pixels_warps_to_almost_nothing() {
    let Some(gpu) = gpu_for_test("a_sideways_step_of_whole_pixels_warps_to_almost_nothing") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let wall = textured_wall();
    let mut m = full(&wall, tmp.path());
    // Two pixels per frame at the wall's depth 2: 2 · 2 / k with k = 96 / (2 tan 20°). The
    // camera steps along −x, the screen's right for a camera looking down −y with z up.
    let step = 2.0 * 2.0 / wall_view(0.0).proj_scale();
    let s = RenderSettings {
        shade: Shade {
            shading: Shading::Colour,
            ..Shade::default()
        },
        ..settings(128, 96, Kernel::Square)
    };
    let mut r = renderer(&gpu, s);
    let mut metrics = PathMetrics::new();
    let mut previous: Option<Image> = None;
    for i in 0..9 {
        let view = wall_view(-step * i as f32);
        let (img, depth) = draw(&mut r, m.as_mut(), &view);
        assert!(
            img.rgba.chunks(4).all(|p| p[3] > 0),
            "the wall fills the frame"
        );
        if let Some(prev) = &previous {
            // As drawn, consecutive frames differ everywhere the texture moved (measured
            // 0.443–0.446 on llvmpipe).
            let plain = harness::metrics::flip_mean(prev, &img).unwrap();
            assert!(plain > 0.2, "frame {i}: unwarped FLIP {plain}");
        }
        previous = Some(img.clone());
        let f = metrics
            .frame_warped(&view, depth, img.clone(), img)
            .unwrap();
        for (lag, w) in LAGS.iter().zip(f.warped) {
            let Some(w) = w else {
                assert!(i < *lag);
                continue;
            };
            // Motion removed: frame i − k moved by 2k pixels is frame i but for the 2k
            // columns that entered at the right (masked) and pixels whose centre lies within
            // rounding of a splat edge, which another rasteriser may round otherwise. Bound:
            // FLIP 0.005, the example (measured on llvmpipe: exactly 0, the
            // rasteriser is shift-invariant here); and the valid share (128 − 2k) / 128
            // within a column (measured: exactly).
            assert!(
                w.method <= 0.005,
                "frame {i}, lag {lag}: warped FLIP {}",
                w.method
            );
            assert_eq!(w.popping(), 0.0, "full is the reference");
            let valid = (128 - 2 * lag) as f64 / 128.0;
            assert!(
                (w.valid - valid).abs() <= 1.0 / 128.0,
                "frame {i}, lag {lag}: {} valid, {valid} expected",
                w.valid
            );
        }
    }
}

#[test]
fn the_reference_depth_and_its_warps_match_the_cpu_mirror() {
    let Some(gpu) = gpu_for_test("the_reference_depth_and_its_warps_match_the_cpu_mirror") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(6_000, 11).unwrap();
    let mut m = full(&cloud, tmp.path());
    // Two views of a 48-frame orbit, 7.5° apart.
    let views = [3, 4].map(|i| View {
        camera: PathSpec::parse("orbit")
            .unwrap()
            .camera(i, 48, &cloud.bounds()),
        width: 200,
        height: 150,
    });
    let cases = Kernel::ALL
        .iter()
        .map(|&k| (Raster::Quads, k))
        .chain([(Raster::Compute, Kernel::Square)]);
    for (raster, kernel) in cases {
        let mut r = renderer(
            &gpu,
            RenderSettings {
                raster,
                ..settings(200, 150, kernel)
            },
        );
        let mut gpu_depths = Vec::new();
        let mut cpu_depths = Vec::new();
        for v in &views {
            let list = m
                .frame(v, Target::Tolerance(1.0), &Feedback::default())
                .unwrap();
            r.draw(v, &list, m.as_ref(), false).unwrap();
            let g = r.read_depth(v).unwrap();
            let c =
                cpu::render_with(v, &list, m.as_ref(), kernel, &Shade::default(), raster).unwrap();
            let c = DepthImage::from_ndc(v, &c.depth);
            let both: Vec<(f32, f32)> = g
                .depth
                .iter()
                .zip(&c.depth)
                .filter(|(a, b)| a.is_finite() && b.is_finite())
                .map(|(a, b)| (*a, *b))
                .collect();
            assert!(
                both.len() > 2_000,
                "{raster:?}/{kernel:?}: {} px",
                both.len()
            );
            // Where both cover a pixel, one depth (the same plane interpolated; f32 rounds
            // to ≤ 3·10⁻⁷ of it, measured) but where the two rasterisers let different
            // splats win an edge pixel: measured on llvmpipe ≤ 32 of 5,221 pixels (0.61 %,
            // squares sized by radius, whose edges are the most pixels), 0–1 for the other
            // kernels. Gate: 1.5 %, 2.5 × that.
            let off = both
                .iter()
                .filter(|(a, b)| (a - b).abs() / b > 1e-5)
                .count();
            assert!(
                off as f64 <= 0.015 * both.len() as f64,
                "{raster:?}/{kernel:?}: depths differ on {off} of {} pixels",
                both.len()
            );
            gpu_depths.push(g);
            cpu_depths.push(c);
        }
        let wg = Warp::new(&views[1], &gpu_depths[1], &views[0], &gpu_depths[0]).unwrap();
        let wc = Warp::new(&views[1], &cpu_depths[1], &views[0], &cpu_depths[0]).unwrap();
        let differ = (0..wg.pixels())
            .filter(|&k| wg.is_valid(k) != wc.is_valid(k))
            .count();
        assert!(
            wg.valid() > 2_000,
            "{raster:?}/{kernel:?}: {} valid",
            wg.valid()
        );
        // The warps (the masks, and so the source pixels) from the two depths: identical on
        // llvmpipe for every kernel; they may differ where coverage does (MIRROR_COVERAGE
        // of render.rs: 0.25 % of the covered pixels) in both frames: twice that.
        let share = differ as f64 / wg.valid().max(wc.valid()) as f64;
        assert!(
            share <= 0.005,
            "{raster:?}/{kernel:?}: masks differ on {differ} px"
        );
    }
}
