//! Render tests on whatever adapter exists (lavapipe in CI; "skipped: no adapter" printed
//! loudly when there is none, a failure when `SPLATBENCH_REQUIRE_GPU=1`).
//!
//! - GPU output agrees with the CPU mirror (`render::cpu`) for every kernel (square, circle,
//!   ellipse, gaussian) and both size modes: coverage differs only on pixels whose centre is within rounding of a splat edge.
//! - Golden images per kernel (a dense statue, and a sparse one whose 6 px splats show their
//!   shape), each with the adapter that blessed it beside it (`<name>.adapter.json`): on that
//!   adapter the render must equal the golden byte for byte; on another, the FLIP error over
//!   the covered pixels must pass a mean and a per-pixel gate (`common::check_golden`) that a
//!   wrong kernel fails (`a_wrong_kernel_fails_the_circle_golden`). Regenerate with
//!   `SPLATBENCH_BLESS=1 cargo test -p harness --test render`; on failure `-actual` and
//!   `-difference` images go to `target/golden-failures/`.
//! - Timestamps, odd resolutions (row padding), attribute-free scenes shaded flat.
#![allow(clippy::unwrap_used)]

mod common;
use common::{
    GOLDEN_MEAN_FLIP, check_golden, disagreement, front_view, full, settings, stream, view,
    with_pixel_size,
};

use harness::gpu::{Gpu, gpu_for_test};
use harness::image::Image;
use harness::render::{BASE_COLOR, Kernel, Raster, RenderSettings, Renderer, Shade, Shading, cpu};
use methods::{
    DrawItem, DrawList, Feedback, LodMethod, MethodKind, Params, SplatBatch, SplatSize, Target,
};
use scenes::generators::Generator;
use scenes::paths::PathSpec;
use scenes::{PointCloud, View};

/// The GPU/CPU-mirror coverage gate: the share of the pixels covered in either image whose
/// coverage differs. Measured on llvmpipe: at most 0.055 % (square splats sized by radius:
/// pixels whose centre lies within rounding of an edge), 0 for the other kernels; the
/// mirror of another shape differs on 1.4–15 % (squares for circles: 1.4 % with 3 px
/// splats). A quarter of a percent is 4.5 × the largest measured and 5 × below a wrong shape.
const MIRROR_COVERAGE: f64 = 0.0025;

#[test]
fn gpu_matches_cpu_mirror() {
    let Some(gpu) = gpu_for_test("gpu_matches_cpu_mirror") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(6_000, 11).unwrap();
    let mut m = full(&cloud, tmp.path());
    let v = view(&cloud, 200, 150, 1);
    let radius_list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    let px_list = with_pixel_size(&radius_list, 3.0);
    for &kernel in Kernel::ALL {
        let mut r = Renderer::new(&gpu, settings(200, 150, kernel)).unwrap();
        for (name, list) in [("radius", &radius_list), ("pixels", &px_list)] {
            let (stats, img) = r.draw(&v, list, m.as_ref(), true).unwrap();
            assert_eq!(stats.points, 6_000);
            let img = img.unwrap();
            let reference = cpu::rasterize(&v, list, m.as_ref(), kernel).unwrap();
            let covered = reference.rgba.chunks(4).filter(|p| p[3] > 0).count();
            assert!(
                covered > 2_000,
                "{name}/{kernel:?}: the view should show the statue ({covered} px)"
            );
            let (cov, col) = disagreement(&img, &reference);
            assert!(
                cov < MIRROR_COVERAGE,
                "{name}/{kernel:?}: coverage differs on {:.3} % of pixels",
                cov * 100.0
            );
            // The bound tells shapes apart: the mirror of another shape disagrees by more.
            for other in Kernel::ALL {
                let same_shape = matches!(
                    (kernel, *other),
                    (Kernel::Circle, Kernel::Gaussian) | (Kernel::Gaussian, Kernel::Circle)
                );
                if *other != kernel && !same_shape {
                    let wrong = cpu::rasterize(&v, list, m.as_ref(), *other).unwrap();
                    let (c, _) = disagreement(&img, &wrong);
                    assert!(
                        c > 4.0 * MIRROR_COVERAGE,
                        "{name}/{kernel:?} against a {other:?} mirror: only {c}"
                    );
                }
            }
            // The gaussian accumulates in f16 on the GPU, f32 here: a little more colour slack.
            let max_col = if kernel == Kernel::Gaussian { 3.0 } else { 2.0 };
            assert!(
                col < max_col,
                "{name}/{kernel:?}: mean colour difference {col}"
            );
        }
    }
}

#[test]
fn golden_image_per_kernel() {
    let Some(gpu) = gpu_for_test("golden_image_per_kernel") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(20_000, 5).unwrap();
    let mut m = full(&cloud, tmp.path());
    let v = view(&cloud, 128, 128, 0);
    let list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    for kernel in Kernel::ALL {
        let mut r = Renderer::new(&gpu, settings(128, 128, *kernel)).unwrap();
        let (_, img) = r.draw(&v, &list, m.as_ref(), true).unwrap();
        check_golden(
            &gpu,
            &format!("statue-{}", kernel.name()),
            &img.unwrap(),
            GOLDEN_MEAN_FLIP,
        );
    }
}

#[test]
fn odd_sizes_flat_colour_and_timestamps() {
    let Some(gpu) = gpu_for_test("odd_sizes_flat_colour_and_timestamps") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(1_000, 1).unwrap();
    let m = full(&cloud, tmp.path());
    // 101 × 37: rows are padded to 256 bytes in the readback; the image must not shear.
    let v = front_view(101, 37);
    let mut r = Renderer::new(&gpu, settings(101, 37, Kernel::Square)).unwrap();
    let (stats, img) = r
        .draw(&v, &stream(&[[0.0, 0.0, 0.0]], None, 5.0), m.as_ref(), true)
        .unwrap();
    let img = img.unwrap();
    assert_eq!(img.rgba.len(), 101 * 37 * 4);
    // A 5 px square centred at pixel (50.5, 18.5): exactly 25 pixels, x 48..53, y 16..21.
    let covered: Vec<(u32, u32)> = (0..37)
        .flat_map(|y| (0..101).map(move |x| (x, y)))
        .filter(|&(x, y)| img.rgba[((y * 101 + x) * 4 + 3) as usize] > 0)
        .collect();
    assert_eq!(covered.len(), 25, "{covered:?}");
    assert!(
        covered
            .iter()
            .all(|&(x, y)| (48..53).contains(&x) && (16..21).contains(&y))
    );
    // No normals, no colours: flat base colour, sRGB-encoded.
    let p = &img.rgba[((18 * 101 + 50) * 4) as usize..][..4];
    let expect = (1.055 * BASE_COLOR[0].powf(1.0 / 2.4) - 0.055) * 255.0;
    assert!((p[0] as f32 - expect).abs() <= 1.0, "{p:?} vs {expect}");
    assert_eq!(
        stats.upload_bytes, 12,
        "a position-only splat uploads 12 bytes"
    );
    if gpu.timestamps {
        assert!(stats.gpu_ms.is_some_and(|t| t >= 0.0));
    }
    // A splat behind the camera draws nothing.
    let (_, img) = r
        .draw(&v, &stream(&[[0.0, 0.0, 9.0]], None, 5.0), m.as_ref(), true)
        .unwrap();
    assert!(img.unwrap().rgba.chunks(4).all(|p| p[3] == 0));
}

#[test]
fn chunk_cache_uploads_once_and_respects_budget() {
    let Some(gpu) = gpu_for_test("chunk_cache_uploads_once_and_respects_budget") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(3_000, 1).unwrap();
    let mut m = full(&cloud, tmp.path());
    let v = view(&cloud, 64, 64, 0);
    let list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    let mut r = Renderer::new(&gpu, settings(64, 64, Kernel::Square)).unwrap();
    let (a, _) = r.draw(&v, &list, m.as_ref(), false).unwrap();
    let (b, _) = r.draw(&v, &list, m.as_ref(), false).unwrap();
    // statue: positions 12 + normals 4 + radii 4 bytes per splat.
    assert_eq!(a.upload_bytes, 3_000 * 20);
    assert_eq!(b.upload_bytes, 0, "second frame hits the cache");
    assert_eq!(b.cache_bytes, 3_000 * 20);
    let _ = Gpu::new;
}

/// A method that serves one chunk of statue splats with random LOD intervals, drawn as a
/// `Sequential` prefix: exercises the vertex-stage interval test and its GPU counter.
struct IntervalMock {
    batch: SplatBatch,
}

impl LodMethod for IntervalMock {
    fn attributes(&self) -> scenes::Attributes {
        self.batch.attributes()
    }
    fn input_points(&self) -> u64 {
        self.batch.len() as u64
    }
    fn frame(
        &mut self,
        _: &View,
        _: Target,
        _: &Feedback,
    ) -> Result<DrawList, methods::MethodError> {
        Ok(DrawList::default())
    }
    fn chunk(
        &self,
        _: methods::ChunkId,
    ) -> Result<std::sync::Arc<SplatBatch>, methods::MethodError> {
        Ok(std::sync::Arc::new(self.batch.clone()))
    }
    fn stats(&self) -> methods::MethodStats {
        Default::default()
    }
}

#[test]
fn interval_test_gpu_count_equals_cpu_mirror() {
    let Some(gpu) = gpu_for_test("interval_test_gpu_count_equals_cpu_mirror") else {
        return;
    };
    let cloud = Generator::Statue.generate(20_000, 3).unwrap();
    let radii = methods::leaf::leaf_radii(&cloud);
    let mut batch = SplatBatch::from_cloud_range(&cloud, 0..cloud.len(), Some(&radii));
    let mut rng = scenes::rng::Pcg32::new(9);
    let r = cloud.bounds().radius();
    batch.lod = Some(
        (0..cloud.len())
            .map(|_| {
                let a = rng.range_f32(0.0, 4.0 * r);
                [a, a + rng.range_f32(0.0, 2.0 * r), 0.0, 0.0]
            })
            .collect(),
    );
    let m = IntervalMock { batch };
    let test: methods::SplatTest = methods::IntervalTest {
        mode: 0,
        scale: 1.0,
        overlap: 0.05 * r,
    }
    .into();
    let mut renderer = Renderer::new(&gpu, settings(160, 120, Kernel::Square)).unwrap();
    for frame in 0..4 {
        let v = view(&cloud, 160, 120, frame);
        for prefix in [20_000u32, 7_777] {
            let list = DrawList {
                items: vec![DrawItem::Sequential {
                    id: 0,
                    prefix,
                    test,
                    size: SplatSize::Radius {
                        scale: 1.0,
                        min_px: 1.0,
                    },
                }],
                ..Default::default()
            };
            let (stats, img) = renderer.draw(&v, &list, &m, true).unwrap();
            let cpu_count = (0..prefix as usize)
                .filter(|&i| cpu::splat_passes(&m.batch, i, &test, v.camera.position))
                .count() as u64;
            assert_eq!(stats.points, prefix as u64);
            assert_eq!(
                stats.gpu_passed,
                Some(cpu_count),
                "frame {frame}, prefix {prefix}"
            );
            assert!(
                cpu_count > 0 && cpu_count < prefix as u64,
                "the test must cull some: {cpu_count}"
            );
            let reference = cpu::rasterize(&v, &list, &m, Kernel::Square).unwrap();
            let (cov, _) = disagreement(&img.unwrap(), &reference);
            assert!(
                cov < 0.01,
                "coverage differs on {:.3} % of pixels",
                cov * 100.0
            );
        }
    }
}

/// Sequential Point Trees on the GPU: the vertex-stage test (interval.wgsl) passes exactly
/// the splats the CPU mirror (`methods::spt::select::interval_pass`) passes, in both error
/// modes, with and without normal clusters, on several views and tolerances.
#[test]
fn spt_gpu_pass_count_equals_cpu_mirror() {
    let Some(gpu) = gpu_for_test("spt_gpu_pass_count_equals_cpu_mirror") else {
        return;
    };
    let cloud = Generator::Statue.generate(30_000, 4).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    for (k, params) in [vec![], vec!["mode=split"], vec!["normal_clusters=true"]]
        .into_iter()
        .enumerate()
    {
        let dir = tmp.path().join(k.to_string());
        let params = Params::parse(&params).unwrap();
        MethodKind::Spt
            .build(&cloud, &params, "test", &dir, &scenes::NoProgress)
            .unwrap();
        let mut spt =
            methods::spt::Spt::open(&dir, methods::Manifest::read(&dir).unwrap()).unwrap();
        let mut r = Renderer::new(&gpu, settings(200, 150, Kernel::Square)).unwrap();
        let zoom = PathSpec::parse("zoom").unwrap();
        let views = [
            view(&cloud, 200, 150, 0),
            view(&cloud, 200, 150, 3),
            View {
                camera: zoom.camera(6, 10, &cloud.bounds()),
                width: 200,
                height: 150,
            },
        ];
        for v in &views {
            for eps in [0.5f32, 1.0, 4.0] {
                let list = spt
                    .frame(v, Target::Tolerance(eps), &Feedback::default())
                    .unwrap();
                let cpu = spt.cpu_passed_in(v, &list).len() as u64;
                let (stats, _) = r.draw(v, &list, &spt, false).unwrap();
                assert_eq!(stats.gpu_passed, Some(cpu), "{params:?} eps {eps}");
                assert!(cpu <= stats.points);
            }
        }
    }
}

/// `shade` with the statue's local Z range (the runner uses the framed box's).
fn shade_of(cloud: &PointCloud, shading: Shading) -> Shade {
    let b = cloud.bounds();
    Shade {
        shading,
        elevation: [b.min.z, b.max.z],
        ..Shade::default()
    }
}

/// Luma standard deviation over the covered pixels of `img`.
fn covered_luma_std(img: &Image) -> f64 {
    let l: Vec<f64> = img
        .rgba
        .chunks(4)
        .filter(|p| p[3] > 0)
        .map(|p| 0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64)
        .collect();
    let mean = l.iter().sum::<f64>() / l.len().max(1) as f64;
    (l.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / l.len().max(1) as f64).sqrt()
}

/// Every shading mode: the GPU agrees with the CPU mirror (coverage as in
/// `gpu_matches_cpu_mirror`, colour within 2 levels on average; EDL adds one rounding of its
/// own); EDL keeps coverage and gives a bare scene structure a flat base colour lacks; the
/// elevation ramp spans its stops.
#[test]
fn shading_modes_match_cpu_mirror() {
    let Some(gpu) = gpu_for_test("shading_modes_match_cpu_mirror") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    // Bare: positions and radii only, like a LiDAR tile without RGB.
    let cloud = Generator::Statue
        .generate(6_000, 11)
        .unwrap()
        .without_normals();
    let mut m = full(&cloud, tmp.path());
    let v = view(&cloud, 160, 120, 1);
    let list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    let mut images = std::collections::HashMap::new();
    for shading in [
        Shading::Lambert,
        Shading::Colour,
        Shading::Edl,
        Shading::Elevation,
    ] {
        // The compute rasteriser shades the same way and resolves depth for EDL.
        for (kernel, raster) in [
            (Kernel::Square, Raster::Quads),
            (Kernel::Gaussian, Raster::Quads),
            (Kernel::Square, Raster::Compute),
        ] {
            let shade = shade_of(&cloud, shading);
            let mut r = Renderer::new(
                &gpu,
                RenderSettings {
                    shade,
                    raster,
                    ..settings(160, 120, kernel)
                },
            )
            .unwrap();
            let (_, img) = r.draw(&v, &list, m.as_ref(), true).unwrap();
            let img = img.unwrap();
            let reference = cpu::render_with(&v, &list, m.as_ref(), kernel, &shade, raster)
                .unwrap()
                .image;
            let (cov, col) = disagreement(&img, &reference);
            assert!(
                cov < 0.01,
                "{shading}/{kernel:?}/{raster:?}: coverage differs on {cov:.4}"
            );
            let max_col = if kernel == Kernel::Gaussian { 3.0 } else { 2.0 };
            assert!(
                col < max_col,
                "{shading}/{kernel:?}/{raster:?}: mean colour difference {col}"
            );
            if raster == Raster::Quads {
                images.insert((shading, kernel), img);
            }
        }
    }
    let flat = &images[&(Shading::Colour, Kernel::Square)];
    let edl = &images[&(Shading::Edl, Kernel::Square)];
    assert_eq!(
        disagreement(flat, edl).0,
        0.0,
        "EDL must not change coverage"
    );
    // Flat: one colour (std 0). EDL: depth edges darken (72.3 levels measured on llvmpipe, GL
    // and Vulkan alike; 20 leaves room for another rasteriser and still rules out flat).
    assert_eq!(covered_luma_std(flat), 0.0);
    let s = covered_luma_std(edl);
    eprintln!("EDL luma std over covered pixels: {s:.2}");
    assert!(s > 20.0, "EDL shows no structure: luma std {s:.2}");
    assert!(
        edl.rgba
            .chunks(4)
            .zip(flat.rgba.chunks(4))
            .all(|(e, f)| (0..3).all(|c| e[c] <= f[c])),
        "EDL only darkens"
    );
    // Elevation: the covered pixels span the ramp from its first stop to near its last.
    let el = &images[&(Shading::Elevation, Kernel::Square)];
    let blues: Vec<u8> = el
        .rgba
        .chunks(4)
        .filter(|p| p[3] > 0)
        .map(|p| p[2])
        .collect();
    let (lo, hi) = (*blues.iter().min().unwrap(), *blues.iter().max().unwrap());
    assert!(
        lo < 60 && hi > 130,
        "elevation blue channel spans {lo}..{hi}"
    );
}

#[test]
fn golden_edl() {
    let Some(gpu) = gpu_for_test("golden_edl") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue
        .generate(20_000, 5)
        .unwrap()
        .without_normals();
    let mut m = full(&cloud, tmp.path());
    let v = view(&cloud, 128, 128, 0);
    let list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    for (shading, name) in [
        (Shading::Edl, "statue-edl"),
        (Shading::Elevation, "statue-elevation"),
    ] {
        let mut r = Renderer::new(
            &gpu,
            RenderSettings {
                shade: shade_of(&cloud, shading),
                ..settings(128, 128, Kernel::Square)
            },
        )
        .unwrap();
        let (_, img) = r.draw(&v, &list, m.as_ref(), true).unwrap();
        check_golden(&gpu, name, &img.unwrap(), GOLDEN_MEAN_FLIP);
    }
}

/// `DrawItem::Chunk { first, points }` draws exactly splats `first .. first + points`: a
/// chunk drawn in two ranges gives the image of the whole chunk, and a range gives the image
/// of a stream holding only its splats; with the quads and the compute rasteriser, and the
/// CPU mirror agrees.
#[test]
fn chunk_ranges_draw_exactly_their_splats() {
    let Some(gpu) = gpu_for_test("chunk_ranges_draw_exactly_their_splats") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(6_000, 11).unwrap();
    let m = full(&cloud, tmp.path());
    let v = view(&cloud, 200, 150, 1);
    let chunk = m.chunk(0).unwrap();
    assert_eq!(chunk.len(), 6_000);
    let item = |first: u32, points: u32, px: f32| DrawItem::Chunk {
        id: 0,
        first,
        points,
        size: SplatSize::Pixels(px),
    };
    let list = |items: Vec<DrawItem>| DrawList {
        items,
        ..Default::default()
    };
    let whole = list(vec![item(0, 6_000, 3.0)]);
    let halves = list(vec![item(0, 2_500, 3.0), item(2_500, 3_500, 3.0)]);
    let range = list(vec![item(1_000, 2_000, 6.0)]);
    let slice = SplatBatch {
        positions: chunk.positions[1_000..3_000].to_vec(),
        normals: chunk.normals.as_ref().map(|n| n[1_000..3_000].to_vec()),
        colors: chunk.colors.as_ref().map(|c| c[1_000..3_000].to_vec()),
        radii: chunk.radii.as_ref().map(|r| r[1_000..3_000].to_vec()),
        lod: None,
    };
    let stream = list(vec![DrawItem::Stream {
        batch: slice,
        size: SplatSize::Pixels(6.0),
    }]);
    for raster in [Raster::Quads, Raster::Compute] {
        let s = RenderSettings {
            raster,
            ..settings(200, 150, Kernel::Square)
        };
        let mut r = Renderer::new(&gpu, s).unwrap();
        let mut draw = |l: &DrawList| {
            let (stats, img) = r.draw(&v, l, m.as_ref(), true).unwrap();
            (stats.points, img.unwrap())
        };
        let (n_whole, a) = draw(&whole);
        let (n_halves, b) = draw(&halves);
        assert_eq!((n_whole, n_halves), (6_000, 6_000));
        assert!(
            a.rgba == b.rgba,
            "{raster:?}: two ranges differ from the whole chunk"
        );
        let (n_range, c) = draw(&range);
        let (_, d) = draw(&stream);
        assert_eq!(n_range, 2_000);
        assert!(
            c.rgba == d.rgba,
            "{raster:?}: a range differs from a stream of its splats"
        );
        assert!(
            c.rgba != a.rgba,
            "{raster:?}: the range drew the whole chunk"
        );
        let mirror = cpu::rasterize(&v, &range, m.as_ref(), Kernel::Square).unwrap();
        let (cov, _) = disagreement(&c, &mirror);
        assert!(
            cov < 0.01,
            "{raster:?}: the CPU mirror's range differs on {cov}"
        );
    }
}

/// QSplat §4.3's elliptical splats: "the ratio of minor to major axes will equal n̂ · v̂",
/// the minor axis along the projected normal, and "clamping the maximum ratio of major to
/// minor axis to 10". One 101 px splat at the centre of a front view (v̂ = +z), its normal
/// tilted by θ towards +y or +x: the covered extent along the tilt ÷ across it is
/// max(cos θ, 1/clamp) for the paper's clamp 10 and for 4, on the GPU and in the CPU mirror, within 2.5 px of 101 (a pixel of
/// rounding at each end of each extent).
#[test]
fn ellipse_axis_ratio_is_n_dot_v_clamped_at_a_tenth() {
    let Some(gpu) = gpu_for_test("ellipse_axis_ratio_is_n_dot_v_clamped_at_a_tenth") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(1_000, 1).unwrap();
    let m = full(&cloud, tmp.path());
    let (w, h, size) = (121u32, 121u32, 101.0f32);
    let v = front_view(w, h);
    // Covered pixels along the centre row (x) and the centre column (y).
    let extents = |img: &Image| {
        let along_x = (0..w).filter(|&x| img.pixel(x, h / 2)[3] > 0).count() as f32;
        let along_y = (0..h).filter(|&y| img.pixel(w / 2, y)[3] > 0).count() as f32;
        (along_x, along_y)
    };
    // QSplat's clamp (10) and another (`--ellipse-clamp 4`): the ratio never falls below 1/clamp.
    for clamp in [harness::render::ELLIPSE_CLAMP, 4.0] {
        let shade = Shade {
            ellipse_clamp: clamp,
            ..Shade::default()
        };
        let mut r = Renderer::new(
            &gpu,
            RenderSettings {
                shade,
                ..settings(w, h, Kernel::Ellipse)
            },
        )
        .unwrap();
        for deg in [0.0f32, 60.0, 80.0, 89.0] {
            let t = deg.to_radians();
            let want = t.cos().max(1.0 / clamp);
            for (tilt_y, n) in [
                (true, glam::Vec3::new(0.0, t.sin(), t.cos())),
                (false, glam::Vec3::new(t.sin(), 0.0, t.cos())),
            ] {
                let mut list = stream(&[[0.0, 0.0, 0.0]], None, size);
                if let DrawItem::Stream { batch, .. } = &mut list.items[0] {
                    batch.normals = Some(vec![methods::octnormal::encode(n)]);
                }
                let (_, img) = r.draw(&v, &list, m.as_ref(), true).unwrap();
                let gpu_img = img.unwrap();
                let cpu_img =
                    cpu::rasterize_shaded(&v, &list, m.as_ref(), Kernel::Ellipse, &shade).unwrap();
                for (who, img) in [("gpu", &gpu_img), ("cpu", &cpu_img)] {
                    let (ex, ey) = extents(img);
                    let (minor, major) = if tilt_y { (ey, ex) } else { (ex, ey) };
                    assert!(
                        (major - size).abs() <= 2.5,
                        "{who} θ = {deg}°: major axis {major} px, not {size}"
                    );
                    let ratio = minor / major;
                    assert!(
                        (ratio - want).abs() <= 2.5 / size,
                        "{who} θ = {deg}°, clamp {clamp} (tilt towards {}): minor/major {ratio}, want {want}",
                        if tilt_y { "y" } else { "x" }
                    );
                }
            }
        }
    }
}

/// The kernel goldens' scene: a 2,000-sample statue drawn with 6 px splats at 128², sparse
/// enough that each splat's shape shows (on the dense 20 K statue, 2–3 px splats overlap and
/// squares drawn for circles change 0.5 % of the covered pixels: less than a quarter-pixel
/// shift of the camera does).
fn sparse_render(gpu: &Gpu, kernel: Kernel, v: Option<View>) -> Image {
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(2_000, 5).unwrap();
    let mut m = full(&cloud, tmp.path());
    let v = v.unwrap_or_else(|| view(&cloud, 128, 128, 0));
    let list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    let list = with_pixel_size(&list, 6.0);
    let mut r = Renderer::new(gpu, settings(128, 128, kernel)).unwrap();
    r.draw(&v, &list, m.as_ref(), true).unwrap().1.unwrap()
}

#[test]
fn golden_sparse_image_per_kernel() {
    let Some(gpu) = gpu_for_test("golden_sparse_image_per_kernel") else {
        return;
    };
    for &kernel in Kernel::ALL {
        let img = sparse_render(&gpu, kernel, None);
        check_golden(
            &gpu,
            &format!("statue-sparse-{}", kernel.name()),
            &img,
            GOLDEN_MEAN_FLIP,
        );
    }
}

/// The goldens tell a wrong kernel from a right one (issue 36): on the sparse scene, squares,
/// ellipses or gaussians drawn where the circle golden is expected fail both the
/// same-adapter comparison (not byte for byte) and the cross-adapter one
/// (`common::cross_adapter_mismatch`: mean FLIP and the share of covered pixels above a
/// per-pixel gate, over the covered pixels only); the circles pass both, and so does the
/// same view with the camera moved sideways by a tenth and by a quarter of a pixel (what
/// another rasteriser's rounding can do to splat edges, generously).
#[test]
fn a_wrong_kernel_fails_the_circle_golden() {
    let Some(gpu) = gpu_for_test("a_wrong_kernel_fails_the_circle_golden") else {
        return;
    };
    let golden = Image::load_png(&common::golden_dir().join("statue-sparse-circle.png")).unwrap();
    let circle = sparse_render(&gpu, Kernel::Circle, None);
    assert_eq!(
        circle.rgba, golden.rgba,
        "the golden is this adapter's render"
    );
    let cross = |img: &Image| common::cross_adapter_mismatch(&golden, img, GOLDEN_MEAN_FLIP);
    assert_eq!(cross(&circle), None);
    let cloud = Generator::Statue.generate(2_000, 5).unwrap();
    let v = view(&cloud, 128, 128, 0);
    let right = v.camera.forward().cross(v.camera.up).normalize();
    let px =
        2.0 * (v.camera.position - v.camera.target).length() * (v.camera.fov_y * 0.5).tan() / 128.0;
    for shift in [0.1f32, 0.25] {
        let mut moved = v;
        moved.camera.position += right * shift * px;
        moved.camera.target += right * shift * px;
        let img = sparse_render(&gpu, Kernel::Circle, Some(moved));
        assert_ne!(img.rgba, golden.rgba);
        let stats = common::golden_stats(&golden, &img);
        assert_eq!(cross(&img), None, "a {shift} px shift: {stats:?}");
    }
    for kernel in [Kernel::Square, Kernel::Ellipse, Kernel::Gaussian] {
        let wrong = sparse_render(&gpu, kernel, None);
        assert_ne!(wrong.rgba, golden.rgba);
        let stats = common::golden_stats(&golden, &wrong);
        assert!(
            cross(&wrong).is_some(),
            "{kernel:?} passes for circles: {stats:?}"
        );
    }
}
