//! Sequential Point Trees: error formulas on hand-built children, the sequential list and
//! its prefix search against the CPU mirror, hole-freeness along ancestor chains, tolerance
//! 0, budgets, the GPU-memory limit, determinism and normal clustering.
#![allow(clippy::unwrap_used)]

mod common;

use common::{spt_build_open as build_open, spt_statue as statue, spt_views as views};
use glam::Vec3;

use methods::spt::{self, Spt, build::PointTree, select};
use methods::{DrawItem, Feedback, IntervalTest, LodMethod, Manifest, Target};
use scenes::generators::Generator;
use scenes::paths::PathSpec;
use scenes::{PointCloud, View};

#[test]
fn list_is_sorted_and_prefix_holds_every_passing_node() {
    let cloud = statue(50_000);
    let tmp = tempfile::tempdir().unwrap();
    for mode in ["unified", "split"] {
        let m = build_open(&cloud, &[&format!("mode={mode}")], &tmp.path().join(mode)).unwrap();
        let lod = m.lod();
        assert!(
            lod.windows(2).all(|w| w[0][1] >= w[1][1]),
            "sorted by e_par descending"
        );
        for (vi, view) in views(&cloud).iter().enumerate() {
            for eps in [0.0, 0.5, 2.0, 8.0] {
                let mut m2 =
                    build_open(&cloud, &[&format!("mode={mode}")], &tmp.path().join(mode)).unwrap();
                let list = m2
                    .frame(view, Target::Tolerance(eps), &Feedback::default())
                    .unwrap();
                let prefix = list.points() as usize;
                let passed = m.cpu_select(view, eps);
                if let Some(&beyond) = passed.iter().find(|&&i| i as usize >= prefix) {
                    panic!(
                        "{mode} view {vi} eps {eps}: node {beyond} passes beyond prefix {prefix}"
                    );
                }
                let frac = passed.len() as f64 / prefix.max(1) as f64;
                println!(
                    "{mode} view {vi} eps {eps}: prefix {prefix}, CPU pass {} ({:.1} % of prefix culled)",
                    passed.len(),
                    100.0 * (1.0 - frac)
                );
                assert_eq!(m.cpu_passed_in(view, &list).len(), passed.len());
            }
        }
    }
}

/// Per leaf: how many nodes of its ancestor chain pass (`same_r`: every node evaluated at
/// the leaf's position and normal, i.e. the ideal recursive test with one view per chain).
fn chain_counts(
    tree: &PointTree,
    lod: &[[f32; 4]],
    view: &View,
    test: &IntervalTest,
    same_r: bool,
) -> Vec<u32> {
    let eye = view.camera.position;
    let pass: Vec<bool> = tree
        .nodes
        .iter()
        .zip(lod)
        .map(|(n, l)| select::interval_pass(n.p, n.n, *l, eye, test))
        .collect();
    tree.leaf_of
        .iter()
        .map(|&leaf| {
            let (p, nl) = (tree.nodes[leaf as usize].p, tree.nodes[leaf as usize].n);
            let mut i = leaf;
            let mut c = 0;
            loop {
                let n = &tree.nodes[i as usize];
                let ok = if same_r {
                    select::interval_pass(p, nl, lod[i as usize], eye, test)
                } else {
                    pass[i as usize]
                };
                c += ok as u32;
                if n.parent == spt::build::NO_PARENT {
                    break c;
                }
                i = n.parent;
            }
        })
        .collect()
}

/// Along every leaf's ancestor chain: the ideal test (one distance per chain) draws exactly
/// one node; the real test (each node at its own distance) with overlap 1 leaves no hole.
///
/// Overdraw (chains with ≥ 2 nodes drawn): the paper (§3.6) accepts that with the overlap
/// "for some nodes both, the node and some of its children are selected", at the cost of
/// "slightly reduced performance". The band is `o·δ` wide in view distance, so its share of
/// the chains grows with `s = ε/k`; the bounds are per tolerance, the maximum over these 7
/// views that this test prints plus 25 % (statue 50 k, 640×480; deterministic):
///
/// | | ε = 1 px: measured max → bound | ε = 4 px |
/// |-|------:|------:|
/// | unified, overlap 1 | 0.51 % → 0.64 % | 1.44 % → 1.80 % |
/// | split, overlap 1 (angular slack) | 11.06 % → 13.8 % | 16.39 % → 20.5 % |
///
/// The margin is below what doubling the band adds, and the test checks it: with `o = 2` the
/// largest shares are 0.83 % / 2.96 % (unified) and 17.61 % / 23.99 % (split), all over the
/// bounds. (Split mode's figures are format 2's: `γ` also bounds the stored normals' angle;
/// format 1 gave 16.34 % at ε = 4 px.)
#[test]
fn chains_have_no_holes_and_little_overlap() {
    let cloud = statue(50_000);
    let radii = methods::leaf::leaf_radii(&cloud);
    let tree = spt::build::build_tree(&cloud, &radii, 40.0);
    let lod = spt::lod_entries(&tree.nodes);
    let n = cloud.len() as f64;
    // Largest share of chains with ≥ 2 nodes drawn (unified, split), at ε = 1 and 4 px.
    const BOUNDS: [(f64, f64); 2] = [(0.0064, 0.138), (0.0180, 0.205)];
    let mut doubled = [(0f64, 0f64); 2];
    for (vi, view) in views(&cloud).iter().enumerate() {
        for eps in [1.0f32, 4.0] {
            let s = eps / view.proj_scale();
            let t = |mode, overlap| IntervalTest {
                mode,
                scale: s,
                overlap,
            };
            // The ideal recursive test (one distance per chain): exactly one node passes.
            for mode in [select::MODE_UNIFIED, select::MODE_SPLIT] {
                let c = chain_counts(&tree, &lod, view, &t(mode, 0.0), true);
                assert!(
                    c.iter().all(|&c| c == 1),
                    "mode {mode}: ideal test not exactly one"
                );
            }
            let c1 = chain_counts(&tree, &lod, view, &t(select::MODE_UNIFIED, 1.0), false);
            let holes1 = c1.iter().filter(|&&c| c == 0).count();
            let dbl1 = c1.iter().filter(|&&c| c >= 2).count();
            let c0 = chain_counts(&tree, &lod, view, &t(select::MODE_UNIFIED, 0.0), false);
            let holes0 = c0.iter().filter(|&&c| c == 0).count();
            let dbl0 = c0.iter().filter(|&&c| c >= 2).count();
            let cs = chain_counts(&tree, &lod, view, &t(select::MODE_SPLIT, 1.0), false);
            let holes_s = cs.iter().filter(|&&c| c == 0).count();
            let dbl_s = cs.iter().filter(|&&c| c >= 2).count();
            println!(
                "view {vi} eps {eps}: unified overlap 1: holes {holes1}, ≥2 passing {:.2} %; \
                 overlap 0: holes {:.3} %, ≥2 {:.3} %; split overlap 1: holes {:.3} %, ≥2 {:.2} %",
                100.0 * dbl1 as f64 / n,
                100.0 * holes0 as f64 / n,
                100.0 * dbl0 as f64 / n,
                100.0 * holes_s as f64 / n,
                100.0 * dbl_s as f64 / n
            );
            assert_eq!(holes1, 0, "view {vi} eps {eps}: holes with overlap 1");
            assert_eq!(
                holes_s, 0,
                "view {vi} eps {eps}: split-mode holes with overlap 1"
            );
            assert!(dbl0 <= dbl1, "overlap 0 must not add double draws");
            let e = (eps == 4.0) as usize;
            let (max_unified, max_split) = BOUNDS[e];
            // The same with the band doubled, to check below that the bounds would notice.
            let share2 = |mode| {
                let c = chain_counts(&tree, &lod, view, &t(mode, 2.0), false);
                c.iter().filter(|&&c| c >= 2).count() as f64 / n
            };
            doubled[e].0 = doubled[e].0.max(share2(select::MODE_UNIFIED));
            doubled[e].1 = doubled[e].1.max(share2(select::MODE_SPLIT));
            assert!(
                dbl1 as f64 <= max_unified * n,
                "view {vi} eps {eps}: {dbl1} chains draw ≥ 2 nodes (unified, overlap 1)"
            );
            assert!(
                dbl_s as f64 <= max_split * n,
                "view {vi} eps {eps}: {dbl_s} chains draw ≥ 2 nodes (split, overlap 1)"
            );
        }
    }
    println!("overlap 2, largest shares with ≥ 2 drawn (unified, split) at eps 1, 4: {doubled:?}");
    for (d, b) in doubled.iter().zip(BOUNDS) {
        assert!(
            d.0 > b.0 && d.1 > b.1,
            "a doubled band ({d:?}) must exceed the bounds ({b:?})"
        );
    }
}

#[test]
fn tolerance_zero_draws_every_leaf_and_far_views_the_root() {
    let cloud = statue(20_000);
    let tmp = tempfile::tempdir().unwrap();
    let mut m = build_open(&cloud, &[], tmp.path()).unwrap();
    let view = views(&cloud)[0];
    let passed = m.cpu_select(&view, 0.0);
    assert_eq!(
        passed.len(),
        cloud.len(),
        "tolerance 0: exactly the leaves pass"
    );
    assert!(passed.iter().all(|&i| m.lod()[i as usize][0] == 0.0));
    let list = m
        .frame(&view, Target::Tolerance(0.0), &Feedback::default())
        .unwrap();
    assert_eq!(
        list.points(),
        m.lod().len() as u64,
        "tolerance 0 sends everything"
    );
    let root = m
        .lod()
        .iter()
        .position(|l| l[1] == select::ROOT_PARENT_ERROR)
        .unwrap();
    assert!(!passed.contains(&(root as u32)));
    // Far away with a huge tolerance: the root alone.
    let mut far = view;
    far.camera.position = far.camera.target + (far.camera.position - far.camera.target) * 50.0;
    far.camera.far = 1e6;
    assert_eq!(m.cpu_select(&far, 1e4), vec![root as u32]);
    let list = m
        .frame(&far, Target::Tolerance(1e4), &Feedback::default())
        .unwrap();
    assert!(
        list.points() >= 1 && list.points() < 100,
        "prefix {}",
        list.points()
    );
}

#[test]
fn budgets_are_respected_and_monotone() {
    let cloud = statue(50_000);
    let tmp = tempfile::tempdir().unwrap();
    for (k, params) in [&[][..], &["normal_clusters=true"][..]]
        .into_iter()
        .enumerate()
    {
        let mut m = build_open(&cloud, params, &tmp.path().join(k.to_string())).unwrap();
        for view in views(&cloud) {
            let mut last = 0;
            for b in [1u64, 10, 100, 1_000, 5_000, 20_000, 60_000, 1_000_000] {
                let l = m
                    .frame(&view, Target::Budget(b), &Feedback::default())
                    .unwrap();
                assert!(l.points() <= b, "budget {b}: prefix {}", l.points());
                assert!(l.points() >= last, "budget {b}: {} < {last}", l.points());
                last = l.points();
            }
            let mut last = 0;
            for eps in [32.0, 8.0, 2.0, 0.5, 0.0] {
                let l = m
                    .frame(&view, Target::Tolerance(eps), &Feedback::default())
                    .unwrap();
                assert!(l.points() >= last, "eps {eps}");
                last = l.points();
            }
            for t in [
                Target::Tolerance(f32::NAN),
                Target::Tolerance(-1.0),
                Target::Budget(0),
            ] {
                assert!(m.frame(&view, t, &Feedback::default()).is_err());
            }
        }
    }
}

#[test]
fn gpu_limit_is_refused_clearly() {
    let cloud = statue(50_000);
    let tmp = tempfile::tempdir().unwrap();
    let e = match build_open(&cloud, &["gpu_limit_mb=1"], tmp.path()) {
        Err(e) => e.to_string(),
        Ok(_) => panic!("a 50 k model must not fit in 1 MiB"),
    };
    assert!(
        e.contains("gpu_limit_mb = 1") && e.contains("MiB") && e.contains("nodes"),
        "{e}"
    );
    assert!(matches!(
        Spt::open(tmp.path(), Manifest::read(tmp.path()).unwrap()),
        Err(methods::MethodError::Limit(_))
    ));
}

#[test]
fn builds_are_deterministic_and_chunks_carry_the_scene_attributes() {
    let cloud = Generator::Terrain.generate(30_000, 3).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let a = build_open(&cloud, &["normal_clusters=true"], &tmp.path().join("a")).unwrap();
    let b = build_open(&cloud, &["normal_clusters=true"], &tmp.path().join("b")).unwrap();
    for f in ["nodes.bin", "lod.bin", "index.json"] {
        let x = std::fs::read(tmp.path().join("a").join(f)).unwrap();
        let y = std::fs::read(tmp.path().join("b").join(f)).unwrap();
        assert!(x == y, "{f} differs between two builds");
    }
    for id in 0..a.index().chunks.len() as u64 {
        let c = a.chunk(id).unwrap();
        assert_eq!(c, b.chunk(id).unwrap());
        c.validate().unwrap();
        let at = c.attributes();
        assert!(at.normals && at.colors && at.radii && c.lod.is_some());
    }
    assert!(a.chunk(a.index().chunks.len() as u64).is_err());
}

#[test]
fn scenes_without_normals_use_the_unified_fallback() {
    let s = statue(10_000);
    let cloud =
        PointCloud::new(s.origin(), s.positions().to_vec().into(), None, None, None).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let e = build_open(&cloud, &["mode=split"], &tmp.path().join("s"))
        .err()
        .unwrap();
    assert!(e.to_string().contains("mode=split needs normals"), "{e}");
    let mut m = build_open(&cloud, &[], &tmp.path().join("u")).unwrap();
    let view = views(&cloud)[1];
    let l = m
        .frame(&view, Target::Tolerance(2.0), &Feedback::default())
        .unwrap();
    let passed = m.cpu_passed_in(&view, &l);
    assert!(!passed.is_empty());
    let c = m.chunk(0).unwrap();
    assert!(c.normals.is_none() && c.colors.is_none() && c.radii.is_some());
    assert_eq!(m.cpu_select(&view, 0.0).len(), cloud.len());
}

/// Normal clusters on a closed object (statue 50 k, the four orbit views at 640×480). The
/// paper (§3.7): skipping the lists whose normals face away leaves "about 50 %" of the points.
/// Bounds, each from the values this test prints (measured once, then a stated margin):
///
/// - ε = 0 (the whole list is the prefix): the share of the nodes skipped is at most the
///   share facing away, exactly (the skip is conservative: every front-facing node is sent,
///   checked node by node). That share is 54.3–56.1 % here, a little over half: a closed
///   surface seen from 2.5 R shows less than half of itself. Skipped: 37.8, 41.1, 33.3,
///   39.8 %, below the paper's ≈ 50 % because clusters straddling the silhouette are kept (a
///   cone covers every node normal of its cluster). Lower bound 30 %: the measured minimum
///   33.3 % less 10 % of itself.
/// - ε = 1 px, the paper's measure (points sent with clusters against the same build
///   without): 41.4, 44.9, 38.2, 43.6 % fewer (44–47 % at 1 M, 1024², issue-4 measurements),
///   again below the paper's ≈ 50 % for the reason above. Lower bound 34 %: the measured
///   minimum 38.2 % less 10 % of itself.
#[test]
fn normal_clusters_skip_about_half_of_a_closed_statue() {
    let cloud = statue(50_000);
    let tmp = tempfile::tempdir().unwrap();
    let mut m = build_open(
        &cloud,
        &["normal_clusters=true", "cpu_mirror=true"],
        &tmp.path().join("c"),
    )
    .unwrap();
    let mut plain = build_open(&cloud, &[], &tmp.path().join("p")).unwrap();
    assert_eq!(m.index().clusters.len(), select::CLUSTERS);
    let total = m.lod().len() as f64;
    for (vi, view) in views(&cloud).iter().enumerate().take(4) {
        let l = m
            .frame(view, Target::Tolerance(0.0), &Feedback::default())
            .unwrap();
        let skipped_frac = 1.0 - l.points() as f64 / total;
        let eye = view.camera.position;
        let sent_at = |m: &mut Spt, eps| {
            m.frame(view, Target::Tolerance(eps), &Feedback::default())
                .unwrap()
                .points() as f64
        };
        let fewer = 1.0 - sent_at(&mut m, 1.0) / sent_at(&mut plain, 1.0);
        let facing = |i: usize| m.gpu_normal(i).dot(eye - m.position(i)) > 1e-3;
        let back = (0..m.lod().len()).filter(|&i| !facing(i)).count() as f64 / total;
        println!(
            "view {vi}: clusters skipped {}, {:.1} % of the nodes skipped at eps 0, {:.1} % \
             back-facing; {:.1} % fewer splats sent at eps 1",
            l.counters[2],
            100.0 * skipped_frac,
            100.0 * back,
            100.0 * fewer
        );
        assert!(
            skipped_frac >= 0.30 && skipped_frac <= back,
            "view {vi}: {skipped_frac} of the nodes skipped ({back} face away)"
        );
        assert!(
            fewer >= 0.34,
            "view {vi}: clusters send only {fewer} fewer at eps 1"
        );
        // Conservative: every node facing the eye is sent.
        let sent: std::collections::HashSet<u32> = l
            .items
            .iter()
            .flat_map(|it| match it {
                DrawItem::Sequential { id, prefix, .. } => {
                    let s = m.index().chunks[*id as usize].start as u32;
                    s..s + prefix
                }
                _ => 0..0,
            })
            .collect();
        for i in 0..m.lod().len() {
            if facing(i) {
                assert!(sent.contains(&(i as u32)), "front-facing node {i} skipped");
            }
        }
        assert!(l.counters[1] as usize == m.cpu_passed_in(view, &l).len());
    }
}

/// The registry contract (`tests/contract.rs` runs it on `spt` with the default parameters)
/// here also with split mode and normal clusters: tolerance 0 draws every visible sample, the
/// splats drawn (`drawn_points`: those passing the interval test) and the prefixes sent are
/// monotone in the tolerance, budgets are respected and monotone, bad targets rejected, chunks
/// decode with the scene's attributes. `drawn_points` (SPT's CPU mirror) equals the generic
/// count through the chunks (`methods::method::count_drawn`).
#[test]
fn obeys_the_registry_contract() {
    for (cloud, params) in [
        (statue(20_000), &["mode=split", "normal_clusters=true"][..]),
        (statue(20_000), &[][..]),
        (Generator::Terrain.generate(20_000, 3).unwrap(), &[][..]),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let mut m = build_open(&cloud, params, tmp.path()).unwrap();
        assert_eq!(m.input_points(), cloud.len() as u64);
        let b = cloud.bounds();
        let mut vs: Vec<View> = (0..3)
            .map(|i| View {
                camera: PathSpec::parse("orbit").unwrap().camera(i, 3, &b),
                width: 256,
                height: 192,
            })
            .collect();
        vs.push(View {
            camera: PathSpec::parse("zoom").unwrap().camera(7, 10, &b),
            width: 256,
            height: 192,
        });
        for view in &vs {
            let f = view.frustum();
            let eye = view.camera.position;
            let visible = (0..cloud.len())
                .filter(|&i| {
                    let p = Vec3::from(cloud.positions()[i]);
                    f.contains(p)
                        && cloud
                            .normals()
                            .is_none_or(|n| Vec3::from(n[i]).dot(eye - p) > 0.0)
                })
                .count() as u64;
            let all = m
                .frame(view, Target::Tolerance(0.0), &Feedback::default())
                .unwrap();
            let drawn = |m: &Spt, l: &methods::DrawList| {
                let d = m.drawn_points(view, l).unwrap();
                assert_eq!(d, methods::method::count_drawn(m, view, l).unwrap());
                assert!(d <= l.points());
                d
            };
            assert!(
                drawn(&m, &all) >= visible,
                "{params:?}: {} < {visible}",
                drawn(&m, &all)
            );
            for item in &all.items {
                let DrawItem::Sequential { id, prefix, .. } = item else {
                    panic!("only Sequential items")
                };
                let c = m.chunk(*id).unwrap();
                c.validate().unwrap();
                assert!(c.len() >= *prefix as usize);
                assert_eq!(c.attributes().normals, cloud.attributes().normals);
                assert_eq!(c.attributes().colors, cloud.attributes().colors);
                assert!(c.radii.is_some() && c.lod.is_some());
            }
            let (mut last, mut last_drawn) = (0, 0);
            for eps in [32.0, 16.0, 8.0, 4.0, 2.0, 1.0, 0.5, 0.0] {
                let l = m
                    .frame(view, Target::Tolerance(eps), &Feedback::default())
                    .unwrap();
                let d = drawn(&m, &l);
                assert!(
                    l.points() >= last && d >= last_drawn,
                    "{params:?} eps {eps}"
                );
                (last, last_drawn) = (l.points(), d);
            }
            let mut last = 0;
            for b in [1u64, 100, 1_000, 5_000, 15_000, 50_000] {
                let l = m
                    .frame(view, Target::Budget(b), &Feedback::default())
                    .unwrap();
                assert!(l.points() <= b && l.points() >= last);
                last = l.points();
            }
            for t in [
                Target::Tolerance(f32::NAN),
                Target::Tolerance(f32::INFINITY),
                Target::Tolerance(-1.0),
                Target::Budget(0),
            ] {
                assert!(m.frame(view, t, &Feedback::default()).is_err());
            }
        }
    }
}

#[test]
fn corrupt_files_and_bad_params_are_named() {
    let cloud = statue(5_000);
    let tmp = tempfile::tempdir().unwrap();
    let e = build_open(&cloud, &["overlapp=1"], &tmp.path().join("p"))
        .err()
        .unwrap();
    assert!(e.to_string().contains("overlapp"), "{e}");
    let e = build_open(&cloud, &["overlap=-1"], &tmp.path().join("q"))
        .err()
        .unwrap();
    assert!(e.to_string().contains("overlap"), "{e}");
    let e = build_open(&cloud, &["mem_mb=15"], &tmp.path().join("m"))
        .err()
        .unwrap();
    assert!(
        e.to_string()
            .contains("mem_mb must be in 16..=2³⁰ (MiB), got 15"),
        "{e}"
    );
    let dir = tmp.path().join("c");
    build_open(&cloud, &[], &dir).unwrap();
    let lod = dir.join("lod.bin");
    let mut bytes = std::fs::read(&lod).unwrap();
    let last = bytes.len() - 1;
    bytes[last] ^= 0x40;
    std::fs::write(&lod, &bytes).unwrap();
    let e = Spt::open(&dir, Manifest::read(&dir).unwrap())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("lod.bin") && e.contains("checksum"), "{e}");
    std::fs::write(&lod, &bytes[..100]).unwrap();
    let e = Spt::open(&dir, Manifest::read(&dir).unwrap())
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("lod.bin"), "{e}");
}

#[test]
fn index_json_counts_of_any_size_are_errors_not_overflows() {
    // Found by the fuzzer (target spt, `fuzz` profile with overflow checks): index.json is
    // plain JSON, and a node count of 2⁶³ − 1 overflowed `nodes × bytes per node` (a panic
    // in debug builds, a wrapped and wrong size check in release).
    let tmp = tempfile::tempdir().unwrap();
    build_open(&statue(2000), &[], tmp.path()).unwrap();
    let path = tmp.path().join("index.json");
    let orig = std::fs::read_to_string(&path).unwrap();
    let nodes = orig
        .lines()
        .find_map(|l| l.trim().strip_prefix("\"nodes\": "))
        .unwrap()
        .trim_end_matches(',')
        .to_owned();
    let open = |text: &str| {
        std::fs::write(&path, text).unwrap();
        Spt::open(tmp.path(), Manifest::read(tmp.path()).unwrap())
            .map(drop)
            .unwrap_err()
            .to_string()
    };
    let e = open(&orig.replacen(
        &format!("\"nodes\": {nodes}"),
        "\"nodes\": 9223372036854775807",
        1,
    ));
    assert!(e.contains("more than gpu_limit_mb"), "{e}");
    // A cluster or chunk count near 2⁶⁴ in an otherwise valid index.
    let e = open(&orig.replacen(
        &format!("\"count\": {nodes}"),
        "\"count\": 18446744073709551615",
        1,
    ));
    assert!(e.contains("index.json"), "{e}");
}

/// §3.4's left bound, counted and not used (`Spt::left_bounds`): in every cluster, the nodes
/// it would skip at the start of the prefix all fail the interval test (checked node by node
/// with the CPU mirror of the vertex test), in both modes and at several distances and
/// tolerances; and some views have such nodes (the count is not vacuously 0).
#[test]
fn a_left_bound_skips_only_nodes_that_fail() {
    let cloud = statue(20_000);
    let tmp = tempfile::tempdir().unwrap();
    for mode in ["unified", "split"] {
        let m = build_open(&cloud, &[&format!("mode={mode}")], &tmp.path().join(mode)).unwrap();
        let mut skipped = 0;
        for view in views(&cloud) {
            for eps in [1.0f32, 4.0, 16.0] {
                let sel = m.select(&view, Target::Tolerance(eps)).unwrap();
                let s = m.test_for(&view, eps);
                let left = m.left_bounds(s.scale, view.camera.position, &sel.prefixes);
                assert_eq!(left.iter().sum::<u64>(), sel.left_skippable);
                let passing: std::collections::HashSet<u32> =
                    m.cpu_select(&view, eps).into_iter().collect();
                for (c, &l) in m.index().clusters.iter().zip(&left) {
                    for i in c.start..c.start + l {
                        assert!(
                            !passing.contains(&(i as u32)),
                            "{mode} ε = {eps}: node {i} passes but a left bound skips it"
                        );
                    }
                }
                skipped += sel.left_skippable;
            }
        }
        assert!(skipped > 0, "{mode}: no view has a node a left bound skips");
    }
}
