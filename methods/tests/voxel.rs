//! `voxel` (colour-filtered voxel LOD, Schütz et al. 2023) read back from its files: every
//! inner node holds exactly one sample per occupied cell of its 128³ grid, with the mean
//! colour of its children's samples in that cell (the default, the authors' filter) or the
//! exact mean colour of the input points in it (`filter=points`), at the cell's centre (or
//! the mean position); the leaves hold every input point once; the files do not depend on the thread
//! count nor on the build memory; the selection replaces a parent's voxels by its drawn
//! children and converges on the input points.
#![allow(clippy::unwrap_used)]

mod common;

use std::collections::BTreeMap;
use std::path::Path;

use glam::DVec3;
use methods::potree::format::Metadata;
use methods::potree::octree::Quant;
use methods::voxel::MODE;
use methods::voxel::grid::{cell_depth, cell_key};
use methods::{Feedback, LodMethod, MethodKind, Params, Target};
use scenes::generators::Generator;
use scenes::{PointCloud, View};

fn build(cloud: &PointCloud, params: &[&str], dir: &Path) -> methods::BuildStats {
    let params = Params::parse(&params.iter().map(|s| s.to_string()).collect::<Vec<_>>()).unwrap();
    MethodKind::Voxel
        .build(cloud, &params, "test", dir, &scenes::NoProgress)
        .unwrap()
}

/// A record read back: integer position and 8-bit colour.
type Rec = ([i32; 3], Option<[u8; 3]>);

/// An input point as the build quantises it: Morton code, integer position, colour.
type Quantised = (u64, [i32; 3], Option<[u8; 3]>);

/// The input points' Morton codes, integer positions and colours, as the build quantises
/// them.
fn quantised(cloud: &PointCloud) -> (Quant, Vec<Quantised>) {
    let quant = Quant::of(cloud);
    let pts = cloud
        .positions()
        .iter()
        .enumerate()
        .map(|(i, &p)| {
            let q = quant.of_local(cloud.origin(), p);
            (quant.morton(q), q, cloud.colors().map(|c| c[i]))
        })
        .collect();
    (quant, pts)
}

/// The cell's centre at `depth`, quantised.
fn centre(quant: &Quant, key: u64, depth: u32) -> [i32; 3] {
    let axis = |shift: u32| f64::from(methods::morton::compact21(key >> shift));
    let cell = quant.size / f64::from(1u32 << depth);
    let c = DVec3::new(axis(2), axis(1), axis(0));
    quant.quantise(quant.min + (c + DVec3::splat(0.5)) * cell)
}

/// What a voxel record in the cell `key` (at `depth`) must hold, from the sums of what it
/// averages (count, colour sums, integer position sums): the rounded mean colour, and the
/// cell's centre or (`position=mean`) the rounded mean position — which lies in its cell, so
/// the cell found from it is the voxel's.
fn expected(
    quant: &Quant,
    key: u64,
    depth: u32,
    position: &str,
    (count, rgb, sum_q): (u64, [u64; 3], [i64; 3]),
) -> ([u8; 3], [i32; 3]) {
    let mean = rgb.map(|v| ((v + count / 2) / count) as u8);
    let q = if position == "centre" {
        centre(quant, key, depth)
    } else {
        let n = count as i64;
        sum_q.map(|v| ((v + n / 2) / n) as i32)
    };
    (mean, q)
}

/// With `filter=points`, on a coloured terrain of 20 k points split at 1,500 per leaf (four
/// levels of voxels): every inner node has one record per occupied cell of its grid, no
/// more, no fewer; its colour is the rounded mean of the 8-bit colours of every input point
/// in the cell (the sums of all the points below, not a mean of the children's means); its
/// position is the cell's centre, or with `position=mean` the rounded mean of the points'
/// integer positions. The leaves hold every input point exactly once, with its own colour.
#[test]
fn one_sample_per_occupied_voxel_with_the_exact_mean_colour() {
    let cloud = Generator::Terrain.generate(20_000, 3).unwrap();
    let (quant, pts) = quantised(&cloud);
    for position in ["centre", "mean"] {
        let tmp = tempfile::tempdir().unwrap();
        let p = format!("position={position}");
        let stats = build(&cloud, &["max_leaf=1500", "filter=points", &p], tmp.path());
        let (meta, nodes) = common::read_back(tmp.path(), "voxel.json", MODE);
        assert_eq!(meta.points, 20_000);
        let mut leaf_points = Vec::new();
        let mut voxels = 0;
        let mut inner = 0;
        for (span, recs) in &nodes {
            let (level, path) = (&span.level, &span.path);
            if span.leaf {
                leaf_points.extend(recs.iter().copied());
                continue;
            }
            inner += 1;
            let depth = cell_depth(*level);
            // The cells of the input points below this node, with their sums.
            let mut cells: BTreeMap<u64, (u64, [u64; 3], [i64; 3])> = BTreeMap::new();
            for (code, q, c) in &pts {
                if code >> (3 * (21 - level)) != *path {
                    continue;
                }
                let e = cells.entry(cell_key(*code, depth)).or_default();
                e.0 += 1;
                let rgb = c.unwrap();
                (0..3).for_each(|k| {
                    e.1[k] += u64::from(rgb[k]);
                    e.2[k] += i64::from(q[k]);
                });
            }
            assert_eq!(recs.len(), cells.len(), "{position}: node {level}/{path:o}");
            voxels += recs.len();
            let mut seen = std::collections::BTreeSet::new();
            for (q, c) in recs {
                let key = cell_key(quant.morton(*q), depth);
                assert!(seen.insert(key), "{position}: cell {key} twice");
                let (mean, want) = expected(&quant, key, depth, position, cells[&key]);
                assert_eq!(c.unwrap(), mean, "{position}: node {level}/{path:o}");
                assert_eq!(*q, want, "{position}: node {level}/{path:o}");
            }
        }
        assert!(inner >= 5, "{position}: {inner} inner nodes");
        let mut want: Vec<Rec> = pts.iter().map(|&(_, q, c)| (q, c)).collect();
        want.sort_unstable();
        leaf_points.sort_unstable();
        assert!(
            leaf_points == want,
            "{position}: the leaves are not the input"
        );
        assert_eq!(
            stats.extra["samples"].as_u64().unwrap(),
            20_000 + voxels as u64
        );
    }
}

/// The default filter, the authors' "average in cell": on the same terrain, every inner
/// node's record in a cell has the rounded mean colour of its children's records in that
/// cell (a child's voxel counts once, as a leaf's point does), read from the files alone;
/// one record per cell its children occupy (the cells the input occupies); at the cell's
/// centre, or with `position=mean` the rounded mean of the children's records' positions.
/// The same build with `filter=points` differs in some colour: the test tells them apart.
#[test]
fn a_voxel_averages_its_childrens_samples_by_default() {
    let cloud = Generator::Terrain.generate(20_000, 3).unwrap();
    let (quant, pts) = quantised(&cloud);
    for position in ["centre", "mean"] {
        let tmp = tempfile::tempdir().unwrap();
        let p = format!("position={position}");
        build(&cloud, &["max_leaf=1500", &p], tmp.path());
        let (_, nodes) = common::read_back(tmp.path(), "voxel.json", MODE);
        let by_node: BTreeMap<(u32, u64), &Vec<Rec>> = nodes
            .iter()
            .map(|(s, recs)| ((s.level, s.path), recs))
            .collect();
        let (mut inner, mut differ) = (0, 0);
        for (span, recs) in &nodes {
            if span.leaf {
                continue;
            }
            inner += 1;
            let (level, path) = (span.level, span.path);
            let depth = cell_depth(level);
            // The children's records by this node's cell: count, colour sums, position sums.
            let mut cells: BTreeMap<u64, (u64, [u64; 3], [i64; 3])> = BTreeMap::new();
            for octant in 0..8 {
                let Some(child) = by_node.get(&(level + 1, path << 3 | octant)) else {
                    continue;
                };
                for (q, c) in child.iter() {
                    let e = cells.entry(cell_key(quant.morton(*q), depth)).or_default();
                    e.0 += 1;
                    let rgb = c.unwrap();
                    (0..3).for_each(|k| {
                        e.1[k] += u64::from(rgb[k]);
                        e.2[k] += i64::from(q[k]);
                    });
                }
            }
            // The input's cells below this node: the same set.
            let mut occupied: Vec<u64> = pts
                .iter()
                .filter(|(code, _, _)| code >> (3 * (21 - level)) == path)
                .map(|(code, _, _)| cell_key(*code, depth))
                .collect();
            occupied.sort_unstable();
            occupied.dedup();
            assert!(
                cells.keys().copied().eq(occupied.iter().copied()),
                "{position}: node {level}/{path:o}: the children's cells are not the input's"
            );
            assert_eq!(recs.len(), cells.len(), "{position}: node {level}/{path:o}");
            for (q, c) in recs.iter() {
                let key = cell_key(quant.morton(*q), depth);
                let (mean, want) = expected(&quant, key, depth, position, cells[&key]);
                assert_eq!(c.unwrap(), mean, "{position}: node {level}/{path:o}");
                assert_eq!(*q, want, "{position}: node {level}/{path:o}");
                // The exact mean over the input points in the cell, for comparison.
                let (n, sum) = pts
                    .iter()
                    .filter(|(code, _, _)| cell_key(*code, depth) == key)
                    .fold((0u64, [0u64; 3]), |(n, s), (_, _, c)| {
                        let c = c.unwrap();
                        (n + 1, [0, 1, 2].map(|k| s[k] + u64::from(c[k])))
                    });
                let exact = sum.map(|v| ((v + n / 2) / n) as u8);
                differ += usize::from(exact != mean);
            }
        }
        assert!(inner >= 5, "{position}: {inner} inner nodes");
        assert!(
            differ > 0,
            "{position}: no voxel tells the children's mean from the points' mean"
        );
    }
}

/// A scene without colours stores and averages none (and one without normals no normals).
#[test]
fn only_the_attributes_the_scene_has_are_stored() {
    let cloud = Generator::Statue.generate(5_000, 1).unwrap();
    assert!(cloud.colors().is_none());
    let tmp = tempfile::tempdir().unwrap();
    build(&cloud, &["max_leaf=500"], tmp.path());
    let meta = Metadata::read(tmp.path()).unwrap();
    let layout = meta.layout(&tmp.path().join("metadata.json")).unwrap();
    assert_eq!(layout.rgb, None);
    assert_eq!(layout.normal.is_some(), cloud.normals().is_some());
    let m = MethodKind::open(tmp.path()).unwrap();
    assert!(!m.attributes().colors);
}

/// A cloud that fits one leaf (20 k points, leaves of 50 k) still has its coarsest level: a
/// root of voxels (one per occupied cell of its grid, fewer than the points) over leaves that
/// hold every point once, each in its octant.
#[test]
fn a_cloud_of_one_leaf_still_gets_its_root_grid() {
    let cloud = Generator::Statue.generate(20_000, 7).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let stats = build(&cloud, &[], tmp.path());
    let (_, nodes) = common::read_back(tmp.path(), "voxel.json", MODE);
    let (root, voxels) = &nodes[0];
    assert!(!root.leaf && root.level == 0);
    let (quant, pts) = quantised(&cloud);
    let mut cells: Vec<u64> = pts.iter().map(|p| cell_key(p.0, cell_depth(0))).collect();
    cells.sort_unstable();
    cells.dedup();
    assert_eq!(voxels.len(), cells.len());
    assert!(voxels.len() < 20_000);
    let leaves: Vec<_> = nodes[1..].iter().filter(|(s, _)| s.leaf).collect();
    assert_eq!(
        leaves.len(),
        nodes.len() - 1,
        "every child of the root is a leaf"
    );
    assert_eq!(leaves.iter().map(|(_, r)| r.len()).sum::<usize>(), 20_000);
    for (s, recs) in leaves {
        assert!(recs.iter().all(|(q, _)| quant.morton(*q) >> 60 == s.path));
    }
    assert_eq!(stats.levels, 2);
}

fn files(dir: &Path) -> Vec<Vec<u8>> {
    ["octree.bin", "hierarchy.bin", "metadata.json", "voxel.json"]
        .iter()
        .map(|f| std::fs::read(dir.join(f)).unwrap())
        .collect()
}

#[test]
fn builds_are_byte_identical_across_thread_counts() {
    let cloud = Generator::Terrain.generate(30_000, 9).unwrap();
    for filter in ["filter=children", "filter=points"] {
        let files = |threads: usize| -> Vec<Vec<u8>> {
            let tmp = tempfile::tempdir().unwrap();
            common::with_threads(threads, || {
                build(&cloud, &["max_leaf=1000", filter], tmp.path())
            });
            files(tmp.path())
        };
        assert!(
            files(1) == files(3),
            "{filter}: a build depends on the thread count"
        );
    }
}

/// A build in units (`mem_mb=1`: at most 16,384 points a unit) writes the in-core build's
/// files byte for byte, with `position=centre` and `mean` and either filter: a voxel's sums come from its
/// own subtree only, so a unit's root hands the top the same voxels.
#[test]
fn a_build_in_units_equals_the_build_in_core() {
    let cloud = Generator::Terrain.generate(120_000, 4).unwrap();
    for (position, filter) in [
        ("centre", "children"),
        ("mean", "children"),
        ("centre", "points"),
    ] {
        let tmp = tempfile::tempdir().unwrap();
        let (core, units) = (tmp.path().join("core"), tmp.path().join("units"));
        let p = format!("position={position}");
        let f = format!("filter={filter}");
        build(&cloud, &["max_leaf=3000", &p, &f], &core);
        let stats = build(&cloud, &["max_leaf=3000", "mem_mb=1", &p, &f], &units);
        let n_units = stats.extra["units"].as_u64().unwrap();
        assert!(n_units > 7, "{position}: {n_units} units");
        assert!(stats.extra["largest_unit"].as_u64().unwrap() <= 16_384);
        assert!(
            files(&core) == files(&units),
            "{position}, {filter}: units change the files"
        );
    }
}

fn view(cloud: &PointCloud, i: usize) -> View {
    View {
        camera: scenes::paths::PathSpec::parse("orbit")
            .unwrap()
            .camera(i, 4, &cloud.bounds()),
        width: 256,
        height: 192,
    }
}

/// Selection: at ε = 0 (every node loaded, `load=sync`) the children have replaced every
/// voxel and exactly the input points in view are drawn, the leaves whole; at ε = 8 px fewer
/// samples are drawn, voxels among them; a budget bounds the samples sent, which never
/// decrease as it grows; nothing drawn overlaps (no node is drawn where a drawn child is).
#[test]
fn children_replace_their_parents_voxels_and_converge_on_the_input() {
    let cloud = Generator::Terrain.generate(40_000, 5).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    build(&cloud, &["max_leaf=2000", "load=sync"], tmp.path());
    let mut m = MethodKind::open(tmp.path()).unwrap();
    for i in 0..4 {
        let v = view(&cloud, i);
        let fb = Feedback::default();
        let all = m.frame(&v, Target::Tolerance(0.0), &fb).unwrap();
        // Every drawn splat of ε = 0 is an input point: the drawn positions are a subset of
        // the input's (decoded as the reader decodes them), each at most once.
        let (quant, pts) = quantised(&cloud);
        let shift = quant.min - cloud.origin();
        let local = |q: [i32; 3]| {
            let w =
                DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])) * quant.scale + shift;
            w.as_vec3().to_array().map(f32::to_bits)
        };
        let mut input: Vec<[u32; 3]> = pts.iter().map(|p| local(p.1)).collect();
        input.sort_unstable();
        let drawn = positions(m.as_ref(), &all);
        let mut sorted = drawn.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), drawn.len(), "view {i}: a sample drawn twice");
        assert!(
            drawn.iter().all(|q| input.binary_search(q).is_ok()),
            "view {i}: a voxel is drawn at ε = 0"
        );
        let coarse = m.frame(&v, Target::Tolerance(8.0), &fb).unwrap();
        assert!(coarse.points() < all.points(), "view {i}");
        let mut last = 0;
        for b in [30_000u64, 60_000, 120_000, 1_000_000] {
            let l = m.frame(&v, Target::Budget(b), &fb).unwrap();
            assert!(l.points() <= b, "view {i}: budget {b}: {}", l.points());
            assert!(l.points() >= last, "view {i}: budget {b}");
            last = l.points();
        }
    }
    // From afar the root's voxels alone are drawn: fewer than the input.
    let far = m
        .frame(
            &view(&cloud, 0),
            Target::Tolerance(1000.0),
            &Feedback::default(),
        )
        .unwrap();
    assert!(far.points() > 0 && far.points() < 40_000);
}

/// The positions (bits) of the splats `list` draws.
fn positions(m: &dyn LodMethod, list: &methods::DrawList) -> Vec<[u32; 3]> {
    let mut out = Vec::new();
    for item in &list.items {
        let c = item.cached().unwrap();
        let batch = m.chunk(c.id).unwrap();
        for p in &batch.positions[c.first as usize..(c.first + c.count) as usize] {
            out.push(p.map(f32::to_bits));
        }
    }
    out
}
