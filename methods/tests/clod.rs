//! `clod` (continuous LOD, Schütz et al. 2019): the levels are Potree's, the per-point filter
//! keeps exactly what a brute-force evaluation of the paper's rule keeps, budgets hold, and
//! builds do not depend on the thread count.
#![allow(clippy::unwrap_used)]

mod common;

use common::{view, with_threads};
use glam::{DVec4, Vec3};
use methods::clod::{Clod, Info, select};
use methods::potree::Mode;
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
/// of Potree's sampler), and the offsets `u` are uniform (mean within 4 σ of ½, σ² = 1/12n);
/// `potree` built from the same cloud has the same levels and root points.
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

    // And they are Potree's: `potree` built from the same cloud at the same `max_leaf` has
    // the same spacing, the same count per level and the same root points (its records
    // decoded to the scene's local frame: within a quantisation step and f32 rounding).
    let ptmp = tempfile::tempdir().unwrap();
    MethodKind::Potree
        .build(
            &cloud,
            &Params::parse(&["max_leaf=2000"]).unwrap(),
            "t",
            ptmp.path(),
            &scenes::NoProgress,
        )
        .unwrap();
    let (meta, nodes) = common::read_back(ptmp.path(), "potree.json", Mode::POTREE);
    let pinfo: methods::potree::Info =
        serde_json::from_str(&std::fs::read_to_string(ptmp.path().join("potree.json")).unwrap())
            .unwrap();
    assert_eq!(meta.spacing, info.spacing, "root spacing");
    let mut potree_levels = vec![0u64; info.levels as usize];
    for (span, recs) in &nodes {
        assert!(
            (span.level as usize) < potree_levels.len(),
            "a deeper level"
        );
        potree_levels[span.level as usize] += recs.len() as u64;
    }
    assert_eq!(potree_levels, info.per_level, "points per level");
    let local =
        |q: [i32; 3]| {
            Vec3::from_array([0, 1, 2].map(|k| {
                (f64::from(q[k]) * meta.scale[k] + meta.offset[k] - pinfo.origin[k]) as f32
            }))
        };
    let potree_root: Vec<Vec3> = nodes
        .iter()
        .filter(|(span, _)| span.level == 0)
        .flat_map(|(_, recs)| recs.iter().map(|(q, _)| local(*q)))
        .collect();
    assert_eq!(potree_root.len(), root.len(), "root points");
    let extent = cloud.bounds().size().max_element();
    let tol = meta.scale.iter().cloned().fold(0.0, f64::max) as f32 + 1e-5 * extent;
    for p in &root {
        let nearest = potree_root
            .iter()
            .map(|q| q.distance(*p))
            .fold(f32::INFINITY, f32::min);
        assert!(
            nearest <= tol,
            "a CLOD root point {nearest} from Potree's root"
        );
    }
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

/// A budget is never exceeded and is met but for rounding: the scale sits just above the
/// (B + 1)-th largest per-point limit (`select::scale_limit`), so every point whose limit
/// exceeds the chosen scale by more than 1e-5 (relative; f32 rounding of the filter's own
/// comparison) is drawn, and those within that margin are few. A budget every point fits is
/// drawn whole, at full size (the scale is `BLEND` × the smallest limit, so no point fades).
/// The count is also checked against the paper's rule evaluated here in f64 at the list's
/// scale, independently of `select`.
#[test]
fn budgets_hold_and_are_met_but_for_rounding() {
    let cloud = Generator::Statue.generate(30_000, 5).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut m = build_open(&cloud, &[], tmp.path());
    let pts = points(&m);
    for dist in [0.8f32, 2.0, 5.0] {
        let v = view(&cloud, dist);
        let limits: Vec<f32> = pts
            .iter()
            .filter_map(|(p, s)| {
                select::scale_limit(*p, *s, &v.view_proj(), v.camera.position, 0.7)
            })
            .collect();
        let all = limits.len() as u64;
        assert_eq!(m.count_kept(&v, 0.0), all);
        for b in [1u64, 100, 1_000, 7_777, all - 1, all, all + 5] {
            let list = m
                .frame(&v, Target::Budget(b), &Feedback::default())
                .unwrap();
            let drawn = m.drawn_points(&v, &list).unwrap();
            let scale = m.budget_scale(&v, b);
            assert!(drawn <= b, "dist {dist}: budget {b} drew {drawn}");
            // Independently of `select`: the paper's rule in f64 at the list's own scale
            // keeps at most the budget, but for points on a boundary, and what the mirror
            // counts as drawn.
            let Some(DrawItem::Sequential {
                test: SplatTest::Clod(c),
                ..
            }) = list.items.first().cloned()
            else {
                panic!("clod draws sequential items with its test");
            };
            let (mut kept, mut unsure) = (0u64, 0u64);
            for &(p, s) in &pts {
                let (k, near) = brute(&v, p, s, c.scale, c.fovea);
                kept += u64::from(k && !near);
                unsure += u64::from(near);
            }
            assert!(
                unsure <= 3,
                "dist {dist}: budget {b}: {unsure} on a boundary"
            );
            assert!(kept <= b, "dist {dist}: budget {b}: the rule keeps {kept}");
            assert!(
                kept <= drawn && drawn <= kept + unsure,
                "dist {dist}: budget {b}: drawn {drawn}, the rule {kept} (+{unsure})"
            );
            let clear = limits.iter().filter(|&&l| l > scale * (1.0 + 1e-5)).count() as u64;
            let near = limits
                .iter()
                .filter(|&&l| (l - scale).abs() <= scale * 1e-5)
                .count();
            assert!(drawn >= clear, "dist {dist}: budget {b}: {drawn} < {clear}");
            assert!(
                near <= 3,
                "dist {dist}: budget {b}: {near} limits at the scale"
            );
            if b >= all {
                assert_eq!(drawn, all, "dist {dist}: budget {b}");
                let least = limits.iter().copied().fold(f32::INFINITY, f32::min);
                assert_eq!(scale, select::BLEND * least, "dist {dist}: no point fades");
            } else {
                assert!(
                    drawn + near as u64 >= b,
                    "dist {dist}: budget {b} drew {drawn}"
                );
            }
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
