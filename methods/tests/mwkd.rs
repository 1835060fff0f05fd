//! Multi-way kd-tree: the plan against the real split (levels, nodes, leaves, leaf sizes
//! within ±1), a 1 M-point split, the bottom-up build (every inner node holds its planned
//! representatives), and the `Representatives` selection (exact count, covering radii, θ,
//! colour only when present, determinism).
#![allow(clippy::unwrap_used)]

use glam::Vec3;
use methods::Params;
use methods::mwkd::build::Lod;
use methods::mwkd::reps::{RepConfig, Splats, representatives};
use methods::mwkd::tree::{Plan, Tree, child_targets};
use methods::mwkd::{Clustering, MwkdParams, QueueOrder};
use scenes::PointCloud;
use scenes::generators::Generator;

/// xorshift64*: deterministic test randomness.
struct Rng(u64);
impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        self.0.wrapping_mul(0x2545_F491_4F6C_DD1D)
    }
    fn unit(&mut self) -> f32 {
        (self.next() >> 40) as f32 / (1u64 << 24) as f32
    }
}

fn random_positions(n: usize, seed: u64) -> Vec<[f32; 3]> {
    let mut r = Rng(seed | 1);
    (0..n)
        .map(|_| [r.unit() * 10.0, r.unit() * 3.0, r.unit()])
        .collect()
}

/// Checks a split against its plan and its own invariants.
fn check_split(tree: &Tree, positions: &[[f32; 3]], fanout: u32, vbo: u64) {
    let n = positions.len() as u64;
    let plan = Plan::new(n, u64::from(fanout), vbo).unwrap();
    assert_eq!(tree.depth, plan.depth, "n={n} N={fanout} s={vbo}");
    assert_eq!(tree.nodes.len() as u64, plan.nodes());
    assert_eq!(tree.leaves().len() as u64, plan.leaves());
    for lp in &plan.levels {
        let range = tree.level_range(lp.level);
        assert_eq!(range.len() as u64, lp.nodes);
        let lens: Vec<u64> = tree.nodes[range.clone()]
            .iter()
            .map(|nd| nd.len as u64)
            .collect();
        assert_eq!(
            *lens.iter().min().unwrap(),
            lp.points_min,
            "level {}",
            lp.level
        );
        assert_eq!(
            *lens.iter().max().unwrap(),
            lp.points_max,
            "level {}",
            lp.level
        );
        assert_eq!(lens.iter().sum::<u64>(), n);
        for i in range {
            assert_eq!(tree.nodes[i].level, lp.level);
        }
    }
    // Leaves within ±1 of each other, tiling the permutation in order.
    let leaves = &tree.nodes[tree.leaves()];
    let (lo, hi) = leaves
        .iter()
        .fold((usize::MAX, 0), |(a, b), l| (a.min(l.len), b.max(l.len)));
    assert!(hi - lo <= 1, "leaves {lo}–{hi}");
    let mut next = 0;
    for l in leaves {
        assert_eq!(l.start, next);
        next += l.len;
    }
    assert_eq!(next, positions.len());
    let mut seen = tree.order.clone();
    seen.sort_unstable();
    assert!(seen.iter().enumerate().all(|(i, &v)| i as u32 == v));
    // Children: contiguous ranges of the parent, ordered along the parent's longest axis,
    // inside their boxes.
    for i in 0..tree.leaves().start {
        let p = tree.nodes[i];
        let axis = p.bounds.longest_axis();
        let kids = tree.children(i);
        assert_eq!(kids.len(), fanout as usize);
        assert_eq!(tree.nodes[kids.start].start, p.start);
        let mut prev_max = f32::NEG_INFINITY;
        for c in kids {
            assert_eq!(tree.parent(c), Some(i));
            let cn = tree.nodes[c];
            let vals: Vec<f32> = tree.order[cn.range()]
                .iter()
                .map(|&j| positions[j as usize][axis])
                .collect();
            for &j in &tree.order[cn.range()] {
                let q = Vec3::from(positions[j as usize]);
                assert!(q.cmpge(cn.bounds.min).all() && q.cmple(cn.bounds.max).all());
            }
            let mn = vals.iter().copied().fold(f32::INFINITY, f32::min);
            assert!(mn >= prev_max, "children of {i} overlap along axis {axis}");
            prev_max = vals.iter().copied().fold(prev_max, f32::max);
        }
    }
}

#[test]
fn plan_matches_real_split_on_random_clouds() {
    for (n, fanout, vbo, seed) in [
        (1usize, 2u32, 1u64, 1u64),
        (5, 4, 8, 2),
        (3_000, 2, 100, 3),
        (3_001, 3, 77, 4),
        (4_097, 4, 63, 5),
        (7_777, 6, 24, 6),
        (10_000, 7, 200, 7),
        (200_000, 8, 4096, 8),
        (150_001, 3, 1000, 9),
    ] {
        let pos = random_positions(n, seed);
        let tree = Tree::split(&pos, fanout, vbo).unwrap();
        check_split(&tree, &pos, fanout, vbo);
    }
}

#[test]
fn split_is_deterministic_and_handles_duplicates() {
    let pos = random_positions(5_000, 11);
    let a = Tree::split(&pos, 5, 60).unwrap();
    let b = Tree::split(&pos, 5, 60).unwrap();
    assert_eq!(a.order, b.order);
    assert_eq!(a.nodes, b.nodes);
    // All points equal: still balanced.
    let same = vec![[1.0f32, 2.0, 3.0]; 1_000];
    let t = Tree::split(&same, 3, 10).unwrap();
    check_split(&t, &same, 3, 10);
}

#[test]
fn split_1m_statue_leaves_within_one() {
    let cloud = Generator::Statue.generate(1_000_000, 7).unwrap();
    let (fanout, vbo) = (6, 4009);
    let t = std::time::Instant::now();
    let tree = Tree::split(cloud.positions(), fanout, vbo).unwrap();
    let secs = t.elapsed().as_secs_f64();
    let plan = Plan::new(1_000_000, 6, 4009).unwrap();
    assert_eq!(tree.depth, plan.depth);
    assert_eq!(tree.nodes.len() as u64, plan.nodes());
    let leaves = &tree.nodes[tree.leaves()];
    let lo = leaves.iter().map(|l| l.len).min().unwrap();
    let hi = leaves.iter().map(|l| l.len).max().unwrap();
    assert!(hi - lo <= 1, "leaves {lo}–{hi}");
    assert_eq!((lo as u64, hi as u64), plan.leaf_points());
    assert_eq!(leaves.iter().map(|l| l.len).sum::<usize>(), 1_000_000);
    eprintln!(
        "1 M statue, N=6 s=4009: {} levels, {} nodes, leaves {lo}–{hi}, split {secs:.2} s",
        plan.level_count(),
        tree.nodes.len()
    );
}

fn params(pairs: &[&str]) -> MwkdParams {
    MwkdParams::from_params(&Params::parse(pairs).unwrap()).unwrap()
}

/// Every inner node holds exactly the planned representatives, which represent exactly the
/// samples under it and cover its children's splats.
fn check_lod(cloud: &PointCloud, p: &MwkdParams) -> Lod {
    let lod = Lod::build(cloud, p).unwrap();
    let tree = &lod.tree;
    let plan = Plan::new(cloud.len() as u64, u64::from(p.fanout), p.vbo).unwrap();
    assert_eq!(tree.depth, plan.depth);
    assert_eq!(lod.inner.len(), tree.nodes.len());
    let (lo, hi) = plan.inner_held().unwrap();
    for (l, lp) in plan.levels.iter().enumerate().take(tree.depth as usize) {
        let mut total = 0u64;
        for i in tree.level_range(l as u32) {
            let reps = &lod.inner[i];
            let held = reps.len() as u64;
            assert!(
                (lp.held_min..=lp.held_max).contains(&held),
                "node {i} holds {held}, plan {}–{}",
                lp.held_min,
                lp.held_max
            );
            assert!((lo..=hi).contains(&held));
            total += held;
            assert_eq!(reps.total_weight(), tree.nodes[i].len as u64, "node {i}");
            assert_eq!(reps.normals.is_some(), cloud.normals().is_some());
            assert_eq!(reps.colors.is_some(), cloud.colors().is_some());
            assert!(reps.radii.iter().all(|r| r.is_finite() && *r > 0.0));
            // Representatives stay in the node's box, grown by their radius.
            let b = tree.nodes[i].bounds;
            for (q, r) in reps.positions.iter().zip(&reps.radii) {
                assert!(q.cmpge(b.min - *r).all() && q.cmple(b.max + *r).all());
            }
        }
        assert_eq!(total, lp.held_total, "level {l}");
    }
    lod
}

#[test]
fn lod_inner_nodes_hold_s_representatives() {
    // s divisible by N and not; statue (normals) and terrain (normals + colours).
    let statue = Generator::Statue.generate(120_000, 3).unwrap();
    let lod = check_lod(&statue, &params(&["fanout=4", "vbo=2048"]));
    assert!(
        lod.inner[..lod.tree.leaves().start]
            .iter()
            .all(|r| r.len() == 2048)
    );
    check_lod(
        &statue,
        &params(&["fanout=6", "vbo=4009", "queue=deviation"]),
    );
    let terrain = Generator::Terrain.generate(60_000, 3).unwrap();
    let lod = check_lod(&terrain, &params(&["fanout=3", "vbo=1000", "grid=20"]));
    assert!(
        lod.inner[..lod.tree.leaves().start]
            .iter()
            .all(|r| r.len() == 1000)
    );
}

#[test]
fn lod_build_is_deterministic() {
    let cloud = Generator::Statue.generate(30_000, 5).unwrap();
    let p = params(&["fanout=5", "vbo=900"]);
    let a = Lod::build(&cloud, &p).unwrap();
    let b = Lod::build(&cloud, &p).unwrap();
    assert_eq!(a.tree.order, b.tree.order);
    assert_eq!(a.inner, b.inner);
}

#[test]
fn child_targets_sum_to_s() {
    for (n, s) in [(6u64, 4009u64), (3, 85437), (8, 364943), (4, 8)] {
        let t = child_targets(n, s);
        assert_eq!(t.len() as u64, n);
        assert_eq!(t.iter().sum::<u64>(), s);
        assert!(t.iter().max().unwrap() - t.iter().min().unwrap() <= 1);
    }
}

// --- Representatives -------------------------------------------------------------------

fn splats_from(cloud: &PointCloud, range: std::ops::Range<usize>, radius: f32) -> Splats {
    let pos = &cloud.positions()[range.clone()];
    Splats {
        positions: pos.iter().map(|p| Vec3::from(*p)).collect(),
        normals: cloud
            .normals()
            .map(|n| n[range.clone()].iter().map(|v| Vec3::from(*v)).collect()),
        colors: cloud
            .colors()
            .map(|c| c[range.clone()].iter().map(|v| v.map(f32::from)).collect()),
        radii: vec![radius; pos.len()],
        weights: (0..pos.len() as u64).map(|i| 1 + i % 3).collect(),
    }
}

/// Exact count, members valid, radii covering members, weights and averages consistent.
fn check_selection(input: &Splats, target: usize, cfg: &RepConfig) {
    let sel = representatives(input, target, cfg);
    let want = target.max(1).min(input.len());
    assert_eq!(sel.reps.len(), want, "target {target}");
    assert_eq!(sel.members.len(), input.len());
    let mut w = vec![0u64; want];
    for (i, &m) in sel.members.iter().enumerate() {
        let m = m as usize;
        assert!(m < want);
        w[m] += input.weights[i];
        let d = input.positions[i].distance(sel.reps.positions[m]) + input.radii[i];
        assert!(
            d <= sel.reps.radii[m],
            "member {i} at {d} outside radius {}",
            sel.reps.radii[m]
        );
    }
    assert_eq!(w, sel.reps.weights, "weights are member sums");
    // Position = weighted mean of the members.
    let mut sum = vec![glam::DVec3::ZERO; want];
    for (i, &m) in sel.members.iter().enumerate() {
        sum[m as usize] += input.positions[i].as_dvec3() * input.weights[i] as f64;
    }
    for k in 0..want {
        let mean = (sum[k] / w[k] as f64).as_vec3();
        assert!(mean.distance(sel.reps.positions[k]) < 1e-4, "rep {k}");
    }
    if let Some(n) = &sel.reps.normals {
        assert!(n.iter().all(|v| (v.length() - 1.0).abs() < 1e-3));
    }
}

#[test]
fn representatives_exact_count_and_cover() {
    let statue = Generator::Statue.generate(20_000, 9).unwrap();
    let terrain = Generator::Terrain.generate(8_000, 9).unwrap();
    let s = splats_from(&statue, 0..20_000, 0.004);
    let t = splats_from(&terrain, 0..8_000, 1.0);
    for cfg in [
        RepConfig::default(),
        RepConfig {
            queue: QueueOrder::Deviation,
            ..RepConfig::default()
        },
        RepConfig {
            grid: 3,
            theta_deg: 5.0,
            relax: 1.1,
            ..RepConfig::default()
        },
    ] {
        for target in [0, 1, 2, 7, 100, 1000, 5000, 19_999, 20_000, 30_000] {
            check_selection(&s, target, &cfg);
        }
        for target in [1, 50, 2000, 7999] {
            check_selection(&t, target, &cfg);
        }
    }
    // Empty input: nothing.
    let e = representatives(&Splats::empty(true, false), 5, &RepConfig::default());
    assert!(e.reps.is_empty() && e.members.is_empty());
}

/// Two interleaved sheets of points in the same cells, normals 90° apart.
fn two_sheets(n: usize, colors: Option<[[f32; 3]; 2]>) -> Splats {
    let mut r = Rng(77);
    let mut s = Splats::empty(true, colors.is_some());
    for i in 0..n {
        let g = i % 2;
        s.positions.push(Vec3::new(r.unit(), r.unit(), 0.0));
        if let Some(nv) = &mut s.normals {
            nv.push(if g == 0 { Vec3::Z } else { Vec3::X });
        }
        if let (Some(cv), Some(c)) = (&mut s.colors, colors) {
            cv.push(c[g]);
        }
        s.radii.push(0.001);
        s.weights.push(1);
    }
    s
}

fn mixes(sel: &methods::mwkd::reps::Selection, group: impl Fn(usize) -> usize) -> usize {
    let mut first: Vec<Option<usize>> = vec![None; sel.reps.len()];
    let mut mixed = vec![false; sel.reps.len()];
    for (i, &m) in sel.members.iter().enumerate() {
        match first[m as usize] {
            None => first[m as usize] = Some(group(i)),
            Some(g) if g != group(i) => mixed[m as usize] = true,
            _ => {}
        }
    }
    mixed.iter().filter(|&&b| b).count()
}

#[test]
fn representatives_respect_theta_when_possible() {
    let s = two_sheets(4_000, None);
    let cfg = RepConfig {
        grid: 4,
        theta_deg: 30.0,
        ..RepConfig::default()
    };
    // 4 × 4 (flat in z) occupied cells × 2 normal groups = 32 ≤ target: no rep mixes the sheets.
    for target in [32, 40, 200, 1000] {
        let sel = representatives(&s, target, &cfg);
        assert_eq!(sel.reps.len(), target);
        assert_eq!(mixes(&sel, |i| i % 2), 0, "target {target}");
        assert!(sel.theta_used_deg <= 30.0 + 1e-3);
        for (k, n) in sel.reps.normals.as_ref().unwrap().iter().enumerate() {
            assert!(
                n.dot(Vec3::Z) > 0.999 || n.dot(Vec3::X) > 0.999,
                "rep {k}: {n}"
            );
        }
    }
    // Below that, θ must be relaxed and sheets merge — still exactly the target.
    let sel = representatives(&s, 10, &cfg);
    assert_eq!(sel.reps.len(), 10);
    assert!(sel.theta_used_deg > 30.0);
    assert!(mixes(&sel, |i| i % 2) > 0);
}

#[test]
fn representatives_use_colour_only_when_present() {
    // Same normals, two colour groups.
    let grey = two_sheets(2_000, None);
    let mut flat = grey.clone();
    flat.normals = Some(vec![Vec3::Z; flat.len()]);
    let mut coloured = flat.clone();
    coloured.colors = Some(
        (0..flat.len())
            .map(|i| {
                if i % 2 == 0 {
                    [250.0, 10.0, 10.0]
                } else {
                    [10.0, 10.0, 250.0]
                }
            })
            .collect(),
    );
    let cfg = RepConfig {
        grid: 4,
        ..RepConfig::default()
    };
    let with = representatives(&coloured, 64, &cfg);
    assert_eq!(mixes(&with, |i| i % 2), 0, "colours separate clusters");
    let colors = with.reps.colors.as_ref().unwrap();
    assert!(colors.iter().all(|c| c[0] > 249.0 || c[2] > 249.0));
    let without = representatives(&flat, 64, &cfg);
    assert!(without.reps.colors.is_none());
    assert!(
        mixes(&without, |i| i % 2) > 0,
        "no colour: groups are free to merge"
    );
    // A uniform colour changes nothing but adds the colour column.
    let mut uniform = flat.clone();
    uniform.colors = Some(vec![[90.0, 90.0, 90.0]; flat.len()]);
    let u = representatives(&uniform, 64, &cfg);
    assert_eq!(u.members, without.members);
    assert_eq!(u.reps.positions, without.reps.positions);
}

#[test]
fn representatives_are_deterministic() {
    let statue = Generator::Statue.generate(10_000, 4).unwrap();
    let s = splats_from(&statue, 0..10_000, 0.003);
    let cfg = RepConfig::default();
    let a = representatives(&s, 777, &cfg);
    let b = representatives(&s, 777, &cfg);
    assert_eq!(a, b);
    // Independent of thread count: run inside a 1-thread pool too.
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let c = pool.install(|| representatives(&s, 777, &cfg));
    assert_eq!(a, c);
}

#[test]
fn lod_1m_statue_leaves_within_one_inner_nodes_hold_s() {
    let cloud = Generator::Statue.generate(1_000_000, 7).unwrap();
    let t = std::time::Instant::now();
    let p = params(&["fanout=8", "vbo=16384"]);
    let lod = check_lod(&cloud, &p);
    let leaves = &lod.tree.nodes[lod.tree.leaves()];
    let lo = leaves.iter().map(|l| l.len).min().unwrap();
    let hi = leaves.iter().map(|l| l.len).max().unwrap();
    assert!(hi - lo <= 1, "leaves {lo}–{hi}");
    assert!(
        lod.inner[..lod.tree.leaves().start]
            .iter()
            .all(|r| r.len() == 16384)
    );
    eprintln!(
        "1 M statue, N=8 s=16384: {} nodes, leaves {lo}–{hi}, inner nodes {} × 16384, build {:.1} s",
        lod.tree.nodes.len(),
        lod.tree.leaves().start,
        t.elapsed().as_secs_f64()
    );
}

/// Fig. 2's grid sampling (`clustering = grid`): one representative per occupied cell of the
/// (lowered) grid, the weighted mean of everything in it, covering its members; never more
/// than the target, and every representative's members share one cell (two members of a
/// representative lie within a cell's extent of each other). The adaptive clustering on
/// the same input gives exactly the target.
#[test]
fn grid_clustering_gives_one_representative_per_occupied_cell() {
    let statue = Generator::Statue.generate(20_000, 9).unwrap();
    let s = splats_from(&statue, 0..20_000, 0.004);
    let (lo, hi) = s
        .positions
        .iter()
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    for target in [7usize, 100, 1000, 5000] {
        let grid = RepConfig {
            clustering: Clustering::Grid,
            ..RepConfig::default()
        };
        let sel = representatives(&s, target, &grid);
        let n = sel.reps.len();
        assert!(n >= 1 && n <= target, "target {target}: {n}");
        let mut w = vec![0u64; n];
        let cell = (hi - lo) / sel.grid_used as f32;
        let mut first: Vec<Option<Vec3>> = vec![None; n];
        for (i, &m) in sel.members.iter().enumerate() {
            let (m, p) = (m as usize, s.positions[i]);
            w[m] += s.weights[i];
            assert!(p.distance(sel.reps.positions[m]) + s.radii[i] <= sel.reps.radii[m]);
            let f = *first[m].get_or_insert(p);
            assert!(
                ((p - f).abs() - cell).max_element() <= 1e-4,
                "target {target}: members of rep {m} span more than a cell"
            );
        }
        assert_eq!(w, sel.reps.weights);
        assert_eq!(
            representatives(&s, target, &RepConfig::default())
                .reps
                .len(),
            target
        );
    }
}
