//! Camera paths: exact geometry of the built-ins, keyframe interpolation, pauses, and every
//! validation error of keyframe files.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use glam::Vec3;
use scenes::paths::{Coordinates, Interpolation, Key, Keyframes, PathSpec};
use scenes::{Aabb, Camera, SceneError};

/// The test box: centre (1, 0, −1), half-extents (2, 2, 2), R = 2√3.
fn bounds() -> Aabb {
    Aabb {
        min: Vec3::new(-1.0, -2.0, -3.0),
        max: Vec3::new(3.0, 2.0, 1.0),
    }
}
const C: Vec3 = Vec3::new(1.0, 0.0, -1.0);
fn r() -> f32 {
    2.0 * 3f32.sqrt()
}

fn close(a: f32, b: f32, tol: f32) -> bool {
    (a - b).abs() <= tol * b.abs().max(1.0)
}

fn assert_vec_close(a: Vec3, b: Vec3, tol: f32, what: &str) {
    assert!((a - b).length() <= tol, "{what}: {a} != {b}");
}

/// Near/far follow the documented formula, and the camera is valid.
fn assert_planes(cam: &Camera, what: &str) {
    assert!(cam.is_valid(), "{what}: invalid camera {cam:?}");
    let d = cam.position.distance(C);
    let r = r();
    assert!(
        close(cam.far, d + 1.01 * r, 1e-5),
        "{what}: far {}",
        cam.far
    );
    let near = (d - 1.01 * r).max(1e-4 * r);
    assert!(
        close(cam.near, near, 1e-4),
        "{what}: near {} vs {near}",
        cam.near
    );
}

fn inside(p: Vec3, b: &Aabb, margin: f32) -> bool {
    p.cmpge(b.min - margin).all() && p.cmple(b.max + margin).all()
}

fn example(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("paths")
        .join(name)
}

fn err_text(e: SceneError) -> String {
    let msg = e.to_string();
    assert!(matches!(e, SceneError::Path(_)), "not a path error: {msg}");
    msg
}

/// Parses `text` as a keyframe file named `t`, expecting an error mentioning every needle.
fn assert_rejects(text: &str, needles: &[&str]) {
    let msg = match Keyframes::from_toml(text, "t") {
        Ok(k) => panic!("accepted {k:?}\n{text}"),
        Err(e) => err_text(e),
    };
    assert!(msg.starts_with("camera path: t:"), "names the file: {msg}");
    for n in needles {
        assert!(msg.contains(n), "{msg:?} should mention {n:?}");
    }
}

// ---------------------------------------------------------------- built-ins

#[test]
fn orbit_geometry_is_exact() {
    let b = bounds();
    let frames = 100;
    let cams = PathSpec::Orbit.cameras(frames, &b);
    let el = 20f32.to_radians();
    let d = 2.5 * r();
    let expected0 = C + Vec3::new(el.cos(), 0.0, el.sin()) * d;
    assert_vec_close(cams[0].position, expected0, 1e-5, "frame 0 on +X");
    let expected_q = C + Vec3::new(0.0, el.cos(), el.sin()) * d;
    assert_vec_close(
        cams[frames / 4].position,
        expected_q,
        1e-5,
        "frame 25 on +Y",
    );
    for (i, cam) in cams.iter().enumerate() {
        let what = format!("orbit frame {i}");
        assert_planes(cam, &what);
        assert!(close(cam.position.distance(C), d, 1e-6), "{what}: distance");
        assert!(
            close(cam.position.z - C.z, d * el.sin(), 1e-5),
            "{what}: height"
        );
        assert_eq!(cam.target, C, "{what}: target");
        assert_eq!(cam.up, Vec3::Z);
        assert!(close(cam.fov_y, 45f32.to_radians(), 1e-6));
        let az = (cam.position.y - C.y).atan2(cam.position.x - C.x);
        let want = std::f32::consts::TAU * i as f32 / frames as f32;
        let diff = (az - want).rem_euclid(std::f32::consts::TAU);
        assert!(
            diff.min(std::f32::consts::TAU - diff) < 1e-5,
            "{what}: angle {az}"
        );
    }
}

#[test]
fn zoom_is_geometric_from_far_to_inside() {
    let b = bounds();
    let cams = PathSpec::Zoom.cameras(100, &b);
    let dist: Vec<f32> = cams.iter().map(|c| c.position.distance(C)).collect();
    assert!(dist[0] >= 8.0 * r() * 0.99, "starts far: {}", dist[0]);
    assert!(close(dist[0], 100.0 * r(), 1e-6));
    assert!(
        close(dist[99], 0.05 * r(), 1e-5),
        "ends at 0.05 R: {}",
        dist[99]
    );
    assert!(inside(cams[99].position, &b, 0.0), "ends inside the bounds");
    let ratio = dist[1] / dist[0];
    for (i, w) in dist.windows(2).enumerate() {
        assert!(w[1] < w[0], "strictly decreasing at {i}");
        assert!(close(w[1] / w[0], ratio, 1e-4), "constant ratio at {i}");
    }
    for (i, cam) in cams.iter().enumerate() {
        assert_planes(cam, &format!("zoom frame {i}"));
        assert_eq!(cam.target, C);
    }
    // A single frame is the start.
    assert!(close(
        PathSpec::Zoom.camera(0, 1, &b).position.distance(C),
        100.0 * r(),
        1e-6
    ));
}

#[test]
fn flythrough_stays_mostly_inside_and_moves_smoothly() {
    let b = bounds();
    let frames = 100;
    let cams = PathSpec::Flythrough.cameras(frames, &b);
    let margin = 0.01 * r();
    let n_inside = cams
        .iter()
        .filter(|c| inside(c.position, &b, margin))
        .count();
    assert!(n_inside * 2 >= frames, "{n_inside} of {frames} inside");
    assert!(
        !inside(cams[0].position, &b, margin),
        "starts outside, flies in"
    );
    let mut max_step = 0f32;
    let mut min_step = f32::MAX;
    for i in 0..frames {
        let cam = &cams[i];
        assert_planes(cam, &format!("flythrough frame {i}"));
        assert_ne!(cam.position, cam.target);
        let next = &cams[(i + 1) % frames];
        let step = cam.position.distance(next.position);
        max_step = max_step.max(step);
        min_step = min_step.min(step);
        // Looking ahead: the next eye is in front of this one.
        assert!(
            (next.position - cam.position).dot(cam.forward()) > 0.0,
            "frame {i} looks ahead"
        );
    }
    assert!(max_step < 0.2 * r(), "max step {max_step}");
    assert!(
        max_step / min_step < 1.05,
        "constant speed: {min_step}..{max_step}"
    );
    // Heights vary.
    let (lo, hi) = cams.iter().fold((f32::MAX, f32::MIN), |(lo, hi), c| {
        (lo.min(c.position.z), hi.max(c.position.z))
    });
    assert!(hi - lo > 0.5 * (b.max.z - b.min.z), "heights {lo}..{hi}");
}

#[test]
fn extremes_are_valid_and_as_documented() {
    let b = bounds();
    let cams = PathSpec::Extremes.cameras(9, &b);
    for (i, cam) in cams.iter().enumerate() {
        assert_planes(cam, &format!("extreme shot {i}"));
    }
    assert!(close(cams[0].position.distance(C), 1e4 * r(), 1e-5), "far");
    assert!(close(cams[1].fov_y, 1f32.to_radians(), 1e-6), "telephoto");
    assert!(close(cams[2].fov_y, 170f32.to_radians(), 1e-6), "wide");
    assert_vec_close(cams[3].forward(), -Vec3::Z, 1e-6, "top-down");
    assert_vec_close(cams[4].forward(), Vec3::Z, 1e-6, "bottom-up");
    assert!(close(cams[5].position.z, b.max.z, 1e-6), "grazing height");
    assert_vec_close(cams[5].forward(), -Vec3::X, 1e-6, "grazing direction");
    assert!(
        close(cams[6].position.distance(b.max), 1e-3 * r(), 1e-3),
        "corner"
    );
    assert!(
        close(cams[7].position.distance(C), 1e-3 * r(), 1e-3),
        "contact"
    );
    assert_eq!(cams[8].position, C, "centre");
    // Each shot is held for an equal share of the frames.
    let long = PathSpec::Extremes.cameras(18, &b);
    for i in 0..9 {
        assert_eq!(long[2 * i], cams[i]);
        assert_eq!(long[2 * i + 1], cams[i]);
        assert!(PathSpec::Extremes.is_still(2 * i + 1, 18, &b));
    }
}

#[test]
fn moving_builtins_are_never_still() {
    let b = bounds();
    for p in [PathSpec::Orbit, PathSpec::Zoom, PathSpec::Flythrough] {
        for i in 0..50 {
            assert!(!p.is_still(i, 50, &b), "{p} frame {i}");
        }
    }
}

#[test]
fn degenerate_bounds_still_give_valid_cameras() {
    let point = Vec3::new(1e6, -3e5, 20.0);
    let cases = [
        ("empty", Aabb::EMPTY),
        ("origin point", Aabb::EMPTY.grow(Vec3::ZERO)),
        ("far point", Aabb::EMPTY.grow(point)),
        (
            "flat",
            Aabb {
                min: Vec3::new(0.0, 0.0, 5.0),
                max: Vec3::new(100.0, 50.0, 5.0),
            },
        ),
        (
            "needle",
            Aabb {
                min: Vec3::new(0.0, 0.0, 0.0),
                max: Vec3::new(0.0, 0.0, 1e-3),
            },
        ),
        (
            "huge",
            Aabb {
                min: Vec3::splat(-1e12),
                max: Vec3::splat(1e12),
            },
        ),
    ];
    let pause = PathSpec::parse(example("pause.toml").to_str().unwrap()).unwrap();
    let paths = [
        PathSpec::Orbit,
        PathSpec::Zoom,
        PathSpec::Flythrough,
        PathSpec::Extremes,
        pause,
    ];
    for (what, b) in &cases {
        for p in &paths {
            for (i, cam) in p.cameras(27, b).iter().enumerate() {
                assert!(cam.is_valid(), "{what} {p} frame {i}: {cam:?}");
            }
        }
    }
}

/// Paths are relative to the model at every scale (issue 13, item 4): a box scaled by
/// 1e-9 … 1e9 about the origin (centred on it, as the readers store clouds, or with a corner
/// on it) gets the cameras of the unit box scaled by the same factor — positions, targets
/// and planes within 1e-5 of R plus the coordinates' size (f32 rounding of the scaled box
/// and of the eye is ≈ 6e-8 relative), the same fov and up, so the same ratio of camera distance to R. The old
/// absolute floor of 1e-6 on R framed a 1e-9 model as if it were 1,000 times larger.
#[test]
fn paths_frame_a_model_the_same_at_every_scale() {
    let units = [
        Aabb {
            min: Vec3::new(-0.4, -0.3, -1.0),
            max: Vec3::new(0.4, 0.3, 1.0),
        },
        Aabb {
            min: Vec3::ZERO,
            max: Vec3::new(0.8, 0.6, 2.0),
        },
    ];
    let pause = PathSpec::parse(example("pause.toml").to_str().unwrap()).unwrap();
    let paths = [
        PathSpec::Orbit,
        PathSpec::Zoom,
        PathSpec::Flythrough,
        PathSpec::Extremes,
        pause,
    ];
    for unit in &units {
        let r1 = unit.radius();
        for s in [1e-9f32, 1e-6, 1e-3, 1e3, 1e6, 1e9] {
            let scaled = Aabb {
                min: unit.min * s,
                max: unit.max * s,
            };
            for p in &paths {
                for i in 0..27 {
                    let (a, b) = (p.camera(i, 27, unit), p.camera(i, 27, &scaled));
                    let what = format!("{p} frame {i} at scale {s:e} of {unit:?}");
                    assert!(b.is_valid(), "{what}: {b:?}");
                    // f32 rounding grows with the coordinates (the far shot is at 10⁴ R).
                    let tol = 1e-5 * (r1 + a.position.length() + a.target.length());
                    assert_vec_close(b.position / s, a.position, tol, &format!("{what}: eye"));
                    assert_vec_close(b.target / s, a.target, tol, &format!("{what}: target"));
                    assert!(
                        (b.far / s - a.far).abs() <= tol && (b.near / s - a.near).abs() <= tol,
                        "{what}: planes {}..{} vs {}..{} scaled",
                        b.near / s,
                        b.far / s,
                        a.near,
                        a.far
                    );
                    assert_eq!((b.fov_y, b.up), (a.fov_y, a.up), "{what}");
                    let ratio =
                        |c: &Camera, bb: &Aabb| c.position.distance(bb.center()) / bb.radius();
                    assert!(
                        (ratio(&b, &scaled) - ratio(&a, unit)).abs()
                            <= 1e-5 * ratio(&a, unit).max(1.0),
                        "{what}: distance / R {} vs {}",
                        ratio(&b, &scaled),
                        ratio(&a, unit)
                    );
                }
            }
        }
    }
}

#[test]
fn out_of_range_frames_do_not_panic() {
    let b = bounds();
    for (name, _) in PathSpec::BUILTIN {
        let p = PathSpec::parse(name).unwrap();
        assert!(p.camera(0, 0, &b).is_valid());
        assert_eq!(p.camera(7, 5, &b), p.camera(4, 5, &b));
        assert!(!p.is_still(0, 5, &b));
    }
}

// ---------------------------------------------------------------- parsing names

#[test]
fn builtin_names_parse_and_round_trip() {
    assert!(PathSpec::BUILTIN.len() >= 3);
    for (name, desc) in PathSpec::BUILTIN {
        let p: PathSpec = name.parse().unwrap();
        assert_eq!(p.name(), *name);
        assert_eq!(p.to_string(), *name);
        assert!(!desc.is_empty());
    }
}

#[test]
fn unknown_name_lists_the_builtins() {
    let msg = err_text(PathSpec::parse("nope").unwrap_err());
    for n in ["'nope'", "orbit", "zoom", "flythrough", "extremes", ".toml"] {
        assert!(msg.contains(n), "{msg} should mention {n}");
    }
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let e = PathSpec::parse("/nonexistent/dir/route.toml").unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }), "{e}");
    assert!(e.to_string().contains("/nonexistent/dir/route.toml"), "{e}");
}

#[test]
fn example_files_parse() {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("paths");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "toml") {
            let p = PathSpec::parse(path.to_str().unwrap())
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            assert_eq!(p.name(), path.file_stem().unwrap().to_str().unwrap());
            for cam in p.cameras(60, &bounds()) {
                assert!(cam.is_valid(), "{}: {cam:?}", path.display());
            }
            n += 1;
        }
    }
    assert!(n >= 2, "pause.toml and closeup.toml at least");
}

// ---------------------------------------------------------------- keyframes

const TWO_KEYS_LINEAR: &str = r#"
coordinates = "absolute"
interpolation = "linear"
fov_deg = 30
[[key]]
t = 0
position = [1.0, 2.0, 3.0]
target = [0.0, 0.0, 0.0]
[[key]]
t = 1
position = [3.0, 6.0, -1.0]
target = [1.0, 1.0, 1.0]
"#;

#[test]
fn parses_from_a_tempfile_and_names_it_by_stem() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("my-route.toml");
    std::fs::write(&file, TWO_KEYS_LINEAR).unwrap();
    let p = PathSpec::parse(file.to_str().unwrap()).unwrap();
    assert_eq!(p.name(), "my-route");
    let PathSpec::Keyframes(k) = &p else {
        panic!("not keyframes: {p:?}")
    };
    assert_eq!(k.coordinates(), Coordinates::Absolute);
    assert_eq!(k.interpolation(), Interpolation::Linear);
    assert_eq!(k.fov_deg(), 30.0);
    assert_eq!(k.keys().len(), 2);
    assert_eq!(k.keys()[1].up, glam::DVec3::Z, "up defaults to +Z");
    // A broken file's error names the file.
    let bad = dir.path().join("broken.toml");
    std::fs::write(&bad, "coordinates = \"absolute\"\n").unwrap();
    let msg = err_text(PathSpec::parse(bad.to_str().unwrap()).unwrap_err());
    assert!(
        msg.contains("broken.toml") && msg.contains("at least 2"),
        "{msg}"
    );
}

#[test]
fn linear_midpoint_and_keys_are_exact() {
    let p = PathSpec::Keyframes(Keyframes::from_toml(TWO_KEYS_LINEAR, "lin").unwrap());
    let b = bounds();
    let cams = p.cameras(5, &b);
    assert_eq!(cams[0].position, Vec3::new(1.0, 2.0, 3.0));
    assert_eq!(cams[0].target, Vec3::ZERO);
    assert_eq!(cams[4].position, Vec3::new(3.0, 6.0, -1.0));
    assert_eq!(cams[4].target, Vec3::ONE);
    assert_eq!(cams[2].position, Vec3::new(2.0, 4.0, 1.0), "midpoint");
    assert_eq!(cams[2].target, Vec3::splat(0.5));
    assert_eq!(cams[1].position, Vec3::new(1.5, 3.0, 2.0), "quarter");
    assert!(close(cams[2].fov_y, 30f32.to_radians(), 1e-6));
    for (i, cam) in cams.iter().enumerate() {
        assert_planes(cam, &format!("linear frame {i}"));
    }
    // One frame: the first key.
    assert_eq!(p.camera(0, 1, &b).position, Vec3::new(1.0, 2.0, 3.0));
}

#[test]
fn two_key_catmull_rom_is_a_straight_line_at_constant_speed() {
    let text = TWO_KEYS_LINEAR.replace("\"linear\"", "\"catmull-rom\"");
    let p = PathSpec::Keyframes(Keyframes::from_toml(&text, "cr2").unwrap());
    let cams = p.cameras(11, &bounds());
    for (i, cam) in cams.iter().enumerate() {
        let s = i as f32 / 10.0;
        let want = Vec3::new(1.0, 2.0, 3.0).lerp(Vec3::new(3.0, 6.0, -1.0), s);
        assert_vec_close(cam.position, want, 1e-5, &format!("frame {i}"));
    }
}

const RELATIVE_CR: &str = r#"
# splatbench camera path
coordinates = "relative"
interpolation = "catmull-rom"
[[key]]
t = 0.0
position = [2.5, 0.0, 0.8]
target = [0.0, 0.0, 0.0]
up = [0.0, 0.0, 1.0]
[[key]]
t = 0.25
position = [0.0, 2.0, 0.5]
target = [0.1, 0.0, 0.0]
[[key]]
t = 0.5
position = [-1.5, 0.0, 0.2]
target = [0.0, 0.2, 0.0]
up = [0.0, 0.2, 1.0]
[[key]]
t = 1.0
position = [0, 0, 0.3]
target = [1, 0, 0]
"#;

#[test]
fn relative_keys_are_hit_exactly_at_their_times() {
    let k = Keyframes::from_toml(RELATIVE_CR, "rel").unwrap();
    assert_eq!(k.fov_deg(), 45.0, "default fov");
    let keys = k.keys().to_vec();
    let p = PathSpec::Keyframes(k);
    let b = bounds();
    // 9 frames: t = 0, 0.125, …, 1 — every key time is a frame time.
    let frames = 9;
    for key in &keys {
        let i = (key.t * 8.0).round() as usize;
        let cam = p.camera(i, frames, &b);
        let want = |v: glam::DVec3| C + v.as_vec3() * r();
        assert_vec_close(cam.position, want(key.position), 1e-5, "key position");
        assert_vec_close(cam.target, want(key.target), 1e-5, "key target");
        assert_vec_close(cam.up, key.up.normalize().as_vec3(), 1e-6, "key up");
    }
    for (i, cam) in p.cameras(200, &b).iter().enumerate() {
        assert_planes(cam, &format!("relative frame {i}"));
    }
    // Smooth: no jumps between consecutive frames.
    let cams = p.cameras(400, &b);
    for w in cams.windows(2) {
        assert!(w[0].position.distance(w[1].position) < 0.05 * r());
    }
}

#[test]
fn absolute_coordinates_ignore_the_bounds() {
    let p = PathSpec::Keyframes(Keyframes::from_toml(TWO_KEYS_LINEAR, "abs").unwrap());
    let other = Aabb {
        min: Vec3::splat(-100.0),
        max: Vec3::splat(50.0),
    };
    assert_eq!(
        p.camera(2, 5, &bounds()).position,
        p.camera(2, 5, &other).position
    );
}

#[test]
fn keyframes_built_in_code_validate_too() {
    let key = |t: f64, x: f64| Key {
        t,
        position: glam::DVec3::new(x, 0.0, 1.0),
        target: glam::DVec3::ZERO,
        up: glam::DVec3::Z,
    };
    let ok = Keyframes::new(
        "code",
        Coordinates::Relative,
        Interpolation::CatmullRom,
        45.0,
        vec![key(0.0, 2.0), key(0.5, 1.0), key(1.0, 0.5)],
    );
    assert_eq!(ok.unwrap().name(), "code");
    let bad = Keyframes::new(
        "code",
        Coordinates::Relative,
        Interpolation::CatmullRom,
        45.0,
        vec![key(0.0, 2.0), key(0.5, 1.0), key(0.5, 0.5)],
    );
    let msg = err_text(bad.unwrap_err());
    assert!(
        msg.contains("code: key[2]") && msg.contains("strictly increase"),
        "{msg}"
    );
}

#[test]
fn pause_file_is_still_exactly_during_the_hold() {
    let p = PathSpec::parse(example("pause.toml").to_str().unwrap()).unwrap();
    assert_eq!(p.name(), "pause");
    let b = bounds();
    // 101 frames: frame i at t = i/100; the hold spans t = 0.4 ..= 0.6 (frames 40..=60).
    let frames = 101;
    for i in 0..frames {
        let want = (41..=60).contains(&i);
        assert_eq!(p.is_still(i, frames, &b), want, "frame {i}");
    }
    let hold = p.camera(50, frames, &b);
    let PathSpec::Keyframes(k) = &p else {
        unreachable!()
    };
    let key = k.keys()[4];
    assert_eq!(key.t, 0.4);
    assert_vec_close(
        hold.position,
        C + key.position.as_vec3() * r(),
        1e-5,
        "hold",
    );
    // The zoom after the hold ends 0.1 R from the centre, inside the box.
    let last = p.camera(frames - 1, frames, &b);
    assert!(close(last.position.distance(C), 0.1 * r(), 1e-3));
    assert!(inside(last.position, &b, 0.0));
}

#[test]
fn closeup_file_moves_every_frame() {
    let p = PathSpec::parse(example("closeup.toml").to_str().unwrap()).unwrap();
    let b = bounds();
    for i in 0..120 {
        assert!(!p.is_still(i, 120, &b), "frame {i}");
    }
}

#[test]
fn a_held_target_stays_exactly_put_while_the_eye_moves() {
    // Targets equal at keys 1 and 2 but not at 0: the target must not wiggle in between.
    let text = r#"
coordinates = "absolute"
[[key]]
t = 0
position = [5, 0, 1]
target = [1, 1, 0]
[[key]]
t = 0.5
position = [0, 5, 1]
target = [0, 0, 0]
[[key]]
t = 1
position = [-5, 0, 1]
target = [0, 0, 0]
"#;
    let p = PathSpec::Keyframes(Keyframes::from_toml(text, "held").unwrap());
    let cams = p.cameras(21, &bounds());
    for (i, cam) in cams.iter().enumerate().skip(10) {
        assert_eq!(cam.target, Vec3::ZERO, "frame {i}");
    }
    assert!(
        cams.windows(2).all(|w| w[0] != w[1]),
        "the eye keeps moving"
    );
}

#[test]
fn integers_are_accepted_as_numbers() {
    let text = "coordinates = \"absolute\"\nfov_deg = 60\n[[key]]\nt = 0\nposition = [1, 2, 3]\ntarget = [0, 0, 0]\n[[key]]\nt = 1\nposition = [2, 2, 3]\ntarget = [0, 0, 0]\n";
    let k = Keyframes::from_toml(text, "ints").unwrap();
    assert_eq!(k.fov_deg(), 60.0);
}

// ---------------------------------------------------------------- validation errors

/// A valid two-key file with `extra` top-level lines and per-key overrides.
fn file(top: &str, key0: &str, key1: &str) -> String {
    format!(
        "{top}\n[[key]]\n{key0}\n[[key]]\n{key1}\n",
        top = if top.contains("coordinates") {
            top.to_string()
        } else {
            format!("coordinates = \"relative\"\n{top}")
        },
        key0 = with_defaults(key0, "t = 0.0", "position = [2.0, 0.0, 0.5]"),
        key1 = with_defaults(key1, "t = 1.0", "position = [1.0, 0.0, 0.5]"),
    )
}

fn with_defaults(key: &str, t: &str, position: &str) -> String {
    let has = |field: &str| {
        key.lines()
            .any(|l| l.split('=').next().map(str::trim) == Some(field))
    };
    let mut lines = vec![key.to_string()];
    if !has("t") {
        lines.push(t.into());
    }
    if !has("position") {
        lines.push(position.into());
    }
    if !has("target") {
        lines.push("target = [0.0, 0.0, 0.0]".into());
    }
    lines.join("\n")
}

#[test]
fn the_test_template_is_valid() {
    Keyframes::from_toml(&file("", "", ""), "t").unwrap();
}

#[test]
fn rejects_unknown_fields_naming_them() {
    assert_rejects(
        &file("", "postion = [1.0, 2.0, 3.0]", ""),
        &["unknown field", "postion"],
    );
    assert_rejects(&file("fov = 40.0", "", ""), &["unknown field", "fov"]);
}

#[test]
fn rejects_unknown_enum_values() {
    assert_rejects(
        &file("coordinates = \"world\"", "", ""),
        &["world", "relative", "absolute"],
    );
    assert_rejects(
        &file("interpolation = \"cubic\"", "", ""),
        &["cubic", "catmull-rom", "linear"],
    );
}

#[test]
fn rejects_missing_coordinates() {
    let text = file("", "", "").replace("coordinates = \"relative\"", "");
    assert_rejects(&text, &["coordinates"]);
}

#[test]
fn rejects_too_few_keys() {
    assert_rejects("coordinates = \"relative\"\n", &["at least 2", "found 0"]);
    assert_rejects(
        "coordinates = \"relative\"\n[[key]]\nt = 0.0\nposition = [1, 0, 0]\ntarget = [0, 0, 0]\n",
        &["at least 2", "found 1"],
    );
}

#[test]
fn rejects_bad_times() {
    assert_rejects(&file("", "t = 0.1", ""), &["key[0]", "t = 0.1", "t = 0"]);
    assert_rejects(&file("", "", "t = 0.9"), &["key[1]", "t = 0.9", "t = 1"]);
    let three = "coordinates = \"relative\"\n\
        [[key]]\nt = 0.0\nposition = [1, 0, 0]\ntarget = [0, 0, 0]\n\
        [[key]]\nt = 0.6\nposition = [2, 0, 0]\ntarget = [0, 0, 0]\n\
        [[key]]\nt = 0.4\nposition = [3, 0, 0]\ntarget = [0, 0, 0]\n\
        [[key]]\nt = 1.0\nposition = [4, 0, 0]\ntarget = [0, 0, 0]\n";
    assert_rejects(three, &["key[2]", "key[1]", "strictly increase"]);
    assert_rejects(&file("", "", "t = 0.0"), &["key[1]", "strictly increase"]);
}

#[test]
fn rejects_non_finite_numbers() {
    assert_rejects(
        &file("", "position = [nan, 0.0, 0.0]", ""),
        &["key[0]", "position", "non-finite"],
    );
    assert_rejects(
        &file("", "", "target = [0.0, inf, 0.0]"),
        &["key[1]", "target", "non-finite"],
    );
    assert_rejects(
        &file("", "up = [0.0, 0.0, -inf]", ""),
        &["key[0]", "up", "non-finite"],
    );
    assert_rejects(&file("", "t = nan", ""), &["key[0]", "t", "non-finite"]);
    assert_rejects(&file("fov_deg = nan", "", ""), &["fov_deg", "(0, 180)"]);
}

#[test]
fn rejects_degenerate_views() {
    assert_rejects(
        &file("", "", "position = [0.0, 0.0, 0.0]"),
        &["key[1]", "position is at the target"],
    );
    // 1e-7 from a target at unit distance from the origin: not "equal", but below what the
    // view maths resolve (issue 13, item 7: the message said "position equals target").
    assert_rejects(
        &file(
            "",
            "",
            "position = [1.0, 0.0, 0.0]\ntarget = [1.0000001, 0.0, 0.0]",
        ),
        &["key[1]", "closer to it than 1e-6"],
    );
    assert_rejects(
        &file("", "position = [2.0, 0.0, 0.0]\nup = [1.0, 0.0, 0.0]", ""),
        &["key[0]", "up is parallel"],
    );
    assert_rejects(
        &file("", "", "up = [0.0, 0.0, 0.0]"),
        &["key[1]", "up is the zero vector"],
    );
    // Fine at the keys, but the eye passes through the target between them.
    assert_rejects(
        &file(
            "interpolation = \"linear\"",
            "position = [1.0, 0.0, 0.0]",
            "position = [-1.0, 0.0, 0.0]",
        ),
        &["between key[0] and key[1]", "position is at the target"],
    );
    // Fine at the keys, but looks straight down between them.
    assert_rejects(
        &file(
            "interpolation = \"linear\"",
            "position = [1.0, 0.0, 1.0]",
            "position = [-1.0, 0.0, 1.0]",
        ),
        &["between key[0] and key[1]", "up is parallel"],
    );
}

#[test]
fn rejects_fov_out_of_range() {
    for fov in ["0.0", "180.0", "-10.0", "200.0"] {
        assert_rejects(
            &file(&format!("fov_deg = {fov}"), "", ""),
            &["fov_deg", "(0, 180)"],
        );
    }
}
