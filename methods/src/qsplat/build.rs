//! Building QSplat's bounding-sphere hierarchy and quantising it.
//!
//! Contract: [`build_tree`] is a deterministic function of the cloud (and its leaf radii):
//! - the samples (position and index) are partitioned in place, top-down, along the longest
//!   axis of each range's bounding box: at the spatial midpoint of that axis ([`Split`]; the
//!   paper's rule, the default) or at the median (`select_nth_unstable_by`, ties broken by
//!   sample index). Halves are split in parallel with `rayon::join` above
//!   [`PAR_THRESHOLD`]. The binary tree is recorded by split position (`Binary`);
//! - binary levels are combined ([`Combine`]): an inner node's children are its binary
//!   grandchildren (a binary child that is a leaf is taken as is) or its binary children,
//!   per binary node whichever gives fewer interior nodes (default), or always the
//!   grandchildren; so every inner node has 2, 3 or 4 children and every leaf is one
//!   sample;
//! - nodes are numbered breadth-first (level by level), properties computed bottom-up
//!   (sphere bounding the children's spheres, normalised mean normal, cone covering the
//!   children's cones, leaf-weighted mean colour) and quantised top-down from the *decoded*
//!   parents ([`super::quant`]), in `forest.rs`. Each level is processed in parallel; the
//!   output does not depend on the thread count.

use glam::{BVec3A, Vec3, Vec3A};
use scenes::PointCloud;

use super::node::Binary;
use super::stats::QuantStats;
use crate::MethodError;
use crate::spill::{Spill, SpillDir};

/// Ranges at least this long are split in parallel.
pub const PAR_THRESHOLD: usize = 1 << 15;

pub use super::node::QNode;

/// A quantised tree in breadth-first order: `levels[l]` lists level `l`'s nodes; the
/// children of level `l`'s nodes are consecutive in level `l + 1`, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct QTree {
    /// Nodes per level.
    pub levels: Vec<Vec<QNode>>,
    /// Root sphere: centre and radius.
    pub root: [f32; 4],
    /// The scene has normals.
    pub normals: bool,
    /// The scene has colours.
    pub colors: bool,
}

impl QTree {
    /// Total nodes.
    pub fn nodes(&self) -> u64 {
        self.levels.iter().map(|l| l.len() as u64).sum()
    }
    /// Nodes without children.
    pub fn leaves(&self) -> u64 {
        self.levels
            .iter()
            .flatten()
            .filter(|n| n.children == 0)
            .count() as u64
    }
}

/// What [`build_tree`] returns besides the file contents.
#[derive(Debug, Clone)]
pub struct Built {
    /// The quantised tree.
    pub tree: QTree,
    /// True sphere per node per level (centre, radius), for tests.
    pub true_spheres: Vec<Vec<(Vec3, f32)>>,
    /// Decoded sphere per node per level, for tests.
    pub decoded_spheres: Vec<Vec<(Vec3, f32)>>,
    /// True unit normal per node per level (zero without normals), for tests: at a leaf,
    /// the sample's normal.
    pub true_normals: Vec<Vec<Vec3>>,
    /// What quantisation did to the nodes (§3.1's figures).
    pub quant: QuantStats,
}

/// Where a range is split (`--param split=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Split {
    /// The paper's rule: the spatial midpoint of the longest axis of the range's bounding
    /// box (samples below the midpoint go left). §3.2 rejects equal-count splits ("putting an
    /// equal number of vertices in each subtree can potentially put the splitting planes
    /// significantly off-center") and calls its trees "axis-aligned bisections" that are not
    /// "complete and balanced". A split that leaves one side empty (coincident samples, or a
    /// midpoint that rounds to an end) falls back to the median.
    #[default]
    Midpoint,
    /// The median along the longest axis (equal counts; the tree shape is a function of `n`).
    Median,
}

/// How binary levels are combined into 2–4 children (`--param combine=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Combine {
    /// Per binary node, its binary grandchildren (a binary child that is a leaf is taken as
    /// is) or its binary children, whichever gives fewer interior nodes in its subtree
    /// (dynamic programme, bottom-up; ties take the grandchildren). The paper only says nodes
    /// are combined "to increase the average branching factor to approximately 4", which
    /// "reduces the number of interior nodes": this rule serves that stated purpose.
    #[default]
    Fewest,
    /// Pair binary levels from the top: every inner node's children are its binary
    /// grandchildren (a binary child that is a leaf is taken as is).
    Pairs,
}

/// Build options.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct BuildOptions {
    /// Split rule.
    pub split: Split,
    /// Combine rule.
    pub combine: Combine,
    /// Sphere-code choice.
    pub fit: super::quant::Fit,
}

/// A binary node's subtree cost: (interior nodes of its combined subtree, the same summed
/// over its binary children). Leaves cost (0, 0).
type Cost = (u64, u64);

/// A sample during partitioning: its position (copied, so that the scans are sequential)
/// and index.
#[derive(Clone, Copy)]
struct Item {
    p: Vec3,
    i: u32,
}

type Bounds = (Vec3, Vec3);

fn bounds_of(items: &[Item]) -> Bounds {
    items.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), it| (lo.min(it.p), hi.max(it.p)),
    )
}

/// Moves the items with coordinate `axis` below `cut` to the front; returns their count and
/// the bounding boxes of the two sides.
///
/// Without a branch on the side (a sample's side is a coin flip on a random scan; with the
/// two-pointer loop this pass was 11–18 % of a QSplat build's samples, `perf`, terrain 10 M,
/// and without the branch the whole build takes ×0.95 the wall time, paired): every item
/// is swapped to the front's end and the front grows by one when it belongs there
/// (Lomuto's scheme), and both boxes take every sample, the other side's as ±∞. Which
/// samples go left depends on the set alone, never on its order, so the tree and the file
/// are those of any other partition scheme.
fn split_at_cut(items: &mut [Item], axis: usize, cut: f64) -> (usize, Bounds, Bounds) {
    let (inf, ninf) = (Vec3A::INFINITY, Vec3A::NEG_INFINITY);
    let (mut lmin, mut lmax, mut rmin, mut rmax) = (inf, ninf, inf, ninf);
    let mut a = 0;
    for j in 0..items.len() {
        let it = items[j];
        let below = (it.p[axis] as f64) < cut;
        items.swap(a, j);
        a += usize::from(below);
        let p = Vec3A::from(it.p);
        let m = BVec3A::splat(below);
        lmin = lmin.min(Vec3A::select(m, p, inf));
        lmax = lmax.max(Vec3A::select(m, p, ninf));
        rmin = rmin.min(Vec3A::select(m, inf, p));
        rmax = rmax.max(Vec3A::select(m, ninf, p));
    }
    (a, (lmin.into(), lmax.into()), (rmin.into(), rmax.into()))
}

/// Partitions `items` (positions `base..base + items.len()`, bounding box `bounds`) in
/// place, records the splits of its binary nodes in `left`/`right`/`grand` (slices of the
/// same positions) and returns the range's split (absolute, 0 for a single sample) and cost.
/// The midpoint scan grows the two halves' boxes as it goes, so a level costs one pass.
fn partition(
    items: &mut [Item],
    bounds: Bounds,
    base: u32,
    opt: BuildOptions,
    left: &mut [u32],
    right: &mut [u32],
    grand: &mut [bool],
) -> (u32, Cost) {
    let n = items.len();
    if n <= 1 {
        return (0, (0, 0));
    }
    let (lo, hi) = bounds;
    let axis = scenes::Aabb { min: lo, max: hi }.longest_axis();
    // The midpoint's split, unless it left a side empty; else the median's.
    let at_cut = (opt.split == Split::Midpoint)
        .then(|| split_at_cut(items, axis, (lo[axis] as f64 + hi[axis] as f64) * 0.5))
        .filter(|&(mid, _, _)| mid != 0 && mid != n);
    let (mid, lb, rb) = at_cut.unwrap_or_else(|| {
        let mid = n / 2;
        items.select_nth_unstable_by(mid, |a, b| {
            a.p[axis].total_cmp(&b.p[axis]).then(a.i.cmp(&b.i))
        });
        (mid, bounds_of(&items[..mid]), bounds_of(&items[mid..]))
    });
    let (pl, pr) = items.split_at_mut(mid);
    let (ll, lr) = left.split_at_mut(mid);
    let (rl, rr) = right.split_at_mut(mid);
    let (gl, gr) = grand.split_at_mut(mid);
    let m = base + mid as u32;
    let ((sl, cl), (sr, cr)) = if n >= PAR_THRESHOLD {
        rayon::join(
            || partition(pl, lb, base, opt, ll, rl, gl),
            || partition(pr, rb, m, opt, lr, rr, gr),
        )
    } else {
        (
            partition(pl, lb, base, opt, ll, rl, gl),
            partition(pr, rb, m, opt, lr, rr, gr),
        )
    };
    lr[0] = sl;
    rr[0] = sr;
    let binary = cl.0 + cr.0;
    let grandkids = cl.1 + cr.1;
    let g = match opt.combine {
        Combine::Pairs => true,
        Combine::Fewest => grandkids <= binary,
    };
    gr[0] = g;
    (m, (1 + if g { grandkids } else { binary }, binary))
}

impl Binary {
    /// Partitions `perm` and records the binary tree.
    /// Partitions the samples at `pos`; returns the tree, the permutation (samples in
    /// leaf order) and the root's cost.
    fn build(pos: &[[f32; 3]], opt: BuildOptions) -> (Self, Vec<u32>, Cost) {
        let n = pos.len();
        let mut items: Vec<Item> = pos
            .iter()
            .enumerate()
            .map(|(i, &p)| Item {
                p: Vec3::from(p),
                i: i as u32,
            })
            .collect();
        let mut left = vec![0u32; n];
        let mut right = vec![0u32; n];
        let mut grand = vec![false; n];
        let bounds = bounds_of(&items);
        let (root, cost) = partition(
            &mut items, bounds, 0, opt, &mut left, &mut right, &mut grand,
        );
        let perm = items.iter().map(|it| it.i).collect();
        (
            Self {
                left,
                right,
                grand,
                root,
            },
            perm,
            cost,
        )
    }

    /// Children of the node `(lo, hi, m)` in the combined tree, as `(lo, hi, split)`.
    pub(super) fn children(&self, (lo, hi, m): (u32, u32, u32), out: &mut Vec<(u32, u32, u32)>) {
        if hi - lo < 2 {
            return;
        }
        let i = m as usize;
        for (a, b, s) in [(lo, m, self.left[i]), (m, hi, self.right[i])] {
            if b - a == 1 || !self.grand[i] {
                out.push((a, b, s));
            } else {
                let j = s as usize;
                out.push((a, s, self.left[j]));
                out.push((s, b, self.right[j]));
            }
        }
    }
}

pub use super::forest::quantise_normal;
pub(super) use super::forest::{
    Forest, Parent, Samples, combine, encode_child, qnode, root_sphere,
};
pub(super) use super::node::TrueNode;

/// Which roots a subtree's forest has.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Roots {
    /// The subtree's root range is a node of the combined tree.
    Whole,
    /// Its parent took its grandchildren: the root's two binary children are the nodes.
    Children,
}

/// A subtree partitioned and laid out as a forest: the permutation, the binary tree, and
/// the root's split and costs.
pub(super) struct Partitioned {
    pub perm: Vec<u32>,
    tree: Binary,
    /// The root's cost: (interior nodes of its combined subtree, the same summed over its
    /// binary children).
    pub cost: (u64, u64),
}

impl Partitioned {
    /// Partitions the `n` samples at `pos`.
    pub(super) fn new(pos: &[[f32; 3]], opt: BuildOptions) -> Self {
        let (tree, perm, cost) = Binary::build(pos, opt);
        Self { perm, tree, cost }
    }

    /// The root's split (0 for a single sample).
    pub(super) fn root_split(&self) -> u32 {
        self.tree.root
    }

    /// Bytes per sample of [`Partitioned::save`]'s file: the permutation, the two child
    /// splits and the combine flag at each position.
    pub(super) const RECORD: usize = 13;

    /// Writes the permutation and the binary tree to a spill file (the root's split and
    /// cost are the caller's to keep), so that a build in units partitions each unit once.
    pub(super) fn save(&self, dir: &SpillDir) -> Result<Spill, MethodError> {
        let mut w = dir.writer("partition", Self::RECORD)?;
        let t = &self.tree;
        let mut rec = [0u8; Self::RECORD];
        for i in 0..self.perm.len() {
            rec[0..4].copy_from_slice(&self.perm[i].to_le_bytes());
            rec[4..8].copy_from_slice(&t.left[i].to_le_bytes());
            rec[8..12].copy_from_slice(&t.right[i].to_le_bytes());
            rec[12] = u8::from(t.grand[i]);
            w.push(&rec)?;
        }
        w.finish()
    }

    /// Reads back what [`Partitioned::save`] wrote for a range of `n` samples whose root
    /// splits at `root` with `cost`. The file's blocks are checksummed; values out of range
    /// (which only a bug could write) are an error naming the file, never an index panic.
    pub(super) fn load(
        spill: &Spill,
        n: usize,
        root: u32,
        cost: Cost,
    ) -> Result<Self, MethodError> {
        let mut perm = Vec::with_capacity(n);
        let (mut left, mut right, mut grand) = (
            Vec::with_capacity(n),
            Vec::with_capacity(n),
            Vec::with_capacity(n),
        );
        let mut seen = vec![false; n];
        let bad =
            |what: String| MethodError::corrupt(&spill.path, format!("temporary file: {what}"));
        spill.read(|block| {
            for r in block.chunks_exact(Self::RECORD) {
                let at = |o: usize| u32::from_le_bytes([r[o], r[o + 1], r[o + 2], r[o + 3]]);
                let (p, l, rt) = (at(0), at(4), at(8));
                if p as usize >= n || std::mem::replace(&mut seen[p as usize], true) {
                    return Err(bad(format!("sample {p} is not a permutation's")));
                }
                if l as usize >= n || rt as usize >= n {
                    return Err(bad(format!("split {} past {n} samples", l.max(rt))));
                }
                perm.push(p);
                left.push(l);
                right.push(rt);
                grand.push(r[12] != 0);
            }
            Ok(())
        })?;
        if perm.len() != n || (root as usize >= n.max(1)) {
            return Err(bad(format!("{} positions for {n} samples", perm.len())));
        }
        Ok(Self {
            perm,
            tree: Binary {
                left,
                right,
                grand,
                root,
            },
            cost,
        })
    }

    /// The forest of the given roots.
    pub(super) fn forest(&self, roots: Roots) -> Forest {
        let n = self.perm.len() as u32;
        let m = self.tree.root;
        let r = match roots {
            Roots::Whole => vec![(0, n, m)],
            Roots::Children => {
                let i = m as usize;
                vec![(0, m, self.tree.left[i]), (m, n, self.tree.right[i])]
            }
        };
        Forest::new(&self.tree, r)
    }
}

/// Builds and quantises the hierarchy of `cloud` with leaf radii `radii`.
pub fn build_tree(cloud: &PointCloud, radii: &[f32]) -> Result<Built, MethodError> {
    build_tree_with(cloud, radii, BuildOptions::default())
}

/// Checks that a tree of `n` samples can be built.
pub(super) fn check_size(n: usize) -> Result<(), MethodError> {
    if n == 0 {
        return Err(MethodError::Limit(
            "qsplat: the cloud has no samples".into(),
        ));
    }
    if n > u32::MAX as usize / 2 {
        return Err(MethodError::Limit(format!(
            "qsplat: {n} samples exceed the 32-bit index"
        )));
    }
    Ok(())
}

/// [`build_tree`] with explicit split and combine rules, in memory, keeping the true and
/// decoded spheres and normals for tests.
pub fn build_tree_with(
    cloud: &PointCloud,
    radii: &[f32],
    opt: BuildOptions,
) -> Result<Built, MethodError> {
    build_in_memory(cloud, radii, opt, true)
}

/// The in-memory build; the true and decoded spheres and normals are kept only with
/// `debug` (empty otherwise).
pub(super) fn build_in_memory(
    cloud: &PointCloud,
    radii: &[f32],
    opt: BuildOptions,
    debug: bool,
) -> Result<Built, MethodError> {
    check_size(cloud.len())?;
    let s = Samples::of_cloud(cloud, radii);
    let part = Partitioned::new(s.pos, opt);
    let forest = part.forest(Roots::Whole);
    let truth = forest.truths(Some(&part.perm), s);
    let attrs = (s.normals.is_some(), s.colors.is_some());
    let q = forest.quantise(&truth, Parent::Root, attrs, opt.fit, 0, debug)?;
    if !debug {
        return Ok(Built {
            tree: QTree {
                levels: q.levels,
                root: q.root,
                normals: attrs.0,
                colors: attrs.1,
            },
            true_spheres: Vec::new(),
            decoded_spheres: Vec::new(),
            true_normals: Vec::new(),
            quant: q.stats,
        });
    }
    Ok(Built {
        tree: QTree {
            levels: q.levels,
            root: q.root,
            normals: attrs.0,
            colors: attrs.1,
        },
        true_spheres: truth
            .iter()
            .map(|l| l.iter().map(|t| (t.c, t.r)).collect())
            .collect(),
        decoded_spheres: q.decoded,
        true_normals: truth
            .iter()
            .map(|l| l.iter().map(|t| t.n).collect())
            .collect(),
        quant: q.stats,
    })
}

#[cfg(test)]
mod tests {
    use super::super::quant;
    use super::*;
    use glam::DVec3;
    use scenes::rng::Pcg32;

    #[test]
    fn quantised_cone_is_never_narrower() {
        let mut rng = Pcg32::new(17);
        for _ in 0..20_000 {
            let axis = rng.unit_vec3();
            let spread = rng.range_f32(0.0, 1.2);
            let kids: Vec<TrueNode> = (0..2 + rng.below(3))
                .map(|_| {
                    let n = (axis + rng.unit_vec3() * spread).normalize_or(Vec3::Z);
                    TrueNode {
                        c: rng.unit_vec3(),
                        r: rng.range_f32(0.01, 0.5),
                        n,
                        cone: if rng.below(2) == 0 {
                            0.0
                        } else {
                            rng.range_f32(0.0, 0.5) as f64
                        },
                        color: [0.0; 3],
                        weight: 1,
                    }
                })
                .collect();
            let t = combine(&kids, true);
            let (code, class) = quantise_normal(t.n, t.cone, true);
            if class == 3 {
                continue;
            }
            let qa = quant::decode_normal(code as u32).unwrap().as_dvec3();
            let q_angle = quant::cone_angle(class);
            // Contains the true cone, hence every child's cone.
            assert!(quant::angle(qa, t.n.as_dvec3()) + t.cone <= q_angle + 1e-12);
            for k in &kids {
                assert!(quant::angle(qa, k.n.as_dvec3()) + k.cone <= q_angle + 1e-9);
            }
        }
    }

    #[test]
    fn degenerate_midpoint_splits_fall_back_to_the_median() {
        // Coincident samples (zero extent) and two adjacent floats (the midpoint rounds to
        // an end): a midpoint split would leave one side empty; the median is taken instead.
        let a = 1.0f32;
        let b = a.next_up();
        let mut pos = vec![[0.5f32, 0.5, 0.5]; 300];
        pos.extend((0..200).map(|i| [if i % 2 == 0 { a } else { b }, 0.0, 0.0]));
        pos.extend((0..7).map(|i| [i as f32, 2.0, 0.0]));
        let cloud = PointCloud::new(DVec3::ZERO, pos.into(), None, None, None).unwrap();
        let radii = vec![0.01f32; cloud.len()];
        for split in [Split::Midpoint, Split::Median] {
            for combine in [Combine::Fewest, Combine::Pairs] {
                let opt = BuildOptions {
                    split,
                    combine,
                    ..Default::default()
                };
                let t = build_tree_with(&cloud, &radii, opt).unwrap().tree;
                assert_eq!(t.leaves(), 507, "{opt:?}");
                assert!(
                    t.levels
                        .iter()
                        .flatten()
                        .all(|n| n.children == 0 || (2..=4).contains(&n.children)),
                    "{opt:?}"
                );
            }
        }
    }

    #[test]
    fn tree_invariants_on_a_small_statue() {
        let cloud = scenes::generators::Generator::Statue
            .generate(3000, 2)
            .unwrap();
        let radii = crate::leaf::leaf_radii(&cloud);
        let b = build_tree(&cloud, &radii).unwrap();
        let levels = &b.tree.levels;
        // Decoded spheres enclose the true ones at every node.
        for (l, (tl, dl)) in b.true_spheres.iter().zip(&b.decoded_spheres).enumerate() {
            for (i, (t, d)) in tl.iter().zip(dl).enumerate() {
                let gap = d.1 as f64 - (d.0.as_dvec3() - t.0.as_dvec3()).length() - t.1 as f64;
                assert!(
                    gap >= 0.0,
                    "level {l} node {i}: decoded sphere misses by {gap}"
                );
            }
        }
        // Every quantised cone contains every leaf normal below it.
        let mut below: Vec<Vec<Vec<Vec3>>> = vec![Vec::new(); levels.len()];
        for l in (0..levels.len()).rev() {
            let mut next = 0usize;
            below[l] = levels[l]
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    if n.children == 0 {
                        return vec![b.true_normals[l][i]];
                    }
                    let kids = next..next + n.children as usize;
                    next += n.children as usize;
                    kids.flat_map(|k| below[l + 1][k].clone()).collect()
                })
                .collect();
            for (i, n) in levels[l].iter().enumerate() {
                assert!(n.children == 0 || (2..=4).contains(&n.children));
                if n.cone == 3 {
                    continue;
                }
                let a = quant::decode_normal(n.normal as u32).unwrap().as_dvec3();
                for v in &below[l][i] {
                    assert!(
                        quant::angle(a, v.as_dvec3()) <= quant::cone_angle(n.cone) + 1e-6,
                        "level {l} node {i}"
                    );
                }
            }
            if l + 1 < levels.len() {
                below[l + 1].clear();
            }
        }
        assert_eq!(b.tree.leaves(), 3000);
    }
}
