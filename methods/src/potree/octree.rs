//! The octree of a build, in memory: positions quantised into the bounding cube
//! ([`Quant`]), points numbered by their rank in Morton order, nodes split until they hold
//! at most `max_leaf` points ([`split`]), inner nodes' points moved up from their children
//! by Poisson-disk or random sampling ([`sample`]). The whole cloud (in core) or one unit of
//! it (out of core, [`super::ooc`]) at a time: a node's sample depends on its children's
//! points only, so both give the same octree.

use glam::DVec3;
use rayon::prelude::*;
use scenes::PointCloud;

use super::format::{self, MAX_LEVEL};
use super::{PotreeParams, Sampling};

/// Cells per axis of the random sampler's grid over a node (the converter's 128).
const RANDOM_GRID: f64 = 128.0;
/// A child with fewer points gives all of them to its parent under `sampling=random` (the
/// converter's rule).
const RANDOM_TAKE_ALL: usize = 100;
/// Bits per axis of the Morton codes the points are sorted by (levels up to 21).
pub const MORTON_BITS: u32 = 21;

/// The quantisation of positions.
#[derive(Debug, Clone, Copy)]
pub struct Quant {
    /// The cube's corner (world) = the format's `offset`.
    pub min: DVec3,
    /// The cube's side.
    pub size: f64,
    /// The format's `scale` (the same on all axes).
    pub scale: f64,
}

impl Quant {
    /// The bounding cube of `cloud` and its quantisation.
    pub fn of(cloud: &PointCloud) -> Self {
        let b = cloud.bounds();
        let origin = cloud.origin();
        let lo = b.min.as_dvec3() + origin;
        let hi = b.max.as_dvec3() + origin;
        // A cloud of one position still needs a cube: one a billionth of its distance from
        // the world origin (or 10⁻⁹) wide. No absolute floor otherwise: scenes of any
        // extent build the same octree.
        let size = (hi - lo).max_element();
        let size = if size > 0.0 {
            size
        } else {
            (lo.abs().max_element() * 1e-9).max(1e-9)
        };
        // The smallest power of ten with size / scale ≤ 2³⁰.
        let scale = 10f64.powf((size / f64::from(1u32 << 30)).log10().ceil());
        // The cube grows by one step so that the largest coordinate stays inside it.
        Quant {
            min: lo,
            size: size + scale,
            scale,
        }
    }
    /// The integer position of the cloud's sample at local position `local`.
    pub fn of_local(&self, origin: DVec3, local: [f32; 3]) -> [i32; 3] {
        self.quantise(glam::Vec3::from(local).as_dvec3() + origin)
    }
    /// The integer position of a world position.
    pub fn quantise(&self, world: DVec3) -> [i32; 3] {
        let q = ((world - self.min) / self.scale).round();
        let max = (self.size / self.scale).floor();
        [q.x, q.y, q.z].map(|v| v.clamp(0.0, max) as i32)
    }
    /// The world position of an integer one.
    pub fn world(&self, q: [i32; 3]) -> DVec3 {
        DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])) * self.scale + self.min
    }
    /// The 63-bit Morton code (octant digits, root first) of an integer position.
    pub fn morton(&self, q: [i32; 3]) -> u64 {
        let cells = f64::from(1u32 << MORTON_BITS);
        let max = (1u32 << MORTON_BITS) - 1;
        let w = self.world(q);
        let c = ((w - self.min) / self.size * cells).floor();
        let c = [c.x, c.y, c.z].map(|v| (v.max(0.0) as u32).min(max));
        // Potree's octant digit has x in bit 2 and z in bit 0.
        crate::morton::morton63([c[2], c[1], c[0]])
    }
}

/// Where the points a tree refers to are: their integer positions and input indices, by
/// their global Morton rank.
pub trait Points: Sync {
    /// Integer position of point `id`.
    fn q(&self, id: u32) -> [i32; 3];
    /// Input index (into the cloud) of point `id`.
    fn input(&self, id: u32) -> u32;
    /// The quantisation.
    fn quant(&self) -> &Quant;
}

/// A range of the cloud's points sorted by Morton code (ties by input index): the whole
/// cloud, or one unit whose first point has global rank `base`.
pub struct Sorted {
    /// Global rank of the first point.
    pub base: u32,
    /// Integer positions, sorted.
    pub q: Vec<[i32; 3]>,
    /// Morton codes, sorted.
    pub codes: Vec<u64>,
    /// Input index of each sorted point.
    pub order: Vec<u32>,
    /// The quantisation.
    pub quant: Quant,
}

impl Sorted {
    /// Every point of `cloud` (in core), keyed by its Morton code under `quant` and sorted.
    pub fn of_cloud(cloud: &PointCloud, quant: Quant) -> Self {
        let origin = cloud.origin();
        let keyed: Vec<(u64, u32)> = cloud
            .positions()
            .par_iter()
            .enumerate()
            .map(|(i, &l)| (quant.morton(quant.of_local(origin, l)), i as u32))
            .collect();
        Self::new(cloud, quant, 0, keyed)
    }

    /// Sorts `keyed` (Morton code, input index) pairs of `cloud`'s points.
    pub fn new(cloud: &PointCloud, quant: Quant, base: u32, mut keyed: Vec<(u64, u32)>) -> Self {
        keyed.par_sort_unstable();
        let origin = cloud.origin();
        let pos = cloud.positions();
        let q = keyed
            .par_iter()
            .map(|&(_, i)| quant.of_local(origin, pos[i as usize]))
            .collect();
        Sorted {
            base,
            q,
            codes: keyed.iter().map(|k| k.0).collect(),
            order: keyed.iter().map(|k| k.1).collect(),
            quant,
        }
    }
    /// Points held.
    pub fn len(&self) -> usize {
        self.q.len()
    }
    /// True if empty.
    pub fn is_empty(&self) -> bool {
        self.q.is_empty()
    }
}

impl Points for Sorted {
    fn q(&self, id: u32) -> [i32; 3] {
        self.q[(id - self.base) as usize]
    }
    fn input(&self, id: u32) -> u32 {
        self.order[(id - self.base) as usize]
    }
    fn quant(&self) -> &Quant {
        &self.quant
    }
}

/// Points by global rank, in any order: what the top of an out-of-core build works on.
pub struct Loose {
    /// (rank, integer position, input index), sorted by rank.
    pub points: Vec<(u32, [i32; 3], u32)>,
    /// The quantisation.
    pub quant: Quant,
}

impl Loose {
    fn at(&self, id: u32) -> &(u32, [i32; 3], u32) {
        let k = self.points.partition_point(|p| p.0 < id);
        &self.points[k]
    }
}

impl Points for Loose {
    fn q(&self, id: u32) -> [i32; 3] {
        self.at(id).1
    }
    fn input(&self, id: u32) -> u32 {
        self.at(id).2
    }
    fn quant(&self) -> &Quant {
        &self.quant
    }
}

/// A node under construction; `E` is what a [`Fill`] keeps beside the points (nothing for
/// Potree's subsample, the voxel grid for `voxel`).
#[derive(Debug, Default)]
pub struct Node<E = ()> {
    /// Depth.
    pub level: u32,
    /// Octant digits from the root.
    pub path: u64,
    /// Children by octant (`None` where absent or dropped, or kept elsewhere).
    pub children: [Option<Box<Node<E>>>; 8],
    /// Children that exist but are not in this tree (an out-of-core unit's root, seen from
    /// the top of the octree), as a child mask.
    pub outer_mask: u8,
    /// The points it holds (global ranks).
    pub points: Vec<u32>,
    /// World box.
    pub min: DVec3,
    /// World box.
    pub max: DVec3,
    /// What the fill keeps beside the points.
    pub extra: E,
}

impl<E: Default> Node<E> {
    /// An empty node at (`level`, `path`) with the box of that octant of the root box.
    pub fn at(level: u32, path: u64, root: (DVec3, DVec3)) -> Self {
        let (mut min, mut max) = root;
        for l in (0..level).rev() {
            (min, max) = format::child_box(min, max, ((path >> (3 * l)) & 7) as u8);
        }
        Node {
            level,
            path,
            min,
            max,
            ..Default::default()
        }
    }
    /// Bit `i`: child `i` exists (here or elsewhere).
    pub fn child_mask(&self) -> u8 {
        (0..8).fold(self.outer_mask, |m, i| {
            m | (u8::from(self.children[i].is_some()) << i)
        })
    }
    /// True if some child is in this tree.
    pub fn has_children_here(&self) -> bool {
        self.children.iter().any(Option::is_some)
    }
    /// True if the node has no children at all.
    pub fn is_leaf(&self) -> bool {
        !self.has_children_here() && self.outer_mask == 0
    }
}

/// Splits `range` (indices into `s`) into the octree under `node` (its level, path and box
/// set): a node of more than `max_leaf` points is split, and the root whatever it holds if
/// `split_root` ([`Fill::splits_root`]).
pub fn split<E: Default + Send>(
    s: &Sorted,
    range: std::ops::Range<usize>,
    mut node: Node<E>,
    max_leaf: usize,
    split_root: bool,
) -> Node<E> {
    let (level, path, min, max) = (node.level, node.path, node.min, node.max);
    let small = range.len() <= max_leaf && !(split_root && level == 0);
    if small || level >= MAX_LEVEL {
        node.points = (s.base + range.start as u32..s.base + range.end as u32).collect();
        return node;
    }
    // Codes share the node's prefix, so the octant digit grows along the range.
    let shift = 3 * (MORTON_BITS - 1 - level);
    let digit = |c: u64| ((c >> shift) & 7) as u8;
    let mut bounds = Vec::with_capacity(8);
    let mut start = range.start;
    for oct in 0..8u8 {
        let stop = start + s.codes[start..range.end].partition_point(|&c| digit(c) <= oct);
        if stop > start {
            bounds.push((oct, start..stop));
        }
        start = stop;
    }
    let kids: Vec<(u8, Node<E>)> = bounds
        .into_par_iter()
        .map(|(oct, r)| {
            let (cmin, cmax) = format::child_box(min, max, oct);
            let child = Node {
                level: level + 1,
                path: (path << 3) | u64::from(oct),
                min: cmin,
                max: cmax,
                ..Default::default()
            };
            (oct, split(s, r, child, max_leaf, false))
        })
        .collect();
    for (oct, k) in kids {
        node.children[usize::from(oct)] = Some(Box::new(k));
    }
    node
}

/// What fills the inner nodes of an octree build and turns the finished tree into node
/// descriptions: Potree's subsample ([`Subsample`]) or `voxel`'s grid of averaged samples.
/// The tree, its split, the units of an out-of-core build and the files are shared
/// ([`super::ooc::build_files`]); only this differs.
pub trait Fill: Sync {
    /// What a node keeps beside its points while the tree is built.
    type Extra: Default + Send + Sync + std::fmt::Debug;
    /// The method's name, for progress phases and spill folders.
    fn name(&self) -> &'static str;
    /// True if the root is an inner node however few points the cloud has (`voxel`: its
    /// coarsest level is always a grid of voxels); false: a cloud of at most `max_leaf`
    /// points is one leaf (Potree).
    fn splits_root(&self) -> bool {
        false
    }
    /// Fills every inner node of `node`'s tree bottom up from its children; nodes without
    /// children in this tree (leaves, or unit roots filled already) are left as they are.
    fn fill<P: Points>(&self, node: &mut Node<Self::Extra>, s: &P);
    /// Every node of `node`'s tree as a description, its contents moved out of the tree.
    fn describe(&self, node: Node<Self::Extra>, out: &mut Vec<super::write::Desc>);
}

/// Potree's inner nodes: points moved up from the children ([`sample`]).
pub struct Subsample<'a> {
    /// The root's spacing.
    pub spacing: f64,
    /// The build's parameters.
    pub params: &'a PotreeParams,
}

impl Fill for Subsample<'_> {
    type Extra = ();
    fn name(&self) -> &'static str {
        super::NAME
    }
    fn fill<P: Points>(&self, node: &mut Node, s: &P) {
        sample(node, s, self.spacing, self.params);
    }
    fn describe(&self, node: Node, out: &mut Vec<super::write::Desc>) {
        super::write::describe(node, out);
    }
}

/// Moves the sample of every inner node of `node`'s tree up from its children, bottom up
/// (children first, in parallel); drops leaves left empty. Nodes without children in this
/// tree keep their points as they are (leaves, or unit roots sampled already).
pub fn sample<P: Points>(node: &mut Node, s: &P, spacing: f64, p: &PotreeParams) {
    node.children
        .par_iter_mut()
        .flatten()
        .for_each(|c| sample(c, s, spacing, p));
    if !node.has_children_here() {
        return;
    }
    // Candidates: every point of every child, with the child's octant.
    let cands: Vec<(u32, u8)> = (0..8u8)
        .filter_map(|o| node.children[usize::from(o)].as_ref().map(|c| (o, c)))
        .flat_map(|(o, c)| c.points.iter().map(move |&i| (i, o)))
        .collect();
    let level_spacing = spacing / f64::from(1u32 << node.level);
    let accepted = match p.sampling {
        Sampling::Poisson => poisson(node, &cands, s, level_spacing),
        Sampling::Random => random(node, &cands, s, p.seed),
    };
    let mut taken: Vec<u32> = cands
        .iter()
        .zip(&accepted)
        .filter(|(_, a)| **a)
        .map(|(c, _)| c.0)
        .collect();
    taken.sort_unstable();
    for c in node.children.iter_mut().flatten() {
        c.points.retain(|i| taken.binary_search(i).is_err());
    }
    for slot in &mut node.children {
        if slot
            .as_ref()
            .is_some_and(|c| c.points.is_empty() && c.is_leaf())
        {
            *slot = None;
        }
    }
    node.points.extend(taken);
}

/// Poisson-disk acceptance: candidates in order of distance from the node's centre (ties by
/// index), each accepted if no accepted point is closer than `spacing`. Exact (a hash grid
/// of `spacing`-sized cells), where the converter gives up after 10,000 comparisons.
fn poisson<P: Points>(node: &Node, cands: &[(u32, u8)], s: &P, spacing: f64) -> Vec<bool> {
    let center = (node.min + node.max) * 0.5;
    let pos: Vec<DVec3> = cands
        .iter()
        .map(|&(i, _)| s.quant().world(s.q(i)))
        .collect();
    let mut order: Vec<usize> = (0..cands.len()).collect();
    order.sort_unstable_by(|&a, &b| {
        let (da, db) = (
            pos[a].distance_squared(center),
            pos[b].distance_squared(center),
        );
        da.total_cmp(&db).then(cands[a].0.cmp(&cands[b].0))
    });
    // Cells of `spacing` over the node (a few outside it, for points on its faces), packed
    // into a key; each cell heads a list of the accepted points in it.
    let cell = |p: DVec3| ((p - node.min) / spacing).floor().as_i64vec3() + glam::I64Vec3::ONE;
    let key = |c: glam::I64Vec3| {
        (c.x as u64 & 0x1f_ffff) | (c.y as u64 & 0x1f_ffff) << 21 | (c.z as u64 & 0x1f_ffff) << 42
    };
    let mut heads: crate::cellmap::CellMap<u32> = Default::default();
    let mut next: Vec<u32> = Vec::new();
    let mut kept: Vec<DVec3> = Vec::new();
    let mut accepted = vec![false; cands.len()];
    let sq = spacing * spacing;
    for k in order {
        let p = pos[k];
        let c = cell(p);
        let mut free = true;
        'near: for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    let mut at = heads
                        .get(&key(c + glam::I64Vec3::new(dx, dy, dz)))
                        .copied()
                        .unwrap_or(u32::MAX);
                    while at != u32::MAX {
                        if kept[at as usize].distance_squared(p) < sq {
                            free = false;
                            break 'near;
                        }
                        at = next[at as usize];
                    }
                }
            }
        }
        if free {
            let slot = heads.entry(key(c)).or_insert(u32::MAX);
            next.push(*slot);
            *slot = kept.len() as u32;
            kept.push(p);
            accepted[k] = true;
        }
    }
    accepted
}

/// Random acceptance as the converter's `-m random`: a child of fewer than 100 points gives
/// them all; otherwise candidates in a random order (seeded by `seed` and the node), at most
/// one per cell of the node's 128³ grid and only within `0.7·√3` of the cell's centre (in
/// cell half-widths).
fn random<P: Points>(node: &Node, cands: &[(u32, u8)], s: &P, seed: u64) -> Vec<bool> {
    let mut per_child = [0usize; 8];
    for &(_, o) in cands {
        per_child[usize::from(o)] += 1;
    }
    let stream = (u64::from(node.level) << 58) ^ node.path;
    let mut rng = scenes::rng::Pcg32::stream(seed, stream);
    let mut order: Vec<usize> = (0..cands.len()).collect();
    for i in (1..order.len()).rev() {
        let j = rng.below(i as u32 + 1) as usize;
        order.swap(i, j);
    }
    let size = node.max - node.min;
    let mut used = std::collections::HashSet::new();
    let mut accepted = vec![false; cands.len()];
    let limit = 0.7 * 3f64.sqrt();
    for k in order {
        let (i, o) = cands[k];
        if per_child[usize::from(o)] < RANDOM_TAKE_ALL {
            accepted[k] = true;
            continue;
        }
        let n = (s.quant().world(s.q(i)) - node.min) / size * RANDOM_GRID;
        let local = (n - n.floor()) * 2.0 - DVec3::ONE;
        let c = n
            .floor()
            .clamp(DVec3::ZERO, DVec3::splat(RANDOM_GRID - 1.0))
            .as_uvec3();
        if local.length() < limit && used.insert(c) {
            accepted[k] = true;
        }
    }
    accepted
}
