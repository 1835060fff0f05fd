//! Sequential Point Trees' error formulas: closed forms of the perpendicular, tangential and
//! geometric errors on hand-built children, their monotonicity up the tree, the box bound,
//! the colour rule and the error without normals.
#![allow(clippy::unwrap_used)]

mod common;
use common::{spt_build_open as build_open, spt_statue as statue, spt_views as views};
use glam::Vec3;
use methods::spt;
use methods::spt::errors::{self, ChildDisk};
use methods::{Feedback, LodMethod, Target};
use scenes::PointCloud;

fn disk(p: [f32; 3], n: Vec3, r: f32) -> ChildDisk {
    ChildDisk {
        p: Vec3::from(p),
        n: n.normalize(),
        r,
    }
}

#[test]
fn perpendicular_error_closed_forms() {
    // Coplanar children with the node's normal: e_p = 0.
    let flat = [
        disk([-1.0, 0.0, 0.0], Vec3::Z, 0.5),
        disk([1.0, 0.0, 0.0], Vec3::Z, 0.5),
        disk([0.0, 1.0, 0.0], Vec3::Z, 0.3),
    ];
    assert!(errors::perpendicular_error(Vec3::ZERO, Vec3::Z, &flat).abs() < 1e-6);
    // Children tilted by ±θ about y (node normal z by symmetry), radius r, plus one raised by
    // h: ρ = r·sin θ, e_p = max(h, ρ) − (−ρ) = max(h, r sin θ) + r sin θ.
    let (t, r, h) = (30f32.to_radians(), 0.5f32, 0.3f32);
    let kids = [
        disk([-1.0, 0.0, 0.0], Vec3::new(t.sin(), 0.0, t.cos()), r),
        disk([1.0, 0.0, 0.0], Vec3::new(-t.sin(), 0.0, t.cos()), r),
        disk([0.0, 1.0, h], Vec3::Z, r),
    ];
    let want = h.max(r * t.sin()) + r * t.sin();
    let got = errors::perpendicular_error(Vec3::ZERO, Vec3::Z, &kids);
    assert!((got - want).abs() < 1e-5, "e_p {got}, closed form {want}");
    // Without the raised child: e_p = 2 r sin θ, and shifting p along n changes nothing.
    let got = errors::perpendicular_error(Vec3::new(0.2, 0.1, 5.0), Vec3::Z, &kids[..2]);
    assert!((got - 2.0 * r * t.sin()).abs() < 1e-5, "{got}");
}

#[test]
fn tangential_and_geometric_error() {
    // Two disks of radius 0.5 at x = ±1, normal z: bounding disk diameter 3, tightest slab
    // (along y) width 1 ⇒ e_t = 2.
    let kids = [
        disk([-1.0, 0.0, 0.0], Vec3::Z, 0.5),
        disk([1.0, 0.0, 0.0], Vec3::Z, 0.5),
    ];
    let (_, rad) = errors::bounding_disk(Vec3::Z, &kids);
    assert!((2.0 * rad - 3.0).abs() < 1e-3, "d = {}", 2.0 * rad);
    let e_t = errors::tangential_error(Vec3::Z, 3.0, &kids);
    assert!((e_t - 2.0).abs() < 1e-5, "e_t {e_t}");
    assert!((errors::slab_width(Vec3::X, &kids) - 3.0).abs() < 1e-6);
    // A single disk: d equals the slab width in every direction ⇒ e_t = 0 (clamped ≥ 0).
    assert_eq!(errors::tangential_error(Vec3::Z, 1.0, &kids[..1]), 0.0);
    // Tilted disk: its extent along x shrinks to 2 r |cos θ|.
    let tilted = [disk([0.0; 3], Vec3::new(0.6, 0.0, 0.8), 1.0)];
    assert!((errors::slab_width(Vec3::X, &tilted) - 1.6).abs() < 1e-5);
    assert!((errors::geometric_error(3.0, 4.0) - 5.0).abs() < 1e-6);
}

#[test]
fn tree_errors_are_monotone_and_consistent() {
    let cloud = statue(20_000);
    let radii = methods::leaf::leaf_radii(&cloud);
    let tree = spt::build::build_tree(&cloud, &radii, 40.0);
    let leaves = tree.nodes.iter().filter(|n| n.leaf).count();
    assert_eq!(leaves, cloud.len(), "one leaf per sample");
    for (i, n) in tree.nodes.iter().enumerate() {
        if n.leaf {
            assert_eq!(n.e_g, 0.0);
        } else {
            assert!(n.e_g > 0.0, "inner node {i} has e_g 0");
            let g = errors::geometric_error(n.e_p, n.e_t);
            assert!(
                (g - n.e_g).abs() <= 1e-4 * n.e_g,
                "node {i}: e_g {} vs {g}",
                n.e_g
            );
        }
        if n.parent != spt::build::NO_PARENT {
            let p = &tree.nodes[n.parent as usize];
            assert!(
                p.e_g >= n.e_g && p.e_p >= n.e_p && p.e_t >= n.e_t,
                "node {i}"
            );
        }
    }
    assert_eq!(tree.nodes[tree.root()].parent, spt::build::NO_PARENT);
}

/// `bound=box` (a departure, see the README): `r_lo` also from the box of each cluster's node
/// centres. It must stay conservative (every passing node inside the prefix), never send more
/// than the default sphere bound (it takes the larger of the two bounds), draw the same
/// splats, and keep budgets.
#[test]
fn box_bound_is_conservative_and_never_longer_than_the_sphere() {
    let cloud = statue(50_000);
    let tmp = tempfile::tempdir().unwrap();
    for (k, extra) in [&[][..], &["normal_clusters=true"][..], &["mode=split"][..]]
        .into_iter()
        .enumerate()
    {
        let with = |b: &str| {
            let mut p: Vec<&str> = extra.to_vec();
            p.push(b);
            build_open(&cloud, &p, &tmp.path().join(format!("{k}-{b}"))).unwrap()
        };
        let (mut sphere, mut boxed) = (with("bound=sphere"), with("bound=box"));
        let (mut sent_s, mut sent_b) = (0u64, 0u64);
        for view in views(&cloud) {
            for eps in [0.5f32, 1.0, 4.0] {
                let t = Target::Tolerance(eps);
                let ls = sphere.frame(&view, t, &Feedback::default()).unwrap();
                let lb = boxed.frame(&view, t, &Feedback::default()).unwrap();
                let sel = boxed.select(&view, t).unwrap();
                // Every passing node lies in its cluster's prefix (skipped clusters aside).
                for i in boxed.cpu_select(&view, eps) {
                    let i = i as u64;
                    let ci = boxed
                        .index()
                        .clusters
                        .iter()
                        .position(|c| i >= c.start && i < c.start + c.count)
                        .unwrap();
                    let c = &boxed.index().clusters[ci];
                    assert!(
                        i < c.start + sel.prefixes[ci]
                            || (sel.prefixes[ci] == 0 && sel.clusters_skipped > 0),
                        "{extra:?} eps {eps}: node {i} passes beyond the box prefix"
                    );
                }
                assert!(lb.points() <= ls.points(), "{extra:?} eps {eps}");
                assert_eq!(
                    boxed.drawn_points(&view, &lb).unwrap(),
                    sphere.drawn_points(&view, &ls).unwrap(),
                    "{extra:?} eps {eps}: both bounds must draw the same splats"
                );
                sent_s += ls.points();
                sent_b += lb.points();
                let lb = boxed
                    .frame(&view, Target::Budget(5_000), &Feedback::default())
                    .unwrap();
                assert!(lb.points() <= 5_000);
            }
        }
        println!(
            "{extra:?}: box sends {:.1} % fewer splats than the sphere over 7 views × 3 tolerances",
            100.0 * (1.0 - sent_b as f64 / sent_s as f64)
        );
        assert!(
            sent_b < sent_s,
            "{extra:?}: the box bound should cut something"
        );
    }
}

/// The colour rule: where a node's children differ in colour by more than the threshold,
/// its geometric error is raised to at least its diameter; a threshold no spread exceeds
/// changes nothing; a scene without colours is unaffected by the threshold.
#[test]
fn colour_rule_raises_error_to_the_diameter() {
    use methods::spt::build::build_tree;
    let cloud = scenes::generators::Generator::Terrain
        .generate(5_000, 2)
        .unwrap();
    let radii = methods::leaf::leaf_radii(&cloud);
    let strict = build_tree(&cloud, &radii, 0.0);
    let off = build_tree(&cloud, &radii, 1000.0);
    assert_eq!(strict.nodes.len(), off.nodes.len());
    let mut kids: Vec<Vec<usize>> = vec![Vec::new(); strict.nodes.len()];
    for (i, n) in strict.nodes.iter().enumerate() {
        if (n.parent as usize) < strict.nodes.len() && n.parent as usize != i {
            kids[n.parent as usize].push(i);
        }
    }
    let mut raised = 0;
    for (i, n) in strict.nodes.iter().enumerate() {
        assert!(
            n.e_g >= off.nodes[i].e_g,
            "node {i}: the rule only ever raises errors"
        );
        if n.leaf || kids[i].is_empty() {
            continue;
        }
        let cols: Vec<[u8; 3]> = kids[i].iter().map(|&k| strict.nodes[k].color).collect();
        if methods::spt::errors::color_spread(&cols) > 0 {
            assert!(
                n.e_g >= 2.0 * n.r * 0.999,
                "node {i}: e_g {} < d {}",
                n.e_g,
                2.0 * n.r
            );
            if off.nodes[i].e_g < 2.0 * n.r * 0.999 {
                raised += 1;
            }
        }
    }
    assert!(
        raised > 0,
        "some node's error must have been raised by colour"
    );
    let grey = scenes::generators::Generator::Statue
        .generate(3_000, 2)
        .unwrap();
    let r = methods::leaf::leaf_radii(&grey);
    let a = build_tree(&grey, &r, 0.0);
    let b = build_tree(&grey, &r, 1000.0);
    assert!(a.nodes.iter().zip(&b.nodes).all(|(x, y)| x.e_g == y.e_g));
}

/// §3: "The maximal error e_g has the node's bounding sphere's diameter d as upper bound.
/// When setting e_g to d we get the Q-Splat representation." Without normals the build sets
/// e_g = d (its bounding ball's diameter), so every inner node sits exactly on the bound:
/// none above it, the largest ratio exactly 1 (the ball bounds its children's balls, so no
/// child's e_g raises a parent's above the parent's own d). With normals on the same
/// positions, the figures count the nodes against the disk's and the sphere's diameter, and
/// a sphere around the children's spheres is never smaller than the disk's in-plane
/// diameter (it bounds the same children).
#[test]
fn eg_is_d_without_normals_and_counted_against_both_diameters_with_them() {
    let s = statue(20_000);
    let bare =
        PointCloud::new(s.origin(), s.positions().to_vec().into(), None, None, None).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let figures = |cloud: &PointCloud, dir: &str| {
        let dir = tmp.path().join(dir);
        std::fs::create_dir_all(&dir).unwrap();
        let stats = spt::build(
            cloud,
            &methods::Params::default(),
            "test",
            &dir,
            &scenes::NoProgress,
        )
        .unwrap();
        let f = |k: &str| stats.extra[k].as_f64().unwrap();
        (
            f("inner_nodes"),
            f("inner_eg_above_d"),
            f("inner_eg_over_d_max"),
            f("inner_eg_above_sphere"),
            f("inner_eg_over_sphere_max"),
        )
    };
    let (inner, above_d, over_d, above_s, over_s) = figures(&bare, "bare");
    assert!(inner > 0.0);
    assert_eq!((above_d, over_d), (0.0, 1.0), "e_g = d without normals");
    assert_eq!(above_s, 0.0, "the sphere is the ball: {over_s}");
    assert!(over_s <= 1.0, "{over_s}");
    let (inner_n, above_d, over_d, above_s, over_s) = figures(&s, "normals");
    assert!(inner_n > 0.0 && over_d > 0.0 && over_s > 0.0);
    assert!(
        above_s <= above_d && over_s <= over_d,
        "sphere ≥ disk: {above_s} {above_d} {over_s} {over_d}"
    );
}
