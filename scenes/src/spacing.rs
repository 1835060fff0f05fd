//! Per-sample spacing: the distance from each point to its k-th nearest neighbour.
//!
//! Contract of [`knn_spacing`]:
//! - exact k-NN distances (Euclidean, in the cloud's local `f32` coordinates), the point itself
//!   excluded by index, so a duplicate of a point *is* a neighbour at distance 0;
//! - one value per input point, in input order, every value finite and `> 0` (see
//!   *Degenerate input* below);
//! - deterministic: the result does not depend on the number of rayon threads;
//! - works for any density: the search structure is a static kd-tree with median splits, so
//!   leaves hold 16–32 points whether the cloud is uniform or varies 1000× in density.
//!
//! **Structure.** An implicit, balanced kd-tree: points (with their input index) are permuted
//! in place, level by level, with `select_nth_unstable_by` at the middle of each node's range
//! along the longest axis of the node's tight bounding box; a node stores only its split value
//! and axis (heap order, so no child pointers), and a node's index range follows from its
//! parent's (`[lo, lo + len/2)` and `[lo + len/2, hi)`). All leaves sit at the same depth.
//! The queries of one leaf (≤ 16 points) search together: one traversal, near child first
//! (by the centre of the queries' bounding box, so their own leaf comes first), each query
//! keeping its k best in a sorted array; a node is pruned when the distance from the queries'
//! box to its cell is not below the largest current k-th distance among them. Leaves run in
//! parallel, results are scattered back to input order. Sharing the traversal made it
//! faster than one descent per query, with the insertion-sort heap (200 k points, k = 6, 2 cores:
//! statue ×1.7, terrain ×1.2; `cargo bench -p methods --bench kernels -- kernels/knn`).
//! The tree keeps its coordinates per axis, so a query's distances to a whole leaf are one
//! vectorised loop; the leaf's candidates below the query's k-th distance are then picked by
//! a bit mask and merged into its sorted k by branch-free `min`/`max` steps. The branches
//! of an insertion loop had been the search's largest cost (`perf annotate`); this change
//! made the k-NN phase of `splatbench build --method full` on terrain 2 M (LAS) ≈ 1.4× faster
//! (0.81–0.85 s → 0.59–0.62 s, 2 cores).
//!
//! **Lanes** (issue 40). The scan runs over a fixed [`LEAF_MAX`] places (each axis array is
//! padded with `LEAF_MAX` values of `+∞`, so a leaf's window never leaves the array; the places
//! past the leaf are masked off), so the distances and the candidates' mask are one
//! straight vectorised loop. The k nearest are held in blocks of 8 lanes, sorted across the
//! blocks, and a candidate `x` goes in with `out[i] = min(d[i], max(d[i−1], x))` on every lane
//! at once — an exact sorted insertion (the lanes past `k` hold larger values and never
//! reach the first `k`), and a no-op when `x` is not below the k-th, so every candidate of
//! the mask is inserted without a branch, into a copy held in registers. With leaves of
//! 16–32 points instead of 8–16 (fewer, larger batches and nodes), the k-NN of the 10 M terrain
//! LAS (k = 6, 2 cores, tree build included) went from 2.93–2.99 s to 2.11–2.12 s, the same
//! distances to the bit.
//!
//! **Degenerate input** (all documented fallbacks, never a panic):
//! - `k = 0` is treated as `k = 1`; `k ≥ n` is clamped to `n − 1` (the farthest other point);
//! - a point whose k-th neighbour is at distance 0 (it has ≥ k exact duplicates), or whose
//!   distance is not finite (NaN input), gets the *smallest positive* k-NN distance found in
//!   the cloud — the finest spacing the cloud really has;
//! - if no point has a positive distance (a single point, or every point with ≥ k
//!   duplicates), every point gets `diagonal / √n` of the bounding box (the spacing of `n`
//!   points spread over a surface of that size), and if that is zero too (all points
//!   coincide), `1.0`.
//!
//! **Splat radius.** [`radius_from_spacing`] is the identity: a splat of radius equal to the
//! k-NN distance reaches the centres of its k nearest neighbours, so neighbouring splats
//! overlap generously and a randomly (Poisson) sampled surface is covered without holes for
//! k ≥ 6 (tested with k = [`DEFAULT_K`]). Half the spacing would make splats of a *regular*
//! grid just touch, but leaves holes wherever random sampling leaves a gap.

use std::ops::Range;

use rayon::prelude::*;

/// The `k` we recommend for splat radii (see [`radius_from_spacing`]).
pub const DEFAULT_K: usize = 8;

/// Most points in a kd-tree leaf; leaves hold between `LEAF_MAX / 2` and `LEAF_MAX`
/// (32 against 16 and 64: 2.11 s, 2.66 s and 2.49 s on the 10 M terrain's k-NN).
const LEAF_MAX: usize = 32;
// A leaf's candidates are a `u32` bit mask (`Batch::scan`).
const _: () = assert!(LEAF_MAX <= 32);

/// Splat radius for a sample of k-NN spacing `spacing`: the identity (see the module docs).
#[inline]
pub fn radius_from_spacing(spacing: f32) -> f32 {
    spacing
}

/// Distance from each point to its `k`-th nearest neighbour (itself excluded), in input
/// order; every value finite and `> 0`. See the module docs for the degenerate cases.
pub fn knn_spacing(positions: &[[f32; 3]], k: usize) -> Vec<f32> {
    let n = positions.len();
    if n == 0 {
        return Vec::new();
    }
    let mut out = if n >= 2 {
        let k = k.clamp(1, n - 1);
        KdTree::build(positions).knn_distances(k)
    } else {
        vec![0.0]
    };
    apply_fallback(&mut out, positions);
    out
}

/// Replaces zero / non-finite spacings as documented in the module docs.
fn apply_fallback(out: &mut [f32], positions: &[[f32; 3]]) {
    let bad = |d: f32| !(d.is_finite() && d > 0.0);
    if !out.par_iter().any(|&d| bad(d)) {
        return;
    }
    let smallest = out
        .par_iter()
        .copied()
        .filter(|&d| !bad(d))
        .reduce(|| f32::INFINITY, f32::min);
    let fallback = fallback_spacing(smallest, || crate::Aabb::from_points(positions), out.len());
    out.par_iter_mut().for_each(|d| {
        if bad(*d) {
            *d = fallback;
        }
    });
}

/// True if `d` is not a usable spacing (zero, or not finite): it is replaced by the fallback.
#[inline]
pub fn is_degenerate(d: f32) -> bool {
    !(d.is_finite() && d > 0.0)
}

/// The spacing given to degenerate points (see the module docs): `smallest`, the smallest
/// positive k-NN distance of the cloud, if finite; else the bounding-box diagonal over
/// `√n`; else 1. `bounds` is asked for only when needed.
pub fn fallback_spacing(smallest: f32, bounds: impl FnOnce() -> crate::Aabb, n: usize) -> f32 {
    if smallest.is_finite() {
        return smallest;
    }
    let b = bounds();
    let diag = b.size().length() / (n as f32).sqrt();
    if diag.is_finite() && diag > 0.0 {
        diag
    } else {
        1.0
    }
}

/// A kd-tree over a set of points answering k-nearest-neighbour queries as lists of squared
/// distances, for builds that split a cloud into parts and merge the parts' answers: the
/// k-th smallest of the union of every part's `k` smallest squared distances is exactly the
/// k-th squared distance [`knn_spacing`] finds over the whole cloud (the same `f32`
/// arithmetic, the same self exclusion by index).
pub struct KnnIndex {
    tree: Option<KdTree>,
}

impl KnnIndex {
    /// Indexes `positions`.
    pub fn new(positions: &[[f32; 3]]) -> Self {
        Self {
            tree: (!positions.is_empty()).then(|| KdTree::build(positions)),
        }
    }

    /// For every indexed point, in input order, the `k` smallest squared distances to the
    /// other indexed points, ascending, `+∞` where there are fewer: `k` values per point.
    pub fn self_lists(&self, k: usize) -> Vec<f32> {
        let Some(t) = &self.tree.as_ref().filter(|_| k > 0) else {
            return Vec::new();
        };
        let by_tree = t.search_leaves(t, true, k, k, |h, o| o.copy_from_slice(h));
        t.to_input_order(&by_tree, k)
    }

    /// For every query point, in order, the `k` smallest squared distances to the indexed
    /// points (none excluded), ascending, `+∞` where there are fewer.
    pub fn query_lists(&self, queries: &[[f32; 3]], k: usize) -> Vec<f32> {
        if k == 0 {
            return Vec::new();
        }
        let Some(t) = &self.tree else {
            return vec![f32::INFINITY; queries.len() * k];
        };
        if queries.is_empty() {
            return Vec::new();
        }
        // Batches of nearby queries: the leaves of a kd-tree over the queries themselves
        // (a batch's search is pruned by the box around its queries).
        let qt = KdTree::build(queries);
        let by_tree = t.search_leaves(&qt, false, k, k, |h, o| o.copy_from_slice(h));
        qt.to_input_order(&by_tree, k)
    }
}

/// A point with its index in the input (`u32` when the cloud's indices fit: 16-byte items
/// instead of 24, a third less to move in the build's selections).
#[derive(Clone, Copy)]
struct Item<I> {
    p: [f32; 3],
    index: I,
}

/// An input index as a build's items hold it.
trait InputIndex: Copy + Send + Sync {
    fn of(i: usize) -> Self;
}

impl InputIndex for u32 {
    #[inline]
    fn of(i: usize) -> Self {
        // `KdTree::build` uses `u32` only when every index fits.
        i as u32
    }
}

impl InputIndex for usize {
    #[inline]
    fn of(i: usize) -> Self {
        i
    }
}

/// The input index of each point in tree order.
enum Indices {
    Narrow(Vec<u32>),
    Wide(Vec<usize>),
}

/// Implicit balanced kd-tree (see the module docs).
struct KdTree {
    /// Coordinates of the points in tree order, one array per axis (each leaf is a
    /// contiguous range; a leaf's distances are computed a whole array row at a time, which
    /// the compiler vectorises).
    xyz: [Vec<f32>; 3],
    /// Input index of each point, in tree order.
    index: Indices,
    /// Internal nodes in heap order: (split value, axis).
    nodes: Vec<(f32, u8)>,
}

impl KdTree {
    fn build(positions: &[[f32; 3]]) -> KdTree {
        if u32::try_from(positions.len()).is_ok() {
            let (xyz, index, nodes) = Self::build_with::<u32>(positions);
            KdTree {
                xyz,
                index: Indices::Narrow(index),
                nodes,
            }
        } else {
            let (xyz, index, nodes) = Self::build_with::<usize>(positions);
            KdTree {
                xyz,
                index: Indices::Wide(index),
                nodes,
            }
        }
    }

    /// The tree's arrays, built with items holding their input index as `I`.
    #[allow(clippy::type_complexity)]
    fn build_with<I: InputIndex>(
        positions: &[[f32; 3]],
    ) -> ([Vec<f32>; 3], Vec<I>, Vec<(f32, u8)>) {
        let n = positions.len();
        let mut items: Vec<Item<I>> = positions
            .par_iter()
            .enumerate()
            .map(|(index, &p)| Item {
                p,
                index: I::of(index),
            })
            .collect();
        // All leaves at depth `depth`, each with at most LEAF_MAX points.
        let mut depth = 0u32;
        while n.div_ceil(1 << depth) > LEAF_MAX {
            depth += 1;
        }
        let mut nodes = vec![(0.0f32, 0u8); (1usize << depth) - 1];
        for level in 0..depth {
            let first = (1usize << level) - 1;
            let count = 1usize << level;
            // The node ranges of this level, as disjoint mutable slices.
            let mut slices: Vec<&mut [Item<I>]> = Vec::with_capacity(count);
            split_level(&mut items, level, &mut slices);
            nodes[first..first + count]
                .par_iter_mut()
                .zip(slices.into_par_iter())
                .for_each(|(node, s)| *node = split_node(s));
        }
        // Each axis padded with LEAF_MAX values of +∞: a leaf's scan reads LEAF_MAX places
        // from its first point (`Batch::scan`), past the last leaf too.
        let pad = std::iter::repeat_n(f32::INFINITY, LEAF_MAX);
        let xyz = [0, 1, 2].map(|a| items.iter().map(|it| it.p[a]).chain(pad.clone()).collect());
        let index = items.iter().map(|it| it.index).collect();
        (xyz, index, nodes)
    }

    /// Points in the tree (the axis arrays hold LEAF_MAX padding places more).
    fn len(&self) -> usize {
        self.xyz[0].len() - LEAF_MAX
    }

    /// The point at tree position `i`.
    #[inline]
    fn point(&self, i: usize) -> [f32; 3] {
        [self.xyz[0][i], self.xyz[1][i], self.xyz[2][i]]
    }

    /// k-NN distance of every point, in input order.
    fn knn_distances(&self, k: usize) -> Vec<f32> {
        let in_tree_order = self.search_leaves(self, true, k, 1, |h, o| o[0] = h[k - 1].sqrt());
        self.to_input_order(&in_tree_order, 1)
    }

    /// `width` values per point in tree order, rearranged to input order.
    fn to_input_order(&self, by_tree: &[f32], width: usize) -> Vec<f32> {
        let mut out = vec![0.0f32; self.len() * width];
        let mut put = |i: usize, v: &[f32]| out[i * width..i * width + width].copy_from_slice(v);
        match &self.index {
            Indices::Narrow(ix) => {
                for (&i, v) in ix.iter().zip(by_tree.chunks_exact(width)) {
                    put(i as usize, v);
                }
            }
            Indices::Wide(ix) => {
                for (&i, v) in ix.iter().zip(by_tree.chunks_exact(width)) {
                    put(i, v);
                }
            }
        }
        out
    }

    /// Searches the `k` nearest of every point of `queries` (a tree over the query points:
    /// `self` when the indexed points query themselves, each excluded by its tree position,
    /// `own`) and writes `width` values per query, in `queries`' tree order, with
    /// `emit(sorted, out)` (`sorted`: the query's `k` smallest squared distances, ascending,
    /// `+∞` where there are fewer; `out` starts as `+∞`).
    fn search_leaves(
        &self,
        queries: &KdTree,
        own: bool,
        k: usize,
        width: usize,
        emit: impl Fn(&[f32], &mut [f32]) + Sync,
    ) -> Vec<f32> {
        // One block of lanes holds the k of every build (6 and 8); four hold the tests'
        // larger k; beyond, the sorted list of any length.
        match k.div_ceil(LANES) {
            0 | 1 => self.search_with::<Lanes<1>>(queries, own, k, width, emit),
            2..=4 => self.search_with::<Lanes<4>>(queries, own, k, width, emit),
            _ => self.search_with::<SortedList>(queries, own, k, width, emit),
        }
    }

    /// [`KdTree::search_leaves`] with the k nearest held as `H`.
    fn search_with<H: Nearest>(
        &self,
        queries: &KdTree,
        own: bool,
        k: usize,
        width: usize,
        emit: impl Fn(&[f32], &mut [f32]) + Sync,
    ) -> Vec<f32> {
        let n = self.len();
        let q = queries.len();
        let leaves = queries.nodes.len() + 1;
        // Each leaf's queries run together (one traversal for its ≤ LEAF_MAX points), the
        // leaves in parallel; results land at the queries' tree positions.
        let mut in_tree_order = vec![f32::INFINITY; q * width];
        let mut ranges = Vec::with_capacity(leaves);
        leaf_ranges(0, q, queries.nodes.len(), 0, &mut ranges);
        let mut outs: Vec<&mut [f32]> = Vec::with_capacity(leaves);
        let mut rest = in_tree_order.as_mut_slice();
        for r in &ranges {
            let (head, tail) = rest.split_at_mut(r.len() * width);
            outs.push(head);
            rest = tail;
        }
        ranges.par_iter().zip(outs.into_par_iter()).for_each_init(
            || (Vec::<H>::new(), Vec::<[f32; 3]>::new()),
            |(heaps, points), (r, out)| {
                heaps.resize_with(r.len(), || H::new(k));
                heaps.iter_mut().for_each(H::clear);
                points.clear();
                points.extend(r.clone().map(|i| queries.point(i)));
                // A query of another set is no indexed point: its `first` lies past every
                // tree position.
                let first = if own { r.start } else { usize::MAX / 2 };
                let mut batch = Batch::new(points, first, heaps);
                let mut cell = [[f32::NEG_INFINITY, f32::INFINITY]; 3];
                self.search_batch(0, 0, n, &mut cell, &mut batch);
                for (o, h) in out.chunks_exact_mut(width).zip(batch.heaps.iter()) {
                    emit(h.sorted(), o);
                }
            },
        );
        in_tree_order
    }

    /// k-NN search of a leaf's queries below `node` (index range `lo..hi`, whose points lie
    /// in `cell`, `[lo, hi]` per axis). A node is skipped when the squared distance from the
    /// queries' bounding box to its cell is not below the worst k-th distance of any query
    /// (`batch.bound`): no point there can enter any query's k nearest. Exact: the box
    /// distance is, with `f32` rounding being monotonic, never above a computed point
    /// distance.
    fn search_batch<H: Nearest>(
        &self,
        node: usize,
        lo: usize,
        hi: usize,
        cell: &mut [[f32; 2]; 3],
        batch: &mut Batch<'_, H>,
    ) {
        if batch.box_distance2(cell) >= batch.bound {
            return;
        }
        if node >= self.nodes.len() {
            let window = |a: &Vec<f32>| -> [f32; LEAF_MAX] {
                // In bounds: the arrays are padded with LEAF_MAX places.
                a[lo..lo + LEAF_MAX]
                    .try_into()
                    .expect("a window of LEAF_MAX places")
            };
            let [x, y, z] = &self.xyz;
            batch.scan([window(x), window(y), window(z)], lo, hi - lo, cell);
            return;
        }
        let (split, axis) = self.nodes[node];
        let a = axis as usize;
        let mid = lo + (hi - lo) / 2;
        // Points left of the split are ≤ it, right ones ≥ it (median selection).
        let left = (2 * node + 1, lo, mid, 1usize);
        let right = (2 * node + 2, mid, hi, 0usize);
        let (near, far) = if batch.centre[a] < split {
            (left, right)
        } else {
            (right, left)
        };
        for (child, clo, chi, side) in [near, far] {
            let old = cell[a][side];
            cell[a][side] = split;
            self.search_batch(child, clo, chi, cell, batch);
            cell[a][side] = old;
        }
    }
}

/// The queries of one leaf during [`KdTree::search_batch`].
struct Batch<'a, H> {
    /// The queries, at tree positions `first..first + queries.len()`.
    queries: &'a [[f32; 3]],
    first: usize,
    /// Their k nearest so far.
    heaps: &'a mut [H],
    /// Bounding box of the (non-NaN) queries, and its centre.
    lo: [f32; 3],
    hi: [f32; 3],
    centre: [f32; 3],
    /// The largest k-th squared distance over the queries (∞ until all have k).
    bound: f32,
}

impl<'a, H: Nearest> Batch<'a, H> {
    fn new(queries: &'a [[f32; 3]], first: usize, heaps: &'a mut [H]) -> Self {
        let mut lo = [f32::INFINITY; 3];
        let mut hi = [f32::NEG_INFINITY; 3];
        for q in queries {
            for a in 0..3 {
                lo[a] = lo[a].min(q[a]);
                hi[a] = hi[a].max(q[a]);
            }
        }
        let centre = [0, 1, 2].map(|a| 0.5 * lo[a] + 0.5 * hi[a]);
        Batch {
            queries,
            first,
            heaps,
            lo,
            hi,
            centre,
            bound: f32::INFINITY,
        }
    }

    /// Squared distance from the queries' box to `cell` (0 where they overlap).
    #[inline]
    fn box_distance2(&self, cell: &[[f32; 2]; 3]) -> f32 {
        let mut d = 0.0f32;
        for ((c, lo), hi) in cell.iter().zip(self.lo).zip(self.hi) {
            let gap = (c[0] - hi).max(lo - c[1]).max(0.0);
            d += gap * gap;
        }
        d
    }

    /// Offers the points of a leaf (its window of LEAF_MAX places per axis from tree position
    /// `lo`, of which the first `len` are its points, inside `cell`) to every query whose own
    /// distance to the cell is below its k-th distance. A query's distances to the window
    /// are one vectorised loop (the same arithmetic as [`dist2`]) that also marks the places
    /// below its k-th distance; the marked points (the query itself unmarked) are offered.
    fn scan(
        &mut self,
        [xs, ys, zs]: [[f32; LEAF_MAX]; 3],
        lo: usize,
        len: usize,
        cell: &[[f32; 2]; 3],
    ) {
        // Leaves hold at most LEAF_MAX points by construction (`KdTree::build`).
        let points = (((1u64 << len) - 1) & u64::from(u32::MAX)) as u32;
        let mut d = [0.0f32; LEAF_MAX];
        for (j, (q, heap)) in self.queries.iter().zip(self.heaps.iter_mut()).enumerate() {
            let worst = heap.worst();
            let mut to_cell = 0.0f32;
            for (c, &x) in cell.iter().zip(q) {
                let gap = (c[0] - x).max(x - c[1]).max(0.0);
                to_cell += gap * gap;
            }
            if to_cell >= worst {
                continue;
            }
            let mut below = 0u32;
            for i in 0..LEAF_MAX {
                let (dx, dy, dz) = (xs[i] - q[0], ys[i] - q[1], zs[i] - q[2]);
                d[i] = dx * dx + dy * dy + dz * dz;
                below |= u32::from(d[i] < worst) << i;
            }
            below &= points;
            // A query excludes itself by its tree position.
            let me = (self.first + j).wrapping_sub(lo);
            if me < len {
                below &= !(1u32 << me);
            }
            heap.offer(&d, below);
        }
        self.bound = self.heaps.iter().map(H::worst).fold(0.0, f32::max);
    }
}

/// The index ranges of the leaves below `node` (range `lo..hi`), in order, for a tree with
/// `internal` internal nodes.
fn leaf_ranges(lo: usize, hi: usize, internal: usize, node: usize, out: &mut Vec<Range<usize>>) {
    if node >= internal {
        out.push(lo..hi);
        return;
    }
    let mid = lo + (hi - lo) / 2;
    leaf_ranges(lo, mid, internal, 2 * node + 1, out);
    leaf_ranges(mid, hi, internal, 2 * node + 2, out);
}

/// Cuts `items` into the node ranges of `level` (in order), pushing them to `out`.
fn split_level<'a, I>(items: &'a mut [Item<I>], level: u32, out: &mut Vec<&'a mut [Item<I>]>) {
    if level == 0 {
        out.push(items);
        return;
    }
    let mid = items.len() / 2;
    let (l, r) = items.split_at_mut(mid);
    split_level(l, level - 1, out);
    split_level(r, level - 1, out);
}

/// Median split of one node along the longest axis of its points' bounds.
fn split_node<I>(s: &mut [Item<I>]) -> (f32, u8) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for it in s.iter() {
        for a in 0..3 {
            lo[a] = lo[a].min(it.p[a]);
            hi[a] = hi[a].max(it.p[a]);
        }
    }
    let ext = [hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2]];
    let axis = if ext[0] >= ext[1] && ext[0] >= ext[2] {
        0
    } else if ext[1] >= ext[2] {
        1
    } else {
        2
    };
    let mid = s.len() / 2;
    let (_, m, _) = s.select_nth_unstable_by(mid, |a, b| a.p[axis].total_cmp(&b.p[axis]));
    (m.p[axis], axis as u8)
}

/// The squared distance as the search computes it (tests compare against it).
#[cfg(test)]
fn dist2(a: [f32; 3], b: [f32; 3]) -> f32 {
    let d = [a[0] - b[0], a[1] - b[1], a[2] - b[2]];
    d[0] * d[0] + d[1] * d[1] + d[2] * d[2]
}

/// The k smallest squared distances a query has seen so far, ascending, `+∞` in the places
/// not yet filled (so the k-th place is the k-th distance once `k` are held, ∞ before).
trait Nearest: Send {
    fn new(k: usize) -> Self;
    fn clear(&mut self);
    /// The k-th distance so far.
    fn worst(&self) -> f32;
    /// Offers `d[i]` for every bit `i` of `below` (each below [`Nearest::worst`] when the
    /// mask was made; those that no longer are change nothing).
    fn offer(&mut self, d: &[f32; LEAF_MAX], below: u32);
    /// The `k` places, ascending.
    fn sorted(&self) -> &[f32];
}

/// Lanes of a block of [`Lanes`].
const LANES: usize = 8;

/// The k nearest (k ≤ `B · LANES`) in `B` blocks of lanes, sorted across the blocks; the
/// lanes past `k` hold values no smaller than the k-th (see the module docs, *Lanes*).
struct Lanes<const B: usize> {
    d: [[f32; LANES]; B],
    k: usize,
}

impl<const B: usize> Nearest for Lanes<B> {
    fn new(k: usize) -> Self {
        debug_assert!(
            k > 0 && k <= B * LANES,
            "k = 0 is answered before any search"
        );
        Lanes {
            d: [[f32::INFINITY; LANES]; B],
            k,
        }
    }
    fn clear(&mut self) {
        self.d = [[f32::INFINITY; LANES]; B];
    }
    #[inline]
    fn worst(&self) -> f32 {
        self.d.as_flattened()[self.k - 1]
    }
    #[inline]
    fn offer(&mut self, d: &[f32; LEAF_MAX], mut below: u32) {
        // Held in registers while the candidates go in.
        let mut h = self.d;
        while below != 0 {
            let i = below.trailing_zeros() as usize;
            below &= below - 1;
            h = insert_lanes(h, d[i]);
        }
        self.d = h;
    }
    fn sorted(&self) -> &[f32] {
        &self.d.as_flattened()[..self.k]
    }
}

/// `x` inserted into the sorted lanes `d`, the largest dropped: `out[i] = min(d[i],
/// max(d[i−1], x))` with `d[−1] = −∞`, every lane at once (`a < b ? a : b` forms, which
/// compile to `minps`/`maxps`; no NaN reaches here: NaN distances are never below a k-th).
/// Unchanged below `x`'s place, so a no-op on the first `k` when `x` is not below the k-th.
#[inline(always)]
fn insert_lanes<const B: usize>(d: [[f32; LANES]; B], x: f32) -> [[f32; LANES]; B] {
    let mut out = [[0.0f32; LANES]; B];
    let mut carry = f32::NEG_INFINITY;
    for (o, block) in out.iter_mut().zip(&d) {
        let mut prev = [carry; LANES];
        prev[1..].copy_from_slice(&block[..LANES - 1]);
        for ((o, &cur), &prev) in o.iter_mut().zip(block).zip(&prev) {
            let m = if prev > x { prev } else { x };
            *o = if cur < m { cur } else { m };
        }
        carry = block[LANES - 1];
    }
    out
}

/// The k nearest for any `k`, as one sorted list (the k of no build needs it).
struct SortedList {
    d: Vec<f32>,
}

impl Nearest for SortedList {
    fn new(k: usize) -> Self {
        SortedList {
            d: vec![f32::INFINITY; k],
        }
    }
    fn clear(&mut self) {
        self.d.fill(f32::INFINITY);
    }
    #[inline]
    fn worst(&self) -> f32 {
        self.d[self.d.len() - 1]
    }
    fn offer(&mut self, d: &[f32; LEAF_MAX], mut below: u32) {
        while below != 0 {
            let i = below.trailing_zeros() as usize;
            below &= below - 1;
            if d[i] < self.worst() {
                // `d[i]` bubbles up the sorted places by `min`/`max`.
                let mut x = d[i];
                for p in self.d.iter_mut() {
                    let (lo, hi) = if *p < x { (*p, x) } else { (x, *p) };
                    *p = lo;
                    x = hi;
                }
            }
        }
    }
    fn sorted(&self) -> &[f32] {
        &self.d
    }
}

/// At most this many evenly strided samples measure the occupancy area of [`area_spacing`].
pub const AREA_SAMPLES: usize = 1 << 20;

/// Cells across the largest extent of `bounds` at which [`area_spacing`] measures the area.
pub const AREA_CELLS: f32 = 64.0;

/// The area per sample `√(A/N)` of the surface the `positions` sample, with `A` measured as
/// an **occupancy area**: the number of occupied cubic cells of side `c` times `c²`, counted
/// over at most [`AREA_SAMPLES`] evenly strided samples inside `bounds` (the cloud's bounds,
/// or the camera framing's inlier box so that far strays do not set the scale; samples
/// outside are not counted). The cell is `c = max(E / AREA_CELLS, 4·√(F/n))`, with `E` the
/// largest extent of `bounds`, `F` its largest face's area and `n` the samples counted: fine
/// enough to follow the surface, and (the second term) about 4× the spacing the samples
/// would have if they covered that face evenly, so that a surface sampled in lines or
/// clusters (an aerial tile scanned in lines: 0.15 m along a line, 4.5 m between lines)
/// still occupies every cell it crosses. Nearest-neighbour estimates see only the spacing
/// along such a line.
///
/// Exact (to the cells cut by the border) for a plane parallel to a face of the cells. A
/// plane of unit normal `m` crosses `‖m‖₁` cells per `c²` of its area, so a curved surface's
/// `A` is overestimated by the mean `‖m‖₁` over its normals (1.5 averaged over all
/// directions, at most √3), and its spacing by the square root of that (≈ 1.22). A surface
/// thinner than the cell but noisy counts as a surface; a volume-filling cloud (fog, a
/// dense point set with no surface) counts the cells it fills, each as `c²`.
///
/// Returns `NaN` when no sample lies in `bounds` or the bounds have no extent.
pub fn area_spacing(positions: &[[f32; 3]], bounds: crate::Aabb) -> f32 {
    let stride = positions.len().div_ceil(AREA_SAMPLES).max(1);
    let inside = |p: &&[f32; 3]| {
        let v = glam::Vec3::from(**p);
        v.cmpge(bounds.min).all() && v.cmple(bounds.max).all()
    };
    let n = positions.iter().step_by(stride).filter(inside).count();
    let size = bounds.size();
    let extent = size.max_element();
    if n == 0 || !extent.is_finite() || extent <= 0.0 {
        return f32::NAN;
    }
    let face = (size.x * size.y).max(size.y * size.z).max(size.z * size.x);
    let cell = (extent / AREA_CELLS).max(4.0 * (face / n as f32).sqrt());
    // 21 bits per axis: at most 2²¹ cells across, far more than E / c ≤ AREA_CELLS.
    let key = |p: &[f32; 3]| {
        let q = |a: usize| (((p[a] - bounds.min[a]) / cell) as u64).min((1 << 21) - 1);
        q(0) | q(1) << 21 | q(2) << 42
    };
    let mut keys: Vec<u64> = positions
        .iter()
        .step_by(stride)
        .filter(inside)
        .map(key)
        .collect();
    keys.par_sort_unstable();
    keys.dedup();
    let area = keys.len() as f64 * (cell as f64).powi(2);
    // The strided samples stand for all the samples inside: scale the count back
    // (`step_by(stride)` visits `⌈len / stride⌉` samples).
    let strided = positions.len().div_ceil(stride);
    let all = (n as f64 * positions.len() as f64 / strided as f64).max(1.0);
    (area / all).sqrt() as f32
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute(p: &[[f32; 3]], k: usize) -> Vec<f32> {
        (0..p.len())
            .map(|i| {
                let mut d: Vec<f32> = (0..p.len())
                    .filter(|&j| j != i)
                    .map(|j| dist2(p[i], p[j]))
                    .collect();
                d.sort_by(f32::total_cmp);
                d[k - 1].sqrt()
            })
            .collect()
    }

    /// A cloud too large for `u32` indices (never built in a test) takes the `usize` items:
    /// both item widths give the same tree and the exact distances.
    #[test]
    fn wide_and_narrow_indices_build_the_same_tree() {
        let mut r = crate::rng::Pcg32::new(3);
        let p: Vec<[f32; 3]> = (0..2000)
            .map(|_| [r.f32(), r.f32(), r.f32() * 0.1])
            .collect();
        let (xyz, index, nodes) = KdTree::build_with::<usize>(&p);
        let wide = KdTree {
            xyz,
            index: Indices::Wide(index),
            nodes,
        };
        let narrow = KdTree::build(&p);
        assert!(matches!(narrow.index, Indices::Narrow(_)));
        assert_eq!(wide.nodes, narrow.nodes);
        assert_eq!(wide.xyz, narrow.xyz);
        let k = 6;
        assert_eq!(wide.knn_distances(k), narrow.knn_distances(k));
        assert_eq!(narrow.knn_distances(k), brute(&p, k));
    }

    #[test]
    fn lists_of_parts_merge_to_the_whole_clouds_spacing() {
        // Random points with duplicates, cut into three parts by index (so the parts
        // overlap in space): each point's own part's list merged with every other part's
        // answer gives, at rank k, exactly knn_spacing's (squared) value.
        let mut r = crate::rng::Pcg32::new(9);
        let mut p: Vec<[f32; 3]> = (0..3000)
            .map(|_| [r.f32(), r.f32() * 0.5, r.f32() * 0.01])
            .collect();
        p.extend_from_within(..40);
        let k = 6;
        let whole = knn_spacing(&p, k);
        let cuts = [0, 700, 2100, p.len()];
        let parts: Vec<&[[f32; 3]]> = cuts.windows(2).map(|w| &p[w[0]..w[1]]).collect();
        let index: Vec<KnnIndex> = parts.iter().map(|q| KnnIndex::new(q)).collect();
        let mut merged = Vec::new();
        for (a, q) in parts.iter().enumerate() {
            let mut lists: Vec<Vec<f32>> = index[a]
                .self_lists(k)
                .chunks_exact(k)
                .map(|l| l.to_vec())
                .collect();
            assert!(lists.iter().all(|l| l.windows(2).all(|w| w[0] <= w[1])));
            for (b, other) in index.iter().enumerate() {
                if a != b {
                    for (l, o) in lists
                        .iter_mut()
                        .zip(other.query_lists(q, k).chunks_exact(k))
                    {
                        l.extend_from_slice(o);
                    }
                }
            }
            for mut l in lists {
                l.sort_by(f32::total_cmp);
                merged.push(l[k - 1].sqrt());
            }
        }
        assert_eq!(merged, whole);
        // Fewer indexed points than k: padded with +∞.
        let small = KnnIndex::new(&p[..3]);
        let l = small.self_lists(4);
        assert_eq!(l.len(), 12);
        assert!(l[1].is_finite() && l[2] == f32::INFINITY && l[3] == f32::INFINITY);
        assert_eq!(
            KnnIndex::new(&[]).query_lists(&p[..2], 3),
            vec![f32::INFINITY; 6]
        );
        // k = 0: no values per point.
        assert!(small.self_lists(0).is_empty());
        assert!(small.query_lists(&p[..2], 0).is_empty());
        // Every list equals the brute-force sorted distances (the whole list, not only the
        // k-th value), here with a k larger than a leaf.
        let k = 20;
        let q = &p[..400];
        let lists = KnnIndex::new(q).self_lists(k);
        for (i, l) in lists.chunks_exact(k).enumerate() {
            let mut d: Vec<f32> = (0..q.len())
                .filter(|&j| j != i)
                .map(|j| dist2(q[i], q[j]))
                .collect();
            d.sort_by(f32::total_cmp);
            assert_eq!(l, &d[..k], "point {i}");
        }
    }

    #[test]
    fn regular_grid_gives_the_grid_spacing() {
        let h = 0.25f32;
        let m = 12;
        let mut p = Vec::new();
        for i in 0..m {
            for j in 0..m {
                for k in 0..m {
                    p.push([i as f32 * h + 3.0, j as f32 * h - 1.0, k as f32 * h]);
                }
            }
        }
        let d1 = knn_spacing(&p, 1);
        let d6 = knn_spacing(&p, 6);
        let d7 = knn_spacing(&p, 7);
        for (idx, q) in p.iter().enumerate() {
            let (i, j, k) = (idx / (m * m), (idx / m) % m, idx % m);
            let interior = [i, j, k].iter().all(|&c| c > 0 && c < m - 1);
            assert!((d1[idx] - h).abs() < 1e-5, "{q:?}: {}", d1[idx]);
            if interior {
                assert!((d6[idx] - h).abs() < 1e-5, "{q:?}: {}", d6[idx]);
                // The 7th neighbour is a face diagonal.
                assert!(
                    (d7[idx] - h * 2f32.sqrt()).abs() < 1e-5,
                    "{q:?}: {}",
                    d7[idx]
                );
            }
        }
    }

    #[test]
    fn degenerate_input_gives_finite_positive_spacing() {
        // Many exact duplicates: the k-th neighbour is at distance 0 for most points.
        let mut p = vec![[1.0f32, 2.0, 3.0]; 50];
        p.extend(vec![[1.5f32, 2.0, 3.0]; 50]);
        p.push([4.0, 2.0, 3.0]);
        let d = knn_spacing(&p, 8);
        assert!(d.iter().all(|d| d.is_finite() && *d > 0.0));
        // The fallback is the smallest positive spacing found (the lone point's 8th NN).
        assert_eq!(d[0], d[100]);
        // All coincident: no positive distance and an empty box → 1.0.
        let d = knn_spacing(&[[7.0f32, 7.0, 7.0]; 20], 8);
        assert!(d.iter().all(|&d| d == 1.0));
        // Two clusters of coincident points: diagonal / √n.
        let mut p = vec![[0.0f32; 3]; 10];
        p.extend(vec![[3.0f32, 4.0, 0.0]; 10]);
        let d = knn_spacing(&p, 4);
        assert!(d.iter().all(|&d| (d - 5.0 / 20f32.sqrt()).abs() < 1e-6));
        // Single point, k = 0, k ≥ n, empty input.
        assert_eq!(knn_spacing(&[[1.0, 1.0, 1.0]], 8), vec![1.0]);
        let p = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
        assert_eq!(knn_spacing(&p, 0), knn_spacing(&p, 1));
        assert_eq!(knn_spacing(&p, 100), vec![3.0, 2.0, 3.0]);
        assert!(knn_spacing(&[], 8).is_empty());
        // NaN input never panics and still gives finite positive values.
        let p = [[0.0f32, 0.0, 0.0], [f32::NAN, 0.0, 0.0], [1.0, 0.0, 0.0]];
        assert!(knn_spacing(&p, 1).iter().all(|d| d.is_finite() && *d > 0.0));
    }

    #[test]
    fn radius_equal_to_spacing_covers_a_random_surface() {
        // Uniform random points on the unit square: every interior test point must lie inside
        // the disc of radius `radius_from_spacing(knn_spacing(.., DEFAULT_K))` of some sample.
        let mut r = crate::rng::Pcg32::new(11);
        let p: Vec<[f32; 3]> = (0..20_000).map(|_| [r.f32(), r.f32(), 0.0]).collect();
        let rad: Vec<f32> = knn_spacing(&p, DEFAULT_K)
            .into_iter()
            .map(radius_from_spacing)
            .collect();
        // Bucket the samples in a grid to test coverage quickly.
        let g = 64usize;
        let mut cells = vec![Vec::new(); g * g];
        for (i, q) in p.iter().enumerate() {
            let (x, y) = ((q[0] * g as f32) as usize, (q[1] * g as f32) as usize);
            cells[y.min(g - 1) * g + x.min(g - 1)].push(i);
        }
        for _ in 0..20_000 {
            let (x, y) = (0.1 + 0.8 * r.f32(), 0.1 + 0.8 * r.f32());
            let (cx, cy) = ((x * g as f32) as usize, (y * g as f32) as usize);
            let covered = (cy - 2..=cy + 2).any(|j| {
                (cx - 2..=cx + 2).any(|i| {
                    cells[j * g + i]
                        .iter()
                        .any(|&s| dist2(p[s], [x, y, 0.0]) < rad[s] * rad[s])
                })
            });
            assert!(covered, "hole at ({x}, {y})");
        }
    }

    /// Every `k` the heaps hold differently — one block of lanes (≤ 8), four (≤ 32), the
    /// sorted list (> 32), and each block's edge — gives the brute-force lists, whole; so do
    /// clouds whose leaves are exactly full (32, 64 points) or one over.
    #[test]
    fn every_heap_and_leaf_size_gives_the_brute_force_lists() {
        let mut r = crate::rng::Pcg32::new(11);
        let mut cloud: Vec<[f32; 3]> = (0..600)
            .map(|i| {
                let s = [1.0, 0.01][i % 2];
                [r.f32() * s, r.f32() * s + (i % 2) as f32, r.f32() * s * 0.1]
            })
            .collect();
        cloud.extend_from_within(..5);
        for n in [2, 32, 33, 64, 65, cloud.len()] {
            let p = &cloud[..n];
            let brute: Vec<Vec<f32>> = (0..n)
                .map(|i| {
                    let mut d: Vec<f32> = (0..n)
                        .filter(|&j| j != i)
                        .map(|j| dist2(p[i], p[j]))
                        .collect();
                    d.sort_by(f32::total_cmp);
                    d.resize(40, f32::INFINITY);
                    d
                })
                .collect();
            let index = KnnIndex::new(p);
            for k in [1, 7, 8, 9, 16, 17, 32, 33, 40] {
                let lists = index.self_lists(k);
                for (i, l) in lists.chunks_exact(k).enumerate() {
                    assert_eq!(l, &brute[i][..k], "n = {n}, k = {k}, point {i}");
                }
            }
        }
    }

    /// The lanes' insertion is a sorted insertion that drops the largest, for any place of
    /// `x` (ties and `+∞` included), across blocks.
    #[test]
    fn inserting_into_lanes_is_a_sorted_insertion() {
        let mut r = crate::rng::Pcg32::new(2);
        for _ in 0..2000 {
            let mut v: Vec<f32> = (0..2 * LANES)
                .map(|_| match r.below(4) {
                    0 => f32::INFINITY,
                    1 => 0.5,
                    _ => r.f32(),
                })
                .collect();
            v.sort_by(f32::total_cmp);
            let x = if r.below(3) == 0 { 0.5 } else { r.f32() };
            let d = [0, 1].map(|b| <[f32; LANES]>::try_from(&v[b * LANES..][..LANES]).unwrap());
            let got = insert_lanes(d, x);
            v.push(x);
            v.sort_by(f32::total_cmp);
            assert_eq!(got.as_flattened(), &v[..2 * LANES]);
        }
    }

    #[test]
    fn matches_brute_force_on_clustered_points() {
        let mut r = crate::rng::Pcg32::new(5);
        let mut p = Vec::new();
        for i in 0..3000 {
            // Three clusters of very different density, and a few exact duplicates.
            let s = [1.0, 0.01, 0.0001][i % 3];
            p.push([r.f32() * s, r.f32() * s + (i % 3) as f32, r.f32() * s]);
        }
        p.push(p[10]);
        p.push(p[11]);
        for k in [1, 3, 8, 20] {
            let got = knn_spacing(&p, k);
            let want = brute(&p, k);
            for (i, (g, w)) in got.iter().zip(&want).enumerate() {
                if *w > 0.0 {
                    assert_eq!(g, w, "point {i}, k = {k}");
                } else {
                    assert!(*g > 0.0 && g.is_finite());
                }
            }
        }
    }
}
