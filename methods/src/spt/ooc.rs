//! The SPT build in bounded memory: the same files, byte for byte, as the in-memory build,
//! with working memory bounded by `--param mem_mb`.
//!
//! The point tree is an octree over Morton codes ([`build`](mod@super::build)), so a subtree
//! is a function of one octree cell's samples. A cloud of more than [`unit_capacity`]
//! samples is built in **units**, octree cells of at most that many samples:
//! 1. **Cells.** One pass over the cloud counts samples per cell of depth 6 (in the cloud's
//!    Morton grid); a cell with more than the capacity is refined by further passes, three
//!    levels at a time, down to the finest cells (which may exceed the capacity only with
//!    that many coincident samples). The cells of at most the capacity under the oversized
//!    ones are the units, in Morton order.
//! 2. **Routing.** A second pass writes every sample to its unit's spill file (input order
//!    within each), and the leaf radii are computed per unit ([`crate::unit_knn`]).
//! 3. **Trees.** The octree above the units is walked as the in-memory recursion walks it
//!    (a cell with one occupied child is not a node); each unit's subtree is built in
//!    memory when reached, its nodes numbered on from the nodes before it (post-order, as in
//!    memory), their `lod` entries and list keys ([`list_key`]) computed, and written to a
//!    spill file sorted by key. The unit's root and the nodes above the units stay in
//!    memory; their parents are known once the walk returns.
//! 4. **List.** The sorted files and the nodes in memory are merged by key into the
//!    [`ListWriter`], which writes the same files as the in-memory build.
//!
//! Spill files sit in `<dir>/spt-spill.tmp/`, checked per block, removed on success and on
//! error.

use std::cmp::Reverse;
use std::collections::{BinaryHeap, HashMap};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;
use scenes::{PointCloud, Progress};

use super::build::{self, BITS, Builder, MortonGrid, NO_PARENT, Node};
use super::list::{ListNode, ListWriter};
use super::quant::{Extent, LodScale};
use super::{Listed, SptMode, SptParams, cluster_of, list_key, lod_entry, non_finite};
use crate::MethodError;
use crate::overlap::overlapped;
use crate::spill::samples::{self, EMPTY_BOX, SampleLayout, f32_at, grow, pos_of, u32_at};
use crate::spill::{Budget, Spill, SpillDir, SpillWriter};
use crate::unit_knn::{UnitBox, UnitRadii, unit_radii};

/// Working bytes per sample of a unit built in memory, the larger of two peaks (≤ 186):
/// while the tree is built, the samples (≤ 35 with the index), the Morton keys with their
/// positions, radii and colours (32), the tree's node counts (4) and per node (≈ 1.33–1.5
/// per sample) the node (52); then the nodes and their [`RunItem`]s (≤ 72 per node, while
/// the unit's run is made, sorted and written).
pub const UNIT_BYTES_PER_SAMPLE: u64 = 256;

/// Samples of the largest unit built in memory under `mem_bytes`.
pub fn unit_capacity(mem_bytes: u64) -> u64 {
    (mem_bytes / UNIT_BYTES_PER_SAMPLE).max(2)
}

/// Depth of the first count of samples per cell.
const FIRST_DEPTH: u32 = 6;
/// Levels a refinement pass adds.
const STEP: u32 = 3;
/// Samples per block when streaming the cloud.
const BLOCK: usize = 1 << 16;
/// Samples per parallel piece of the routing pass.
const ROUTE_PIECE: usize = 1 << 12;
/// Nodes per batch handed from the merge to the list's writer.
const WRITE_BATCH: usize = 1 << 12;

/// An octree cell: depth below the root and Morton prefix (`3·depth` bits).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
struct Cell {
    depth: u32,
    prefix: u64,
}

impl Cell {
    const ROOT: Cell = Cell {
        depth: 0,
        prefix: 0,
    };
    fn child(self, o: u64) -> Cell {
        Cell {
            depth: self.depth + 1,
            prefix: (self.prefix << 3) | o,
        }
    }
    /// The codes of the cell's samples: `[start, end)`.
    fn codes(self) -> (u64, u64) {
        let shift = 3 * (BITS - self.depth);
        (self.prefix << shift, (self.prefix + 1) << shift)
    }
}

/// Samples per cell: a first count at [`FIRST_DEPTH`] and refinements of oversized cells.
struct Counts {
    /// Prefix sums over the cells of depth [`FIRST_DEPTH`], in Morton order.
    first: Vec<u64>,
    /// Per refined cell: prefix sums over its descendants [`STEP`] levels down.
    refined: HashMap<Cell, Vec<u64>>,
}

impl Counts {
    fn count(&self, c: Cell) -> u64 {
        let (sums, depth, base) = if c.depth <= FIRST_DEPTH {
            (&self.first, FIRST_DEPTH, 0)
        } else {
            let d = FIRST_DEPTH + STEP * ((c.depth - FIRST_DEPTH - 1) / STEP);
            let anc = Cell {
                depth: d,
                prefix: c.prefix >> (3 * (c.depth - d)),
            };
            let deepest = (d + STEP).min(BITS);
            let Some(s) = self.refined.get(&anc) else {
                return 0;
            };
            (s, deepest, anc.prefix << (3 * (deepest - d)))
        };
        let shift = 3 * (depth - c.depth);
        let lo = ((c.prefix << shift) - base) as usize;
        let hi = (((c.prefix + 1) << shift) - base) as usize;
        sums[hi] - sums[lo]
    }
}

fn prefix_sums(counts: &[u64]) -> Vec<u64> {
    let mut s = Vec::with_capacity(counts.len() + 1);
    s.push(0);
    let mut acc = 0;
    for &c in counts {
        acc += c;
        s.push(acc);
    }
    s
}

/// Calls `f` with each block of the cloud's Morton codes (computed in parallel), releasing
/// the positions' pages behind.
fn for_codes(
    cloud: &PointCloud,
    grid: MortonGrid,
    mut f: impl FnMut(usize, &[u64]) -> Result<(), MethodError>,
) -> Result<(), MethodError> {
    let n = cloud.len();
    let mut codes = Vec::with_capacity(BLOCK);
    for start in (0..n).step_by(BLOCK) {
        let end = (start + BLOCK).min(n);
        codes.clear();
        codes.par_extend(
            cloud.positions()[start..end]
                .par_iter()
                .map(|&p| grid.code(p)),
        );
        f(start, &codes)?;
        cloud.release_pages(start..end);
    }
    Ok(())
}

/// Step 1: the counts, refined until every cell holding more than `cap` samples is split
/// (or is a finest cell).
fn count_cells(cloud: &PointCloud, grid: MortonGrid, cap: u64) -> Result<Counts, MethodError> {
    let mut first = vec![0u64; 1 << (3 * FIRST_DEPTH)];
    let shift = 3 * (BITS - FIRST_DEPTH);
    for_codes(cloud, grid, |_, codes| {
        for &c in codes {
            first[(c >> shift) as usize] += 1;
        }
        Ok(())
    })?;
    let mut counts = Counts {
        first: prefix_sums(&first),
        refined: HashMap::new(),
    };
    drop(first);
    let mut depth = FIRST_DEPTH;
    while depth < BITS {
        let big: Vec<Cell> = (0..1u64 << (3 * depth))
            .filter(|_| depth == FIRST_DEPTH)
            .map(|prefix| Cell { depth, prefix })
            .chain(
                counts
                    .refined
                    .keys()
                    .filter(|c| c.depth + STEP == depth)
                    .flat_map(|c| {
                        let below = 3 * STEP;
                        (0..1u64 << below).map(move |o| Cell {
                            depth,
                            prefix: (c.prefix << below) | o,
                        })
                    }),
            )
            .filter(|&c| counts.count(c) > cap)
            .collect();
        if big.is_empty() {
            break;
        }
        let deepest = (depth + STEP).min(BITS);
        let mut hist: HashMap<u64, Vec<u64>> = big
            .iter()
            .map(|c| (c.prefix, vec![0u64; 1 << (3 * (deepest - depth))]))
            .collect();
        let (cell_shift, sub_shift) = (3 * (BITS - depth), 3 * (BITS - deepest));
        let mask = (1u64 << (3 * (deepest - depth))) - 1;
        for_codes(cloud, grid, |_, codes| {
            for &c in codes {
                if let Some(h) = hist.get_mut(&(c >> cell_shift)) {
                    h[((c >> sub_shift) & mask) as usize] += 1;
                }
            }
            Ok(())
        })?;
        for (prefix, h) in hist {
            counts
                .refined
                .insert(Cell { depth, prefix }, prefix_sums(&h));
        }
        depth = deepest;
    }
    Ok(counts)
}

/// The units: cells of at most `cap` samples (or finest) whose ancestors all hold more, in
/// Morton order.
fn units_of(counts: &Counts, cap: u64) -> Vec<(Cell, u64)> {
    let mut out = Vec::new();
    let mut stack = vec![Cell::ROOT];
    while let Some(c) = stack.pop() {
        let n = counts.count(c);
        if n == 0 {
            continue;
        }
        if n <= cap || c.depth == BITS {
            out.push((c, n));
        } else {
            stack.extend((0..8).rev().map(|o| c.child(o)));
        }
    }
    out
}

/// A unit as built.
struct Unit {
    cell: Cell,
    n: u64,
    spill: Spill,
    bbox: (Vec3, Vec3),
}

/// Steps 1 and 2: the units' sample files.
fn route(
    cloud: &PointCloud,
    grid: MortonGrid,
    cap: u64,
    layout: SampleLayout,
    dir: &SpillDir,
) -> Result<Vec<Unit>, MethodError> {
    let counts = count_cells(cloud, grid, cap)?;
    let cells = units_of(&counts, cap);
    drop(counts);
    let starts: Vec<u64> = cells.iter().map(|(c, _)| c.codes().0).collect();
    let mut writers = Vec::with_capacity(cells.len());
    for _ in &cells {
        writers.push(dir.writer_with_block("samples", layout.bytes(), 1 << 16)?);
    }
    let mut boxes = vec![EMPTY_BOX; cells.len()];
    let rb = layout.bytes();
    for_codes(cloud, grid, |start, codes| {
        // Each sample's unit and record, found in parallel pieces, then written in order.
        let pieces: Vec<(Vec<u32>, Vec<u8>)> = codes
            .par_chunks(ROUTE_PIECE)
            .enumerate()
            .map(|(c, piece)| {
                let mut to = Vec::with_capacity(piece.len());
                let mut recs = Vec::with_capacity(piece.len() * rb);
                for (j, &code) in piece.iter().enumerate() {
                    to.push((starts.partition_point(|&s| s <= code) - 1) as u32);
                    layout.encode(cloud, start + c * ROUTE_PIECE + j, &mut recs);
                }
                (to, recs)
            })
            .collect();
        for (to, recs) in &pieces {
            for (&u, rec) in to.iter().zip(recs.chunks_exact(rb)) {
                let u = u as usize;
                writers[u].push(rec)?;
                grow(&mut boxes[u], pos_of(rec));
            }
        }
        Ok(())
    })?;
    let mut units = Vec::with_capacity(cells.len());
    for (((cell, n), w), bbox) in cells.into_iter().zip(writers).zip(boxes) {
        let spill = w.finish()?;
        if spill.records != n {
            return Err(MethodError::Bug(format!(
                "spt: {} samples routed to a cell counted with {n}",
                spill.records
            )));
        }
        units.push(Unit {
            cell,
            n,
            spill,
            bbox,
        });
    }
    Ok(units)
}

/// A node record of a sorted run, holding only what the scene has: list id (`u32`),
/// centre, radius and `lod` entry (36 bytes), then the normal and its cluster (16) when the
/// scene has normals, the colour and a pad byte (4) when it has colours. The list key is
/// not stored: [`list_key`] of the cluster, `lod` and id gives it back (without normals the
/// normal is `Vec3::Z`, the cluster 0 and, without colours, the colour black, as the tree
/// holds them). 40 bytes on a coloured scene without normals (64 with a stored key, every
/// attribute and padding).
#[derive(Debug, Clone, Copy)]
struct RunRecord {
    normals: bool,
    colors: bool,
}

impl RunRecord {
    fn bytes(self) -> usize {
        36 + if self.normals { 16 } else { 0 } + if self.colors { 4 } else { 0 }
    }

    /// Node `nd` with list id `id` into `out` (exactly [`Self::bytes`] long).
    fn encode(self, id: u32, nd: &ListNode, out: &mut [u8]) {
        let mut at = 0;
        let mut put = |b: &[u8]| {
            out[at..at + b.len()].copy_from_slice(b);
            at += b.len();
        };
        put(&id.to_le_bytes());
        for v in nd.p.to_array().into_iter().chain([nd.r]).chain(nd.lod) {
            put(&v.to_le_bytes());
        }
        if self.normals {
            for v in nd.n.to_array() {
                put(&v.to_le_bytes());
            }
            put(&nd.cluster.to_le_bytes());
        }
        if self.colors {
            put(&nd.color);
            put(&[0]);
        }
        debug_assert_eq!(at, self.bytes());
    }

    /// The `lod` entry of record `r`.
    fn lod(r: &[u8]) -> [f32; 4] {
        [f32_at(r, 20), f32_at(r, 24), f32_at(r, 28), f32_at(r, 32)]
    }

    /// The list key and node of record `r`.
    fn decode(self, r: &[u8]) -> (u128, ListNode) {
        let v = |i: usize| f32_at(r, 4 + 4 * i);
        let lod = Self::lod(r);
        let (n, cluster, c) = if self.normals {
            (Vec3::new(v(8), v(9), v(10)), u32_at(r, 48), 52)
        } else {
            (Vec3::Z, 0, 36)
        };
        let color = if self.colors {
            [r[c], r[c + 1], r[c + 2]]
        } else {
            [0; 3]
        };
        let nd = ListNode {
            p: Vec3::new(v(0), v(1), v(2)),
            n,
            color,
            r: v(3),
            lod,
            cluster,
        };
        (list_key(cluster, &lod, u32_at(r, 0)), nd)
    }
}

/// A non-root node of a unit while the unit's run is sorted: its list key (two words, so that
/// the item packs without padding) and its run record of `N` bytes ([`RunRecord::bytes`]).
/// Sorting the records themselves reads the nodes once in their own order; sorting keys and
/// gathering each node and `lod` entry in list order afterwards was a random read per node
/// (≈ 1.3 s of the 10 M terrain's point tree: `results/measurements/issue-40-builds.md`).
#[derive(Clone, Copy)]
struct RunItem<const N: usize> {
    key: [u64; 2],
    rec: [u8; N],
}

/// Writes the sorted run of a unit's non-root `nodes` (ids from `base`; each node's parent is
/// in the unit) with records `rr` of `N` bytes to `w`: each node's `lod` entry, list key
/// ([`list_key`] with `cluster`) and record, sorted by key. The first node in list order whose
/// `lod` entry is not finite is the error.
fn sorted_run<const N: usize>(
    rr: RunRecord,
    nodes: &[Node],
    base: u64,
    cluster: impl Fn(&Node) -> u32 + Sync,
    w: &mut SpillWriter,
) -> Result<(), MethodError> {
    let root = nodes.len() - 1;
    let mut items: Vec<RunItem<N>> = nodes[..root]
        .par_iter()
        .enumerate()
        .map(|(i, nd)| {
            let lod = lod_entry(nd, Some(&nodes[nd.parent as usize]));
            let (c, id) = (cluster(nd), (base + i as u64) as u32);
            let key = list_key(c, &lod, id);
            let mut rec = [0; N];
            rr.encode(id, &ListNode::of(nd, lod, c), &mut rec);
            RunItem {
                key: [(key >> 64) as u64, key as u64],
                rec,
            }
        })
        .collect();
    if let Some((_, i)) = items
        .par_iter()
        .enumerate()
        .filter(|(_, it)| !RunRecord::lod(&it.rec).iter().all(|v| v.is_finite()))
        .map(|(i, it)| (it.key, i))
        .min()
    {
        return Err(non_finite(
            base + i as u64,
            &RunRecord::lod(&items[i].rec),
            &nodes[i],
        ));
    }
    items.par_sort_unstable_by_key(|it| it.key);
    for it in &items {
        w.push(&it.rec)?;
    }
    Ok(())
}

/// The walk of step 3.
struct Walk<'a> {
    p: &'a SptParams,
    grid: MortonGrid,
    has_normals: bool,
    has_colors: bool,
    units: &'a [Unit],
    next_unit: usize,
    load: &'a dyn Fn(usize) -> Result<samples::SampleColumns, MethodError>,
    dir: &'a SpillDir,
    /// Nodes numbered so far.
    next_id: u64,
    /// Nodes kept in memory (unit roots and nodes above the units), by id.
    kept: Vec<(u64, Node)>,
    /// The bounding-sphere radius of each kept node ([`super::InnerNodes`]).
    kept_sphere: Vec<f32>,
    runs: Vec<Spill>,
    inner: super::InnerNodes,
    /// The extent of the nodes in the runs (the kept ones are added at the end: each node
    /// once, as the in-memory build adds them).
    extent: Extent,
    progress: &'a dyn Progress,
}

impl Walk<'_> {
    /// Samples in cell `c`, from the units (the walk only asks for cells at or above them).
    fn count(&self, c: Cell) -> u64 {
        let (lo, hi) = c.codes();
        let from = self.units.partition_point(|u| u.cell.codes().1 <= lo);
        self.units[from..]
            .iter()
            .take_while(|u| u.cell.codes().0 < hi)
            .map(|u| u.n)
            .sum()
    }

    /// The subtree of cell `c` (samples `n`), as the in-memory `subtree` makes it: (index
    /// into `kept`, height).
    fn cell(&mut self, c: Cell, n: u64) -> Result<(usize, u32), MethodError> {
        let unit = self.units.get(self.next_unit);
        if unit.is_some_and(|u| u.cell == c) {
            return self.unit();
        }
        // Above the units: more than the capacity, so more than one sample.
        let kids: Vec<(Cell, u64)> = (0..8)
            .map(|o| c.child(o))
            .map(|k| (k, self.count(k)))
            .filter(|&(_, m)| m > 0)
            .collect();
        debug_assert_eq!(kids.iter().map(|k| k.1).sum::<u64>(), n);
        if kids.len() == 1 {
            return self.cell(kids[0].0, kids[0].1);
        }
        let mut children = Vec::with_capacity(kids.len());
        let mut height = 0;
        for (k, m) in kids {
            let (i, h) = self.cell(k, m)?;
            children.push(i);
            height = height.max(h);
        }
        let nodes: Vec<Node> = children.iter().map(|&i| self.kept[i].1).collect();
        let node = build::inner_node(
            &nodes,
            self.has_normals,
            self.has_colors,
            self.p.color_threshold,
        );
        let id = self.next_id;
        self.next_id += 1;
        let sphere = super::InnerNodes::sphere(
            node.p,
            children
                .iter()
                .map(|&i| (self.kept[i].1.p, self.kept_sphere[i])),
        );
        self.inner.add(&node, sphere);
        self.kept_sphere.push(sphere);
        let me = self.kept.len();
        for &i in &children {
            self.kept[i].1.parent = id as u32;
        }
        self.kept.push((id, node));
        Ok((me, height + 1))
    }

    /// Builds the next unit: its sorted run of non-root nodes; its root is kept.
    fn unit(&mut self) -> Result<(usize, u32), MethodError> {
        let u = self.next_unit;
        self.next_unit += 1;
        let unit = &self.units[u];
        let s = (self.load)(u)?;
        let mut bld = Builder::new(s.view(), self.grid, self.p.color_threshold, false);
        let (_, height) = bld.subtree(0, s.pos.len(), BITS - unit.cell.depth);
        let nodes = std::mem::take(&mut bld.nodes);
        drop(bld);
        drop(s);
        let base = self.next_id;
        let (p, has_n) = (self.p, self.has_normals);
        let root = nodes.len() - 1;
        self.extent = std::mem::take(&mut self.extent).merge(&Extent::of(&nodes[..root]));
        // Small blocks: every run has a reader open during the merge.
        let rr = RunRecord {
            normals: self.has_normals,
            colors: self.has_colors,
        };
        let mut w = self.dir.writer_with_block("run", rr.bytes(), 1 << 16)?;
        let cluster = |nd: &Node| cluster_of(p, has_n, nd.n);
        match rr.bytes() {
            36 => sorted_run::<36>(rr, &nodes, base, cluster, &mut w)?,
            40 => sorted_run::<40>(rr, &nodes, base, cluster, &mut w)?,
            52 => sorted_run::<52>(rr, &nodes, base, cluster, &mut w)?,
            56 => sorted_run::<56>(rr, &nodes, base, cluster, &mut w)?,
            b => return Err(MethodError::Bug(format!("spt: a run record of {b} bytes"))),
        }
        self.runs.push(w.finish()?);
        // The unit's root is counted here and not again when it is kept.
        let (counted, root_sphere) = super::InnerNodes::of(&nodes);
        self.inner.merge(counted);
        self.kept_sphere.push(root_sphere);
        self.next_id += nodes.len() as u64;
        let mut r = nodes[root];
        r.parent = NO_PARENT;
        self.kept.push((self.next_id - 1, r));
        self.progress.inc(unit.n);
        Ok((self.kept.len() - 1, height))
    }
}

/// Builds the tree in units and writes the list's files (not `index.json`).
pub(crate) fn list_in_units(
    cloud: &PointCloud,
    p: &SptParams,
    budget: Budget<'_>,
    progress: &dyn Progress,
    t0: Instant,
) -> Result<Listed, MethodError> {
    let n = cloud.len();
    let cap = unit_capacity(budget.mem_bytes);
    let layout = SampleLayout::of(cloud);
    let grid = MortonGrid::new(cloud.bounds());
    let dir = SpillDir::create(budget.dir, "spt-spill")?;
    progress.start("spt: cells and units", n as u64);
    let units = route(cloud, grid, cap, layout, &dir)?;
    progress.finish();
    if let Some(h) = budget.hook {
        h(&units.iter().map(|u| &u.spill).collect::<Vec<_>>());
    }
    let radii = if layout.radii {
        None
    } else {
        Some(leaf_radii(
            cloud,
            &units,
            layout,
            budget.mem_bytes,
            &dir,
            progress,
        )?)
    };
    let capped = std::cell::Cell::new(0u64);
    let load = |u: usize| {
        let r = match &radii {
            Some(r) => {
                let (r, c) = r.load(u)?;
                capped.set(capped.get() + c);
                Some(r)
            }
            None => None,
        };
        samples::load(&units[u].spill, layout, units[u].n as usize, r)
    };
    progress.start("spt: point tree (units)", n as u64);
    let mut walk = Walk {
        p,
        grid,
        has_normals: layout.normals,
        has_colors: layout.colors,
        units: &units,
        next_unit: 0,
        load: &load,
        dir: &dir,
        next_id: 0,
        kept: Vec::new(),
        kept_sphere: Vec::new(),
        runs: Vec::new(),
        inner: super::InnerNodes::default(),
        extent: Extent::default(),
        progress,
    };
    let (_, levels) = walk.cell(Cell::ROOT, n as u64)?;
    progress.finish();
    if walk.next_unit != units.len() {
        return Err(MethodError::Bug(format!(
            "spt: the walk reached {} of {} units",
            walk.next_unit,
            units.len()
        )));
    }
    let tree_seconds = t0.elapsed().as_secs_f64();
    let total = walk.next_id;
    let Walk {
        kept,
        runs,
        inner,
        mut extent,
        ..
    } = walk;
    for (_, nd) in &kept {
        extent.add(nd);
    }
    drop(radii);
    let top = kept_run(&kept, p, layout.normals)?;
    // Step 4: merge.
    let w = ListWriter::create(
        budget.dir,
        cloud.attributes(),
        &extent,
        LodScale::of(cloud.bounds()),
        total,
        p.normal_clusters,
        p.mode == SptMode::Split,
    )?;
    progress.start("spt: writing", total);
    let rr = RunRecord {
        normals: layout.normals,
        colors: layout.colors,
    };
    let w = merge_runs(w, &runs, top, rr, progress)?;
    let index = w.finish(levels)?;
    progress.finish();
    Ok(Listed {
        index,
        inner,
        radii_capped: capped.get(),
        tree_seconds,
        units: runs.len() as u64,
    })
}

/// The leaf radii of the units' samples (for a cloud without radii), computed group of units
/// by group within `mem_bytes` ([`crate::unit_knn`]).
fn leaf_radii(
    cloud: &PointCloud,
    units: &[Unit],
    layout: SampleLayout,
    mem_bytes: u64,
    dir: &SpillDir,
    progress: &dyn Progress,
) -> Result<UnitRadii, MethodError> {
    let boxes: Vec<UnitBox> = units
        .iter()
        .map(|u| UnitBox {
            n: u.n,
            bbox: u.bbox,
        })
        .collect();
    let load = |u: usize| samples::positions(&units[u].spill, layout);
    unit_radii(
        &boxes,
        &load,
        cloud.len(),
        cloud.bounds(),
        mem_bytes,
        dir,
        "spt",
        progress,
    )
}

/// The kept nodes' own run, in memory: their list entries by list key.
fn kept_run(
    kept: &[(u64, Node)],
    p: &SptParams,
    normals: bool,
) -> Result<Vec<(u128, ListNode)>, MethodError> {
    let by_id: HashMap<u64, usize> = kept.iter().enumerate().map(|(i, k)| (k.0, i)).collect();
    let mut top: Vec<(u128, ListNode)> = Vec::with_capacity(kept.len());
    for (id, nd) in kept {
        let parent = (nd.parent != NO_PARENT).then(|| &kept[by_id[&(nd.parent as u64)]].1);
        let lod = lod_entry(nd, parent);
        if !lod.iter().all(|v| v.is_finite()) {
            return Err(non_finite(*id, &lod, nd));
        }
        let cluster = cluster_of(p, normals, nd.n);
        top.push((
            list_key(cluster, &lod, *id as u32),
            ListNode::of(nd, lod, cluster),
        ));
    }
    top.sort_unstable_by_key(|t| t.0);
    Ok(top)
}

/// Step 4: merges the units' `runs` (records `rr`) and the kept nodes' run `top` by list
/// key into `w`: the merge on this thread, the list's encoding and writing on a second one.
fn merge_runs(
    w: ListWriter,
    runs: &[Spill],
    top: Vec<(u128, ListNode)>,
    rr: RunRecord,
    progress: &dyn Progress,
) -> Result<ListWriter, MethodError> {
    let mut readers = runs
        .iter()
        .map(Spill::reader)
        .collect::<Result<Vec<_>, _>>()?;
    overlapped(
        w,
        WRITE_BATCH,
        |w, nodes: Vec<ListNode>| {
            for nd in &nodes {
                w.push(nd)?;
            }
            progress.inc(nodes.len() as u64);
            Ok::<(), MethodError>(())
        },
        |feed| {
            let mut heap: BinaryHeap<Reverse<(u128, usize)>> = BinaryHeap::new();
            let mut heads: Vec<Option<ListNode>> = vec![None; readers.len()];
            for (i, r) in readers.iter_mut().enumerate() {
                if let Some(rec) = r.next_record()? {
                    let (k, nd) = rr.decode(rec);
                    heads[i] = Some(nd);
                    heap.push(Reverse((k, i)));
                }
            }
            let mut top = top.into_iter().peekable();
            loop {
                let from_runs = heap.peek().map(|Reverse((k, _))| *k);
                let from_top = top.peek().map(|t| t.0);
                match (from_runs, from_top) {
                    (None, None) => break,
                    (Some(k), t) if t.is_none_or(|t| k < t) => {
                        let Some(Reverse((_, i))) = heap.pop() else {
                            break;
                        };
                        if let Some(nd) = heads[i].take() {
                            feed.push(nd)?;
                        }
                        if let Some(rec) = readers[i].next_record()? {
                            let (k, nd) = rr.decode(rec);
                            heads[i] = Some(nd);
                            heap.push(Reverse((k, i)));
                        }
                    }
                    _ => {
                        if let Some((_, nd)) = top.next() {
                            feed.push(nd)?;
                        }
                    }
                }
            }
            Ok(())
        },
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A node for [`sorted_run`]'s tests: at `x`, error `e_g`, child of node `parent`.
    fn node(x: f32, e_g: f32, parent: u32) -> Node {
        Node {
            p: Vec3::new(x, 0.0, 0.0),
            n: Vec3::Z,
            r: 1.0,
            e_p: 0.0,
            e_t: 0.0,
            e_g,
            phi_q: 0,
            parent,
            color: [1, 2, 3],
            leaf: parent != NO_PARENT,
        }
    }

    /// The run is sorted by list key, each record that of its node; and of two nodes with
    /// non-finite `lod` entries the error names the first in list order (a NaN error sorts
    /// before an infinite one: descending total order), not the first by index.
    #[test]
    fn a_unit_run_is_in_list_order_and_its_error_is_the_first_in_that_order() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SpillDir::create(tmp.path(), "t").unwrap();
        let rr = RunRecord {
            normals: false,
            colors: true,
        };
        let cluster = |_: &Node| 0;
        let nodes = [
            node(0.0, 1.0, 3),
            node(1.0, 3.0, 3),
            node(2.0, 2.0, 3),
            node(1.0, 4.0, NO_PARENT),
        ];
        let mut w = dir.writer("run", rr.bytes()).unwrap();
        sorted_run::<40>(rr, &nodes, 7, cluster, &mut w).unwrap();
        let run = w.finish().unwrap();
        let mut got = Vec::new();
        run.read(|b| {
            got.extend(b.chunks_exact(40).map(|r| rr.decode(r)));
            Ok(())
        })
        .unwrap();
        let keys: Vec<u128> = got.iter().map(|g| g.0).collect();
        // Parent error equal: own error descending, so nodes 1, 2, 0 (ids 8, 9, 7).
        assert_eq!(
            keys.iter().map(|&k| k as u32).collect::<Vec<_>>(),
            [8, 9, 7]
        );
        for (k, nd) in &got {
            let i = (*k as u32 - 7) as usize;
            assert_eq!(nd.p, nodes[i].p);
            assert_eq!(nd.lod, lod_entry(&nodes[i], Some(&nodes[3])));
        }
        let bad = [
            node(0.0, 1.0, 3),
            node(1.0, f32::INFINITY, 3),
            node(2.0, f32::NAN, 3),
            node(1.0, 4.0, NO_PARENT),
        ];
        let mut w = dir.writer("run", rr.bytes()).unwrap();
        let e = sorted_run::<40>(rr, &bad, 7, cluster, &mut w).unwrap_err();
        assert!(e.to_string().contains("node 9 "), "{e}");
    }

    #[test]
    fn run_records_give_back_the_node_and_its_list_key_with_every_attribute_set() {
        for (normals, colors) in [(false, false), (false, true), (true, false), (true, true)] {
            let rr = RunRecord { normals, colors };
            let nd = ListNode {
                p: Vec3::new(1.5, -2.25, 1e-30),
                n: if normals {
                    Vec3::new(0.6, 0.0, -0.8)
                } else {
                    Vec3::Z
                },
                color: if colors { [255, 7, 0] } else { [0; 3] },
                r: 0.125,
                lod: [3.0, f32::MIN_POSITIVE, 0.0, -0.0],
                cluster: if normals { 41 } else { 0 },
            };
            let id = 0xDEAD_BEEF;
            let mut rec = vec![0u8; rr.bytes()];
            rr.encode(id, &nd, &mut rec);
            let (key, back) = rr.decode(&rec);
            assert_eq!(back, nd, "normals {normals} colors {colors}");
            assert_eq!(key, list_key(nd.cluster, &nd.lod, id));
            // Only what the scene has: 36 bytes, + 16 with normals, + 4 with colours.
            assert_eq!(rr.bytes(), 36 + 16 * normals as usize + 4 * colors as usize);
        }
    }
}
