//! The MWKD build in bounded memory (`--param mem_mb=`): the same repository and index,
//! byte for byte, as the in-memory build ([`super::build::write_repository`] over
//! [`Tree::split`]), without a 4-byte index per sample or random reads of the scene file.
//!
//! 1. **Split, streamed.** A node with more than [`unit_capacity`] samples is split as in
//!    memory — along the longest axis of its tight box, child `i` taking the samples of rank
//!    `⌊c/N⌋·i + min(i, c mod N)` onwards in (coordinate, input index) order — by streaming
//!    its sample records ([`crate::spill::samples`]; the root's straight from the cloud's
//!    columns, releasing their pages behind the cursor): the `N − 1` boundary keys come from
//!    one selection ([`split::select_keys`], 2 passes for all of them: counts per slice of
//!    the node's box, then the keys of the slices holding a boundary), and one more
//!    pass routes every record into its child's spill file ([`split::route`], stable, so
//!    each file keeps input order). A node of at most the capacity is a **unit**.
//! 2. **Units, bottom-up.** In post-order over the nodes above the units, a unit is loaded
//!    (its records in input order), split in memory to the whole tree's leaf depth
//!    ([`Tree::split_to_depth`]; its selection keys order like the whole cloud's because
//!    local indices increase with input indices, and leaves are put in input order), and
//!    built by [`bottom_up`] with its node ids mapped to the whole tree's; what its root
//!    holds passes up. A node above the units then gathers its children's representatives.
//!    Nodes are written in post-order as in memory, so the files are the same (tested:
//!    `methods/tests/mwkd_ooc.rs`).
//!
//! Memory: one unit (≤ [`UNIT_BYTES_PER_SAMPLE`] bytes per sample), the held
//! representatives of the open path (`N·s` splats per level), the node array and the spill
//! writers' blocks. Disk: the spill files of one level of the split at a time, about the
//! cloud's records once (`16 + 4 + 12 + 4` bytes per sample at most).
//!
//! Only the balanced trees (`tree=mwkd` and `tree=kd`) are built so; the ablation octree is
//! built in memory. Spill files live in `<dir>/mwkd-spill.tmp/` and are removed on success
//! and on error; a damaged one is an error naming it ([`crate::spill`]).

use std::collections::HashMap;
use std::path::Path;

use glam::Vec3;
use scenes::{Aabb, PointCloud, Progress};

use super::build::{
    Columns, Encoded, Input, LEAF_KNN_MIN, RepoSink, Written, bottom_up, encode_node, inner_held,
};
use super::reps::{RepConfig, Splats};
use super::tree::{NO_PARENT, Node, Tree, leaf_depth};
use crate::MethodError;
use crate::spill::samples::{self, SampleLayout};
use crate::spill::{Budget, Spill, SpillDir, split};

/// Working bytes per sample of a unit: its records as columns (input index 4, position 12,
/// and the scene's radius 4, normal 12 and colour 3 when it has them), the split's items
/// while it runs (16; its order, 4, after) and tree, and the splats of the tasks in flight
/// with their encoded output. Measured: ≈ 27 bytes per unit sample on terrain 10 M
/// (colours, no normals; peak RSS 40.5 MB with 16 units of 625 k, 88.4 MB with 4 of
/// 2.5 M) when the split permuted only the order; with its items, 48 MB with 16 units at
/// `mem_mb=64` (was 43). 64 leaves room for normals and radii (+16) and the tasks' buffers.
pub const UNIT_BYTES_PER_SAMPLE: u64 = 64;

/// Samples of the largest unit built in memory under a budget of `mem_bytes`.
pub fn unit_capacity(mem_bytes: u64) -> u64 {
    (mem_bytes / UNIT_BYTES_PER_SAMPLE).max(1)
}

/// A build in units: the index, the tree's nodes and how it went.
pub struct Built {
    /// What was written.
    pub written: Written,
    /// The tree's nodes (as [`Tree::split`] numbers them).
    pub nodes: Vec<Node>,
    /// Depth of the leaves.
    pub depth: u32,
    /// Units built one at a time.
    pub units: u64,
    /// Seconds of the streamed split (step 1).
    pub split_seconds: f64,
}

/// The shape and settings the build shares with [`Tree::split`].
#[derive(Clone, Copy)]
pub struct Shape {
    /// Fan-out `N`.
    pub fanout: u32,
    /// VBO size `s`.
    pub vbo: u64,
    /// Representative selection.
    pub reps: RepConfig,
    /// How nodes are stored.
    pub compression: crate::store::Compression,
}

struct Unit {
    id: usize,
    spill: Option<Spill>,
}

struct Pending {
    src: Option<Spill>,
    id: usize,
    level: u32,
    start: usize,
    n: u64,
    bbox: (Vec3, Vec3),
}

/// Builds the balanced tree of `cloud` with `shape` into the repository file `repo`, in
/// units of at most [`unit_capacity`]`(budget.mem_bytes)` samples.
pub fn write_repository(
    cloud: &PointCloud,
    shape: Shape,
    repo: &Path,
    budget: Budget<'_>,
    progress: &dyn Progress,
) -> Result<Built, MethodError> {
    let t0 = std::time::Instant::now();
    let n = cloud.len() as u64;
    let nf = shape.fanout as usize;
    let depth = leaf_depth(n, u64::from(shape.fanout), shape.vbo)?;
    let total = (0..=depth)
        .try_fold(0usize, |acc, l| {
            nf.checked_pow(l).and_then(|p| acc.checked_add(p))
        })
        .ok_or_else(|| MethodError::Limit("mwkd: node count overflows".into()))?;
    let cap = unit_capacity(budget.mem_bytes);
    let spill = SpillDir::create(budget.dir, "mwkd-spill")?;
    let layout = SampleLayout::of(cloud);
    let mut b = Builder {
        cloud,
        shape,
        depth,
        layout,
        nodes: vec![
            Node {
                level: 0,
                start: 0,
                len: 0,
                bounds: Aabb::EMPTY,
                first_child: 0,
                child_count: 0,
                parent: NO_PARENT,
            };
            total
        ],
        units: HashMap::new(),
    };
    progress.start("mwkd: split (streamed)", n);
    b.split_top(cap, &spill, progress)?;
    progress.finish();
    if let Some(h) = budget.hook {
        let files: Vec<&Spill> = b.units.values().filter_map(|u| u.spill.as_ref()).collect();
        h(&files);
    }
    let split_seconds = t0.elapsed().as_secs_f64();
    let units = b.units.len() as u64;
    let mut out = RepoSink::create(repo, total)?;
    progress.start("mwkd: nodes", total as u64);
    b.visit(0, &mut out, progress)?;
    progress.finish();
    let written = out.finish(&b.nodes)?;
    Ok(Built {
        written,
        nodes: b.nodes,
        depth,
        units,
        split_seconds,
    })
}

struct Builder<'a> {
    cloud: &'a PointCloud,
    shape: Shape,
    depth: u32,
    layout: SampleLayout,
    nodes: Vec<Node>,
    /// Units by the id of their root.
    units: HashMap<usize, Unit>,
}

impl Builder<'_> {
    /// Step 1: splits every node of more than `cap` samples into its children's spill
    /// files; the others become units.
    fn split_top(
        &mut self,
        cap: u64,
        spill: &SpillDir,
        progress: &dyn Progress,
    ) -> Result<(), MethodError> {
        let nf = self.shape.fanout as usize;
        let bounds = self.cloud.bounds();
        let mut stack = vec![Pending {
            src: None,
            id: 0,
            level: 0,
            start: 0,
            n: self.cloud.len() as u64,
            bbox: (bounds.min, bounds.max),
        }];
        while let Some(r) = stack.pop() {
            let split = r.level < self.depth && (r.n > cap || r.src.is_none());
            self.nodes[r.id] = Node {
                level: r.level,
                start: r.start,
                len: r.n as usize,
                bounds: Aabb {
                    min: r.bbox.0,
                    max: r.bbox.1,
                },
                first_child: if split { (nf * r.id + 1) as u32 } else { 0 },
                child_count: if split { nf as u32 } else { 0 },
                parent: if r.id == 0 {
                    NO_PARENT
                } else {
                    ((r.id - 1) / nf) as u32
                },
            };
            if !split {
                if r.level == self.depth && r.n < LEAF_KNN_MIN as u64 && !self.layout.radii {
                    // In memory such a leaf measures among its parent's samples, which a
                    // unit of its own would not have.
                    return Err(MethodError::Limit(format!(
                        "mwkd: unit {} would be a leaf of {} samples (< {LEAF_KNN_MIN}); \
                         raise mem_mb",
                        r.id, r.n
                    )));
                }
                let src = r.src.ok_or_else(|| {
                    MethodError::Bug("mwkd: the root cannot be a unit out of core".into())
                })?;
                progress.inc(r.n);
                self.units.insert(
                    r.id,
                    Unit {
                        id: r.id,
                        spill: Some(src),
                    },
                );
                continue;
            }
            let (q, rem) = (r.n / nf as u64, r.n % nf as u64);
            let starts: Vec<u64> = (0..=nf as u64).map(|i| i * q + i.min(rem)).collect();
            let axis = self.nodes[r.id].bounds.longest_axis();
            let (cloud, layout) = (self.cloud, self.layout);
            let range = split::key_range(r.bbox.0[axis], r.bbox.1[axis]);
            let pivots = split::select_keys(&starts[1..nf], range, |f| {
                split::scan(r.src.as_ref(), cloud, layout, |rec| {
                    f(split::rank_key(rec, axis));
                    Ok(())
                })
            })?;
            let parts = split::route(r.src.as_ref(), cloud, layout, spill, nf, |rec| {
                let k = split::rank_key(rec, axis);
                pivots.partition_point(|&p| p <= k)
            })?;
            if let Some(s) = r.src {
                s.remove();
            }
            for (i, (count, file, bbox)) in parts.into_iter().enumerate().rev() {
                if count != starts[i + 1] - starts[i] {
                    return Err(MethodError::corrupt(
                        &file.path,
                        format!(
                            "temporary file: child {i} of node {} got {count} samples, {} expected",
                            r.id,
                            starts[i + 1] - starts[i]
                        ),
                    ));
                }
                stack.push(Pending {
                    src: Some(file),
                    id: nf * r.id + 1 + i,
                    level: r.level + 1,
                    start: r.start + starts[i] as usize,
                    n: count,
                    bbox,
                });
            }
        }
        Ok(())
    }

    /// Step 2: builds and writes the subtree of node `id` in post-order; returns what `id`
    /// holds.
    fn visit(
        &mut self,
        id: usize,
        out: &mut RepoSink,
        progress: &dyn Progress,
    ) -> Result<Splats, MethodError> {
        if let Some(unit) = self.units.remove(&id) {
            return self.unit(unit, out, progress);
        }
        let node = self.nodes[id];
        let kids = node.first_child as usize..(node.first_child + node.child_count) as usize;
        let held = kids
            .map(|c| self.visit(c, out, progress))
            .collect::<Result<Vec<_>, _>>()?;
        let empty = Splats::empty(self.layout.normals, self.layout.colors);
        let held = inner_held(&held, self.shape.vbo, &self.shape.reps, empty);
        out.put(id, &node, encode_node(id, &held, self.shape.compression)?)?;
        progress.inc(1);
        Ok(held)
    }

    /// Loads, splits and builds one unit; its nodes are numbered as in the whole tree.
    fn unit(
        &mut self,
        mut unit: Unit,
        out: &mut RepoSink,
        progress: &dyn Progress,
    ) -> Result<Splats, MethodError> {
        let root = self.nodes[unit.id];
        let file = unit
            .spill
            .take()
            .ok_or_else(|| MethodError::Bug(format!("mwkd: unit {} read twice", unit.id)))?;
        let cols = samples::load(&file, self.layout, root.len, None)?;
        file.remove();
        let local = Tree::split_to_depth(
            &cols.pos,
            self.shape.fanout,
            self.shape.vbo,
            self.depth - root.level,
        )?;
        let nf = self.shape.fanout as usize;
        // Local node `li` of local level `l` is the same node of level `root.level + l` of
        // the whole tree, as many places into the unit root's descendants of that level.
        let global = |li: usize| -> usize {
            let l = local.nodes[li].level;
            let k = li - Tree::level_start(nf, l);
            let offset = unit.id - Tree::level_start(nf, root.level);
            Tree::level_start(nf, root.level + l) + offset * nf.pow(l) + k
        };
        for (li, ln) in local.nodes.iter().enumerate() {
            self.nodes[global(li)] = Node {
                level: root.level + ln.level,
                start: root.start + ln.start,
                len: ln.len,
                bounds: ln.bounds,
                first_child: if ln.child_count == 0 {
                    0
                } else {
                    global(ln.first_child as usize) as u32
                },
                child_count: ln.child_count,
                parent: if li == 0 {
                    root.parent
                } else {
                    global(ln.parent as usize) as u32
                },
            };
        }
        let input = Input {
            cols: Columns {
                pos: &cols.pos,
                radii: self.layout.radii.then_some(cols.radii.as_slice()),
                normals: cols.normals.as_deref(),
                colors: cols.colors.as_deref(),
            },
            tree: &local,
            reps: self.shape.reps,
        };
        let nodes = &self.nodes;
        let how = self.shape.compression;
        let map = |li: usize, s: &Splats| encode_node(global(li), s, how);
        bottom_up(
            &input,
            (root.len / 16).max(1),
            &map,
            &mut |li, e: Encoded| {
                let g = global(li);
                out.put(g, &nodes[g], e)
            },
            progress,
        )
    }
}
