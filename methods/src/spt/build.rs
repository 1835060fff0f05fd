//! The SPT point tree: an octree over the samples, built bottom-up with per-node disks and
//! errors ([`super::errors`]).
//!
//! Contract:
//! - Samples are sorted by 63-bit Morton code (21 bits per axis in the cloud's bounding cube;
//!   ties by sample index, so the tree is deterministic). Each octree cell holding one
//!   sample is a leaf (leaves are single samples, never buckets, so tolerance 0 draws every
//!   sample); a cell with one occupied child cell is not a node (chains collapse); a cell at
//!   the finest level (2⁻²¹ of the cube) holding several samples (duplicates) gets one leaf
//!   per sample.
//! - Leaf: centre = sample, normal = sample normal, radius = leaf radius
//!   ([`crate::leaf::leaf_radii`]), errors 0.
//! - Inner node: normal = normalised sum of children's normals (the first child's normal if
//!   they cancel); centre and radius `d/2` from [`super::errors::bounding_disk`] (without
//!   normals: [`super::errors::bounding_ball`]); errors `e_p, e_t` per the paper. Colour =
//!   the children's mean; if their spread exceeds the threshold, the errors are raised so
//!   that `e_g ≥ d` (`e_p, e_t ≥ d/√2`).
//! - Errors are made monotone (a node's `e_p`, `e_t`, `e_g` are at least its children's);
//!   then `φ = atan2(e_t, e_p)` is quantised ([`super::select::PHI_STEPS`]) and `e_g` raised
//!   (by the least factor, times 1 + 1e-6) so that `e_p = e_g·cos φ_q ≥` the monotone `e_p`
//!   and likewise `e_t`: the stored split errors are exactly what the GPU decodes, and they
//!   stay monotone along every chain. Inner nodes have `e_g > 0` (at least
//!   [`MIN_INNER_ERROR`]). Without normals `e_p = e_t = 0` and `e_g = d` (QSplat's LOD).
//! - The per-sample copies are the Morton keys, each sorted together with its sample's
//!   position, radius and colour (so that the leaves read them in order: gathered by index
//!   they were a cache miss per leaf), and the node array; normals are read by index.

use glam::Vec3;
use std::sync::atomic::{AtomicU32, Ordering};

use rayon::prelude::*;
use scenes::PointCloud;
use smallvec::SmallVec;

use super::errors::{self, ChildDisk};
use super::select;

/// `parent` of the root.
pub const NO_PARENT: u32 = u32::MAX;
/// Smallest error of an inner node (so that leaves alone pass at tolerance 0).
pub const MIN_INNER_ERROR: f32 = 1e-30;
/// Smallest stored radius (radii must be > 0 in a column file).
pub const MIN_RADIUS: f32 = 1e-30;
/// Bits per axis of the Morton codes: the deepest cells are `BITS` levels below the root.
pub(super) const BITS: u32 = 21;

/// One node of the point tree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Centre.
    pub p: Vec3,
    /// Unit normal (`Vec3::Z` when the scene has no normals).
    pub n: Vec3,
    /// Radius `d/2` of the bounding disk.
    pub r: f32,
    /// Perpendicular error (monotone, see the module doc).
    pub e_p: f32,
    /// Tangential error.
    pub e_t: f32,
    /// Geometric error `sqrt(e_p² + e_t²)` (`d` without normals).
    pub e_g: f32,
    /// Quantised `φ = atan2(e_t, e_p)` ([`super::select::quantize_phi`]); `e_p = e_g·cos φ`
    /// and `e_t = e_g·sin φ` hold for the quantised angle.
    pub phi_q: u32,
    /// Parent index or [`NO_PARENT`].
    pub parent: u32,
    /// Mean colour (zero without colours).
    pub color: [u8; 3],
    /// True for a leaf (one sample).
    pub leaf: bool,
}

/// The tree: nodes in post-order (children before parents; the root is last).
#[derive(Debug, Clone, PartialEq)]
pub struct PointTree {
    /// All nodes.
    pub nodes: Vec<Node>,
    /// Number of levels (1 for a single sample).
    pub levels: u32,
    /// For each sample, its leaf node.
    pub leaf_of: Vec<u32>,
}

impl PointTree {
    /// The root's index.
    pub fn root(&self) -> usize {
        self.nodes.len() - 1
    }
}

pub(super) use crate::spill::samples::SampleView as Samples;

/// The Morton code of a position: 21 bits per axis in the cube of side `size` at `lo` (the
/// cloud's bounds).
#[derive(Debug, Clone, Copy)]
pub(super) struct MortonGrid {
    lo: Vec3,
    size: f32,
}

impl MortonGrid {
    /// The grid of a cloud with bounds `b`.
    pub(super) fn new(b: scenes::Aabb) -> Self {
        Self {
            lo: b.min,
            size: b.size().max_element().max(f32::MIN_POSITIVE),
        }
    }

    /// The code of `p`.
    pub(super) fn code(&self, p: [f32; 3]) -> u64 {
        let cells = (1u32 << BITS) as f32;
        let q = |v: f32, lo: f32| (((v - lo) / self.size * cells) as u32).min((1 << BITS) - 1);
        crate::morton::morton63([q(p[0], self.lo.x), q(p[1], self.lo.y), q(p[2], self.lo.z)])
    }
}

/// A sample in Morton order: its code, index, and what its leaf needs besides the normal.
#[derive(Debug, Clone, Copy, Default)]
struct Key {
    code: u64,
    idx: u32,
    pos: [f32; 3],
    r: f32,
    /// Black without colours.
    color: [u8; 3],
}

pub(super) struct Builder<'a> {
    s: Samples<'a>,
    keys: Vec<Key>,
    pub nodes: Vec<Node>,
    /// Each sample's leaf (filled only when asked for: the build in units does not need it).
    leaf_of: Option<Vec<u32>>,
    color_threshold: f32,
}

/// Builds the point tree of `cloud` with leaf radii `radii` (one per sample);
/// `color_threshold` is the colour rule's threshold in 0..=255 units (ignored without colours).
pub fn build_tree(cloud: &PointCloud, radii: &[f32], color_threshold: f32) -> PointTree {
    let s = Samples::of_cloud(cloud, radii);
    let mut bld = Builder::new(s, MortonGrid::new(cloud.bounds()), color_threshold, true);
    let n = cloud.len();
    let (_, height) = bld.subtree(0, n, BITS);
    PointTree {
        nodes: bld.nodes,
        levels: height,
        leaf_of: bld.leaf_of.unwrap_or_default(),
    }
}

/// A node's children (or their ranges, disks, colours): on the stack up to an octree cell's
/// 8 (a cell of duplicates at the finest level has more, on the heap), instead of five heap
/// allocations per inner node; the build's wall time did not move measurably with it
/// (`results/measurements/issue-40-builds.md`).
type Kids<T> = SmallVec<[T; 8]>;

/// Cells of at least this many samples build their children's subtrees in parallel.
const PAR_SAMPLES: usize = 1 << 14;

impl<'a> Builder<'a> {
    /// A builder over `s`, sorted by Morton code in `grid` (ties by index); `leaf_of`: keep
    /// each sample's leaf.
    pub(super) fn new(
        s: Samples<'a>,
        grid: MortonGrid,
        color_threshold: f32,
        leaf_of: bool,
    ) -> Self {
        let mut keys: Vec<Key> = s
            .pos
            .par_iter()
            .enumerate()
            .map(|(i, &p)| Key {
                code: grid.code(p),
                idx: i as u32,
                pos: p,
                r: s.radii[i],
                color: s.colors.map_or([0; 3], |c| c[i]),
            })
            .collect();
        keys.par_sort_unstable_by_key(|k| (k.code, k.idx));
        let n = s.pos.len();
        Self {
            s,
            keys,
            nodes: Vec::with_capacity(n + n / 2),
            leaf_of: leaf_of.then(|| vec![0; n]),
            color_threshold,
        }
    }

    /// Builds the cell holding `keys[lo..hi]` whose codes agree above `level·3` bits,
    /// appending its nodes to `nodes` (post-order); returns (node index, height).
    pub(super) fn subtree(&mut self, lo: usize, hi: usize, level: u32) -> (u32, u32) {
        let leaf_of: Option<Vec<AtomicU32>> = self
            .leaf_of
            .as_ref()
            .map(|l| l.iter().map(|&v| AtomicU32::new(v)).collect());
        let starts = inner_starts(&self.keys);
        let ctx = Ctx {
            s: self.s,
            keys: &self.keys,
            starts: &starts,
            color_threshold: self.color_threshold,
            leaf_of: leaf_of.as_deref(),
        };
        let base = self.nodes.len();
        let count = ctx.count(lo, hi);
        self.nodes.resize(base + count, PLACEHOLDER);
        let r = ctx.subtree(&mut self.nodes[base..], base as u32, lo, hi, level);
        if let (Some(l), Some(a)) = (&mut self.leaf_of, leaf_of) {
            *l = a.into_iter().map(AtomicU32::into_inner).collect();
        }
        r
    }
}

/// For each `k < keys.len()`, how many of the pairs of neighbouring keys `(keys[i],
/// keys[i + 1])`, `i < k`, are the first pair of their inner node: an inner node at split
/// level `l` (its cell's codes agree above `3·l` bits; 0 for a cell of equal codes) owns the
/// pairs between its neighbouring children, exactly the pairs inside its cell that differ
/// first at level `l`, so a pair starts a node unless the nearest earlier pair at level
/// `≥ l` is at level `l` itself (then both lie in one cell at level `l`, hence one node).
/// A cell's subtree over `keys[lo..hi]` therefore has `hi − lo` leaves and
/// `starts[hi − 1] − starts[lo]` inner nodes ([`Ctx::count`], O(1) instead of a walk).
fn inner_starts(keys: &[Key]) -> Vec<u32> {
    let mut out = Vec::with_capacity(keys.len());
    if keys.is_empty() {
        return out;
    }
    out.push(0);
    // `last[l]`: the level of the latest pair at level ≥ l (u8::MAX before any).
    let mut last = [u8::MAX; BITS as usize + 1];
    let mut sum = 0u32;
    for w in keys.windows(2) {
        let level = split_level(w[0].code ^ w[1].code) as usize;
        sum += u32::from(last[level] != level as u8);
        last[..=level].fill(level as u8);
        out.push(sum);
    }
    out
}

/// Nodes of the subtree of the cell over `keys[lo..hi]` (non-empty), from the keys'
/// [`inner_starts`]: its leaves and its inner nodes.
fn cell_nodes(starts: &[u32], lo: usize, hi: usize) -> usize {
    hi - lo + (starts[hi - 1] - starts[lo]) as usize
}

/// The level (1..=[`BITS`]) of the highest octal digit set in `diff` (codes XORed), 0 if
/// none.
fn split_level(diff: u64) -> u32 {
    if diff == 0 {
        0
    } else {
        (63 - diff.leading_zeros()) / 3 + 1
    }
}

/// A node slot not yet built.
const PLACEHOLDER: Node = Node {
    p: Vec3::ZERO,
    n: Vec3::Z,
    r: 0.0,
    e_p: 0.0,
    e_t: 0.0,
    e_g: 0.0,
    phi_q: 0,
    parent: NO_PARENT,
    color: [0; 3],
    leaf: false,
};

/// An inner node of [`Ctx::sequential`] waiting for its geometry ([`Ctx::finish`]): its
/// slot, its height (1 above leaves) and its children's node indices.
struct Pending {
    slot: usize,
    height: u32,
    children: Kids<u32>,
}

/// What a subtree build reads.
#[derive(Clone, Copy)]
struct Ctx<'a> {
    s: Samples<'a>,
    keys: &'a [Key],
    /// [`inner_starts`] of `keys`.
    starts: &'a [u32],
    color_threshold: f32,
    leaf_of: Option<&'a [AtomicU32]>,
}

impl Ctx<'_> {
    /// The ranges of `keys[lo..hi]`'s occupied child cells at `level` (> 0).
    fn child_ranges(&self, lo: usize, hi: usize, level: u32) -> Kids<(usize, usize)> {
        let shift = 3 * (level - 1);
        let oct = |k: &Key| (k.code >> shift) & 7;
        let mut ranges = Kids::new();
        let mut s = lo;
        while s < hi {
            let o = oct(&self.keys[s]);
            let e = s + self.keys[s..hi].partition_point(|k| oct(k) == o);
            ranges.push((s, e));
            s = e;
        }
        ranges
    }

    /// The highest level `≤ level` at which `keys[lo..hi]` (sorted) fall into more than
    /// one child cell, 0 if none: every level above it has one occupied child, which is no
    /// node, so the recursion goes there directly (one step instead of a search per level).
    fn first_split(&self, lo: usize, hi: usize, level: u32) -> u32 {
        let bits = 3 * level;
        let mask = if bits >= 64 {
            u64::MAX
        } else {
            (1u64 << bits) - 1
        };
        split_level((self.keys[lo].code ^ self.keys[hi - 1].code) & mask)
    }

    /// Nodes of the subtree [`Self::subtree`] builds for the cell holding `keys[lo..hi]`
    /// ([`cell_nodes`]).
    fn count(&self, lo: usize, hi: usize) -> usize {
        cell_nodes(self.starts, lo, hi)
    }

    /// Builds the cell's subtree into `out`, exactly [`Self::count`] slots whose first is
    /// node `base`, in post-order (the cell's node last); returns (node index, height). A
    /// cell of at least [`PAR_SAMPLES`] samples builds its children in parallel, each into
    /// its own part of `out`: the nodes, their numbering and every value are those of the
    /// sequential recursion, and nothing is copied.
    fn subtree(&self, out: &mut [Node], base: u32, lo: usize, hi: usize, level: u32) -> (u32, u32) {
        if hi - lo < PAR_SAMPLES {
            let (mut at, mut pending) = (0, Vec::new());
            let r = self.sequential(out, base, &mut at, lo, hi, level, &mut pending);
            debug_assert_eq!(at, out.len(), "count and build disagree");
            self.finish(out, base, pending);
            return r;
        }
        let level = self.first_split(lo, hi, level);
        let mut children = Kids::new();
        let mut height = 0;
        if level == 0 {
            for (j, i) in (lo..hi).enumerate() {
                children.push(self.leaf(out, base, j, i));
            }
            height = 1;
        } else {
            let ranges = self.child_ranges(lo, hi, level);
            debug_assert!(ranges.len() >= 2, "first_split found a split here");
            let counts: Vec<usize> = ranges.iter().map(|&(s, e)| self.count(s, e)).collect();
            // The children's slots, in order, then this node's.
            let mut parts = Vec::with_capacity(ranges.len());
            let mut rest = &mut out[..];
            let mut at = base;
            for (&r, &c) in ranges.iter().zip(&counts) {
                let (head, tail) = rest.split_at_mut(c);
                parts.push((head, at, r));
                at += c as u32;
                rest = tail;
            }
            let built: Vec<(u32, u32)> = if hi - lo >= PAR_SAMPLES {
                parts
                    .into_par_iter()
                    .map(|(o, b, (s, e))| self.subtree(o, b, s, e, level - 1))
                    .collect()
            } else {
                parts
                    .into_iter()
                    .map(|(o, b, (s, e))| self.subtree(o, b, s, e, level - 1))
                    .collect()
            };
            for (c, h) in built {
                children.push(c);
                height = height.max(h);
            }
        }
        (self.inner(out, base, &children), height + 1)
    }

    /// [`Self::subtree`] on one thread: the nodes go to `out[*at..]` in post-order, `at`
    /// advancing past them, so no subtree needs counting first (counting before every
    /// split had walked each subtree once per level above it). Leaves are written; each
    /// inner node gets its slot and goes to `pending`, for [`Self::finish`].
    #[allow(clippy::too_many_arguments)]
    fn sequential(
        &self,
        out: &mut [Node],
        base: u32,
        at: &mut usize,
        lo: usize,
        hi: usize,
        level: u32,
        pending: &mut Vec<Pending>,
    ) -> (u32, u32) {
        if hi - lo == 1 {
            *at += 1;
            return (self.leaf(out, base, *at - 1, lo), 1);
        }
        let level = self.first_split(lo, hi, level);
        let mut children = Kids::new();
        let mut height = 0;
        if level == 0 {
            for i in lo..hi {
                children.push(self.leaf(out, base, *at, i));
                *at += 1;
            }
            height = 1;
        } else {
            // At least two child cells: `first_split` found the keys differing here.
            for (s, e) in self.child_ranges(lo, hi, level) {
                let (c, h) = self.sequential(out, base, at, s, e, level - 1, pending);
                children.push(c);
                height = height.max(h);
            }
        }
        *at += 1;
        pending.push(Pending {
            slot: *at - 1,
            height: height + 1,
            children,
        });
        (base + (*at - 1) as u32, height + 1)
    }

    /// The inner nodes `pending` of a subtree in `out` (node `base` first), by height, so
    /// that every node's children are final before it; those of one height are independent
    /// and go [`errors::BATCH`] at a time through [`inner_nodes`].
    fn finish(&self, out: &mut [Node], base: u32, mut pending: Vec<Pending>) {
        pending.sort_by_key(|p| p.height);
        for level in pending.chunk_by(|a, b| a.height == b.height) {
            for batch in level.chunks(errors::BATCH) {
                let batch: SmallVec<[(usize, &[u32]); errors::BATCH]> = batch
                    .iter()
                    .map(|p| (p.slot, p.children.as_slice()))
                    .collect();
                self.write_inner(out, base, &batch);
            }
        }
    }

    /// Writes the leaf of `keys[k]` into slot `j` of `out` (node `base + j`).
    fn leaf(&self, out: &mut [Node], base: u32, j: usize, k: usize) -> u32 {
        let key = &self.keys[k];
        let i = key.idx as usize;
        let idx = base + j as u32;
        if let Some(l) = self.leaf_of {
            l[i].store(idx, Ordering::Relaxed);
        }
        out[j] = Node {
            p: Vec3::from(key.pos),
            n: self
                .s
                .normals
                .map_or(Vec3::Z, |n| Vec3::from(n[i]).normalize_or(Vec3::Z)),
            r: key.r.max(MIN_RADIUS),
            e_p: 0.0,
            e_t: 0.0,
            e_g: 0.0,
            phi_q: 0,
            parent: NO_PARENT,
            color: key.color,
            leaf: true,
        };
        idx
    }

    /// Writes the inner node over `children` into the last slot of `out`.
    fn inner(&self, out: &mut [Node], base: u32, children: &[u32]) -> u32 {
        let slot = out.len() - 1;
        self.write_inner(out, base, &[(slot, children)]);
        base + slot as u32
    }

    /// Computes the inner nodes over `batch`'s children (node indices; at most
    /// [`errors::BATCH`] nodes, none a child of another) together, writes each into its slot of
    /// `out` (node `base` first) and links its children to it.
    fn write_inner(&self, out: &mut [Node], base: u32, batch: &[(usize, &[u32])]) {
        let at = |c: u32| (c - base) as usize;
        let kids: SmallVec<[Kids<Node>; errors::BATCH]> = batch
            .iter()
            .map(|(_, children)| children.iter().map(|&c| out[at(c)]).collect())
            .collect();
        let refs: SmallVec<[&[Node]; errors::BATCH]> = kids.iter().map(|k| k.as_slice()).collect();
        let nodes = inner_nodes(
            &refs,
            self.s.normals.is_some(),
            self.s.colors.is_some(),
            self.color_threshold,
        );
        for (&(slot, children), node) in batch.iter().zip(nodes) {
            out[slot] = node;
            for &c in children {
                out[at(c)].parent = base + slot as u32;
            }
        }
    }
}

/// The inner node over `kids` (see the module docs); its `parent` is [`NO_PARENT`].
pub(super) fn inner_node(
    kids: &[Node],
    has_normals: bool,
    has_colors: bool,
    color_threshold: f32,
) -> Node {
    inner_nodes(&[kids], has_normals, has_colors, color_threshold)[0]
}

/// [`inner_node`] of up to [`errors::BATCH`] nodes at once, their bounding disks (balls)
/// searched together ([`errors::bounding_disks`]): the same nodes as one at a time.
pub(super) fn inner_nodes(
    kids: &[&[Node]],
    has_normals: bool,
    has_colors: bool,
    color_threshold: f32,
) -> SmallVec<[Node; errors::BATCH]> {
    let disks: SmallVec<[Kids<ChildDisk>; errors::BATCH]> = kids
        .iter()
        .map(|k| {
            k.iter()
                .map(|c| ChildDisk {
                    p: c.p,
                    n: c.n,
                    r: c.r,
                })
                .collect()
        })
        .collect();
    let normals: SmallVec<[Vec3; errors::BATCH]> = kids
        .iter()
        .map(|k| {
            if has_normals {
                k.iter()
                    .map(|c| c.n)
                    .sum::<Vec3>()
                    .try_normalize()
                    .unwrap_or(k[0].n)
            } else {
                Vec3::Z
            }
        })
        .collect();
    let spheres = if has_normals {
        let problems: SmallVec<[errors::DiskProblem; errors::BATCH]> = normals
            .iter()
            .zip(&disks)
            .map(|(&n, d)| errors::DiskProblem::new(n, d))
            .collect();
        errors::bounding_disks(&problems)
    } else {
        let problems: SmallVec<[errors::Problem<Vec3>; errors::BATCH]> =
            disks.iter().map(|d| errors::ball_problem(d)).collect();
        errors::bounding_balls(&problems)
    };
    kids.iter()
        .zip(&disks)
        .zip(normals.iter().zip(spheres))
        .map(|((k, d), (&n, pr))| {
            finish_inner(k, d, n, pr, has_normals, has_colors, color_threshold)
        })
        .collect()
}

/// The inner node over `kids` (disks `disks`) with normal `n` and bounding disk (or ball)
/// `(p, r)`: its errors, colour and quantised φ.
fn finish_inner(
    kids: &[Node],
    disks: &[ChildDisk],
    n: Vec3,
    (p, r): (Vec3, f32),
    has_normals: bool,
    has_colors: bool,
    color_threshold: f32,
) -> Node {
    let (mut e_p, mut e_t, mut e_g);
    if has_normals {
        e_p = errors::perpendicular_error(p, n, disks);
        e_t = errors::tangential_error(n, 2.0 * r, disks);
        e_g = errors::geometric_error(e_p, e_t);
    } else {
        e_p = 0.0;
        e_t = 0.0;
        e_g = 2.0 * r;
    }
    let mut color = [0u8; 3];
    if has_colors {
        let cols: Kids<[u8; 3]> = kids.iter().map(|c| c.color).collect();
        for (ch, out) in color.iter_mut().enumerate() {
            let sum: u32 = cols.iter().map(|c| c[ch] as u32).sum();
            *out = ((sum + cols.len() as u32 / 2) / cols.len() as u32) as u8;
        }
        if errors::color_spread(&cols) as f32 > color_threshold {
            let d = 2.0 * r;
            e_p = e_p.max(d * std::f32::consts::FRAC_1_SQRT_2);
            e_t = e_t.max(d * std::f32::consts::FRAC_1_SQRT_2);
            e_g = e_g.max(d);
        }
    }
    // Monotone errors, then e_g = sqrt(e_p² + e_t²) exactly.
    for c in kids {
        e_p = e_p.max(c.e_p);
        e_t = e_t.max(c.e_t);
        e_g = e_g.max(c.e_g);
    }
    let mut phi_q = 0;
    if has_normals {
        e_g = e_g
            .max(errors::geometric_error(e_p, e_t))
            .max(MIN_INNER_ERROR);
        // Quantise φ (floor or ceil, whichever needs less raising) and raise e_g so that
        // the quantised components still dominate (e_p, e_t), hence every child's.
        let phi = e_t.atan2(e_p) / std::f32::consts::FRAC_PI_2 * select::PHI_STEPS;
        let need = |q: f32| {
            let a = q * (std::f32::consts::FRAC_PI_2 / select::PHI_STEPS);
            let (s, c) = a.sin_cos();
            let part = |e: f32, w: f32| {
                if e <= 0.0 {
                    0.0
                } else if w > 0.0 {
                    e / w
                } else {
                    f32::INFINITY
                }
            };
            e_g.max(part(e_p, c)).max(part(e_t, s))
        };
        // Candidates around φ (a neighbour too: at q = 0 or q = 255 one component
        // would need an infinite factor).
        let base = phi.floor();
        let q = [base - 1.0, base, base + 1.0, base + 2.0]
            .into_iter()
            .filter(|q| (0.0..=select::PHI_STEPS).contains(q))
            .min_by(|&a, &b| need(a).total_cmp(&need(b)))
            .unwrap_or(0.0);
        e_g = need(q) * (1.0 + 1e-6);
        let (s, c) = (q * (std::f32::consts::FRAC_PI_2 / select::PHI_STEPS)).sin_cos();
        e_p = e_g * c;
        e_t = e_g * s;
        phi_q = q as u32;
    } else {
        e_g = e_g.max(MIN_INNER_ERROR);
    }
    Node {
        p,
        n,
        r: r.max(MIN_RADIUS),
        e_p,
        e_t,
        e_g,
        phi_q,
        parent: NO_PARENT,
        color,
        leaf: false,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The nodes of the cell over `keys[lo..hi]` at `level`, by walking the tree as the
    /// build does (the count [`inner_starts`] replaced).
    fn walked(keys: &[Key], lo: usize, hi: usize, level: u32) -> usize {
        if hi - lo == 1 {
            return 1;
        }
        let diff = keys[lo].code ^ keys[hi - 1].code;
        let level = split_level(diff & ((1u64 << (3 * level)) - 1));
        if level == 0 {
            return hi - lo + 1;
        }
        let shift = 3 * (level - 1);
        let mut total = 1;
        let mut s = lo;
        while s < hi {
            let o = (keys[s].code >> shift) & 7;
            let e = s + keys[s..hi].partition_point(|k| (k.code >> shift) & 7 == o);
            total += walked(keys, s, e, level - 1);
            s = e;
        }
        total
    }

    /// Every cell's count ([`cell_nodes`] of [`inner_starts`], as [`Ctx::count`]) against
    /// the walk, on codes with chains, duplicates and lone samples (few digits set, so cells
    /// repeat at every level).
    #[test]
    fn counting_by_pair_starts_gives_every_cells_nodes() {
        let mut seed = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = move || {
            seed ^= seed << 13;
            seed ^= seed >> 7;
            seed ^= seed << 17;
            seed
        };
        for (n, digits) in [(1, 3), (2, 1), (9, 2), (300, 4), (2000, 21), (5000, 6)] {
            let mut keys: Vec<Key> = (0..n as u32)
                .map(|i| {
                    // Digits only at a few levels, each 0, 1 or 7: chains and duplicates.
                    let mut code = 0u64;
                    for _ in 0..digits {
                        let level = next() % 21;
                        code |= [0, 1, 7][(next() % 3) as usize] << (3 * level);
                    }
                    Key {
                        code,
                        idx: i,
                        ..Key::default()
                    }
                })
                .collect();
            keys.sort_unstable_by_key(|k| (k.code, k.idx));
            let starts = inner_starts(&keys);
            let count = |lo: usize, hi: usize| cell_nodes(&starts, lo, hi);
            assert_eq!(count(0, n), walked(&keys, 0, n, BITS), "n = {n}");
            // Every cell at every level: the runs of keys sharing a prefix.
            for level in (0..BITS).rev() {
                let mut s = 0;
                while s < n {
                    let e = s + keys[s..]
                        .partition_point(|k| k.code >> (3 * level) == keys[s].code >> (3 * level));
                    assert_eq!(
                        count(s, e),
                        walked(&keys, s, e, level.max(1)),
                        "n = {n}, level {level}, cell {s}..{e}"
                    );
                    s = e;
                }
            }
        }
    }
}
