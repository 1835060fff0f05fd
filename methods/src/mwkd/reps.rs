//! `Representatives` (paper, Fig. 4): from the splats of a node, exactly `target` LOD
//! splats, each the size-weighted average of a cluster of input splats with a radius that
//! covers them.
//!
//! Procedure ([`representatives`]), deterministic (no hashing, no threads, ties broken by
//! order):
//! 1. **Grid.** A K³ grid over the bounding box of the input (`K` per axis, so cells follow
//!    the node's aspect). Every input splat starts as its own cluster; the clusters of a cell
//!    form that cell's *list*. Clustering never crosses cells, so at least one cluster per
//!    occupied cell survives: when the grid has more occupied cells than `target`, `K` is
//!    lowered to the largest value whose grid has at most `target` occupied cells (binary
//!    search, then downwards if needed). The paper's fixed `K = 35` assumes `s/N` well
//!    above the number of occupied cells; this keeps the count exact for small `s`.
//! 2. **Queue.** Every list with ≥ 2 clusters goes into a priority queue ordered by its
//!    length (default) or by its largest normal deviation (angle between a cluster's mean
//!    normal and the list's mean normal), ties by cell order.
//! 3. **Merging.** While the total cluster count `c > target`: pop the top list; among its
//!    pairs that are *compatible* — mean normals less than θ apart and, only when the input
//!    has colours, mean colours less than the colour threshold apart in every channel — merge
//!    the cheapest pair (cost = angle/θ₀ + centroid distance/cell diagonal [+ colour
//!    difference/colour threshold₀]); push the list back while it has ≥ 2 clusters. A list
//!    without a compatible pair is set aside; when the queue runs dry, θ and the colour
//!    threshold are multiplied by `relax` (beyond 180° / 255 they become unbounded, so the
//!    loop always ends) and the set-aside lists are queued again. A list longer than
//!    [`ALL_PAIRS_MAX`] clusters (only when the grid was coarsened far below `K`, or for
//!    piles of duplicates) merges up to a quarter of its clusters per pop, in disjoint
//!    cheapest-first pairs found among each cluster's next [`WINDOW`] (then 4 × `WINDOW`)
//!    neighbours in Morton order, so a single huge cell costs O(L log L) per round, not
//!    O(L²) per merge.
//!
//! With `clustering = grid` (Fig. 2's comparison) steps 2–3 are replaced by merging every
//! cell's splats into one cluster: one representative per occupied cell, at most `target`.
//! 4. **Output.** One representative per cluster, clusters in cell order: position, normal
//!    (renormalised) and colour are the weight-averaged member values (weights = samples
//!    represented), weight = their sum, radius = `max(|p_m − p| + r_m)` over the members
//!    (so every member's splat lies inside the representative's sphere).
//!
//! Cost: O(m log m) for the grid plus O(L²) per merge for a short list of L clusters (lists
//! hold the clusters of one cell: a handful for a surface sampled at `s` points over K²
//! cells), O(L·WINDOW) per batch for a long one.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::{DVec3, Vec3};

use super::{Clustering, QueueOrder};

/// A set of splats, by column. `normals` and `colors` are present or absent for the whole
/// set; colours are 0..=255 per channel (as `f32`, averages are not rounded).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Splats {
    /// Centres.
    pub positions: Vec<Vec3>,
    /// Unit normals, if the scene has them.
    pub normals: Option<Vec<Vec3>>,
    /// Colours (0..=255 per channel), if the scene has them.
    pub colors: Option<Vec<[f32; 3]>>,
    /// Splat radii (≥ 0).
    pub radii: Vec<f32>,
    /// Original samples each splat represents (≥ 1).
    pub weights: Vec<u64>,
}

impl Splats {
    /// An empty set with the given optional columns.
    pub fn empty(normals: bool, colors: bool) -> Self {
        Splats {
            positions: Vec::new(),
            normals: normals.then(Vec::new),
            colors: colors.then(Vec::new),
            radii: Vec::new(),
            weights: Vec::new(),
        }
    }

    /// Number of splats.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True if there is no splat.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// Total samples represented.
    pub fn total_weight(&self) -> u64 {
        self.weights.iter().sum()
    }

    /// Appends `other` (which must carry the same optional columns; a missing column in
    /// `other` is filled with zeros to keep the columns aligned).
    pub fn append(&mut self, other: &Splats) {
        self.positions.extend_from_slice(&other.positions);
        if let Some(n) = &mut self.normals {
            match &other.normals {
                Some(o) => n.extend_from_slice(o),
                None => n.resize(self.positions.len(), Vec3::ZERO),
            }
        }
        if let Some(c) = &mut self.colors {
            match &other.colors {
                Some(o) => c.extend_from_slice(o),
                None => c.resize(self.positions.len(), [0.0; 3]),
            }
        }
        self.radii.extend_from_slice(&other.radii);
        self.weights.extend_from_slice(&other.weights);
    }

    /// Splat `i` alone (for the identity selection).
    fn push_from(&mut self, src: &Splats, i: usize) {
        self.positions.push(src.positions[i]);
        if let (Some(d), Some(s)) = (&mut self.normals, &src.normals) {
            d.push(s[i]);
        }
        if let (Some(d), Some(s)) = (&mut self.colors, &src.colors) {
            d.push(s[i]);
        }
        self.radii.push(src.radii[i]);
        self.weights.push(src.weights[i]);
    }
}

/// Settings of the selection (from [`super::MwkdParams::rep_config`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RepConfig {
    /// `K` of the K³ grid (≥ 1).
    pub grid: u32,
    /// Initial normal threshold θ, degrees.
    pub theta_deg: f32,
    /// Relaxation factor (> 1).
    pub relax: f32,
    /// Initial colour threshold (per channel, 0..=255); used only when colours are present.
    pub color_threshold: f32,
    /// Queue order.
    pub queue: QueueOrder,
    /// Adaptive clustering (steps 2–3) or one representative per cell (step 1 only).
    pub clustering: Clustering,
}

impl Default for RepConfig {
    fn default() -> Self {
        super::MwkdParams::default().rep_config()
    }
}

/// The result of [`representatives`].
#[derive(Debug, Clone, PartialEq)]
pub struct Selection {
    /// The representatives: `min(target, input.len())` of them (at least one for non-empty
    /// input).
    pub reps: Splats,
    /// For every input splat, the index of its representative.
    pub members: Vec<u32>,
    /// The `K` actually used (lower than the configured one when the grid had to be
    /// coarsened to reach `target`).
    pub grid_used: u32,
    /// The final normal threshold, degrees (∞ once relaxed past 180°).
    pub theta_used_deg: f32,
}

struct Cluster {
    weight: u64,
    sum_p: DVec3,
    sum_n: DVec3,
    sum_c: [f64; 3],
    /// Cached means.
    center: Vec3,
    normal: Vec3,
    color: [f32; 3],
    /// First and last member: the members form a list threaded through [`Members::next`]
    /// (one array for all clusters, not a vector per cluster).
    head: u32,
    tail: u32,
}

/// The member lists of all clusters: `next[i]` follows input splat `i` in its cluster's
/// list ([`NONE`] at the end). Appending a cluster's list to another's is O(1).
struct Members {
    next: Vec<u32>,
}

const NONE: u32 = u32::MAX;

impl Members {
    /// Every input splat its own one-member list.
    fn singletons(m: usize) -> Self {
        Members {
            next: vec![NONE; m],
        }
    }

    /// The members of `c`, in the order they joined.
    fn of<'a>(&'a self, c: &Cluster) -> impl Iterator<Item = usize> + 'a {
        let mut at = c.head;
        std::iter::from_fn(move || {
            (at != NONE).then(|| {
                let i = at;
                at = self.next[i as usize];
                i as usize
            })
        })
    }
}

impl Cluster {
    fn new(s: &Splats, i: usize) -> Self {
        let w = s.weights[i].max(1);
        let wf = w as f64;
        let p = s.positions[i];
        let n = s.normals.as_ref().map_or(Vec3::ZERO, |n| n[i]);
        let c = s.colors.as_ref().map_or([0.0; 3], |c| c[i]);
        Cluster {
            weight: w,
            sum_p: p.as_dvec3() * wf,
            sum_n: n.as_dvec3() * wf,
            sum_c: [c[0] as f64 * wf, c[1] as f64 * wf, c[2] as f64 * wf],
            center: p,
            normal: n.normalize_or_zero(),
            color: c,
            head: i as u32,
            tail: i as u32,
        }
    }

    fn absorb(&mut self, o: Cluster, members: &mut Members) {
        self.weight += o.weight;
        self.sum_p += o.sum_p;
        self.sum_n += o.sum_n;
        for k in 0..3 {
            self.sum_c[k] += o.sum_c[k];
        }
        let w = self.weight as f64;
        self.center = (self.sum_p / w).as_vec3();
        self.normal = self.sum_n.normalize_or_zero().as_vec3();
        self.color = [
            (self.sum_c[0] / w) as f32,
            (self.sum_c[1] / w) as f32,
            (self.sum_c[2] / w) as f32,
        ];
        members.next[self.tail as usize] = o.head;
        self.tail = o.tail;
    }
}

fn angle(a: Vec3, b: Vec3) -> f32 {
    a.dot(b).clamp(-1.0, 1.0).acos()
}

fn color_diff(a: [f32; 3], b: [f32; 3]) -> f32 {
    (0..3).map(|k| (a[k] - b[k]).abs()).fold(0.0, f32::max)
}

/// A position's coordinates in its box `lo..lo+size` as fractions `(v − lo) / size` (NaN
/// on an axis where the box is flat or the coordinate not finite: that axis's cell is 0),
/// computed once for every grid [`choose_grid`] tries and for the [`morton_codes`].
fn box_fractions(pos: &[Vec3], lo: Vec3, size: Vec3) -> Vec<[f32; 3]> {
    let f = |v: f32, l: f32, s: f32| {
        if s > 0.0 && v.is_finite() {
            (v - l) / s
        } else {
            f32::NAN
        }
    };
    pos.iter()
        .map(|p| {
            [
                f(p.x, lo.x, size.x),
                f(p.y, lo.y, size.y),
                f(p.z, lo.z, size.z),
            ]
        })
        .collect()
}

/// The cell of a position (its [`box_fractions`]) in a `k`-per-axis grid over its box (as
/// a row-major index into the `k³` cells): per axis `⌊t·k⌋` clamped to `0..k`, the cast
/// doing both the floor (fractions are ≥ 0; a negative or NaN one saturates to 0) and the
/// lower clamp, without a call to `floorf`.
fn cell_key(t: [f32; 3], k: u32) -> u64 {
    let (kf, k64) = (k as f32, u64::from(k));
    let coord = |t: f32| ((t * kf) as u64).min(k64 - 1);
    (coord(t[0]) * k64 + coord(t[1])) * k64 + coord(t[2])
}

/// [`cell_key`] of every input splat.
fn cell_keys(fr: &[[f32; 3]], k: u32) -> Vec<u64> {
    fr.iter().map(|&t| cell_key(t, k)).collect()
}

/// Whether the keys of a `k`-grid ([`cell_key`]) occupy at most `target` cells. Up to
/// [`BITMAP_CELLS`] cells this marks a bitmap and stops at the first cell past `target`
/// (keys are computed only up to there: most probes of [`choose_grid`] stop early); finer
/// grids sort and count.
fn occupied_at_most(keys: impl Iterator<Item = u64>, k: u32, target: usize) -> bool {
    let cells = u64::from(k).pow(3);
    if cells > BITMAP_CELLS {
        let mut v: Vec<u64> = keys.collect();
        v.sort_unstable();
        v.dedup();
        return v.len() <= target;
    }
    let mut seen = vec![0u64; cells.div_ceil(64) as usize];
    let mut count = 0usize;
    for key in keys {
        let (word, bit) = ((key / 64) as usize, 1u64 << (key % 64));
        if seen[word] & bit == 0 {
            seen[word] |= bit;
            count += 1;
            if count > target {
                return false;
            }
        }
    }
    true
}

/// Most cells of a grid whose occupancy [`occupied_at_most`] counts with a bitmap (512 KiB).
const BITMAP_CELLS: u64 = 1 << 22;

/// The largest `k ≤ grid` whose grid has at most `target` occupied cells, and the cell
/// keys of that grid.
fn choose_grid(fr: &[[f32; 3]], grid: u32, target: usize) -> (u32, Vec<u64>) {
    let fits = |k: u32| occupied_at_most(fr.iter().map(|&t| cell_key(t, k)), k, target);
    if fits(grid) {
        return (grid, cell_keys(fr, grid));
    }
    // Binary search assuming monotonicity, then walk down if a glitch breaks it.
    let (mut good, mut bad) = (1u32, grid);
    while bad - good > 1 {
        let mid = good + (bad - good) / 2;
        if fits(mid) {
            good = mid;
        } else {
            bad = mid;
        }
    }
    let mut k = good;
    while k > 1 && !fits(k) {
        k -= 1;
    }
    (k, cell_keys(fr, k))
}

/// Lists longer than this merge in batches over a window of neighbours (in Morton order)
/// instead of one best pair out of all pairs, keeping degenerate inputs (one huge cell)
/// near-linear per round.
const ALL_PAIRS_MAX: usize = 64;
/// Neighbours (in list order) each cluster is paired with in a long list.
const WINDOW: usize = 16;

/// 30-bit Morton codes (10 bits per axis) of positions given as [`box_fractions`]: per axis
/// `round(t·1023)` clamped to `0..=1023` (a NaN fraction, a flat axis or a coordinate that is
/// not finite, gives 0).
fn morton_codes(fr: &[[f32; 3]]) -> Vec<u32> {
    let q = |t: f32| -> u32 {
        if t.is_nan() {
            0
        } else {
            (t * 1023.0).round().clamp(0.0, 1023.0) as u32
        }
    };
    fr.iter()
        .map(|t| crate::morton::morton63([q(t[0]), q(t[1]), q(t[2])]) as u32)
        .collect()
}

/// What a merge decision needs to see.
struct PairCtx<'a> {
    clusters: &'a [Option<Cluster>],
    has_n: bool,
    has_c: bool,
    theta: f32,
    col_t: f32,
    theta0: f32,
    col0: f32,
    cell_diag: f32,
}

impl PairCtx<'_> {
    /// Cost of merging clusters `a` and `b`, `None` if they are not compatible.
    fn cost(&self, a: usize, b: usize) -> Option<f32> {
        let ca = self.clusters[a].as_ref()?;
        let cb = self.clusters[b].as_ref()?;
        let ang = if self.has_n {
            angle(ca.normal, cb.normal)
        } else {
            0.0
        };
        if ang >= self.theta {
            return None;
        }
        let dc = if self.has_c {
            color_diff(ca.color, cb.color)
        } else {
            0.0
        };
        if dc >= self.col_t {
            return None;
        }
        let mut cost = ang / self.theta0 + ca.center.distance(cb.center) / self.cell_diag;
        if self.has_c {
            cost += dc / self.col0;
        }
        Some(cost)
    }

    /// The merges to do in `list` now, as disjoint `(keep, absorbed)` position pairs, at
    /// most `want`: the cheapest compatible pair of all pairs for a short list; for a long
    /// one, up to a quarter of its length in disjoint pairs, cheapest first, among each
    /// cluster's next [`WINDOW`] (then 4 × [`WINDOW`]) neighbours in list (Morton) order.
    /// Empty if no such pair is compatible under the current thresholds.
    fn plan_merges(&self, list: &[usize], want: usize) -> Vec<(usize, usize)> {
        let l = list.len();
        let best_of_all = || {
            let mut best: Option<(f32, usize, usize)> = None;
            for a in 0..l {
                for b in a + 1..l {
                    if let Some(c) = self.cost(list[a], list[b])
                        && best.is_none_or(|(bc, _, _)| c < bc)
                    {
                        best = Some((c, a, b));
                    }
                }
            }
            best.map(|(_, a, b)| vec![(a, b)]).unwrap_or_default()
        };
        if l <= ALL_PAIRS_MAX {
            return best_of_all();
        }
        let mut cand: Vec<(f32, usize, usize)> = Vec::new();
        for window in [WINDOW, 4 * WINDOW] {
            for a in 0..l {
                for b in a + 1..(a + 1 + window).min(l) {
                    if let Some(c) = self.cost(list[a], list[b]) {
                        cand.push((c, a, b));
                    }
                }
            }
            if !cand.is_empty() {
                break;
            }
        }
        if cand.is_empty() {
            return Vec::new();
        }
        cand.sort_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)).then(x.2.cmp(&y.2)));
        let cap = want.min((l / 4).max(1));
        let mut used = vec![false; l];
        let mut out = Vec::with_capacity(cap);
        for (_, a, b) in cand {
            if out.len() == cap {
                break;
            }
            if !used[a] && !used[b] {
                used[a] = true;
                used[b] = true;
                out.push((a, b));
            }
        }
        out
    }
}

/// Selects exactly `min(target, input.len())` representatives of `input` (at least one if
/// the input is non-empty; `target = 0` is treated as 1). See the module docs.
pub fn representatives(input: &Splats, target: usize, cfg: &RepConfig) -> Selection {
    let m = input.len();
    let target = target.max(1);
    if m <= target {
        return every_splat(input, cfg);
    }
    let has_n = input.normals.is_some();
    let has_c = input.colors.is_some();

    // 1. Grid (lowered until it has at most `target` occupied cells).
    let (k, lists, cell_diag) = cell_lists(input, cfg.grid, target);
    let mut merger = Merger {
        clusters: (0..m).map(|i| Some(Cluster::new(input, i))).collect(),
        members: Members::singletons(m),
        lists,
        count: m,
    };
    if cfg.clustering == Clustering::Grid {
        merger.merge_cells();
    }

    // 2.–3. Merge until exactly `target` clusters remain.
    let theta = merger.merge_to(target, cfg, has_n, has_c, cell_diag);

    // 4. One representative per cluster, in cell order.
    let (reps, members) = merger.representatives(input, has_n, has_c);
    Selection {
        reps,
        members,
        grid_used: k,
        theta_used_deg: theta.to_degrees(),
    }
}

/// The selection of an input of at most `target` splats: every splat, its own
/// representative.
fn every_splat(input: &Splats, cfg: &RepConfig) -> Selection {
    let m = input.len();
    let mut reps = Splats::empty(input.normals.is_some(), input.colors.is_some());
    for i in 0..m {
        reps.push_from(input, i);
    }
    Selection {
        reps,
        members: (0..m as u32).collect(),
        grid_used: cfg.grid,
        theta_used_deg: cfg.theta_deg,
    }
}

/// Step 1: the grid's `K` (lowered from `grid` until at most `target` cells are occupied),
/// the occupied cells' lists of splats (cells in key order, splats in Morton order within
/// a cell), and a cell's diagonal (1 for a degenerate grid).
fn cell_lists(input: &Splats, grid: u32, target: usize) -> (u32, Vec<Vec<usize>>, f32) {
    let m = input.len();
    let bounds = input
        .positions
        .iter()
        .filter(|p| p.is_finite())
        .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |(l, h), p| {
            (l.min(*p), h.max(*p))
        });
    let (lo, size) = if bounds.0.x <= bounds.1.x {
        (bounds.0, bounds.1 - bounds.0)
    } else {
        (Vec3::ZERO, Vec3::ZERO)
    };
    let fr = box_fractions(&input.positions, lo, size);
    let (k, keys) = choose_grid(&fr, grid.max(1), target);
    let cell_diag = {
        let d = (size / k as f32).length();
        if d > 0.0 && d.is_finite() { d } else { 1.0 }
    };
    let morton = morton_codes(&fr);
    let mut order: Vec<u32> = (0..m as u32).collect();
    order.sort_unstable_by_key(|&i| (keys[i as usize], morton[i as usize], i));
    let mut lists: Vec<Vec<usize>> = Vec::new();
    let mut prev = None;
    for &i in &order {
        let key = keys[i as usize];
        if prev != Some(key) {
            lists.push(Vec::new());
            prev = Some(key);
        }
        if let Some(l) = lists.last_mut() {
            l.push(i as usize);
        }
    }
    (k, lists, cell_diag)
}

/// Queue priority of a cell's list of clusters (`queue`: the order): its length, or its
/// clusters' largest normal deviation from their mean (ties: the length).
fn priority(queue: QueueOrder, list: &[usize], clusters: &[Option<Cluster>]) -> u64 {
    match queue {
        QueueOrder::Length => list.len() as u64,
        QueueOrder::Deviation => {
            let mean = list
                .iter()
                .filter_map(|&c| clusters[c].as_ref())
                .fold(DVec3::ZERO, |a, c| a + c.sum_n)
                .normalize_or_zero()
                .as_vec3();
            let dev = list
                .iter()
                .filter_map(|&c| clusters[c].as_ref())
                .map(|c| angle(c.normal, mean))
                .fold(0.0f32, f32::max);
            // Non-negative floats order like their bits; the length breaks ties.
            (u64::from(dev.to_bits()) << 32) | list.len() as u64
        }
    }
}

/// The clustering in progress: every input splat's cluster (`None` once absorbed into
/// another), their member lists, and per occupied cell the list of its clusters.
struct Merger {
    clusters: Vec<Option<Cluster>>,
    members: Members,
    lists: Vec<Vec<usize>>,
    /// Clusters left.
    count: usize,
}

impl Merger {
    /// Fig. 2's grid sampling: every cell's clusters merged into one, so each occupied cell
    /// (at most `target` of them) gives one representative; the queue is then empty.
    fn merge_cells(&mut self) {
        for list in &mut self.lists {
            let head = list[0];
            for &c in &list[1..] {
                if let Some(cb) = self.clusters[c].take()
                    && let Some(ca) = self.clusters[head].as_mut()
                {
                    ca.absorb(cb, &mut self.members);
                }
            }
            list.truncate(1);
        }
        self.count = self.lists.len();
    }

    /// Steps 2–3: a queue of the cells with ≥ 2 clusters, merged until exactly `target`
    /// clusters remain, the thresholds relaxed whenever every cell left is blocked.
    /// Returns the final normal threshold (radians).
    fn merge_to(
        &mut self,
        target: usize,
        cfg: &RepConfig,
        has_n: bool,
        has_c: bool,
        cell_diag: f32,
    ) -> f32 {
        let theta0 = cfg.theta_deg.to_radians().max(f32::MIN_POSITIVE);
        // 2. Queue of lists with ≥ 2 clusters.
        let mut heap: BinaryHeap<(u64, Reverse<usize>)> = self
            .lists
            .iter()
            .enumerate()
            .filter(|(_, l)| l.len() >= 2)
            .map(|(id, l)| (priority(cfg.queue, l, &self.clusters), Reverse(id)))
            .collect();

        // 3. Merge until exactly `target` clusters remain.
        let mut theta = theta0;
        let mut col_t = cfg.color_threshold;
        let mut blocked: Vec<usize> = Vec::new();
        let relax = if cfg.relax > 1.0 { cfg.relax } else { 2.0 };
        while self.count > target {
            let Some((_, Reverse(id))) = heap.pop() else {
                if blocked.is_empty() {
                    // Unreachable: ≤ target cells and > target clusters means some list has ≥ 2.
                    break;
                }
                theta = if theta * relax >= std::f32::consts::PI {
                    f32::INFINITY
                } else {
                    theta * relax
                };
                col_t = if col_t * relax >= 255.0 {
                    f32::INFINITY
                } else {
                    col_t * relax
                };
                for id in blocked.drain(..) {
                    heap.push((
                        priority(cfg.queue, &self.lists[id], &self.clusters),
                        Reverse(id),
                    ));
                }
                continue;
            };
            let want = self.count - target;
            let merges = {
                let ctx = PairCtx {
                    clusters: &self.clusters,
                    has_n,
                    has_c,
                    theta,
                    col_t,
                    theta0,
                    col0: cfg.color_threshold,
                    cell_diag,
                };
                ctx.plan_merges(&self.lists[id], want)
            };
            if merges.is_empty() {
                blocked.push(id);
                continue;
            }
            self.apply(id, &merges);
            if self.lists[id].len() >= 2 {
                heap.push((
                    priority(cfg.queue, &self.lists[id], &self.clusters),
                    Reverse(id),
                ));
            }
        }
        theta
    }

    /// Merges the pairs `merges` (positions in cell `id`'s list) into their first cluster
    /// and drops the second ones from the list.
    fn apply(&mut self, id: usize, merges: &[(usize, usize)]) {
        let list = &mut self.lists[id];
        let mut dead = vec![false; list.len()];
        for &(a, b) in merges {
            let (ia, ib) = (list[a], list[b]);
            if let Some(cb) = self.clusters[ib].take()
                && let Some(ca) = self.clusters[ia].as_mut()
            {
                ca.absorb(cb, &mut self.members);
            }
            dead[b] = true;
            self.count -= 1;
        }
        let mut k = 0;
        list.retain(|_| {
            k += 1;
            !dead[k - 1]
        });
    }

    /// Step 4: one representative per cluster, in cell order, covering its members; and
    /// for every input splat the index of its representative.
    fn representatives(&self, input: &Splats, has_n: bool, has_c: bool) -> (Splats, Vec<u32>) {
        let mut reps = Splats::empty(has_n, has_c);
        let mut members = vec![0u32; input.len()];
        for list in &self.lists {
            for &c in list {
                let Some(cl) = self.clusters[c].as_ref() else {
                    continue;
                };
                let k = reps.len() as u32;
                let mut r = 0.0f32;
                for mi in self.members.of(cl) {
                    members[mi] = k;
                    r = r.max(input.positions[mi].distance(cl.center) + input.radii[mi]);
                }
                reps.positions.push(cl.center);
                if let Some(n) = &mut reps.normals {
                    let nn = if cl.normal == Vec3::ZERO {
                        input
                            .normals
                            .as_ref()
                            .map_or(Vec3::ZERO, |v| v[cl.head as usize])
                    } else {
                        cl.normal
                    };
                    n.push(nn);
                }
                if let Some(col) = &mut reps.colors {
                    col.push(cl.color);
                }
                // A relative margin of a few ulps keeps the cover exact after f32 rounding.
                reps.radii.push(r * (1.0 + 4.0 * f32::EPSILON));
                reps.weights.push(cl.weight);
            }
        }
        (reps, members)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn occupancy_test_agrees_with_counting_distinct_cells() {
        let mut rng = scenes::rng::Pcg32::new(3);
        // k = 35 takes the bitmap, k = 200 (8·10⁶ cells) the sort.
        for k in [1u32, 2, 35, 200] {
            let cells = u64::from(k).pow(3);
            for m in [1usize, 50, 3000] {
                let keys: Vec<u64> = (0..m)
                    .map(|_| u64::from(rng.below(cells.min(2000) as u32)) * (cells / 2000).max(1))
                    .map(|c| c.min(cells - 1))
                    .collect();
                let mut distinct = keys.clone();
                distinct.sort_unstable();
                distinct.dedup();
                let d = distinct.len();
                for target in [d.saturating_sub(1), d, d + 1] {
                    assert_eq!(
                        occupied_at_most(keys.iter().copied(), k, target),
                        d <= target,
                        "k {k} m {m}"
                    );
                }
            }
        }
    }
}
