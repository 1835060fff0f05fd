//! `clod` (continuous LOD, Schütz et al. 2019): the levels are Potree's, the per-point filter
//! keeps exactly what a brute-force evaluation of the paper's rule keeps, budgets hold, and
//! builds do not depend on the thread count.
#![allow(clippy::unwrap_used)]

mod common;

use common::{view, with_threads};
use glam::{DVec4, Vec3};
use methods::clod::{Clod, Info};
use methods::{DrawItem, Feedback, LodMethod, Manifest, MethodKind, Params, SplatTest, Target};
use scenes::generators::Generator;
use scenes::{PointCloud, View};

fn build_open(cloud: &PointCloud, params: &[&str], dir: &std::path::Path) -> Clod {
    MethodKind::Clod
        .build(
            cloud,
            &Params::parse(params).unwrap(),
            "t",
            dir,
            &scenes::NoProgress,
        )
        .unwrap();
    let mut manifest = Manifest::read(dir).unwrap();
    manifest.params = Params::parse(params).unwrap();
    Clod::open(dir, manifest).unwrap()
}

/// Every point of the build: (position, spacing), chunk by chunk.
fn points(m: &Clod) -> Vec<(Vec3, f32)> {
    let mut out = Vec::new();
    for id in 0.. {
        let Ok(c) = m.chunk(id) else { break };
        let lod = c.lod.as_ref().unwrap();
        out.extend(
            c.positions
                .iter()
                .zip(lod)
                .map(|(p, l)| (Vec3::from(*p), l[0])),
        );
    }
    out
}

/// The paper's rule evaluated in f64, independently of `select`: kept iff in front of the
/// eye, inside |ndc| ≤ 2 and `s ≥ scale·d / max(1 − fovea·|ndc|, 0.3)`. Returns (kept, and
/// whether the decision is within 1e-5 (relative) of a boundary, where f32 may decide
/// either way).
fn brute(v: &View, p: Vec3, s: f32, scale: f32, fovea: f32) -> (bool, bool) {
    let vp = v.view_proj().as_dmat4();
    let c: DVec4 = vp * p.as_dvec3().extend(1.0);
    if c.w <= 0.0 {
        return (false, c.w.abs() < 1e-9);
    }
    let (x, y) = (c.x / c.w, c.y / c.w);
    let edge = (x.abs() - 2.0).abs().min((y.abs() - 2.0).abs()) < 1e-5;
    if x.abs() > 2.0 || y.abs() > 2.0 {
        return (false, edge);
    }
    let dc = (x * x + y * y).sqrt();
    let d = p.as_dvec3().distance(v.camera.position.as_dvec3());
    let t = f64::from(scale) * d / (1.0 - f64::from(fovea) * dc).max(0.3);
    let s = f64::from(s);
    (s >= t, edge || (s - t).abs() <= 1e-5 * t.max(1e-30))
}

/// The levels are those of Potree's octree at the same `max_leaf`: each point's spacing is
/// `spacing₀ / 2^(level + u)` with `u ∈ [0, 1)`, the levels' counts are `clod.json`'s, the
/// root level is a Poisson-disk sample (no two root points closer than `spacing₀`, the rule
/// of Potree's sampler), and the offsets `u` are uniform (mean within 4 σ of ½, σ² = 1/12n).
#[test]
fn levels_are_potrees_and_the_offsets_are_uniform() {
    let cloud = Generator::Statue.generate(30_000, 2).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let m = build_open(&cloud, &["max_leaf=2000"], tmp.path());
    let info: &Info = m.info();
    let pts = points(&m);
    assert_eq!(pts.len(), cloud.len());
    assert!(info.levels >= 3, "a 30 k statue at max_leaf 2000 has depth");
    let mut per_level = vec![0u64; info.levels as usize];
    let mut sum_u = 0.0f64;
    let mut root = Vec::new();
    for &(p, s) in &pts {
        let x = (info.spacing / f64::from(s)).log2();
        let level = x.floor();
        let u = x - level;
        assert!((0.0..1.0 + 1e-6).contains(&u), "offset {u}");
        per_level[level as usize] += 1;
        sum_u += u;
        if level == 0.0 {
            root.push(p);
        }
    }
    assert_eq!(per_level, info.per_level);
    assert_eq!(per_level.iter().sum::<u64>(), cloud.len() as u64);
    let n = pts.len() as f64;
    let sigma = (1.0 / 12.0 / n).sqrt();
    assert!(
        (sum_u / n - 0.5).abs() < 4.0 * sigma,
        "mean offset {}",
        sum_u / n
    );
    // Root: Poisson-disk at spacing₀ (positions quantised by the octree's sampler: 1e-3 slack).
    let min_d = info.spacing as f32 * (1.0 - 1e-3);
    for (i, a) in root.iter().enumerate() {
        for b in &root[i + 1..] {
            assert!(
                a.distance(*b) >= min_d,
                "root points {} apart",
                a.distance(*b)
            );
        }
    }
    assert!(root.len() > 100, "the root holds a sample: {}", root.len());
}

/// The frame's test keeps exactly the points the paper's rule keeps (evaluated here in f64),
/// but for points within 1e-5 of a boundary; the test culls some and keeps some.
#[test]
fn the_kept_set_equals_a_brute_force_filter() {
    let cloud = Generator::Statue.generate(30_000, 3).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    for fovea in ["0.7", "0"] {
        let dir = tmp.path().join(fovea);
        let mut m = build_open(&cloud, &[&format!("fovea={fovea}")], &dir);
        let f: f32 = fovea.parse().unwrap();
        let pts = points(&m);
        for dist in [0.6f32, 1.0, 1.5] {
            let v = view(&cloud, dist);
            for eps in [0.5f32, 1.0, 2.0] {
                let list = m
                    .frame(&v, Target::Tolerance(eps), &Feedback::default())
                    .unwrap();
                let Some(DrawItem::Sequential {
                    test: t @ SplatTest::Clod(c),
                    ..
                }) = list.items.first().cloned()
                else {
                    panic!("clod draws sequential items with its test");
                };
                assert_eq!(c.scale, eps / v.proj_scale());
                let (mut kept, mut unsure) = (0usize, 0usize);
                for &(p, s) in &pts {
                    let ours = t.passes(p, Vec3::Z, [s, 0.0, 0.0, 0.0], v.camera.position);
                    let (theirs, near) = brute(&v, p, s, c.scale, f);
                    unsure += usize::from(near);
                    assert!(
                        ours == theirs || near,
                        "dist {dist} eps {eps}: {p} spacing {s}"
                    );
                    kept += usize::from(ours);
                }
                assert!(
                    0 < kept && kept < pts.len(),
                    "dist {dist} eps {eps}: kept {kept}"
                );
                assert!(
                    unsure <= 3,
                    "dist {dist} eps {eps}: {unsure} points on a boundary"
                );
                assert_eq!(m.drawn_points(&v, &list).unwrap(), kept as u64);
                assert_eq!(m.count_kept(&v, c.scale), kept as u64);
            }
        }
    }
}

/// The paper's rule has no floor: once the target spacing exceeds even the root's spacing
/// (the bounding cube's side / 128) everywhere, nothing is kept — at 4 radii the statue
/// spans ≈ 60 px of 240, its root spacing ≈ 0.5 px, below ε = 3 px.
#[test]
fn a_model_whose_root_spacing_projects_below_epsilon_vanishes() {
    let cloud = Generator::Statue.generate(20_000, 4).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut m = build_open(&cloud, &["fovea=0"], tmp.path());
    let v = view(&cloud, 4.0);
    let spacing0 = m.info().spacing as f32;
    let nearest = points(&m)
        .iter()
        .map(|(p, _)| p.distance(v.camera.position))
        .fold(f32::INFINITY, f32::min);
    let root_px = spacing0 * v.proj_scale() / nearest;
    assert!(
        root_px < 3.0,
        "root spacing {root_px} px at the nearest point"
    );
    let list = m
        .frame(&v, Target::Tolerance(3.0), &Feedback::default())
        .unwrap();
    assert_eq!(m.drawn_points(&v, &list).unwrap(), 0);
    // Just below the root's projected spacing the root's nearest points come back.
    let list = m
        .frame(&v, Target::Tolerance(root_px * 0.5), &Feedback::default())
        .unwrap();
    assert!(m.drawn_points(&v, &list).unwrap() > 0);
}

/// A tolerance of 0 keeps every point in front of the eye inside the extended frustum.
#[test]
fn tolerance_zero_keeps_the_whole_extended_frustum() {
    let cloud = Generator::Statue.generate(20_000, 4).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut m = build_open(&cloud, &[], tmp.path());
    for dist in [0.5f32, 1.0, 3.0] {
        let v = view(&cloud, dist);
        let expect = points(&m)
            .iter()
            .filter(|(p, _)| {
                let c = v.view_proj() * p.extend(1.0);
                c.w > 0.0 && (c.x / c.w).abs() <= 2.0 && (c.y / c.w).abs() <= 2.0
            })
            .count() as u64;
        let list = m
            .frame(&v, Target::Tolerance(0.0), &Feedback::default())
            .unwrap();
        assert_eq!(m.drawn_points(&v, &list).unwrap(), expect, "dist {dist}");
    }
}

/// A budget is never exceeded and is nearly met: the scale sits just above the (B + 1)-th
/// largest per-point limit, so only points whose limit lies within a few f32 steps of it
/// can be dropped besides those the budget excludes.
#[test]
fn budgets_hold_and_are_nearly_met() {
    let cloud = Generator::Statue.generate(30_000, 5).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut m = build_open(&cloud, &[], tmp.path());
    for dist in [0.8f32, 2.0, 5.0] {
        let v = view(&cloud, dist);
        let all = m.count_kept(&v, 0.0);
        for b in [1u64, 100, 1_000, 7_777, all - 1, all, all + 5] {
            let list = m
                .frame(&v, Target::Budget(b), &Feedback::default())
                .unwrap();
            let drawn = m.drawn_points(&v, &list).unwrap();
            assert!(drawn <= b, "dist {dist}: budget {b} drew {drawn}");
            assert!(
                drawn + 8 >= b.min(all),
                "dist {dist}: budget {b} drew only {drawn}"
            );
        }
    }
}

/// One thread or two: the same files.
#[test]
fn builds_do_not_depend_on_the_thread_count() {
    let cloud = Generator::Statue.generate(25_000, 6).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let build = |threads: usize, name: &str| {
        let dir = tmp.path().join(name);
        with_threads(threads, || {
            MethodKind::Clod
                .build(&cloud, &Params::default(), "t", &dir, &scenes::NoProgress)
                .unwrap()
        });
        dir
    };
    let (a, b) = (build(1, "one"), build(2, "two"));
    for f in ["points.sbc", "clod.json", "method.json"] {
        assert_eq!(
            std::fs::read(a.join(f)).unwrap(),
            std::fs::read(b.join(f)).unwrap(),
            "{f}"
        );
    }
}

/// Bad parameters name themselves; a build missing a file names it.
#[test]
fn bad_parameters_and_missing_files_are_errors_naming_them() {
    for (p, needle) in [
        ("fovea=1.5", "fovea must be in 0..=1"),
        ("point_size=0", "point_size must be a finite number > 0"),
        ("max_leaf=0", "max_leaf must be ≥ 1"),
        ("fovae=0", "unknown field `fovae`"),
    ] {
        let e = MethodKind::Clod
            .check_params(&Params::parse(&[p]).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains("clod") && e.contains(needle), "{p}: {e}");
    }
    let cloud = Generator::Statue.generate(5_000, 7).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    build_open(&cloud, &[], tmp.path());
    std::fs::remove_file(tmp.path().join("clod.json")).unwrap();
    let e = MethodKind::open(tmp.path()).err().unwrap().to_string();
    assert!(e.contains("clod.json"), "{e}");
}
