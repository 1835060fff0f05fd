//! The viewer's session driven headless (no window): what its keys do to the frame, the
//! target, the kernel and the images shown, and that a played path draws `run`'s poses.
#![allow(clippy::unwrap_used)]

use harness::gpu::gpu_for_test;
use harness::render::{Kernel, RenderSettings};
use harness::runner::{PreparedScene, load_scene};
use harness::viewer::command::Event;
use harness::viewer::overlay::HOLE;
use harness::viewer::session::{Display, Overlay, Session, SessionConfig};
use methods::{MethodKind, Params, Target};
use scenes::paths::PathSpec;
use scenes::{NoProgress, SceneSpec};

const SCENE: &str = "statue:20000:1";

fn scene(cache: &std::path::Path) -> PreparedScene {
    let render = RenderSettings {
        width: 160,
        height: 120,
        ..Default::default()
    };
    load_scene(
        &SceneSpec::parse(SCENE, None, 1).unwrap(),
        render,
        cache,
        &NoProgress,
    )
    .unwrap()
}

fn config(dir: &std::path::Path, methods: &[MethodKind]) -> SessionConfig {
    SessionConfig {
        methods: methods.iter().map(|m| (*m, Params::default())).collect(),
        build_dir: None,
        target: Target::Tolerance(1.0),
        cache: dir.join("cache"),
        out: dir.join("out"),
        play: None,
        play_frames: 8,
        scene_flags: format!("--scene {SCENE}"),
    }
}

fn press(s: &mut Session<'_>, key: &str) {
    s.event(&Event::Key(key.into(), true)).unwrap();
    s.event(&Event::Key(key.into(), false)).unwrap();
}

#[test]
fn keys_switch_method_target_kernel_and_overlays() {
    let Some(gpu) = gpu_for_test("keys_switch_method_target_kernel_and_overlays") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(&dir.path().join("cache"));
    let cfg = config(dir.path(), &[MethodKind::Qsplat, MethodKind::Spt]);
    let mut s = Session::new(&gpu, &scene, cfg, &NoProgress).unwrap();
    s.frame(0.0, &NoProgress).unwrap();
    assert!(
        matches!(s.display(), Display::Target(_)),
        "the renderer's target, not a copy"
    );
    assert!(s.info.stats.points > 0);

    press(&mut s, "2");
    s.frame(0.0, &NoProgress).unwrap();
    assert_eq!(s.method(), MethodKind::Spt);
    assert!(s.info.stats.gpu_passed.is_some(), "SPT's interval test ran");
    press(&mut s, "3");
    assert!(s.message.starts_with("no method 3"), "{}", s.message);
    assert_eq!(s.method(), MethodKind::Spt);

    press(&mut s, "minus");
    assert_eq!(s.target(), Target::Tolerance(std::f32::consts::SQRT_2));
    press(&mut s, "plus");
    press(&mut s, "plus");
    let Target::Tolerance(e) = s.target() else {
        panic!()
    };
    assert!((e - std::f32::consts::FRAC_1_SQRT_2).abs() < 1e-6, "{e}");

    press(&mut s, "k");
    assert_eq!(s.settings().kernel, Kernel::Circle);

    // The hole mask marks exactly the metric's holes against the reference.
    press(&mut s, "1");
    press(&mut s, "h");
    press(&mut s, "c");
    press(&mut s, "f12");
    s.frame(0.0, &NoProgress).unwrap();
    assert_eq!(s.overlay(), Overlay::Holes);
    let Display::Image(mask, _) = s.display() else {
        panic!("the hole mask is an image")
    };
    let red = mask.rgba.chunks_exact(4).filter(|p| *p == HOLE).count();
    // The same frame and its reference, from the screenshot taken with it.
    let shot = s.shots.last().unwrap();
    let frame = harness::image::Image::load_png(&shot.frame).unwrap();
    let reference = harness::image::Image::load_png(&shot.reference).unwrap();
    let holes = harness::metrics::hole_ratio(&reference, &frame).unwrap();
    assert_eq!(
        red as f64 / reference.coverage_count() as f64,
        holes,
        "{red} red pixels"
    );
    let (_, flip) = s.info.flip.expect("C measured the frame");
    assert_eq!(
        flip,
        harness::metrics::flip_mean(&reference, &frame).unwrap()
    );
    press(&mut s, "g");
    s.frame(0.0, &NoProgress).unwrap();
    assert_eq!(s.overlay(), Overlay::Flip);
    assert!(matches!(s.display(), Display::Image(..)));
    press(&mut s, "g");
    s.frame(0.0, &NoProgress).unwrap();
    assert!(
        matches!(s.display(), Display::Target(_)),
        "G again turns it off"
    );
}

#[test]
fn a_played_path_draws_runs_poses_and_gives_the_camera_back() {
    let Some(gpu) = gpu_for_test("a_played_path_draws_runs_poses_and_gives_the_camera_back") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(&dir.path().join("cache"));
    let mut cfg = config(dir.path(), &[MethodKind::Qsplat]);
    cfg.play = Some(PathSpec::Orbit);
    let mut s = Session::new(&gpu, &scene, cfg, &NoProgress).unwrap();
    press(&mut s, "p");
    for i in 0..8 {
        assert!(s.playing(), "frame {i}");
        let want = PathSpec::Orbit.camera(i, 8, &scene.bounds);
        assert_eq!(s.camera(), want, "frame {i} is run's frame {i} of 8");
        s.frame(1.0 / 30.0, &NoProgress).unwrap();
    }
    assert!(!s.playing());
    assert_eq!(s.message, "playback done");
    // The user takes over where the path ended.
    let last = PathSpec::Orbit.camera(7, 8, &scene.bounds);
    assert!(s.camera().position.distance(last.position) < 1e-4 * scene.bounds.size().length());

    // Recording: Enter with fewer than two keys says so and writes nothing.
    press(&mut s, "space");
    press(&mut s, "enter");
    assert!(s.message.contains("at least 2 keyframes"), "{}", s.message);
    assert!(s.saved_paths().is_empty());
}

#[test]
fn level_colours_tint_each_drawn_node_by_its_level() {
    let Some(gpu) = gpu_for_test("level_colours_tint_each_drawn_node_by_its_level") else {
        return;
    };
    let dir = tempfile::tempdir().unwrap();
    let scene = scene(&dir.path().join("cache"));
    let cfg = config(dir.path(), &[MethodKind::Qsplat, MethodKind::Mwkd]);
    let mut s = Session::new(&gpu, &scene, cfg, &NoProgress).unwrap();
    press(&mut s, "l");
    assert!(!s.level_colours());
    assert!(
        s.message.contains("no nodes to colour by level"),
        "{}",
        s.message
    );
    press(&mut s, "2");
    // MWKD streams its nodes in: draw until the view has all it asks for.
    for _ in 0..10 {
        s.frame(0.0, &NoProgress).unwrap();
    }
    press(&mut s, "f12");
    s.frame(0.0, &NoProgress).unwrap();
    press(&mut s, "l");
    assert!(s.level_colours());
    press(&mut s, "c");
    press(&mut s, "g");
    assert!(
        s.message
            .starts_with("FLIP compares the method's own colours"),
        "{}",
        s.message
    );
    assert_eq!(s.overlay(), Overlay::Method, "no FLIP map of tinted splats");
    press(&mut s, "f12");
    s.frame(0.0, &NoProgress).unwrap();
    let plain = harness::image::Image::load_png(&s.shots[0].frame).unwrap();
    let tinted = harness::image::Image::load_png(&s.shots[1].frame).unwrap();
    let covered = |img: &harness::image::Image| -> Vec<[u8; 4]> {
        img.rgba
            .chunks_exact(4)
            .filter(|p| p[3] > 0)
            .map(|p| [p[0], p[1], p[2], p[3]])
            .collect()
    };
    let (p, t) = (covered(&plain), covered(&tinted));
    assert_eq!(
        p.len(),
        t.len(),
        "the same splats, only their colour changes"
    );
    let grey = |c: &[u8; 4]| c[0].abs_diff(c[1]) < 8 && c[1].abs_diff(c[2]) < 8;
    assert!(p.iter().all(grey), "the statue has no colour of its own");
    // Each pixel's hue is its level's: the channel order of the palette entry.
    let hues: std::collections::BTreeSet<[bool; 3]> = t
        .iter()
        .filter(|c| !grey(c))
        .map(|c| [c[0] > c[1], c[1] > c[2], c[0] > c[2]])
        .collect();
    let palette: std::collections::BTreeSet<[bool; 3]> = harness::render::LEVEL_PALETTE
        .iter()
        .filter(|c| !(c[0] == c[1] && c[1] == c[2]))
        .map(|c| [c[0] > c[1], c[1] > c[2], c[0] > c[2]])
        .collect();
    eprintln!("hues drawn {hues:?}");
    assert!(hues.is_subset(&palette), "{hues:?} ⊄ {palette:?}");
    assert!(t.iter().filter(|c| !grey(c)).count() * 2 > t.len());
}
