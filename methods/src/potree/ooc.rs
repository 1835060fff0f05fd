//! The build in units, for clouds larger than `mem_mb` allows (PotreeConverter's chunking,
//! Schütz et al. 2020 §4.1, in our terms):
//!
//! 1. **Count**: every point's Morton code; counts per cell of the level-[`GRID_LEVEL`] grid
//!    over the cube (128³ cells).
//! 2. **Plan**: from the root down, a node of more points than a unit may hold is split
//!    (the in-core build splits it too: a unit holds at least `max_leaf` points); the
//!    others become *units*, in Morton order. A grid cell denser than a unit stays one unit
//!    (recorded as `largest_unit`): the grid is the finest this pass splits.
//! 3. **Route**: one pass over the cloud appends (code, index) to its unit's spill file.
//! 4. **Units**, one after the other: sort, split, sample (as in core); every node but the
//!    unit's root is encoded into a second spill file, breadth first; the root, with its
//!    points, joins the top.
//! 5. **Top**: the nodes above the units sample from the units' roots, bottom up.
//! 6. **Files**: nodes breadth first, unit nodes copied from their spill files in order.
//!
//! A node's sample depends only on its children's points, and points are numbered by their
//! global Morton rank in both builds: the files are byte-identical to the in-core build's
//! (`methods/tests/potree.rs`).

use glam::DVec3;
use rayon::prelude::*;
use scenes::{PointCloud, Progress};

use super::octree::{self, Fill, Loose, MORTON_BITS, Node, Quant, Sorted};
use super::write::{self, Desc, Src};
use crate::MethodError;
use crate::spill::{Budget, Spill, SpillDir};

/// Level of the counting grid (8⁷ = 2,097,152 cells; 16 MiB of counts and unit numbers).
pub const GRID_LEVEL: u32 = 7;
/// Working memory a unit takes per point (codes, ranks, integer positions, node lists,
/// sampling candidates), bytes: a unit holds at most `mem_mb·2²⁰ / 64` points.
pub const UNIT_BYTES_PER_POINT: u64 = 64;
/// Block size of the spill files (many are read at once while the files are written).
const SPILL_BLOCK: usize = 1 << 16;

/// Points a unit may hold within `mem_bytes`.
pub fn unit_capacity(mem_bytes: u64) -> u64 {
    mem_bytes / UNIT_BYTES_PER_POINT
}

/// A planned unit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Unit {
    /// Level of its root.
    pub level: u32,
    /// Octant digits of its root.
    pub path: u64,
    /// Points.
    pub count: u64,
}

/// Plans units over `prefix` (prefix sums of the grid's cell counts, `8^GRID_LEVEL + 1`
/// entries): nodes of more than `cap` points are split, down to the grid's level.
pub fn plan(prefix: &[u64], cap: u64) -> Vec<Unit> {
    fn visit(prefix: &[u64], cap: u64, level: u32, path: u64, out: &mut Vec<Unit>) {
        let shift = 3 * (GRID_LEVEL - level);
        let lo = (path << shift) as usize;
        let hi = ((path + 1) << shift) as usize;
        let count = prefix[hi] - prefix[lo];
        if count == 0 {
            return;
        }
        if count > cap && level < GRID_LEVEL {
            for o in 0..8 {
                visit(prefix, cap, level + 1, (path << 3) | o, out);
            }
        } else {
            out.push(Unit { level, path, count });
        }
    }
    let mut out = Vec::new();
    visit(prefix, cap, 0, 0, &mut out);
    out
}

/// The grid cell (level-[`GRID_LEVEL`] path) of a Morton code.
fn cell_of(code: u64) -> usize {
    (code >> (3 * (MORTON_BITS - GRID_LEVEL))) as usize
}

/// What [`build_files`] made.
pub struct Built {
    /// The files written.
    pub written: write::Written,
    /// Units (1 in core).
    pub units: u64,
    /// Points of the largest unit (the cloud's in core).
    pub largest_unit: u64,
}

/// What an octree build in the Potree format is made of.
pub struct Tree<'a, F> {
    /// The points.
    pub cloud: &'a PointCloud,
    /// Their cube and quantisation.
    pub quant: Quant,
    /// Leaf capacity: a node of more points is split.
    pub max_leaf: u32,
    /// What fills the inner nodes.
    pub fill: &'a F,
    /// The metadata (hierarchy sizes filled in by the files' writer).
    pub meta: crate::potree::format::Metadata,
}

/// Builds `tree`'s octree (nodes of at most `max_leaf` points, inner nodes filled by `fill`)
/// into the Potree files in `budget.dir`: in core when the cloud fits `budget.mem_bytes`
/// ([`unit_capacity`]), else in units of at most that many points. Both give the same files
/// byte for byte.
pub fn build_files<F: Fill>(
    tree: Tree<'_, F>,
    budget: Budget<'_>,
    progress: &dyn Progress,
) -> Result<Built, MethodError> {
    let n = tree.cloud.len();
    if n as u64 > unit_capacity(budget.mem_bytes) {
        return build(tree, budget, progress);
    }
    let (cloud, quant, fill) = (tree.cloud, tree.quant, tree.fill);
    let name = fill.name();
    progress.start(&format!("{name}: sort"), n as u64);
    let sorted = Sorted::of_cloud(cloud, quant);
    progress.finish();
    progress.start(&format!("{name}: octree"), n as u64);
    let at = Node::at(0, 0, (quant.min, quant.min + DVec3::splat(quant.size)));
    let max_leaf = tree.max_leaf as usize;
    let mut root = octree::split(&sorted, 0..n, at, max_leaf, fill.splits_root());
    fill.fill(&mut root, &sorted);
    progress.finish();
    let mut descs = Vec::new();
    fill.describe(root, &mut descs);
    let written = write::write_files(cloud, tree.meta, &mut descs, &sorted, &mut [], budget.dir)?;
    Ok(Built {
        written,
        units: 1,
        largest_unit: n as u64,
    })
}

/// [`build_files`] in units of at most `budget.mem_bytes / 64` points.
fn build<F: Fill>(
    tree: Tree<'_, F>,
    budget: Budget<'_>,
    progress: &dyn Progress,
) -> Result<Built, MethodError> {
    let Tree {
        cloud,
        quant,
        max_leaf,
        fill,
        meta,
    } = tree;
    let n = cloud.len();
    let name = fill.name();
    let origin = cloud.origin();
    let pos = cloud.positions();
    let code_of = |i: usize| quant.morton(quant.of_local(origin, pos[i]));
    // 1. Count.
    progress.start(&format!("{name}: count"), n as u64);
    let prefix = count_cells(n, &code_of);
    progress.finish();
    // 2. Plan.
    let cap = unit_capacity(budget.mem_bytes).max(u64::from(max_leaf));
    let units = plan(&prefix, cap);
    let (unit_of, bases) = unit_cells(&units, &prefix);
    drop(prefix);
    // 3. Route.
    let spill = SpillDir::create(budget.dir, &format!("{name}-units"))?;
    progress.start(&format!("{name}: route"), n as u64);
    let routed = route(cloud, &code_of, &unit_of, units.len(), &spill)?;
    drop(unit_of);
    progress.finish();
    if let Some(hook) = budget.hook {
        hook(&routed.iter().collect::<Vec<_>>());
    }
    // 4. Units.
    progress.start(&format!("{name}: units"), n as u64);
    let builder = UnitBuilder {
        cloud,
        quant,
        max_leaf,
        fill,
        spill: &spill,
        root_box: (quant.min, quant.min + DVec3::splat(quant.size)),
        bpp: meta
            .layout(&budget.dir.join(crate::potree::format::METADATA_FILE))?
            .bytes_per_point,
    };
    let mut built = BuiltUnits {
        descs: Vec::new(),
        encoded: Vec::with_capacity(units.len()),
        roots: Vec::with_capacity(units.len()),
        loose: Vec::new(),
        largest: 0,
    };
    for (k, (u, routed)) in units.iter().zip(routed).enumerate() {
        builder.unit(k, u, routed, bases[k], &mut built)?;
        progress.inc(u.count);
    }
    progress.finish();
    let BuiltUnits {
        mut descs,
        encoded,
        roots,
        loose,
        largest,
    } = built;
    // 5. Top: the nodes above the units, filled from the units' roots.
    let loose = builder.top(roots, loose, &mut descs);
    // 6. Files.
    let mut readers = encoded
        .iter()
        .map(Spill::reader)
        .collect::<Result<Vec<_>, _>>()?;
    let written = write::write_files(cloud, meta, &mut descs, &loose, &mut readers, budget.dir)?;
    Ok(Built {
        written,
        units: units.len() as u64,
        largest_unit: largest,
    })
}

/// Step 1: the prefix sums of the points per cell of the counting grid (`8^GRID_LEVEL + 1`
/// entries), point `i` of `n` having Morton code `code_of(i)`.
fn count_cells(n: usize, code_of: &(impl Fn(usize) -> u64 + Sync)) -> Vec<u64> {
    let cells = 1usize << (3 * GRID_LEVEL);
    let counts = (0..n)
        .into_par_iter()
        .fold(
            || vec![0u32; cells],
            |mut c, i| {
                c[cell_of(code_of(i))] += 1;
                c
            },
        )
        .reduce(
            || vec![0u32; cells],
            |mut a, b| {
                a.iter_mut().zip(&b).for_each(|(x, y)| *x += y);
                a
            },
        );
    let mut prefix = Vec::with_capacity(cells + 1);
    prefix.push(0u64);
    for c in &counts {
        prefix.push(prefix.last().copied().unwrap_or(0) + u64::from(*c));
    }
    prefix
}

/// The unit of each grid cell (`u32::MAX`: none), and each unit's first global rank.
fn unit_cells(units: &[Unit], prefix: &[u64]) -> (Vec<u32>, Vec<u32>) {
    let cells = 1usize << (3 * GRID_LEVEL);
    let mut unit_of = vec![u32::MAX; cells];
    let mut bases = Vec::with_capacity(units.len());
    for (k, u) in units.iter().enumerate() {
        let shift = 3 * (GRID_LEVEL - u.level);
        let (lo, hi) = ((u.path << shift) as usize, ((u.path + 1) << shift) as usize);
        unit_of[lo..hi].fill(k as u32);
        bases.push(prefix[lo] as u32);
    }
    (unit_of, bases)
}

/// Step 3: one pass over the cloud appends each point's (code, index) to its unit's spill
/// file (`unit_of`: the unit of each grid cell; `units` of them).
fn route(
    cloud: &PointCloud,
    code_of: &impl Fn(usize) -> u64,
    unit_of: &[u32],
    units: usize,
    spill: &SpillDir,
) -> Result<Vec<Spill>, MethodError> {
    let mut writers = (0..units)
        .map(|_| spill.writer_with_block("route", 12, SPILL_BLOCK))
        .collect::<Result<Vec<_>, _>>()?;
    let mut rec = [0u8; 12];
    for i in 0..cloud.len() {
        let code = code_of(i);
        rec[..8].copy_from_slice(&code.to_le_bytes());
        rec[8..].copy_from_slice(&(i as u32).to_le_bytes());
        writers[unit_of[cell_of(code)] as usize].push(&rec)?;
        if i % (1 << 16) == 0 {
            cloud.release_pages(i.saturating_sub(1 << 16)..i);
        }
    }
    writers
        .into_iter()
        .map(|w| w.finish())
        .collect::<Result<_, _>>()
}

/// What step 4 has made of the units so far.
struct BuiltUnits<E> {
    /// Every node below a unit's root.
    descs: Vec<Desc>,
    /// Per unit, the spill file of those nodes' points.
    encoded: Vec<Spill>,
    /// Per unit, its root (with its points).
    roots: Vec<Node<E>>,
    /// The units' roots' points: (rank, integer position, input index).
    loose: Vec<(u32, [i32; 3], u32)>,
    /// Points of the largest unit.
    largest: u64,
}

/// What steps 4 and 5 build the nodes with.
struct UnitBuilder<'a, F> {
    cloud: &'a PointCloud,
    quant: Quant,
    max_leaf: u32,
    fill: &'a F,
    spill: &'a SpillDir,
    /// The root's box.
    root_box: (DVec3, DVec3),
    /// Bytes per point in the files.
    bpp: usize,
}

impl<F: Fill> UnitBuilder<'_, F> {
    /// Step 4 for unit `k` (`u`, its points routed to `routed`, which is removed; `base`:
    /// its first global rank): sort, split, fill as in core; every node but the root is
    /// encoded into a spill file, breadth first; the root, with its points, joins the top.
    fn unit(
        &self,
        k: usize,
        u: &Unit,
        routed: Spill,
        base: u32,
        out: &mut BuiltUnits<F::Extra>,
    ) -> Result<(), MethodError> {
        let (cloud, bpp) = (self.cloud, self.bpp);
        let mut keyed = Vec::with_capacity(u.count as usize);
        routed.read(|block| {
            for r in block.chunks_exact(12) {
                let code = u64::from_le_bytes(r[..8].try_into().unwrap_or([0; 8]));
                let idx = u32::from_le_bytes(r[8..].try_into().unwrap_or([0; 4]));
                keyed.push((code, idx));
            }
            Ok(())
        })?;
        routed.remove();
        out.largest = out.largest.max(keyed.len() as u64);
        let sorted = Sorted::new(cloud, self.quant, base, keyed);
        let at = Node::at(u.level, u.path, self.root_box);
        let max_leaf = self.max_leaf as usize;
        let mut root = octree::split(
            &sorted,
            0..sorted.len(),
            at,
            max_leaf,
            self.fill.splits_root(),
        );
        self.fill.fill(&mut root, &sorted);
        // Every node below the root, breadth first, encoded into the unit's file.
        root.outer_mask = root.child_mask();
        let mut below = Vec::new();
        for c in std::mem::take(&mut root.children).into_iter().flatten() {
            self.fill.describe(*c, &mut below);
        }
        below.sort_unstable_by_key(|d| (d.level, d.path));
        let mut w = self.spill.writer_with_block("unit", bpp, SPILL_BLOCK)?;
        let mut buf = vec![0u8; bpp];
        for d in below {
            match &d.src {
                Src::Ids(ids) => {
                    for &id in ids {
                        let i = sorted.order[(id - sorted.base) as usize];
                        write::encode(
                            cloud,
                            i as usize,
                            sorted.q[(id - sorted.base) as usize],
                            &mut buf,
                        );
                        w.push(&buf)?;
                    }
                }
                Src::Encoded(records) => {
                    for r in records.chunks_exact(bpp) {
                        w.push(r)?;
                    }
                }
                Src::Unit(_) => {}
            }
            out.descs.push(Desc {
                src: Src::Unit(k),
                ..d
            });
        }
        out.encoded.push(w.finish()?);
        for &id in &root.points {
            let j = (id - sorted.base) as usize;
            out.loose.push((id, sorted.q[j], sorted.order[j]));
        }
        out.roots.push(root);
        Ok(())
    }

    /// Step 5: the nodes above the units, filled from the units' `roots` (whose points are
    /// `loose`), described into `descs`; returns the points by rank.
    fn top(
        &self,
        roots: Vec<Node<F::Extra>>,
        mut loose: Vec<(u32, [i32; 3], u32)>,
        descs: &mut Vec<Desc>,
    ) -> Loose {
        loose.sort_unstable_by_key(|l| l.0);
        let loose = Loose {
            points: loose,
            quant: self.quant,
        };
        let mut top = Node::at(0, 0, self.root_box);
        for r in roots {
            insert(&mut top, r, self.root_box);
        }
        self.fill.fill(&mut top, &loose);
        self.fill.describe(top, descs);
        loose
    }
}

/// Puts unit root `r` into the top tree under `top`, creating the nodes on the way.
fn insert<E: Default>(top: &mut Node<E>, r: Node<E>, root_box: (DVec3, DVec3)) {
    if r.level == top.level {
        // The unit is the whole cloud's root.
        *top = r;
        return;
    }
    let digit = ((r.path >> (3 * (r.level - top.level - 1))) & 7) as usize;
    if top.level + 1 == r.level {
        top.children[digit] = Some(Box::new(r));
        return;
    }
    let child = top.children[digit].get_or_insert_with(|| {
        Box::new(Node::at(
            top.level + 1,
            (top.path << 3) | digit as u64,
            root_box,
        ))
    });
    insert(child, r, root_box);
}
