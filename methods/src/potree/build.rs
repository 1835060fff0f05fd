//! Our converter: a scene into the Potree 2.0 format, following PotreeConverter 2.0
//! (Schütz et al. 2020, §4) in what the files hold:
//!
//! 1. The bounding **cube** of the points (the box's longest side on every axis); positions
//!    quantised to `int32` with `offset` = the cube's corner and `scale` = the smallest power
//!    of ten that fits the cube in 2³⁰ steps. The root's spacing is the cube's side / 128.
//! 2. The **octree**: a node with more than `max_leaf` points (10,000) is split into its
//!    octants, down to level [`format::MAX_LEVEL`] (deeper piles of duplicates stay in one
//!    leaf). Points are sorted by Morton code once, so every node is a range.
//! 3. **Subsampling**, bottom up: an inner node takes its points *from its children* (they
//!    are moved, not copied: every input point is stored exactly once), Poisson-disk with
//!    the level's spacing `spacing / 2^level`, or at random (see [`super::Sampling`]). A leaf
//!    left empty is dropped, as the converter does.
//! 4. **Files**: `octree.bin` node after node in breadth-first order (the converter writes
//!    them as they complete); `hierarchy.bin` in chunks of `step` levels, the root's first,
//!    nodes breadth first within a chunk, the chunk's last level as proxies.
//!
//! The build is in core (a 10 M-point scene takes ~0.5 GB); PotreeConverter's out-of-core
//! chunking is not reproduced yet. Rayon splits the work by subtree; the output does not
//! depend on the number of threads.

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;
use scenes::{PointCloud, Progress};

use super::format::{
    self, AttributeDesc, BoundingBox, HierarchyInfo, MAX_LEVEL, Metadata, NodeKind, Record,
};
use super::{FORMAT_VERSION, INFO_FILE, Info, NAME, PotreeParams, Sampling};
use crate::{BuildStats, Manifest, MethodError, Params};

/// Cells per axis of the random sampler's grid over a node (the converter's 128).
const RANDOM_GRID: f64 = 128.0;
/// A child with fewer points gives all of them to its parent under `sampling=random` (the
/// converter's rule).
const RANDOM_TAKE_ALL: usize = 100;
/// Bits per axis of the Morton codes the points are sorted by (levels up to 21).
const MORTON_BITS: u32 = 21;

/// The quantisation of positions.
#[derive(Debug, Clone, Copy)]
struct Quant {
    /// The cube's corner (world) = the format's `offset`.
    min: DVec3,
    /// The cube's side.
    size: f64,
    /// The format's `scale` (the same on all axes).
    scale: f64,
}

impl Quant {
    fn of(cloud: &PointCloud) -> Self {
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
    fn quantise(&self, world: DVec3) -> [i32; 3] {
        let q = ((world - self.min) / self.scale).round();
        let max = (self.size / self.scale).floor();
        [q.x, q.y, q.z].map(|v| v.clamp(0.0, max) as i32)
    }
    fn world(&self, q: [i32; 3]) -> DVec3 {
        DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])) * self.scale + self.min
    }
    fn morton(&self, q: [i32; 3]) -> u64 {
        let cells = f64::from(1u32 << MORTON_BITS);
        let max = (1u32 << MORTON_BITS) - 1;
        let w = self.world(q);
        let c = ((w - self.min) / self.size * cells).floor();
        let c = [c.x, c.y, c.z].map(|v| (v.max(0.0) as u32).min(max));
        // Potree's octant digit has x in bit 2 and z in bit 0.
        crate::morton::morton63([c[2], c[1], c[0]])
    }
}

/// A node under construction.
#[derive(Debug, Default)]
struct Node {
    level: u32,
    path: u64,
    /// Children by octant (`None` where absent or dropped).
    children: [Option<Box<Node>>; 8],
    /// The points it holds (indices into the sorted order).
    points: Vec<u32>,
    /// World box.
    min: DVec3,
    max: DVec3,
}

impl Node {
    fn child_mask(&self) -> u8 {
        (0..8).fold(0u8, |m, i| m | (u8::from(self.children[i].is_some()) << i))
    }
    fn is_leaf(&self) -> bool {
        self.children.iter().all(Option::is_none)
    }
}

/// Input of the build, sorted by Morton code.
struct Sorted {
    q: Vec<[i32; 3]>,
    codes: Vec<u64>,
    /// Input index of sorted point `i`.
    order: Vec<u32>,
    quant: Quant,
}

/// Splits `range` of the sorted points into the octree under (`level`, `path`, box).
fn split(
    s: &Sorted,
    range: std::ops::Range<usize>,
    at: (u32, u64, DVec3, DVec3),
    max_leaf: usize,
) -> Node {
    let (level, path, min, max) = at;
    let mut node = Node {
        level,
        path,
        min,
        max,
        ..Default::default()
    };
    if range.len() <= max_leaf || level >= MAX_LEVEL {
        node.points = (range.start as u32..range.end as u32).collect();
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
    let kids: Vec<(u8, Node)> = bounds
        .into_par_iter()
        .map(|(oct, r)| {
            let (cmin, cmax) = format::child_box(min, max, oct);
            (
                oct,
                split(
                    s,
                    r,
                    (level + 1, (path << 3) | u64::from(oct), cmin, cmax),
                    max_leaf,
                ),
            )
        })
        .collect();
    for (oct, k) in kids {
        node.children[usize::from(oct)] = Some(Box::new(k));
    }
    node
}

/// Moves the sample of every inner node of `node`'s subtree up from its children, bottom up
/// (children first, in parallel); drops leaves left empty.
fn sample(node: &mut Node, s: &Sorted, spacing: f64, p: &PotreeParams) {
    node.children
        .par_iter_mut()
        .flatten()
        .for_each(|c| sample(c, s, spacing, p));
    if node.is_leaf() {
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
    node.points = taken;
}

/// Poisson-disk acceptance: candidates in order of distance from the node's centre (ties by
/// index), each accepted if no accepted point is closer than `spacing`. Exact (a hash grid
/// of `spacing`-sized cells), where the converter gives up after 10,000 comparisons.
fn poisson(node: &Node, cands: &[(u32, u8)], s: &Sorted, spacing: f64) -> Vec<bool> {
    let center = (node.min + node.max) * 0.5;
    let pos: Vec<DVec3> = cands
        .iter()
        .map(|&(i, _)| s.quant.world(s.q[i as usize]))
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
fn random(node: &Node, cands: &[(u32, u8)], s: &Sorted, seed: u64) -> Vec<bool> {
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
        let n = (s.quant.world(s.q[i as usize]) - node.min) / size * RANDOM_GRID;
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

/// A node of the finished octree, breadth first.
struct Flat<'a> {
    node: &'a Node,
    children: [u32; 8],
}

fn flatten(root: &Node) -> Vec<Flat<'_>> {
    let mut out = vec![Flat {
        node: root,
        children: [u32::MAX; 8],
    }];
    let mut i = 0;
    while i < out.len() {
        let n = out[i].node;
        for (o, c) in n.children.iter().enumerate() {
            if let Some(c) = c {
                out[i].children[o] = out.len() as u32;
                out.push(Flat {
                    node: c,
                    children: [u32::MAX; 8],
                });
            }
        }
        i += 1;
    }
    out
}

/// The hierarchy chunks: per chunk root (levels 0, step, 2·step, …, breadth first), its nodes
/// breadth first down to `step` levels below it.
fn chunks(flat: &[Flat<'_>], step: u32) -> Vec<Vec<u32>> {
    let mut out = Vec::new();
    for (r, f) in flat.iter().enumerate() {
        if f.node.level % step != 0 {
            continue;
        }
        let mut chunk = vec![r as u32];
        let mut i = 0;
        while i < chunk.len() {
            let n = &flat[chunk[i] as usize];
            if n.node.level < f.node.level + step {
                chunk.extend(n.children.iter().copied().filter(|&c| c != u32::MAX));
            }
            i += 1;
        }
        out.push(chunk);
    }
    out
}

/// Builds the Potree octree of `cloud` into `dir`: `octree.bin`, `hierarchy.bin`,
/// `metadata.json`, `potree.json`, then the manifest last.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let t0 = std::time::Instant::now();
    let p = PotreeParams::from_params(params)?;
    let n = cloud.len();
    if n == 0 || n > u32::MAX as usize {
        return Err(MethodError::Limit(format!(
            "method '{NAME}': {n} points; a build takes 1..=2³² − 1"
        )));
    }
    let quant = Quant::of(cloud);
    progress.start("potree: sort", n as u64);
    let origin = cloud.origin();
    let q: Vec<[i32; 3]> = cloud
        .positions()
        .par_iter()
        .map(|&l| quant.quantise(glam::Vec3::from(l).as_dvec3() + origin))
        .collect();
    let mut keyed: Vec<(u64, u32)> = q
        .par_iter()
        .enumerate()
        .map(|(i, &v)| (quant.morton(v), i as u32))
        .collect();
    keyed.par_sort_unstable();
    let order: Vec<u32> = keyed.iter().map(|k| k.1).collect();
    let sorted = Sorted {
        q: order.iter().map(|&i| q[i as usize]).collect(),
        codes: keyed.iter().map(|k| k.0).collect(),
        order,
        quant,
    };
    drop((q, keyed));
    progress.finish();
    progress.start("potree: octree", n as u64);
    let (min, max) = (quant.min, quant.min + DVec3::splat(quant.size));
    let mut root = split(&sorted, 0..n, (0, 0, min, max), p.max_leaf as usize);
    let spacing = quant.size / 128.0;
    sample(&mut root, &sorted, spacing, &p);
    progress.finish();
    let flat = flatten(&root);
    let written = write_files(cloud, &sorted, &flat, &p, dir, spacing, scene)?;
    let depth = flat.iter().map(|f| f.node.level).max().unwrap_or(0);
    crate::method::write_json(
        &dir.join(INFO_FILE),
        &Info {
            origin: origin.to_array(),
            nodes: flat.len() as u64,
            levels: depth + 1,
        },
    )?;
    let mut extra = serde_json::Map::new();
    let mut put = |k: &str, v: serde_json::Value| {
        extra.insert(k.into(), v);
    };
    put(
        "sampling",
        serde_json::to_value(p.sampling).unwrap_or_default(),
    );
    put("max_leaf", p.max_leaf.into());
    put("step", p.step.into());
    put("spacing", spacing.into());
    put("scale", quant.scale.into());
    put("hierarchy_chunks", written.chunks.into());
    put("octree_bytes", written.octree_bytes.into());
    put("hierarchy_bytes", written.hierarchy_bytes.into());
    let stats = BuildStats {
        points_in: n as u64,
        nodes: flat.len() as u64,
        levels: depth + 1,
        bytes_in: cloud.column_bytes(),
        bytes_out: written.octree_bytes + written.hierarchy_bytes + written.metadata_bytes,
        bits_per_sample: 0.0,
        seconds: t0.elapsed().as_secs_f64(),
        points_per_s: 0.0,
        extra,
    }
    .finish();
    let decoding_attrs = super::format::Decoding {
        layout: written.layout,
        scale: DVec3::ZERO,
        offset: DVec3::ZERO,
        origin: DVec3::ZERO,
    }
    .attributes();
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: decoding_attrs,
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    Ok(stats)
}

/// What [`write_files`] wrote.
struct Written {
    octree_bytes: u64,
    hierarchy_bytes: u64,
    metadata_bytes: u64,
    chunks: u64,
    layout: format::Layout,
}

/// The point record's attributes for `cloud`: position, then `rgb` and `NormalX/Y/Z` if the
/// scene has colours and normals (nothing it lacks).
fn attribute_list(cloud: &PointCloud, quant: &Quant) -> Vec<AttributeDesc> {
    let desc = |name: &str, n: u32, ty: &str, es: u32| AttributeDesc {
        name: name.into(),
        description: String::new(),
        size: n * es,
        num_elements: n,
        element_size: es,
        type_name: ty.into(),
        min: None,
        max: None,
        scale: None,
        offset: None,
    };
    let b = cloud.bounds();
    let o = cloud.origin();
    let mut out = vec![AttributeDesc {
        min: Some((b.min.as_dvec3() + o).to_array().to_vec()),
        max: Some((b.max.as_dvec3() + o).to_array().to_vec()),
        scale: Some(vec![quant.scale; 3]),
        offset: Some(quant.min.to_array().to_vec()),
        ..desc("position", 3, "int32", 4)
    }];
    if cloud.colors().is_some() {
        out.push(desc("rgb", 3, "uint16", 2));
    }
    if cloud.normals().is_some() {
        for axis in ["NormalX", "NormalY", "NormalZ"] {
            out.push(desc(axis, 1, "float", 4));
        }
    }
    out
}

fn write_files(
    cloud: &PointCloud,
    s: &Sorted,
    flat: &[Flat<'_>],
    p: &PotreeParams,
    dir: &Path,
    spacing: f64,
    scene: &str,
) -> Result<Written, MethodError> {
    use std::io::Write;
    let attributes = attribute_list(cloud, &s.quant);
    let depth = flat.iter().map(|f| f.node.level).max().unwrap_or(0);
    let (min, max) = (s.quant.min, s.quant.min + DVec3::splat(s.quant.size));
    let mut meta = Metadata {
        version: format::VERSION.into(),
        name: scene.into(),
        description: String::new(),
        points: cloud.len() as u64,
        projection: String::new(),
        hierarchy: HierarchyInfo {
            first_chunk_size: 0,
            step_size: p.step,
            depth,
        },
        offset: s.quant.min.to_array(),
        scale: [s.quant.scale; 3],
        spacing,
        bounding_box: BoundingBox {
            min: min.to_array(),
            max: max.to_array(),
        },
        encoding: format::ENCODING.into(),
        attributes,
    };
    let meta_path = dir.join(format::METADATA_FILE);
    let layout = meta.layout(&meta_path)?;
    let bpp = layout.bytes_per_point;
    // octree.bin, breadth first.
    let octree_path = dir.join(format::OCTREE_FILE);
    let file = std::fs::File::create(&octree_path).map_err(|e| MethodError::io(&octree_path, e))?;
    let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
    let mut spans = Vec::with_capacity(flat.len());
    let mut offset = 0u64;
    let mut rec = vec![0u8; bpp];
    let (normals, colors) = (cloud.normals(), cloud.colors());
    for f in flat {
        for &i in &f.node.points {
            let src = s.order[i as usize] as usize;
            let q = s.q[i as usize];
            for k in 0..3 {
                rec[4 * k..4 * k + 4].copy_from_slice(&q[k].to_le_bytes());
            }
            let mut at = 12;
            if let Some(c) = colors {
                for k in 0..3 {
                    let v = u16::from(c[src][k]) * 257;
                    rec[at + 2 * k..at + 2 * k + 2].copy_from_slice(&v.to_le_bytes());
                }
                at += 6;
            }
            if let Some(nm) = normals {
                for k in 0..3 {
                    rec[at + 4 * k..at + 4 * k + 4].copy_from_slice(&nm[src][k].to_le_bytes());
                }
            }
            out.write_all(&rec)
                .map_err(|e| MethodError::io(&octree_path, e))?;
        }
        let size = f.node.points.len() as u64 * bpp as u64;
        spans.push((offset, size));
        offset += size;
    }
    out.flush().map_err(|e| MethodError::io(&octree_path, e))?;
    drop(out);
    // hierarchy.bin.
    let chunk_list = chunks(flat, p.step);
    let mut chunk_at = std::collections::HashMap::new();
    let mut pos = 0u64;
    for c in &chunk_list {
        let size = (c.len() * format::RECORD_BYTES) as u64;
        chunk_at.insert(c[0], (pos, size));
        pos += size;
    }
    let mut bytes = Vec::with_capacity(pos as usize);
    for c in &chunk_list {
        let top = flat[c[0] as usize].node.level;
        for &id in c {
            let f = &flat[id as usize];
            let record = if id != c[0] && f.node.level == top + p.step {
                let (offset, size) = chunk_at[&id];
                Record {
                    kind: NodeKind::Proxy,
                    child_mask: f.node.child_mask(),
                    points: f.node.points.len() as u32,
                    offset,
                    size,
                }
            } else {
                let (offset, size) = spans[id as usize];
                Record {
                    kind: if f.node.is_leaf() {
                        NodeKind::Leaf
                    } else {
                        NodeKind::Inner
                    },
                    child_mask: f.node.child_mask(),
                    points: f.node.points.len() as u32,
                    offset,
                    size,
                }
            };
            bytes.extend_from_slice(&record.to_bytes());
        }
    }
    let hierarchy_path = dir.join(format::HIERARCHY_FILE);
    std::fs::write(&hierarchy_path, &bytes).map_err(|e| MethodError::io(&hierarchy_path, e))?;
    meta.hierarchy.first_chunk_size = chunk_at[&0].1;
    crate::method::write_json(&meta_path, &meta)?;
    let metadata_bytes = std::fs::metadata(&meta_path)
        .map_err(|e| MethodError::io(&meta_path, e))?
        .len();
    Ok(Written {
        octree_bytes: offset,
        hierarchy_bytes: bytes.len() as u64,
        metadata_bytes,
        chunks: chunk_list.len() as u64,
        layout,
    })
}
