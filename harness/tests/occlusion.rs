//! Three-phase occlusion culling (LPC §4) in the renderer and its CPU mirror, on constructed
//! scenes served by a test double [`Walls`]: a big near "wall" chunk, a small cloud straight
//! behind it, one beside it, and a few more placed for single checks.
//!
//! GPU tests run on whatever adapter exists ("skipped: no adapter" printed loudly when there
//! is none, a failure when `SPLATBENCH_REQUIRE_GPU=1`). GPU and CPU must take the same
//! visible/occluded decision for every candidate; their sample counts may differ by
//! [`COUNT_SLACK`] pixels (rasteriser precision on the icosahedron's and the splats' edges),
//! and the scenes keep every count far from its threshold, so no decision needs a tolerance.
#![allow(clippy::unwrap_used)]

mod common;
mod occlusion_scene;
use common::disagreement;
use occlusion_scene::*;

use std::collections::HashSet;

use harness::gpu::gpu_for_test;
use harness::image::Image;
use harness::render::{FrameStats, Kernel, Raster, RenderSettings, Renderer, cpu, exact_counts};
use harness::runner;
use methods::{ChunkId, DrawList, Feedback, LodMethod, Target};
use scenes::View;

/// GPU and CPU sample counts of one query may differ by this many pixels.
const COUNT_SLACK: u64 = 8;

/// Pixels of exactly colour `rgb`.
fn pixels_of(img: &Image, rgb: [u8; 3]) -> usize {
    img.rgba
        .chunks(4)
        .filter(|p| p[3] > 0 && p[..3] == rgb)
        .count()
}

/// Draws `list` on the GPU and the CPU; checks that both take the same decision for every
/// candidate, that their counts agree within [`COUNT_SLACK`], that they draw the same splats
/// and the same image (the tolerance of `tests/render.rs`). Returns the GPU stats and image.
///
/// Where the renderer cannot count exactly ([`exact_counts`] false: wgpu's GL backend, whose
/// queries answer 0/1), counts are compared as "any sample passed".
fn draw_both(
    r: &mut Renderer<'_>,
    v: &View,
    list: &DrawList,
    m: &dyn LodMethod,
) -> (FrameStats, Image) {
    let (stats, img) = r.draw(v, list, m, true).unwrap();
    let img = img.unwrap();
    let settings = r.settings();
    let c = cpu::render_with(
        v,
        list,
        m,
        settings.kernel,
        &settings.shade,
        settings.raster,
    )
    .unwrap();
    let (go, mut co) = (stats.occlusion.as_ref().unwrap(), c.occlusion.unwrap());
    if !r.exact_counts() {
        for n in co.samples.iter_mut().flatten() {
            *n = (*n > 0) as u64;
        }
    }
    assert_eq!(go.visible, co.visible, "visible: GPU {go:?}\nCPU {co:?}");
    assert_eq!(go.occluded, co.occluded, "occluded: GPU {go:?}\nCPU {co:?}");
    assert_eq!(go.clouds_queried, co.clouds_queried);
    // The hardware query agrees with the exact fragment count on zero / non-zero.
    for (h, n) in go.query_results.iter().zip(&go.samples) {
        assert_eq!(h.map(|h| h > 0), n.map(|n| n > 0), "{go:?}");
    }
    for (g, c) in go.samples.iter().zip(&co.samples) {
        match (g, c) {
            (None, None) => {}
            (Some(g), Some(c)) => assert!(
                g.abs_diff(*c) <= COUNT_SLACK,
                "sample counts GPU {g} CPU {c}: {:?} vs {:?}",
                go.samples,
                co.samples
            ),
            _ => panic!(
                "queried on one side only: {:?} vs {:?}",
                go.samples, co.samples
            ),
        }
    }
    assert_eq!(stats.points, c.points, "splats drawn");
    assert_eq!(stats.chunks, c.chunks, "chunks drawn");
    assert_eq!(go.phase3_points, co.phase3_points);
    let (cov, col) = disagreement(&img, &c.image);
    assert!(cov < 0.01, "coverage differs on {:.3} %", cov * 100.0);
    assert!(col < 2.0, "mean colour difference {col}");
    (stats, img)
}

#[test]
fn wall_hides_the_cloud_behind_it_but_not_the_one_beside() {
    let Some(gpu) = gpu_for_test("wall_hides_the_cloud_behind_it_but_not_the_one_beside") else {
        return;
    };
    let mut m = Walls::scene();
    let v = view();
    // The wall was visible last frame: phase 1 draws it; the balls are queried against it.
    let list = m
        .frame(&v, Target::Tolerance(1.0), &feedback(&[WALL]))
        .unwrap();
    assert_eq!(list.items.len(), 1);
    // Both rasterisers: the compute one's phases 1 and 3 write the visibility buffer, its
    // resolve the depth the queries test.
    for (kernel, raster) in [
        (Kernel::Square, Raster::Quads),
        (Kernel::Circle, Raster::Quads),
        (Kernel::Square, Raster::Compute),
    ] {
        let mut r = Renderer::new(
            &gpu,
            RenderSettings {
                raster,
                ..settings(kernel)
            },
        )
        .unwrap();
        let (stats, img) = draw_both(&mut r, &v, &list, &m);
        let o = stats.occlusion.as_ref().unwrap();
        eprintln!("{kernel:?}: samples {:?}, {stats:?}", o.samples);
        assert_eq!(o.visible, vec![WALL, BESIDE], "{kernel:?}");
        assert_eq!(o.occluded, vec![BEHIND]);
        assert_eq!((o.clouds_queried, o.clouds_occluded), (3, 1));
        assert_eq!(o.samples[BEHIND as usize], Some(0));
        if exact_counts(&gpu) {
            assert!(o.samples[BESIDE as usize].unwrap() > 50, "{:?}", o.samples);
        }
        // The wall is drawn once (phase 1), the ball beside once (phase 3), the one behind
        // never: it is not even uploaded.
        assert_eq!(stats.points, m.points(&[WALL, BESIDE]));
        assert_eq!(o.phase3_points, m.points(&[BESIDE]));
        assert_eq!(stats.chunks, 2);
        assert_eq!(stats.upload_bytes, m.bytes(WALL) + m.bytes(BESIDE));
        assert_eq!(r.cached(), HashSet::from([WALL, BESIDE]));
        assert!(
            pixels_of(&img, [40, 40, 200]) > 100,
            "the ball beside shows"
        );
        assert_eq!(pixels_of(&img, [40, 200, 40]), 0);
        if gpu.timestamps {
            assert_eq!(stats.phase_gpu_ms.len(), 3);
            assert!(stats.phase_gpu_ms.iter().all(Option::is_some));
            let sum: f64 = stats.phase_gpu_ms.iter().flatten().sum();
            assert!((stats.gpu_ms.unwrap() - sum).abs() < 1e-9);
            assert_eq!(o.query_gpu_ms, stats.phase_gpu_ms[1]);
        }
    }
    // Without phase 1 nothing occludes: everything is visible and drawn in phase 3.
    let list = m
        .frame(&v, Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    let mut r = Renderer::new(&gpu, settings(Kernel::Square)).unwrap();
    let (stats, _) = draw_both(&mut r, &v, &list, &m);
    let o = stats.occlusion.unwrap();
    assert_eq!(o.visible, vec![WALL, BEHIND, BESIDE]);
    assert_eq!(stats.points, m.points(&[WALL, BEHIND, BESIDE]));
}

#[test]
fn eye_inside_or_sphere_at_the_near_plane_is_visible_without_a_query() {
    let Some(gpu) =
        gpu_for_test("eye_inside_or_sphere_at_the_near_plane_is_visible_without_a_query")
    else {
        return;
    };
    let mut m = Walls::scene();
    // 3: contains the eye (z = 5); 4: reaches the near plane (nearest point 0.05 from the
    // eye, near = 0.1) without containing the eye; both behind-the-wall-sized, in front of
    // it. 5: a big sphere centred behind the wall whose icosahedron reaches the eye.
    m.clouds.push(ball([0.0, 0.0, 4.5], 0.6, 50, [250, 250, 0]));
    m.clouds
        .push(ball([0.3, 0.0, 4.2], 0.75, 50, [0, 250, 250]));
    let mut big = ball([0.0, 0.0, -3.0], 7.5, 50, [250, 0, 250]);
    big.batch.positions = vec![[0.0, 0.0, -3.0]];
    big.batch.colors = Some(vec![color([250, 0, 250])]);
    m.clouds.push(big);
    let v = view();
    let list = m
        .frame(&v, Target::Tolerance(1.0), &feedback(&[WALL]))
        .unwrap();
    let mut r = Renderer::new(&gpu, settings(Kernel::Square)).unwrap();
    let (stats, _) = draw_both(&mut r, &v, &list, &m);
    let o = stats.occlusion.unwrap();
    assert_eq!(&o.samples[3..], &[None, None, None], "{:?}", o.samples);
    assert_eq!(o.visible, vec![WALL, BESIDE, 3, 4, 5]);
    assert_eq!(o.occluded, vec![BEHIND]);
    assert_eq!(
        o.clouds_queried, 3,
        "only the wall and the two balls are queried"
    );
    // Visible without a query still means drawn (phase 3).
    assert_eq!(stats.points, m.points(&[WALL, BESIDE, 3, 4, 5]));
}

#[test]
fn threshold_decides_a_sliver() {
    let Some(gpu) = gpu_for_test("threshold_decides_a_sliver") else {
        return;
    };
    let mut m = Walls::scene();
    // A ball mostly hidden by the wall's right edge: a sliver of its sphere shows (≈ 46 px;
    // the ball beside shows ≈ 184 px, the wall's own sphere ≈ 9,300).
    m.clouds[BEHIND as usize] = ball([2.3, 0.0, -3.0], 0.5, 400, [40, 200, 40]);
    let v = view();
    let mut r = Renderer::new(&gpu, settings(Kernel::Square)).unwrap();
    let mut sliver = 0;
    for threshold in [0, 100] {
        m.threshold = threshold;
        let list = m
            .frame(&v, Target::Tolerance(1.0), &feedback(&[WALL]))
            .unwrap();
        if threshold > 0 && !exact_counts(&gpu) {
            // Boolean queries (GL) cannot honour a threshold: a clear error, not a guess.
            let e = r.draw(&v, &list, &m, false).unwrap_err();
            assert!(e.to_string().contains("exact sample counts"), "{e}");
            return;
        }
        let (stats, _) = draw_both(&mut r, &v, &list, &m);
        let o = stats.occlusion.unwrap();
        sliver = o.samples[BEHIND as usize].unwrap();
        eprintln!("threshold {threshold}: samples {:?}", o.samples);
        if threshold == 0 {
            assert!(o.visible.contains(&BEHIND), "{o:?}");
        } else {
            assert!(o.occluded.contains(&BEHIND), "{o:?}");
            assert_eq!(stats.points, m.points(&[WALL, BESIDE]));
        }
    }
    assert!(
        sliver > COUNT_SLACK && sliver + COUNT_SLACK < 100,
        "a sliver, not hidden and not whole: {sliver} px"
    );
}

#[test]
fn feedback_carries_visibility_to_the_next_frame() {
    let Some(gpu) = gpu_for_test("feedback_carries_visibility_to_the_next_frame") else {
        return;
    };
    let mut m = Walls::scene();
    let v = view();
    let mut r = Renderer::new(&gpu, settings(Kernel::Square)).unwrap();
    let mut last: Option<(FrameStats, View)> = None;
    let mut frames = Vec::new();
    for i in 0..4u64 {
        // The runner's own feedback path.
        let fb = runner::next_feedback(i, &r, last.as_ref(), &v);
        let list = m.frame(&v, Target::Tolerance(1.0), &fb).unwrap();
        let phase1: Vec<ChunkId> = list
            .items
            .iter()
            .filter_map(|it| it.cached().map(|c| c.id))
            .collect();
        let (stats, _) = draw_both(&mut r, &v, &list, &m);
        let counters = runner::frame_counters(&m, &list, &stats, 0, Default::default());
        let o = stats.occlusion.clone().unwrap();
        frames.push((
            phase1,
            o.visible,
            o.occluded,
            stats.points,
            stats.upload_bytes,
        ));
        assert_eq!(
            counters,
            vec![3.0, o.clouds_queried as f64, o.clouds_occluded as f64]
        );
        last = Some((stats, v));
    }
    let all = m.bytes(WALL) + m.bytes(BEHIND) + m.bytes(BESIDE);
    // Frame 0: nothing in phase 1, so nothing occludes: all visible, all drawn in phase 3.
    assert_eq!(frames[0].0, Vec::<ChunkId>::new());
    assert_eq!(frames[0].1, vec![WALL, BEHIND, BESIDE]);
    assert_eq!(frames[0].3, m.points(&[WALL, BEHIND, BESIDE]));
    assert_eq!(frames[0].4, all);
    // Frame 1: last frame's visible clouds are phase 1; the ball behind, drawn in phase 1,
    // is now found occluded by the wall (drawn once all the same, never twice).
    assert_eq!(frames[1].0, vec![WALL, BEHIND, BESIDE]);
    assert_eq!(frames[1].2, vec![BEHIND]);
    assert_eq!(frames[1].3, m.points(&[WALL, BEHIND, BESIDE]));
    assert_eq!(frames[1].4, 0, "cached");
    // Frame 2 on: the occluded ball waits for its query, fails it, and is not drawn.
    for f in &frames[2..] {
        assert_eq!(f.0, vec![WALL, BESIDE]);
        assert_eq!(
            (f.1.clone(), f.2.clone()),
            (vec![WALL, BESIDE], vec![BEHIND])
        );
        assert_eq!(f.3, m.points(&[WALL, BESIDE]));
    }
    // The feedback the runner builds names them.
    let fb = runner::next_feedback(4, &r, last.as_ref(), &v);
    assert_eq!(fb.visible, HashSet::from([WALL, BESIDE]));
    assert_eq!(fb.occluded, HashSet::from([BEHIND]));
    assert!(fb.camera_still);
}

#[test]
fn occlusion_columns_only_for_occlusion_culled_methods() {
    let mut m = Walls::scene();
    assert_eq!(
        runner::frame_columns(&m),
        vec!["clouds", "clouds_queried", "clouds_occluded"]
    );
    m.occlusion = false;
    assert_eq!(runner::frame_columns(&m), vec!["clouds"]);
    let list = m
        .frame(&view(), Target::Tolerance(1.0), &Feedback::default())
        .unwrap();
    assert!(list.occlusion.is_none());
    assert_eq!(
        runner::frame_counters(&m, &list, &FrameStats::default(), 0, Default::default()),
        vec![3.0]
    );
}

#[test]
fn gaussian_kernel_refuses_occlusion_culling() {
    let mut m = Walls::scene();
    let v = view();
    let list = m
        .frame(&v, Target::Tolerance(1.0), &feedback(&[WALL]))
        .unwrap();
    let e = cpu::render(&v, &list, &m, Kernel::Gaussian).unwrap_err();
    assert!(e.to_string().contains("opaque kernel"), "{e}");
    let Some(gpu) = gpu_for_test("gaussian_kernel_refuses_occlusion_culling") else {
        return;
    };
    let mut r = Renderer::new(&gpu, settings(Kernel::Gaussian)).unwrap();
    let e = r.draw(&v, &list, &m, false).unwrap_err();
    assert!(e.to_string().contains("opaque kernel"), "{e}");
}
