//! CLOD on the GPU (`clod.wgsl`): the filter passes exactly the points its CPU mirror
//! (`methods::clod::select`) keeps, and the faded, distance-sized points cover the pixels
//! the CPU mirror of the rasteriser covers: exactly with the compute rasteriser, and with the
//! quads but for pixels whose centre lies within the rasteriser's snapping of an edge; under a
//! budget, what passes on the GPU is what the mirror counts, within the budget.
#![allow(clippy::unwrap_used)]

mod common;
use common::{settings, view};

use harness::gpu::gpu_for_test;
use harness::render::{Kernel, Raster, Renderer, cpu};
use methods::clod::Clod;
use methods::{Feedback, LodMethod, Manifest, MethodKind, Params, Target};
use scenes::View;
use scenes::generators::Generator;
use scenes::paths::PathSpec;

/// Pixels whose centre lies within 2^-SUBPIXEL_BITS px of an edge of a kept point's square:
/// the fixed-function rasteriser snaps the quads' corners to that grid, the CPU mirror uses
/// exact floats, so only these pixels may be covered in one image and not the other. CLOD's
/// faded points are often below a pixel, where such pixels are a large share of the covered
/// ones (a 0.3 px square covers a centre with probability 0.09 and has one within 1/256 px of
/// an edge with probability ≈ 0.005), hence this bound instead of `render.rs`'s fraction.
fn borderline(v: &View, m: &Clod, list: &methods::DrawList) -> std::collections::HashSet<usize> {
    let delta = 1.0 / (1u32 << cpu::SUBPIXEL_BITS) as f32;
    let (w, h) = (v.width as i64, v.height as i64);
    let mut out = std::collections::HashSet::new();
    for (cx, cy, half) in cpu::squares(v, list, m).unwrap() {
        let near =
            |c: f32, x: f32| ((x - (c - half)).abs() <= delta) || ((x - (c + half)).abs() <= delta);
        let inside = |c: f32, q: f32| (q - c).abs() <= half + delta;
        let x0 = ((cx - half - delta - 0.5).floor() as i64).max(0);
        let x1 = ((cx + half + delta - 0.5).ceil() as i64).min(w - 1);
        let y0 = ((cy - half - delta - 0.5).floor() as i64).max(0);
        let y1 = ((cy + half + delta - 0.5).ceil() as i64).min(h - 1);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (xc, yc) = (x as f32 + 0.5, y as f32 + 0.5);
                if inside(cx, xc) && inside(cy, yc) && (near(cx, xc) || near(cy, yc)) {
                    out.insert((y * w + x) as usize);
                }
            }
        }
    }
    out
}

/// Pixels covered in one image and not in the other.
fn coverage_differs(a: &harness::image::Image, b: &harness::image::Image) -> Vec<usize> {
    a.rgba
        .chunks(4)
        .zip(b.rgba.chunks(4))
        .enumerate()
        .filter(|(_, (pa, pb))| (pa[3] > 0) != (pb[3] > 0))
        .map(|(i, _)| i)
        .collect()
}

/// Exact pass counts hold on lavapipe (IEEE f32, no contraction into fused multiply-adds):
/// an adapter that fuses or rounds division and square roots differently may decide a point
/// within an ulp of the boundary the other way.
#[test]
fn clod_gpu_pass_count_and_coverage_equal_the_cpu_mirror() {
    let Some(gpu) = gpu_for_test("clod_gpu_pass_count_and_coverage_equal_the_cpu_mirror") else {
        return;
    };
    let cloud = Generator::Statue.generate(20_000, 8).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let zoom = PathSpec::parse("zoom").unwrap();
    let views = [
        view(&cloud, 200, 150, 0),
        view(&cloud, 200, 150, 2),
        View {
            camera: zoom.camera(7, 10, &cloud.bounds()),
            width: 200,
            height: 150,
        },
    ];
    for (k, params) in [vec![], vec!["fovea=0", "point_size=0.5"]]
        .into_iter()
        .enumerate()
    {
        let dir = tmp.path().join(k.to_string());
        let params = Params::parse(&params).unwrap();
        MethodKind::Clod
            .build(&cloud, &params, "t", &dir, &scenes::NoProgress)
            .unwrap();
        let mut manifest = Manifest::read(&dir).unwrap();
        manifest.params = params.clone();
        let mut m = Clod::open(&dir, manifest).unwrap();
        for raster in [Raster::Quads, Raster::Compute] {
            let s = harness::render::RenderSettings {
                raster,
                ..settings(200, 150, Kernel::Square)
            };
            let mut r = Renderer::new(&gpu, s).unwrap();
            for (vi, v) in views.iter().enumerate() {
                for eps in [0.2f32, 0.4, 0.8] {
                    let what = format!("{params:?} {raster:?} view {vi} eps {eps}");
                    let list = m
                        .frame(v, Target::Tolerance(eps), &Feedback::default())
                        .unwrap();
                    let kept = m.count_kept(v, eps / v.proj_scale());
                    let (stats, img) = r.draw(v, &list, &m, true).unwrap();
                    assert_eq!(stats.gpu_passed, Some(kept), "{what}");
                    assert_eq!(stats.points, cloud.len() as u64, "{what}: all sent");
                    assert!(0 < kept && kept < stats.points, "{what}: kept {kept}");
                    let reference =
                        cpu::render_with(v, &list, &m, Kernel::Square, &Default::default(), raster)
                            .unwrap()
                            .image;
                    let img = img.unwrap();
                    let differ = coverage_differs(&img, &reference);
                    match raster {
                        // The compute rasteriser and its mirror test the same float centres.
                        Raster::Compute => assert!(differ.is_empty(), "{what}: {differ:?}"),
                        Raster::Quads => {
                            let edge = borderline(v, &m, &list);
                            let off: Vec<_> = differ.iter().filter(|i| !edge.contains(i)).collect();
                            assert!(
                                off.is_empty(),
                                "{what}: {} of {} differing pixels are not on an edge: {off:?}",
                                off.len(),
                                differ.len()
                            );
                        }
                    }
                }
                // Budgets on the GPU: what passes the filter there is what the mirror counts,
                // and never more than the budget.
                for b in [300u64, 3_000] {
                    let what = format!("{params:?} {raster:?} view {vi} budget {b}");
                    let list = m.frame(v, Target::Budget(b), &Feedback::default()).unwrap();
                    let (stats, _) = r.draw(v, &list, &m, false).unwrap();
                    let mirror = m.drawn_points(v, &list).unwrap();
                    assert_eq!(stats.gpu_passed, Some(mirror), "{what}");
                    assert!(0 < mirror && mirror <= b, "{what}: {mirror} passed");
                }
            }
        }
    }
}

/// `clod.wgsl`'s constants are `methods::clod::select`'s (the port is line for line).
#[test]
fn the_shader_constants_are_the_mirrors() {
    use methods::clod::select as s;
    for (name, v) in [
        ("CLOD_FOVEA_FLOOR", s::FOVEA_FLOOR),
        ("CLOD_EXTENT", s::EXTENT),
        ("CLOD_BLEND", s::BLEND),
        ("CLOD_SIZE_FACTOR", s::SIZE_FACTOR),
        ("CLOD_MIN_PX", s::MIN_PX),
        ("CLOD_MAX_PX", s::MAX_PX),
        ("CLOD_FINAL", s::FINAL),
        ("CLOD_POINT_MIN_PX", s::POINT_MIN_PX),
    ] {
        let line = format!("const {name}: f32 = {v:?};");
        assert!(harness::render::SPLAT_WGSL.contains(&line), "{line}");
    }
}

/// A draw item with CLOD's sizes but another test (or none) is an error naming it, on the GPU
/// and in the CPU mirror, never a silent 1 px or 0 px size.
#[test]
fn clod_sizes_without_clods_test_are_refused() {
    let cloud = Generator::Statue.generate(2_000, 9).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    MethodKind::Clod
        .build(
            &cloud,
            &Params::default(),
            "t",
            tmp.path(),
            &scenes::NoProgress,
        )
        .unwrap();
    let mut m = Clod::open(tmp.path(), Manifest::read(tmp.path()).unwrap()).unwrap();
    let v = view(&cloud, 64, 64, 0);
    let mut list = m
        .frame(&v, Target::Tolerance(0.5), &Feedback::default())
        .unwrap();
    for item in &mut list.items {
        if let methods::DrawItem::Sequential { test, .. } = item {
            *test = methods::IntervalTest {
                mode: 0,
                scale: 1.0,
                overlap: 0.0,
            }
            .into();
        }
    }
    let e = cpu::rasterize(&v, &list, &m, Kernel::Square).unwrap_err();
    assert!(
        e.to_string().contains("CLOD's sizes without CLOD's test"),
        "{e}"
    );
    let Some(gpu) = gpu_for_test("clod_sizes_without_clods_test_are_refused") else {
        return;
    };
    let mut r = Renderer::new(&gpu, settings(64, 64, Kernel::Square)).unwrap();
    let e = r.draw(&v, &list, &m, false).unwrap_err();
    assert!(
        format!("{e:#}").contains("CLOD's sizes without CLOD's test"),
        "{e:#}"
    );
}
