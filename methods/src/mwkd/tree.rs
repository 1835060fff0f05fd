//! The multi-way kd-tree: its plan from `(n, N, s)` alone, the real split of a cloud, and
//! the bottom-up LOD build.
//!
//! **Depth rule** ([`leaf_depth`]): the leaves sit at depth `d` = the smallest `d ≥ 0` with
//! `N^d · (s + 1) ≥ n`, i.e. the shallowest fully balanced tree whose leaves hold at most
//! `s + 1` samples (`⌈n / N^d⌉ ≤ s + 1`). The paper writes `l = ⌈log m / log N⌉` with
//! `m = n/s`, but its Table II was made with `s` reported as `⌊n / N^d⌋`, so leaves may hold
//! `s + 1`: for (N, s) = (6, 24029), `n/s = 7776.03 > 6⁵` and the literal formula gives
//! depth 6, the table 5 (`6⁵ · 24030 = 186,857,280 ≥ 186,850,683`). This integer rule
//! reproduces all five rows (see the tests) and is evaluated in exact integer arithmetic.
//!
//! **Split**: a node of `c` samples is cut along the longest axis of its tight bounding box
//! into `N` children by nth-element selection; child `i` gets `⌊c/N⌋ + [i < c mod N]`
//! samples, so at every level the counts are `⌊n/N^l⌋` or `⌈n/N^l⌉` — every leaf within
//! ±1 of every other. Nodes are kept in an array, level by level: node `i`'s children are
//! `N·i + 1 … N·i + N`, level `l` starts at `(N^l − 1)/(N − 1)`. The selection orders by
//! coordinate, ties by input index, so a node's sample *set* depends only on its ancestors'
//! sets; a leaf's samples are then put in input order, so that a subtree split on its own
//! (the build in units, [`super::ooc`]) gives the very same leaves.
//!
//! **Inner nodes** hold representatives: child `i` passes `t_i = ⌊s/N⌋ + [i < s mod N]`
//! (so `Σ t_i = s`), or all it holds if that is fewer. [`Plan`] predicts exactly how many
//! samples every level's nodes hold, and [`super::build::Lod::build`] produces them.

use std::ops::Range;

use glam::Vec3;
use rayon::prelude::*;
use scenes::Aabb;

use crate::MethodError;
use crate::sortkey::f32_total_order;

/// Depth of the leaves (the root is level 0; the tree has `depth + 1` levels): the smallest
/// `d ≥ 0` with `N^d · (s + 1) ≥ n` (see the module docs). Errors if `n = 0`, `N < 2` or
/// `s = 0`.
pub fn leaf_depth(n: u64, fanout: u64, vbo: u64) -> Result<u32, MethodError> {
    check_args(n, fanout, vbo)?;
    let (n, fanout, cap) = (u128::from(n), u128::from(fanout), u128::from(vbo) + 1);
    let mut d = 0u32;
    let mut pow = 1u128; // N^d ≤ n here, so no overflow.
    while pow * cap < n {
        pow *= fanout;
        d += 1;
    }
    Ok(d)
}

fn check_args(n: u64, fanout: u64, vbo: u64) -> Result<(), MethodError> {
    if n == 0 {
        return Err(MethodError::Param(
            "method 'mwkd': the tree needs at least 1 sample".into(),
        ));
    }
    if fanout < 2 {
        return Err(MethodError::Param(format!(
            "method 'mwkd': fanout must be ≥ 2, got {fanout}"
        )));
    }
    if vbo == 0 {
        return Err(MethodError::Param("method 'mwkd': vbo must be ≥ 1".into()));
    }
    Ok(())
}

/// Per-child representative targets `t_i = ⌊s/N⌋ + [i < s mod N]` (they sum to `s`).
pub fn child_targets(fanout: u64, vbo: u64) -> Vec<u64> {
    (0..fanout)
        .map(|i| vbo / fanout + u64::from(i < vbo % fanout))
        .collect()
}

/// One level of a [`Plan`].
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct LevelPlan {
    /// Level (0 = root).
    pub level: u32,
    /// Nodes on the level (`N^level`).
    pub nodes: u64,
    /// Fewest input samples under a node of this level (`⌊n/N^l⌋`).
    pub points_min: u64,
    /// Most input samples under a node of this level.
    pub points_max: u64,
    /// Fewest samples a node of this level holds (leaves: their samples; inner nodes: their
    /// representatives).
    pub held_min: u64,
    /// Most samples a node of this level holds.
    pub held_max: u64,
    /// Samples held by all nodes of this level together.
    pub held_total: u64,
}

/// The shape of the tree for `n` samples, fan-out `N` and VBO size `s`, without data.
#[derive(Debug, Clone, PartialEq, Eq, serde::Serialize)]
pub struct Plan {
    /// Input samples `n`.
    pub points: u64,
    /// Fan-out `N`.
    pub fanout: u64,
    /// VBO size `s`.
    pub vbo: u64,
    /// Depth of the leaves ([`leaf_depth`]).
    pub depth: u32,
    /// Levels `0..=depth`.
    pub levels: Vec<LevelPlan>,
}

impl Plan {
    /// Plans the tree (exact integer arithmetic). Errors name the bad argument.
    pub fn new(n: u64, fanout: u64, vbo: u64) -> Result<Plan, MethodError> {
        let depth = leaf_depth(n, fanout, vbo)?;
        let nn = u128::from(n);
        let nf = u128::from(fanout);
        let big = |what: &str| MethodError::Limit(format!("mwkd plan: {what} overflows 64 bits"));
        // Nodes per level and the floor of samples per node.
        let mut pows = Vec::with_capacity(depth as usize + 1);
        let mut pow = 1u128;
        for _ in 0..=depth {
            pows.push(pow);
            pow *= nf; // ≤ N·n: fits u128.
        }
        // held[l] = (held by a node of ⌊n/N^l⌋ samples, held by one of ⌊n/N^l⌋ + 1).
        let floor = |l: usize| nn / pows[l];
        let d = depth as usize;
        let mut held = vec![(0u128, 0u128); d + 1];
        held[d] = (floor(d), floor(d) + 1);
        let t_lo = u128::from(vbo) / nf;
        let t_extra = u128::from(vbo) % nf; // children 0..t_extra get t_lo + 1
        for l in (0..d).rev() {
            let f_child = floor(l + 1);
            let h_child = |c: u128| {
                if c == f_child {
                    held[l + 1].0
                } else {
                    held[l + 1].1
                }
            };
            let node = |c: u128| -> u128 {
                // Children 0..c mod N hold c/N + 1 samples, the rest c/N.
                let (q, r) = (c / nf, c % nf);
                let mut sum = 0u128;
                // Breakpoints split 0..N into runs where child count and target are constant.
                let mut cuts = [0, r.min(t_extra), r.max(t_extra), nf];
                cuts.sort_unstable();
                for w in cuts.windows(2) {
                    let (a, b) = (w[0], w[1]);
                    if b > a {
                        let cc = if a < r { q + 1 } else { q };
                        let t = if a < t_extra { t_lo + 1 } else { t_lo };
                        sum += (b - a) * t.min(h_child(cc));
                    }
                }
                sum
            };
            let f = floor(l);
            held[l] = (node(f), node(f + 1));
        }
        let mut levels = Vec::with_capacity(d + 1);
        for (l, &p) in pows.iter().enumerate() {
            let f = floor(l);
            let r = nn % p; // nodes holding f + 1 samples
            let (h0, h1) = held[l];
            let (held_min, held_max) = match (p - r > 0, r > 0) {
                (true, true) => (h0.min(h1), h0.max(h1)),
                (true, false) => (h0, h0),
                _ => (h1, h1),
            };
            let to64 = |v: u128, what: &str| u64::try_from(v).map_err(|_| big(what));
            levels.push(LevelPlan {
                level: l as u32,
                nodes: to64(p, "nodes")?,
                points_min: to64(f, "points")?,
                points_max: to64(if r > 0 { f + 1 } else { f }, "points")?,
                held_min: to64(held_min, "samples")?,
                held_max: to64(held_max, "samples")?,
                held_total: to64((p - r) * h0 + r * h1, "samples")?,
            });
        }
        // The totals must fit too.
        let total: u128 = pows.iter().sum();
        u64::try_from(total).map_err(|_| big("node count"))?;
        let samples: u128 = levels.iter().map(|l| u128::from(l.held_total)).sum();
        u64::try_from(samples).map_err(|_| big("samples stored"))?;
        Ok(Plan {
            points: n,
            fanout,
            vbo,
            depth,
            levels,
        })
    }

    /// Levels of the tree (`depth + 1`, as in the paper's Table II).
    pub fn level_count(&self) -> u32 {
        self.depth + 1
    }

    /// Nodes in the tree, `(N^(d+1) − 1)/(N − 1)`.
    pub fn nodes(&self) -> u64 {
        self.levels.iter().map(|l| l.nodes).sum()
    }

    /// Leaves, `N^d`.
    pub fn leaves(&self) -> u64 {
        self.levels.last().map_or(1, |l| l.nodes)
    }

    /// Fewest and most samples in a leaf (they differ by at most 1).
    pub fn leaf_points(&self) -> (u64, u64) {
        self.levels
            .last()
            .map_or((0, 0), |l| (l.points_min, l.points_max))
    }

    /// Fewest and most representatives an inner node holds (`None` if the root is a leaf).
    pub fn inner_held(&self) -> Option<(u64, u64)> {
        let inner = &self.levels[..self.depth as usize];
        (!inner.is_empty()).then(|| {
            (
                inner.iter().map(|l| l.held_min).min().unwrap_or(0),
                inner.iter().map(|l| l.held_max).max().unwrap_or(0),
            )
        })
    }

    /// Samples stored over all nodes (leaf samples + inner representatives).
    pub fn samples_total(&self) -> u64 {
        self.levels.iter().map(|l| l.held_total).sum()
    }

    /// The human table printed by `splatbench plan`.
    pub fn table(&self) -> String {
        let mut s = format!(
            "mwkd plan: n = {}, fanout N = {}, vbo s = {}\n{:>5} {:>12} {:>23} {:>23}\n",
            self.points,
            self.fanout,
            self.vbo,
            "level",
            "nodes",
            "input samples/node",
            "held samples/node"
        );
        let range = |a: u64, b: u64| {
            if a == b {
                a.to_string()
            } else {
                format!("{a}–{b}")
            }
        };
        for l in &self.levels {
            let kind = if l.level == self.depth {
                " (leaves)"
            } else {
                ""
            };
            s.push_str(&format!(
                "{:>5} {:>12} {:>23} {:>23}{kind}\n",
                l.level,
                l.nodes,
                range(l.points_min, l.points_max),
                range(l.held_min, l.held_max)
            ));
        }
        let (lmin, lmax) = self.leaf_points();
        s.push_str(&format!(
            "levels {}, nodes {}, leaves {}, samples per leaf {}",
            self.level_count(),
            self.nodes(),
            self.leaves(),
            range(lmin, lmax)
        ));
        match self.inner_held() {
            Some((a, b)) => s.push_str(&format!(
                ", representatives per inner node {}, samples stored {}\n",
                range(a, b),
                self.samples_total()
            )),
            None => s.push_str(", no inner node\n"),
        }
        s
    }

    /// Machine-readable form (`splatbench plan --json`).
    pub fn to_json(&self) -> serde_json::Value {
        let (lmin, lmax) = self.leaf_points();
        let inner = self.inner_held();
        serde_json::json!({
            "method": super::NAME,
            "points": self.points,
            "fanout": self.fanout,
            "vbo": self.vbo,
            "levels": self.level_count(),
            "depth": self.depth,
            "nodes": self.nodes(),
            "leaves": self.leaves(),
            "leaf_points_min": lmin,
            "leaf_points_max": lmax,
            "inner_held_min": inner.map(|i| i.0),
            "inner_held_max": inner.map(|i| i.1),
            "samples_total": self.samples_total(),
            "per_level": self.levels,
        })
    }
}

/// A node of the real tree.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Node {
    /// Level (0 = root).
    pub level: u32,
    /// Its samples: `Tree::order[range]`.
    pub start: usize,
    /// Number of input samples under the node.
    pub len: usize,
    /// Tight bounding box of those samples.
    pub bounds: Aabb,
    /// First child's index (children are contiguous); meaningless for a leaf.
    pub first_child: u32,
    /// Number of children (0 for a leaf).
    pub child_count: u32,
    /// Parent's index ([`NO_PARENT`] for the root).
    pub parent: u32,
}

/// [`Node::parent`] of the root.
pub const NO_PARENT: u32 = u32::MAX;

impl Node {
    /// Index range into [`Tree::order`].
    pub fn range(&self) -> Range<usize> {
        self.start..self.start + self.len
    }
}

/// A split of a set of positions into a tree whose nodes own contiguous runs of
/// [`Tree::order`]: the real, fully balanced N-ary split ([`Tree::split`]), or for the
/// paper's Table IV ablation a binary kd-tree (the same split with `N = 2`) or an octree
/// ([`Tree::octree`]).
#[derive(Debug, Clone)]
pub struct Tree {
    /// Fan-out `N` (most children of a node; 8 for an octree).
    pub fanout: usize,
    /// VBO size `s`.
    pub vbo: u64,
    /// Depth of the deepest leaf (all leaves, for [`Tree::split`]).
    pub depth: u32,
    /// Nodes, level by level, children of a node contiguous (for [`Tree::split`]: children
    /// of `i` at `N·i + 1 … N·i + N`).
    pub nodes: Vec<Node>,
    /// Permutation of the input indices: every node's samples are contiguous.
    pub order: Vec<u32>,
}

/// A sample during [`Tree::split_to_depth`]: its position and input index.
#[derive(Clone, Copy)]
struct Item {
    p: [f32; 3],
    i: u32,
}

/// Partitions `items` so that, for each boundary `b`, the `b` samples first along `axis`
/// (coordinate in total order, then index: every sample has its own rank) come before the
/// others: middle boundary first, then both halves (depth ≤ log₂ N + 1). The items carry
/// their positions, so the selection reads them in place: the same sets as the selection of
/// 64-bit keys (coordinate bits, index) gathered from the positions at random, without
/// those gathers (with the children's bounds, ≈ 12 % of the 10 M terrain build's samples).
fn multi_select(items: &mut [Item], bounds: &[usize], axis: usize) {
    if bounds.is_empty() || items.len() < 2 {
        return;
    }
    let mid = bounds.len() / 2;
    let b = bounds[mid];
    if b > 0 && b < items.len() {
        items.select_nth_unstable_by_key(b, |it| {
            (u64::from(f32_total_order(it.p[axis])) << 32) | u64::from(it.i)
        });
    }
    let (left, right) = items.split_at_mut(b.min(items.len()));
    multi_select(left, &bounds[..mid], axis);
    let rb: Vec<usize> = bounds[mid + 1..].iter().map(|&x| x - b).collect();
    multi_select(right, &rb, axis);
}

fn bounds_of(idx: &[u32], pos: &[[f32; 3]]) -> Aabb {
    idx.iter()
        .fold(Aabb::EMPTY, |b, &i| b.grow(Vec3::from(pos[i as usize])))
}

impl Tree {
    /// Splits `positions` into the tree of [`Plan::new`]`(n, fanout, vbo)` (level by level,
    /// nodes of a level in parallel; deterministic). Each leaf's samples are in input order.
    pub fn split(positions: &[[f32; 3]], fanout: u32, vbo: u64) -> Result<Tree, MethodError> {
        let depth = leaf_depth(positions.len() as u64, u64::from(fanout), vbo)?;
        Self::split_to_depth(positions, fanout, vbo, depth)
    }

    /// [`Tree::split`] with its leaves at `depth`: the subtree a node of a larger tree has
    /// below it (the build in units splits each unit so; the rule of [`leaf_depth`] applied
    /// to a node's own count can differ by one level from its depth in the whole tree).
    pub fn split_to_depth(
        positions: &[[f32; 3]],
        fanout: u32,
        vbo: u64,
        depth: u32,
    ) -> Result<Tree, MethodError> {
        let n = positions.len();
        if n > u32::MAX as usize {
            return Err(MethodError::Limit(format!(
                "mwkd: {n} points exceed the in-core split's 2³² limit"
            )));
        }
        check_args(n as u64, u64::from(fanout), vbo)?;
        let nf = fanout as usize;
        let total_nodes = (0..=depth).try_fold(0usize, |acc, l| {
            nf.checked_pow(l).and_then(|p| acc.checked_add(p))
        });
        let total_nodes =
            total_nodes.ok_or_else(|| MethodError::Limit("mwkd: node count overflows".into()))?;
        // The samples with their positions, permuted together: a node's selection and its
        // children's bounds read its own contiguous run, not the positions at random.
        let mut items: Vec<Item> = positions
            .par_iter()
            .enumerate()
            .map(|(i, &p)| Item { p, i: i as u32 })
            .collect();
        let mut nodes = Vec::with_capacity(total_nodes);
        nodes.push(Node {
            level: 0,
            start: 0,
            len: n,
            bounds: Aabb::from_points(positions),
            first_child: 0,
            child_count: 0,
            parent: NO_PARENT,
        });
        let mut level_start = 0usize;
        for level in 0..depth {
            let level_end = nodes.len();
            // Mutable slices of `items`, one per node of this level (they tile it in order).
            let mut slices = Vec::with_capacity(level_end - level_start);
            let mut rest: &mut [Item] = &mut items;
            for node in &nodes[level_start..level_end] {
                let (head, tail) = rest.split_at_mut(node.len);
                slices.push((*node, head));
                rest = tail;
            }
            let children: Vec<Vec<Node>> = slices
                .into_par_iter()
                .enumerate()
                .map(|(k, (node, idx))| {
                    let parent = (level_start + k) as u32;
                    let (q, r) = (node.len / nf, node.len % nf);
                    let starts: Vec<usize> = (0..=nf).map(|i| i * q + i.min(r)).collect();
                    let axis = node.bounds.longest_axis();
                    multi_select(idx, &starts[1..nf], axis);
                    (0..nf)
                        .map(|i| {
                            let s = &idx[starts[i]..starts[i + 1]];
                            Node {
                                level: level + 1,
                                start: node.start + starts[i],
                                len: s.len(),
                                bounds: s
                                    .iter()
                                    .fold(Aabb::EMPTY, |b, it| b.grow(Vec3::from(it.p))),
                                first_child: 0,
                                child_count: 0,
                                parent,
                            }
                        })
                        .collect()
                })
                .collect();
            nodes.extend(children.into_iter().flatten());
            for (k, node) in nodes[level_start..level_end].iter_mut().enumerate() {
                node.first_child = ((level_start + k) * nf + 1) as u32;
                node.child_count = nf as u32;
            }
            level_start = level_end;
        }
        // Leaves in input order: the selection leaves them in an order that depends on the
        // whole split's history; this order is the same for a unit split on its own.
        let mut slices = Vec::with_capacity(nodes.len() - level_start);
        let mut rest: &mut [Item] = &mut items;
        for node in &nodes[level_start..] {
            let (head, tail) = rest.split_at_mut(node.len);
            slices.push(head);
            rest = tail;
        }
        slices
            .into_par_iter()
            .for_each(|s| s.sort_unstable_by_key(|it| it.i));
        let order = items.par_iter().map(|it| it.i).collect();
        Ok(Tree {
            fanout: nf,
            vbo,
            depth,
            nodes,
            order,
        })
    }

    /// Index of the first node of level `l` in a fully balanced tree of fan-out `fanout`:
    /// `(N^l − 1)/(N − 1)`.
    pub fn level_start(fanout: usize, l: u32) -> usize {
        (fanout.pow(l) - 1) / (fanout - 1)
    }

    /// Node indices of level `l`: `(N^l − 1)/(N − 1) ..` `(N^(l+1) − 1)/(N − 1)` (fully
    /// balanced trees from [`Tree::split`] only).
    pub fn level_range(&self, l: u32) -> Range<usize> {
        Self::level_start(self.fanout, l)..Self::level_start(self.fanout, l + 1)
    }

    /// The leaves' indices (fully balanced trees from [`Tree::split`] only; see
    /// [`Tree::is_leaf`] for any tree).
    pub fn leaves(&self) -> Range<usize> {
        self.level_range(self.depth)
    }

    /// Children of node `i` (empty for a leaf).
    pub fn children(&self, i: usize) -> Range<usize> {
        let n = &self.nodes[i];
        n.first_child as usize..(n.first_child + n.child_count) as usize
    }

    /// True if node `i` has no child.
    pub fn is_leaf(&self, i: usize) -> bool {
        self.nodes[i].child_count == 0
    }

    /// Parent of node `i` (`None` for the root).
    pub fn parent(&self, i: usize) -> Option<usize> {
        let p = self.nodes[i].parent;
        (p != NO_PARENT).then_some(p as usize)
    }

    /// An octree over the cube around `positions`' bounding box (the paper's Table IV
    /// baseline): a node of more than `vbo` samples is cut at its cube's centre into the
    /// (up to 8) non-empty octants, down to `max_depth` (deeper nodes stay leaves however
    /// many samples they hold — piles of duplicates). Unbalanced: leaves at any depth, with
    /// 1 … `vbo` samples. Nodes breadth first, children of a node contiguous in octant order,
    /// so the result is deterministic.
    pub fn octree(positions: &[[f32; 3]], vbo: u64, max_depth: u32) -> Result<Tree, MethodError> {
        let n = positions.len();
        if n == 0 || n > u32::MAX as usize {
            return Err(MethodError::Limit(format!(
                "octree: {n} points (need 1 ..= 2³²−1)"
            )));
        }
        check_args(n as u64, 8, vbo)?;
        let b = Aabb::from_points(positions);
        let half = b.size().max_element() / 2.0;
        let mut order: Vec<u32> = (0..n as u32).collect();
        let mut nodes = vec![Node {
            level: 0,
            start: 0,
            len: n,
            bounds: b,
            first_child: 0,
            child_count: 0,
            parent: NO_PARENT,
        }];
        // Cube (centre, half side) of each node.
        let mut cubes = vec![(b.center(), half)];
        let mut depth = 0;
        let mut i = 0;
        while i < nodes.len() {
            let node = nodes[i];
            if node.len as u64 > vbo && node.level < max_depth {
                let (c, h) = cubes[i];
                let octant = |j: u32| {
                    let p = positions[j as usize];
                    usize::from(p[0] >= c.x)
                        | usize::from(p[1] >= c.y) << 1
                        | usize::from(p[2] >= c.z) << 2
                };
                let idx = &mut order[node.range()];
                idx.sort_by_key(|&j| (octant(j), j));
                let first = nodes.len() as u32;
                let mut start = 0;
                for o in 0..8 {
                    let len = idx[start..].iter().take_while(|&&j| octant(j) == o).count();
                    if len == 0 {
                        continue;
                    }
                    let s = &idx[start..start + len];
                    nodes.push(Node {
                        level: node.level + 1,
                        start: node.start + start,
                        len,
                        bounds: bounds_of(s, positions),
                        first_child: 0,
                        child_count: 0,
                        parent: i as u32,
                    });
                    let sign = |bit: usize| if o >> bit & 1 == 1 { 0.5 } else { -0.5 };
                    cubes.push((c + Vec3::new(sign(0), sign(1), sign(2)) * h, h / 2.0));
                    start += len;
                }
                nodes[i].first_child = first;
                nodes[i].child_count = nodes.len() as u32 - first;
                depth = depth.max(node.level + 1);
            }
            i += 1;
        }
        Ok(Tree {
            fanout: 8,
            vbo,
            depth,
            nodes,
            order,
        })
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    const ST_MATTHEW: u64 = 186_850_683;
    /// Table II (fan-out, VBO size, levels, nodes).
    const TABLE_II: [(u64, u64, u32, u64); 5] = [
        (6, 4009, 7, 55_987),
        (6, 24029, 6, 9_331),
        (7, 77822, 5, 2_801),
        (3, 85437, 8, 3_280),
        (8, 364943, 4, 585),
    ];

    #[test]
    fn plan_reproduces_table_ii() {
        for (nf, s, levels, nodes) in TABLE_II {
            let p = Plan::new(ST_MATTHEW, nf, s).unwrap();
            assert_eq!(p.level_count(), levels, "N={nf} s={s}");
            assert_eq!(p.nodes(), nodes, "N={nf} s={s}");
            assert_eq!(p.nodes(), (nf.pow(levels) - 1) / (nf - 1));
            let (lo, hi) = p.leaf_points();
            assert!(
                hi - lo <= 1 && hi <= s + 1,
                "N={nf} s={s}: leaves {lo}–{hi}"
            );
            // Every inner node holds exactly s representatives here (leaves are big enough).
            assert_eq!(p.inner_held(), Some((s, s)), "N={nf} s={s}");
            assert_eq!(
                p.levels.iter().map(|l| l.held_total).sum::<u64>(),
                ST_MATTHEW + s * (nodes - p.leaves())
            );
        }
    }

    #[test]
    fn literal_float_formula_misses_a_row() {
        // Documents why the integer rule is needed: ⌈log(n/s)/log N⌉ gives 7 levels for
        // (6, 24029), the table says 6.
        let d = ((ST_MATTHEW as f64 / 24029.0).ln() / 6f64.ln()).ceil() as u32;
        assert_eq!(d + 1, 7);
        assert_eq!(leaf_depth(ST_MATTHEW, 6, 24029).unwrap() + 1, 6);
    }

    #[test]
    fn depth_rule_edges() {
        assert_eq!(leaf_depth(1, 2, 1).unwrap(), 0);
        assert_eq!(leaf_depth(10, 4, 9).unwrap(), 0); // 10 ≤ s + 1
        assert_eq!(leaf_depth(11, 4, 9).unwrap(), 1);
        assert_eq!(leaf_depth(40, 4, 9).unwrap(), 1);
        assert_eq!(leaf_depth(41, 4, 9).unwrap(), 2);
        assert_eq!(leaf_depth(u64::MAX, 2, 1).unwrap(), 63);
        assert!(leaf_depth(0, 2, 1).is_err());
        assert!(leaf_depth(5, 1, 1).is_err());
        assert!(leaf_depth(5, 2, 0).is_err());
        // 2⁶⁴ − 1 nodes fit, but leaves + representatives do not: an error, no panic.
        assert!(Plan::new(u64::MAX, 2, 1).is_err());
        let p = Plan::new(u64::MAX / 2, 2, u64::MAX / 8).unwrap();
        assert_eq!(p.level_count(), 3);
    }

    #[test]
    fn plan_held_counts_small_children() {
        // n = 34, s = 10, N = 3: leaves of 3–4 samples, some below their target t_i.
        let p = Plan::new(34, 3, 10).unwrap();
        assert_eq!(p.depth, 2);
        assert_eq!(p.leaf_points(), (3, 4));
        let (lo, hi) = p.inner_held().unwrap();
        assert!(lo <= hi && hi <= 10, "{lo}–{hi}");
    }

    #[test]
    fn multi_select_partitions() {
        let pos: Vec<[f32; 3]> = (0..101)
            .map(|i| [((i * 37) % 101) as f32, 0.0, 0.0])
            .collect();
        let mut items: Vec<Item> = (0..101)
            .map(|i| Item {
                p: pos[i],
                i: i as u32,
            })
            .collect();
        multi_select(&mut items, &[20, 40, 61, 81], 0);
        for w in [0..20, 20..40, 40..61, 61..81, 81..101].windows(2) {
            let max_a = items[w[0].clone()]
                .iter()
                .map(|it| it.p[0])
                .fold(f32::MIN, f32::max);
            let min_b = items[w[1].clone()]
                .iter()
                .map(|it| it.p[0])
                .fold(f32::MAX, f32::min);
            assert!(max_a <= min_b);
        }
    }
}
