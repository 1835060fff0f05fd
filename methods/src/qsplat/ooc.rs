//! The QSplat build in bounded memory: the same tree and the same file, byte for byte, as the
//! in-memory build, with working memory bounded by a budget (`--param mem_mb=`).
//!
//! A cloud of at most [`unit_capacity`] samples is built in memory ([`super::build`]). A
//! larger one is built in **units**:
//!
//! 1. **Partition.** The top of the binary tree is split exactly as in memory (same bounding
//!    boxes, axis, midpoint cut, median fallback; [`Split`]), but by streaming: the root's
//!    samples are read from the cloud's columns in input order, every larger range from its
//!    spill file, into two child spill files (stable, so each file keeps input order). A
//!    median is found by a selection over the 64-bit keys (coordinate in total order,
//!    then sample index; [`split::select_keys`]), the same order as the
//!    in-memory `select_nth_unstable_by`. A range of at most the capacity is a unit.
//! 2. **Costs.** Each unit is partitioned in memory; its root's split costs go into the
//!    top tree's dynamic programme ([`Combine`]), which decides the top nodes' combining. A
//!    unit's root is then either a node of the combined tree, or its parent took the root's
//!    grandchildren and the root's two binary children are nodes ([`Roots`]).
//! 3. **Truths.** Each unit's forest is laid out and its true properties computed bottom-up;
//!    the forest roots' properties go up into the top tree, whose nodes are combined and
//!    then quantised top-down.
//! 4. **Quantisation.** Each unit's forest is quantised from its parent's decoded sphere and
//!    its stored nodes written per level to spill files.
//! 5. **Assembly.** [`format::write_levels`] streams the levels: at each level, the top
//!    nodes and the units' nodes in left-to-right (sample-position) order, which is the
//!    breadth-first order of the in-memory tree.
//!
//! A unit is partitioned once (step 2): its permutation and binary tree go to a spill file
//! (13 bytes per sample) that steps 3 and 4 read back. Partitioning it again in each step
//! had been a quarter of the build's CPU time (`perf`, terrain 2 M in 3 units). Its true
//! properties are computed twice (steps 3 and 4) rather than kept: they would be ≈ 70 bytes
//! per sample of disk traffic each way for about as much time as they take to compute.
//! Units are processed one at a time, each in parallel inside, so the bound holds for any
//! thread count and the output does not depend on it.
//!
//! Spill files sit in `<dir>/qsplat-spill.tmp/` and are removed on success and on error; a
//! spill file that changed or was cut short is an error naming it ([`crate::spill`]).

use std::path::Path;

use glam::Vec3;
use scenes::{Aabb, PointCloud, Progress};

use super::build::{
    self, BuildOptions, Combine, Parent, Partitioned, QNode, Roots, Split, TrueNode,
};
use super::format::{self, FileStats, Levels};
use super::stats::QuantStats;
use crate::MethodError;
pub use crate::spill::Budget;
use crate::spill::samples::{self, SampleColumns, SampleLayout as Layout, f32_at};
use crate::spill::{Spill, SpillDir, split};
use crate::unit_knn::{UnitBox, UnitRadii, unit_radii};

/// Working bytes per sample of a unit built in memory: the samples (≤ 31; while they are put
/// in tree order one column is held twice, ≤ 12 more, before the per-node arrays exist), the
/// permutation and binary tree (13), and per node (≈ 1.33 per sample) the combined forest's ranges
/// (16), true properties (52) and the quantisation's spheres, margins and stored nodes (up
/// to ≈ 60 while a level is encoded): ≈ 200 by count; 240 measured as peak RSS per unit
/// sample (terrain 2 M, two units, `mem_mb` 256: 266 MB), rounded up.
pub const UNIT_BYTES_PER_SAMPLE: u64 = 256;

/// Samples of the largest unit built in memory under a budget of `mem_bytes`.
pub fn unit_capacity(mem_bytes: u64) -> u64 {
    (mem_bytes / UNIT_BYTES_PER_SAMPLE).max(2)
}

/// What the tree file holds, for the build's statistics.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TreeStats {
    /// Nodes.
    pub nodes: u64,
    /// Leaves (= samples).
    pub leaves: u64,
    /// Levels.
    pub levels: u32,
    /// The file.
    pub file: FileStats,
    /// Units built one at a time (1: built in memory).
    pub units: u64,
    /// Leaf radii capped as isolated ([`crate::leaf`]).
    pub radii_capped: u64,
    /// What quantisation did to the nodes (§3.1's figures).
    pub quant: QuantStats,
}

/// Builds the tree of `cloud` into `path` within `budget`, with the leaf radii of
/// [`crate::leaf::leaf_radii`] (computed per unit out of core: [`crate::unit_knn`]).
pub fn build_file(
    cloud: &PointCloud,
    opt: BuildOptions,
    path: &Path,
    budget: Budget<'_>,
    progress: &dyn Progress,
) -> Result<TreeStats, MethodError> {
    let Budget {
        mem_bytes,
        dir,
        hook,
    } = budget;
    let n = cloud.len();
    build::check_size(n)?;
    let cap = unit_capacity(mem_bytes);
    if n as u64 <= cap {
        return build_file_in_memory(cloud, opt, path, progress);
    }
    let spill = SpillDir::create(dir, "qsplat-spill")?;
    let layout = Layout::of(cloud);
    progress.start("qsplat: partition", n as u64);
    let (mut top, bounds) = partition_top(cloud, layout, opt.split, cap, &spill, progress)?;
    progress.finish();
    if let Some(h) = hook {
        h(&top.units.iter().map(|u| &u.spill).collect::<Vec<_>>());
    }
    let radii = if layout.radii {
        None
    } else {
        Some(top.leaf_radii(layout, n, bounds, mem_bytes, &spill, progress)?)
    };
    progress.start("qsplat: unit splits", n as u64);
    for u in &mut top.units {
        let (_, pos) = u.positions(layout)?;
        let p = Partitioned::new(&pos, opt);
        u.cost = p.cost;
        u.split = p.root_split() as u64;
        u.partition = Some(p.save(&spill)?);
        progress.inc(u.n);
    }
    progress.finish();
    if let Some(h) = hook {
        h(&top
            .units
            .iter()
            .flat_map(|u| &u.partition)
            .collect::<Vec<_>>());
    }
    top.decide(opt.combine);
    let combined = top.combined();
    let forests = UnitForests {
        top: &top,
        combined: &combined,
        radii: radii.as_ref(),
        layout,
    };

    progress.start("qsplat: unit truths", n as u64);
    let mut capped = 0;
    let mut roots: Vec<Vec<TrueNode>> = Vec::with_capacity(top.units.len());
    for (i, u) in top.units.iter().enumerate() {
        // The radii's cap count is taken once, here.
        let (_, truth) = forests.forest(i, &mut capped)?;
        roots.push(truth.into_iter().next().unwrap_or_default());
        progress.inc(u.n);
    }
    progress.finish();
    let attrs = (layout.normals, layout.colors);
    let quantised = combined.quantise(&roots, attrs, opt.fit, &top)?;

    progress.start("qsplat: unit nodes", n as u64);
    let mut stored = StoredNodes {
        nodes: quantised.nodes.len() as u64,
        quant: quantised.stats,
        segments: quantised
            .nodes
            .iter()
            .map(|&(lo, level, node)| Segment {
                lo,
                first_level: level,
                part: Part::Top(node),
            })
            .collect(),
    };
    for i in 0..top.units.len() {
        forests.write_nodes(i, quantised.unit_parent[i], opt.fit, &spill, &mut stored)?;
        progress.inc(top.units[i].n);
    }
    progress.finish();
    let StoredNodes {
        mut segments,
        nodes,
        quant,
    } = stored;
    segments.sort_by_key(|s| (s.lo, s.first_level));
    let levels = Assembled {
        segments,
        colors: layout.colors,
    };
    progress.start("qsplat: write", 0);
    let file = format::write_levels(path, &levels, quantised.root, attrs.0, attrs.1)?;
    progress.finish();
    Ok(TreeStats {
        nodes,
        leaves: n as u64,
        levels: levels.count() as u32,
        file,
        units: top.units.len() as u64,
        radii_capped: capped,
        quant,
    })
}

/// [`build_file`] of a cloud that fits the budget: built in memory, written in one go.
fn build_file_in_memory(
    cloud: &PointCloud,
    opt: BuildOptions,
    path: &Path,
    progress: &dyn Progress,
) -> Result<TreeStats, MethodError> {
    let n = cloud.len();
    progress.start("qsplat: leaf radii", n as u64);
    let radii = crate::leaf::leaf_radii(cloud);
    progress.finish();
    progress.start("qsplat: hierarchy", n as u64);
    let built = build::build_in_memory(cloud, &radii, opt, false)?;
    progress.finish();
    let t = &built.tree;
    let file = format::write(path, t)?;
    Ok(TreeStats {
        nodes: t.nodes(),
        leaves: t.leaves(),
        levels: t.levels.len() as u32,
        file,
        units: 1,
        radii_capped: radii.capped,
        quant: built.quant,
    })
}

/// The stored nodes so far: their count, quantisation figures, and the segments of the
/// levels that hold them.
struct StoredNodes {
    nodes: u64,
    quant: QuantStats,
    segments: Vec<Segment>,
}

/// What steps 3 and 4 rebuild each unit's forest from.
struct UnitForests<'a> {
    top: &'a Top,
    combined: &'a Combined,
    /// The units' leaf radii, when the scene has none of its own.
    radii: Option<&'a UnitRadii>,
    layout: Layout,
}

impl UnitForests<'_> {
    /// Unit `u` loaded, partitioned and laid out as its forest, with its true properties
    /// (steps 3 and 4 each rebuild it); `capped` counts its capped radii.
    fn forest(
        &self,
        u: usize,
        capped: &mut u64,
    ) -> Result<(build::Forest, Vec<Vec<TrueNode>>), MethodError> {
        let r = match self.radii {
            Some(r) => {
                let (r, c) = r.load(u)?;
                *capped += c;
                Some(r)
            }
            None => None,
        };
        let unit = &self.top.units[u];
        let mut s = unit.load(self.layout, r)?;
        let saved = unit
            .partition
            .as_ref()
            .ok_or_else(|| MethodError::Bug(format!("qsplat: unit {u} was never partitioned")))?;
        let p = Partitioned::load(saved, unit.n as usize, unit.split as u32, unit.cost)?;
        let forest = p.forest(self.combined.unit_roots[u]);
        s.permute(&p.perm);
        let truth = forest.truths(None, s.view());
        Ok((forest, truth))
    }

    /// Step 4 for unit `i`: its forest quantised from its roots' parent (decoded sphere and
    /// margin), its stored nodes written per level to spill files, added to `out`.
    fn write_nodes(
        &self,
        i: usize,
        (pd, pm): ((Vec3, f32), f64),
        fit: super::quant::Fit,
        spill: &SpillDir,
        out: &mut StoredNodes,
    ) -> Result<(), MethodError> {
        let colors = self.layout.colors;
        let attrs = (self.layout.normals, colors);
        let nb = format::node_bytes(colors);
        let (forest, truth) = self.forest(i, &mut 0)?;
        let first_level = self.combined.unit_level[i];
        let q = forest.quantise(&truth, Parent::Node(pd, pm), attrs, fit, first_level, false)?;
        out.nodes += q.levels.iter().map(|l| l.len() as u64).sum::<u64>();
        out.quant.merge(&q.stats);
        let mut files = Vec::with_capacity(q.levels.len());
        let mut rec = Vec::with_capacity(nb);
        for level in &q.levels {
            let mut w = spill.writer("nodes", nb)?;
            for node in level {
                rec.clear();
                format::encode_node(node, colors, &mut rec);
                w.push(&rec)?;
            }
            files.push(w.finish()?);
        }
        out.segments.push(Segment {
            lo: self.top.units[i].lo,
            first_level,
            part: Part::Unit(files),
        });
        Ok(())
    }
}

/// A range of samples at most the capacity, built in memory.
struct Unit {
    /// First sample position of the range in the tree.
    lo: u64,
    n: u64,
    spill: Spill,
    /// Its permutation and binary tree (step 2; read back by steps 3 and 4).
    partition: Option<Spill>,
    /// Its root's split costs (step 2).
    cost: (u64, u64),
    /// Its root's split, relative to `lo` (step 2).
    split: u64,
    /// Bounding box of its positions.
    bbox: (Vec3, Vec3),
}

impl Unit {
    /// The unit's samples; the radii from the records, or `radii` when the scene has none.
    fn load(&self, layout: Layout, radii: Option<Vec<f32>>) -> Result<SampleColumns, MethodError> {
        samples::load(&self.spill, layout, self.n as usize, radii)
    }

    /// The unit's sample indices and positions.
    fn positions(&self, layout: Layout) -> Result<(Vec<u32>, Vec<[f32; 3]>), MethodError> {
        samples::positions(&self.spill, layout)
    }
}

/// A child of a top node.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Child {
    Top(usize),
    Unit(usize),
}

/// A binary node above the units.
struct TopNode {
    lo: u64,
    kids: [Child; 2],
    cost: (u64, u64),
    grand: bool,
}

/// The binary tree above the units, in depth-first order (left first), and the units in
/// left-to-right order.
struct Top {
    nodes: Vec<TopNode>,
    units: Vec<Unit>,
}

/// A range waiting to be split: where its samples are, and its bounding box.
struct Pending {
    src: Option<Spill>,
    lo: u64,
    n: u64,
    bbox: (Vec3, Vec3),
    parent: Option<(usize, usize)>,
}

/// Step 1: splits ranges larger than `cap` as the in-memory build would, into spill files.
fn partition_top(
    cloud: &PointCloud,
    layout: Layout,
    split: Split,
    cap: u64,
    spill: &SpillDir,
    progress: &dyn Progress,
) -> Result<(Top, Aabb), MethodError> {
    let mut top = Top {
        nodes: Vec::new(),
        units: Vec::new(),
    };
    // The cloud's bounds are its positions' (min/max, so the same values the in-memory
    // partition folds).
    let bounds = cloud.bounds();
    let mut stack = vec![Pending {
        src: None,
        lo: 0,
        n: cloud.len() as u64,
        bbox: (bounds.min, bounds.max),
        parent: None,
    }];
    while let Some(r) = stack.pop() {
        let child = if r.n <= cap {
            let src = r.src.ok_or_else(|| {
                MethodError::Bug("qsplat: the root cannot be a unit out of core".into())
            })?;
            top.units.push(Unit {
                lo: r.lo,
                n: r.n,
                spill: src,
                partition: None,
                cost: (0, 0),
                split: 0,
                bbox: r.bbox,
            });
            progress.inc(r.n);
            Child::Unit(top.units.len() - 1)
        } else {
            let (lo, hi) = r.bbox;
            let axis = Aabb { min: lo, max: hi }.longest_axis();
            let mut halves = None;
            if split == Split::Midpoint {
                let cut = (lo[axis] as f64 + hi[axis] as f64) * 0.5;
                let h = halves_by(&r, cloud, layout, spill, |rec| {
                    (f32_at(rec, 4 + 4 * axis) as f64) < cut
                })?;
                if h.0.0 == 0 || h.0.0 == r.n {
                    h.0.1.remove();
                    h.1.1.remove();
                } else {
                    halves = Some(h);
                }
            }
            let ((nl, left, lbox), (nr, right, rbox)) = match halves {
                Some(h) => h,
                None => {
                    let range = split::key_range(lo[axis], hi[axis]);
                    let pivot = split::select_keys(&[r.n / 2], range, |f| {
                        split::scan(r.src.as_ref(), cloud, layout, |rec| {
                            f(split::rank_key(rec, axis));
                            Ok(())
                        })
                    })?[0];
                    halves_by(&r, cloud, layout, spill, |rec| {
                        split::rank_key(rec, axis) < pivot
                    })?
                }
            };
            if let Some(s) = r.src {
                s.remove();
            }
            let id = top.nodes.len();
            top.nodes.push(TopNode {
                lo: r.lo,
                kids: [Child::Top(usize::MAX); 2],
                cost: (0, 0),
                grand: false,
            });
            stack.push(Pending {
                src: Some(right),
                lo: r.lo + nl,
                n: nr,
                bbox: rbox,
                parent: Some((id, 1)),
            });
            stack.push(Pending {
                src: Some(left),
                lo: r.lo,
                n: nl,
                bbox: lbox,
                parent: Some((id, 0)),
            });
            Child::Top(id)
        };
        if let Some((p, side)) = r.parent {
            top.nodes[p].kids[side] = child;
        }
    }
    Ok((top, bounds))
}

type Half = split::Part;

/// Streams `r`'s records into a left file (`left(record)`) and a right file.
fn halves_by(
    r: &Pending,
    cloud: &PointCloud,
    layout: Layout,
    spill: &SpillDir,
    left: impl Fn(&[u8]) -> bool,
) -> Result<(Half, Half), MethodError> {
    let mut parts = split::route(r.src.as_ref(), cloud, layout, spill, 2, |rec| {
        usize::from(!left(rec))
    })?
    .into_iter();
    match (parts.next(), parts.next()) {
        (Some(l), Some(r)) => Ok((l, r)),
        _ => Err(MethodError::Bug(
            "qsplat: a split gave fewer than two parts".into(),
        )),
    }
}

impl Top {
    /// The units' leaf radii (for a cloud without radii; `n` samples in `bounds`),
    /// computed group of units by group within `mem_bytes` ([`crate::unit_knn`]).
    fn leaf_radii(
        &self,
        layout: Layout,
        n: usize,
        bounds: Aabb,
        mem_bytes: u64,
        spill: &SpillDir,
        progress: &dyn Progress,
    ) -> Result<UnitRadii, MethodError> {
        let boxes: Vec<UnitBox> = self
            .units
            .iter()
            .map(|u| UnitBox {
                n: u.n,
                bbox: u.bbox,
            })
            .collect();
        let load = |u: usize| self.units[u].positions(layout);
        unit_radii(
            &boxes, &load, n, bounds, mem_bytes, spill, "qsplat", progress,
        )
    }

    fn child_cost(&self, c: Child) -> (u64, u64) {
        match c {
            Child::Top(t) => self.nodes[t].cost,
            Child::Unit(u) => self.units[u].cost,
        }
    }

    fn child_samples(&self, c: Child) -> u64 {
        match c {
            // A top node is larger than the capacity (≥ 2).
            Child::Top(_) => u64::MAX,
            Child::Unit(u) => self.units[u].n,
        }
    }

    /// The top nodes' costs and combine decisions, bottom-up (children follow their parent
    /// in depth-first order), as [`build`]'s `partition` makes them.
    fn decide(&mut self, combine: Combine) {
        for t in (0..self.nodes.len()).rev() {
            let [l, r] = self.nodes[t].kids;
            let (cl, cr) = (self.child_cost(l), self.child_cost(r));
            let binary = cl.0 + cr.0;
            let grandkids = cl.1 + cr.1;
            let g = match combine {
                Combine::Pairs => true,
                Combine::Fewest => grandkids <= binary,
            };
            let node = &mut self.nodes[t];
            node.grand = g;
            node.cost = (1 + if g { grandkids } else { binary }, binary);
        }
    }

    /// Appends the children in the combined tree of `node` (none unless it is a top node):
    /// its binary children, or — when it takes grandchildren — theirs (a single-sample child
    /// is taken as is), as [`build`]'s `Binary::children` does.
    fn combined_children(&self, node: CNode, out: &mut Vec<CNode>) {
        let CNode::Top(t) = node else { return };
        let t = &self.nodes[t];
        for k in t.kids {
            if self.child_samples(k) == 1 || !t.grand {
                out.push(CNode::of(k));
            } else {
                match k {
                    Child::Top(k) => out.extend(self.nodes[k].kids.map(CNode::of)),
                    Child::Unit(u) => out.extend([CNode::Half(u, 0), CNode::Half(u, 1)]),
                }
            }
        }
    }

    /// The combined tree above the units, breadth-first.
    fn combined(&self) -> Combined {
        let mut c = Combined {
            levels: vec![vec![CNode::Top(0)]],
            unit_roots: vec![Roots::Whole; self.units.len()],
            unit_level: vec![0; self.units.len()],
        };
        loop {
            let level = c.levels.len() - 1;
            let mut next = Vec::new();
            for &node in &c.levels[level] {
                match node {
                    CNode::Top(_) => self.combined_children(node, &mut next),
                    CNode::Whole(u) => {
                        c.unit_level[u] = level;
                    }
                    CNode::Half(u, _) => {
                        c.unit_roots[u] = Roots::Children;
                        c.unit_level[u] = level;
                    }
                }
            }
            if next.is_empty() {
                break;
            }
            c.levels.push(next);
        }
        c
    }
}

/// A node of the combined tree above or at the units.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
enum CNode {
    Top(usize),
    /// A unit's root.
    Whole(usize),
    /// One of a unit root's binary children.
    Half(usize, usize),
}

impl CNode {
    fn of(c: Child) -> CNode {
        match c {
            Child::Top(t) => CNode::Top(t),
            Child::Unit(u) => CNode::Whole(u),
        }
    }
}

/// The combined tree down to the units' forest roots.
struct Combined {
    /// Breadth-first levels; units' forest roots appear, nothing below them.
    levels: Vec<Vec<CNode>>,
    /// Each unit's forest roots.
    unit_roots: Vec<Roots>,
    /// The level of each unit's forest roots.
    unit_level: Vec<usize>,
}

/// The top nodes quantised.
struct TopQuantised {
    /// `(first sample position, level, stored node)` per top node.
    nodes: Vec<(u64, usize, QNode)>,
    /// The header's root sphere.
    root: [f32; 4],
    /// Per unit: the decoded sphere and margin of its forest roots' parent.
    unit_parent: Vec<((Vec3, f32), f64)>,
    /// What quantisation did to the top nodes.
    stats: QuantStats,
}

impl Combined {
    /// True properties of the top nodes bottom-up from the units' forest roots
    /// (`roots[u]`), then their quantisation top-down.
    fn quantise(
        &self,
        roots: &[Vec<TrueNode>],
        (has_n, has_c): (bool, bool),
        fit: super::quant::Fit,
        top: &Top,
    ) -> Result<TopQuantised, MethodError> {
        let mut truth: std::collections::HashMap<CNode, TrueNode> = Default::default();
        let mut buf = Vec::new();
        for level in self.levels.iter().rev() {
            for &node in level {
                let t = match node {
                    CNode::Whole(u) => roots[u][0],
                    CNode::Half(u, s) => roots[u][s],
                    CNode::Top(_) => {
                        buf.clear();
                        top.combined_children(node, &mut buf);
                        let ts: Vec<TrueNode> = buf.iter().map(|k| truth[k]).collect();
                        build::combine(&ts, has_n)
                    }
                };
                truth.insert(node, t);
            }
        }
        let is_leaf = |node: &CNode| match *node {
            CNode::Top(_) => false,
            CNode::Whole(u) => top.units[u].n == 1,
            CNode::Half(u, 0) => top.units[u].split == 1,
            CNode::Half(u, _) => top.units[u].n - top.units[u].split == 1,
        };
        let mut out = TopQuantised {
            nodes: Vec::new(),
            root: [0.0; 4],
            unit_parent: vec![((Vec3::ZERO, 0.0), 0.0); top.units.len()],
            stats: QuantStats::default(),
        };
        let mut decoded: std::collections::HashMap<CNode, ((Vec3, f32), f64)> = Default::default();
        let (rd, rm) = build::root_sphere(&truth[&CNode::Top(0)]);
        out.root = [rd.0.x, rd.0.y, rd.0.z, rd.1];
        decoded.insert(CNode::Top(0), (rd, rm));
        let mut codes: std::collections::HashMap<CNode, u16> = Default::default();
        codes.insert(CNode::Top(0), 0);
        for (l, level) in self.levels.iter().enumerate() {
            for (i, &node) in level.iter().enumerate() {
                let CNode::Top(t) = node else { continue };
                let (pd, pm) = decoded[&node];
                buf.clear();
                top.combined_children(node, &mut buf);
                for &k in &buf {
                    match k {
                        CNode::Top(_) => {
                            let (code, d, m) =
                                build::encode_child(&truth[&k], pd, pm, fit, || {
                                    format!("a child of node {i} of level {l}")
                                })?;
                            out.stats.merge(&QuantStats::spheres(
                                &[truth[&k]],
                                &[(code, d, m)],
                                l + 1,
                                |_| pd,
                            ));
                            codes.insert(k, code);
                            decoded.insert(k, (d, m));
                        }
                        CNode::Whole(u) | CNode::Half(u, _) => out.unit_parent[u] = (pd, pm),
                    }
                }
                // Whole units that are single samples have an all-leaves parent too, but
                // their own unit writes them: only the flag of this node is needed here.
                let all_leaves = buf.iter().all(is_leaf);
                let qn = build::qnode(
                    &truth[&node],
                    codes[&node],
                    buf.len() as u8,
                    all_leaves,
                    has_n,
                    has_c,
                );
                out.stats
                    .merge(&QuantStats::nodes(&[truth[&node]], &[qn], has_n));
                out.nodes.push((top.nodes[t].lo, l, qn));
            }
        }
        Ok(out)
    }
}

/// A part of the tree in left-to-right order: a top node, or a unit's forest levels.
struct Segment {
    lo: u64,
    first_level: usize,
    part: Part,
}

enum Part {
    Top(QNode),
    Unit(Vec<Spill>),
}

/// The tree's levels assembled from the top nodes and the units' spill files.
struct Assembled {
    segments: Vec<Segment>,
    colors: bool,
}

impl Levels for Assembled {
    fn count(&self) -> usize {
        self.segments
            .iter()
            .map(|s| match &s.part {
                Part::Top(_) => s.first_level + 1,
                Part::Unit(files) => s.first_level + files.len(),
            })
            .max()
            .unwrap_or(0)
    }

    fn visit(
        &self,
        l: usize,
        f: &mut dyn FnMut(&[QNode]) -> Result<(), MethodError>,
    ) -> Result<(), MethodError> {
        let mut nodes = Vec::new();
        for s in &self.segments {
            match &s.part {
                Part::Top(n) if s.first_level == l => f(std::slice::from_ref(n))?,
                Part::Unit(files) if l >= s.first_level && l - s.first_level < files.len() => {
                    let file = &files[l - s.first_level];
                    file.read(|block| {
                        nodes.clear();
                        nodes.extend(
                            block
                                .chunks_exact(file.record)
                                .map(|b| format::decode_node(b, self.colors)),
                        );
                        f(&nodes)
                    })?;
                }
                _ => {}
            }
        }
        Ok(())
    }
}
