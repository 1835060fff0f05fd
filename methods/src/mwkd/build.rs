//! The MWKD build: split, then representatives bottom-up, every node encoded
//! ([`super::codec`]), LZO-compressed and checksummed into `repo.bin` ([`crate::store`]),
//! and the index array ([`super::index`]) last.
//!
//! **Bottom-up, one path at a time.** [`bottom_up`] walks the tree in post-order: a node's
//! children are finished (encoded and handed on) before the node itself, and a finished
//! child passes up only its `t_i` representatives. What is held at any moment is the data
//! of one root-to-leaf path (≤ `N·s` splats per level) plus the output not yet written, so
//! memory does not grow with the model (the paper's "out-of-core friendly" bottom-up build).
//!
//! **Parallel and deterministic.** The tree is cut into *tasks*: the highest nodes with at
//! most `task_points` samples under them (found depth first). Tasks run `threads` at a time,
//! each in post-order with its own output buffer; the nodes are handed on in the tree's
//! post-order whatever the cut (a task's buffer once it is its turn, a node above the tasks
//! once its children are). The repository is thus byte-identical for any thread count and
//! any `task_points` (tests `build_is_deterministic_for_any_thread_count`,
//! `the_in_memory_files_do_not_depend_on_mem_mb`).
//!
//! **Split.** [`Tree::split`] permutes the samples' positions with their input indices
//! (16 bytes per sample while it runs, a 4-byte index per sample after); a cloud larger
//! than one unit of `mem_mb` is split by streaming instead and built unit by unit
//! ([`super::ooc`]), into the same files.
//!
//! **Leaf radii**: the scene's radii if it has them, else the distance to the 8th nearest
//! neighbour ([`scenes::spacing`], as `full`) computed within the leaf ([`leaf_radii`]): a
//! sample near a leaf's border finds its neighbours on one side only and gets a somewhat
//! larger radius, and radii are capped at [`LEAF_RADIUS_CAP`] × the leaf's median (slivers).
//! This keeps the build one leaf at a time.

use glam::Vec3;
use rayon::prelude::*;
use scenes::{PointCloud, Progress};

use super::MwkdParams;
use super::codec;
use super::index::IndexNode;
use super::reps::{RepConfig, Splats, representatives};
use super::tree::{Node, Tree, child_targets};
use crate::MethodError;
use crate::cull::Cone;
use crate::store::{self, RepoWriter};

/// Leaves with fewer samples than this take their k-NN radii from their parent's samples.
pub const LEAF_KNN_MIN: usize = 64;

/// The samples a tree's [`Tree::order`] indexes: a cloud's columns, or a unit's
/// ([`super::ooc`]).
#[derive(Debug, Clone, Copy)]
pub struct Columns<'a> {
    /// Positions.
    pub pos: &'a [[f32; 3]],
    /// The scene's radii, when it has them.
    pub radii: Option<&'a [f32]>,
    /// Normals, when the scene has them.
    pub normals: Option<&'a [[f32; 3]]>,
    /// Colours, when the scene has them.
    pub colors: Option<&'a [[u8; 3]]>,
}

impl<'a> Columns<'a> {
    /// The columns of `cloud`.
    pub fn of(cloud: &'a PointCloud) -> Self {
        Self {
            pos: cloud.positions(),
            radii: cloud.radii(),
            normals: cloud.normals(),
            colors: cloud.colors(),
        }
    }

    /// No splats, with the optional columns these samples have.
    pub fn empty(&self) -> Splats {
        Splats::empty(self.normals.is_some(), self.colors.is_some())
    }
}

/// What a leaf holds: its samples, with the scene's radii or the within-leaf k-NN spacing
/// ([`leaf_radii`]; a leaf of fewer than [`LEAF_KNN_MIN`] samples — an octree octant that
/// clips a corner of the surface — measures among its parent's samples, of which its own are
/// a contiguous run: alone, one sample has no neighbour and three have only each other).
pub fn leaf_splats(cols: Columns<'_>, tree: &Tree, i: usize) -> Splats {
    let node = &tree.nodes[i];
    let idx = &tree.order[node.range()];
    let pos = cols.pos;
    let gather = |idx: &[u32]| -> Vec<[f32; 3]> { idx.iter().map(|&j| pos[j as usize]).collect() };
    let positions = gather(idx);
    let radii = match (cols.radii, tree.parent(i)) {
        (Some(r), _) => idx.iter().map(|&j| r[j as usize]).collect(),
        (None, Some(p)) if idx.len() < LEAF_KNN_MIN => {
            let parent = &tree.nodes[p];
            let all = leaf_radii(&gather(&tree.order[parent.range()]));
            let at = node.start - parent.start;
            all[at..at + idx.len()].to_vec()
        }
        (None, _) => leaf_radii(&positions),
    };
    Splats {
        positions: positions.into_iter().map(Vec3::from).collect(),
        normals: cols
            .normals
            .map(|n| idx.iter().map(|&j| Vec3::from(n[j as usize])).collect()),
        colors: cols
            .colors
            .map(|c| idx.iter().map(|&j| c[j as usize].map(f32::from)).collect()),
        radii,
        weights: vec![1; idx.len()],
    }
}

/// Largest leaf radius from k-NN spacing, as a multiple of the leaf's median radius.
pub const LEAF_RADIUS_CAP: f32 = 3.0;

/// Splat radii of a leaf's samples without scene radii: the k-NN spacing within the leaf
/// ([`scenes::spacing::knn_spacing`], `k` = 8, as `full`), capped at
/// [`LEAF_RADIUS_CAP`] × the leaf's median. The cap matters where a leaf's box clips a
/// sliver of another part of the surface: its few samples find their 8 neighbours only
/// far away, and one such radius (36 × the mean on a 200 K statue) became a 110-pixel
/// square that every ancestor inherited through its covering radii. A sample's true
/// spacing is that of the surface around it, which the leaf's median estimates.
pub fn leaf_radii(positions: &[[f32; 3]]) -> Vec<f32> {
    let mut r: Vec<f32> = scenes::spacing::knn_spacing(positions, scenes::spacing::DEFAULT_K)
        .into_iter()
        .map(scenes::spacing::radius_from_spacing)
        .collect();
    if r.len() > 2 {
        let mut sorted = r.clone();
        let mid = sorted.len() / 2;
        let (_, median, _) = sorted.select_nth_unstable_by(mid, f32::total_cmp);
        let cap = *median * LEAF_RADIUS_CAP;
        for v in &mut r {
            *v = v.min(cap);
        }
    }
    r
}

/// What an inner node holds: the `t_k` representatives of what each child `k` holds
/// ([`child_targets`] for as many children as `held` has), concatenated in child order.
pub fn inner_held(held: &[Splats], vbo: u64, reps: &RepConfig, mut out: Splats) -> Splats {
    let targets = child_targets(held.len() as u64, vbo);
    for (h, &t) in held.iter().zip(&targets) {
        out.append(&representatives(h, t as usize, reps).reps);
    }
    out
}

/// The tree and what the build needs to read for it.
pub struct Input<'a> {
    /// The samples the tree's order indexes.
    pub cols: Columns<'a>,
    /// Their split.
    pub tree: &'a Tree,
    /// Representative selection settings.
    pub reps: RepConfig,
}

impl Input<'_> {
    /// What inner node `i` holds, from what its children hold.
    fn inner(&self, held: &[Splats]) -> Splats {
        inner_held(held, self.tree.vbo, &self.reps, self.cols.empty())
    }

    /// Post-order over the subtree of `i`: every node below `i` goes through `emit`, and what
    /// `i` holds is returned (its samples for a leaf, the concatenated representatives its
    /// children pass up for an inner node).
    fn subtree(
        &self,
        i: usize,
        emit: &mut dyn FnMut(usize, &Splats) -> Result<(), MethodError>,
    ) -> Result<Splats, MethodError> {
        if self.tree.is_leaf(i) {
            return Ok(leaf_splats(self.cols, self.tree, i));
        }
        let mut held = Vec::with_capacity(self.tree.children(i).len());
        for c in self.tree.children(i) {
            let h = self.subtree(c, emit)?;
            emit(c, &h)?;
            held.push(h);
        }
        Ok(self.inner(&held))
    }
}

/// What a task returns: what its root holds, and every node's mapped output in post-order.
type TaskOutput<T> = (Splats, Vec<(usize, T)>);

/// One step of the post-order: a task (a subtree run as a whole) or a node above the tasks.
enum Step {
    Task(usize),
    Node(usize),
}

/// Runs the bottom-up build: every node's held splats go through `map` (on worker threads)
/// and the results through `sink` (on the calling thread) in **post-order** (children in
/// order, then the node), whatever `task_points` and the thread count are; returns what the
/// root holds. `task_points` bounds the samples under one task (see the module docs); each
/// node counts one on `progress`.
pub fn bottom_up<T: Send>(
    input: &Input<'_>,
    task_points: usize,
    map: &(dyn Fn(usize, &Splats) -> Result<T, MethodError> + Sync),
    sink: &mut dyn FnMut(usize, T) -> Result<(), MethodError>,
    progress: &dyn Progress,
) -> Result<Splats, MethodError> {
    let tree = input.tree;
    // The post-order with each task as one step: tasks are the highest nodes with at most
    // `task_points` samples.
    let mut steps = Vec::new();
    let mut stack = vec![(0usize, false)];
    while let Some((i, expanded)) = stack.pop() {
        if expanded {
            steps.push(Step::Node(i));
        } else if tree.is_leaf(i) || tree.nodes[i].len <= task_points.max(1) {
            steps.push(Step::Task(i));
        } else {
            stack.push((i, true));
            stack.extend(tree.children(i).rev().map(|c| (c, false)));
        }
    }
    let tasks: Vec<usize> = steps
        .iter()
        .filter_map(|s| match s {
            Step::Task(t) => Some(*t),
            Step::Node(_) => None,
        })
        .collect();
    let threads = rayon::current_num_threads().max(1);
    let mut held_of: std::collections::HashMap<usize, Splats> = Default::default();
    let mut done: std::collections::HashMap<usize, Vec<(usize, T)>> = Default::default();
    let mut next = 0;
    // One empty batch when there is no task (never: the root is a task or has some below).
    for batch in tasks.chunks(threads) {
        let results: Vec<Result<TaskOutput<T>, MethodError>> = batch
            .par_iter()
            .map(|&t| {
                let mut out = Vec::new();
                let mut emit = |i: usize, s: &Splats| -> Result<(), MethodError> {
                    out.push((i, map(i, s)?));
                    Ok(())
                };
                let held = input.subtree(t, &mut emit)?;
                emit(t, &held)?;
                Ok((held, out))
            })
            .collect();
        for (&t, r) in batch.iter().zip(results) {
            let (held, out) = r?;
            done.insert(t, out);
            held_of.insert(t, held);
        }
        // Every step now ready, in post-order: a task once run, a node above the tasks once
        // its children are (they come before it).
        while let Some(step) = steps.get(next) {
            match *step {
                Step::Task(t) => {
                    let Some(out) = done.remove(&t) else { break };
                    progress.inc(out.len() as u64);
                    for (i, v) in out {
                        sink(i, v)?;
                    }
                }
                Step::Node(i) => {
                    let held = tree
                        .children(i)
                        .map(|c| {
                            held_of.remove(&c).ok_or_else(|| {
                                MethodError::Bug(format!("mwkd build: node {c} missing"))
                            })
                        })
                        .collect::<Result<Vec<_>, _>>()?;
                    let held = input.inner(&held);
                    sink(i, map(i, &held)?)?;
                    progress.inc(1);
                    held_of.insert(i, held);
                }
            }
            next += 1;
        }
    }
    held_of
        .remove(&0)
        .ok_or_else(|| MethodError::Bug("mwkd build: the root was not built".into()))
}

/// One node, encoded and compressed (the output of the disk build's `map`).
pub struct Encoded {
    /// The bytes to store: LZO-compressed, or as is ([`store::Compression::pack`]).
    pub stored: Vec<u8>,
    /// How `stored` was packed.
    pub how: store::Compression,
    /// Uncompressed length.
    pub raw_len: usize,
    /// The codec header (box, radius range, count).
    pub header: codec::NodeHeader,
    /// Mean radius.
    pub radius_mean: f32,
    /// Cone of the node's own normals.
    pub cone: Cone,
}

/// Encodes what node `id` holds and packs it with `how`.
pub fn encode_node(id: usize, s: &Splats, how: store::Compression) -> Result<Encoded, MethodError> {
    let positions: Vec<[f32; 3]> = s.positions.iter().map(|p| p.to_array()).collect();
    let normals: Option<Vec<[f32; 3]>> = s
        .normals
        .as_ref()
        .map(|n| n.iter().map(|v| v.to_array()).collect());
    let colors: Option<Vec<[u8; 3]>> = s.colors.as_ref().map(|c| {
        c.iter()
            .map(|rgb| rgb.map(|v| v.round().clamp(0.0, 255.0) as u8))
            .collect()
    });
    let (raw, header) = codec::encode(&positions, &s.radii, normals.as_deref(), colors.as_deref())
        .map_err(|e| MethodError::Limit(format!("node {id}: {e}")))?;
    let radius_mean =
        (s.radii.iter().map(|&r| f64::from(r)).sum::<f64>() / s.len().max(1) as f64) as f32;
    let cone = match &s.normals {
        Some(n) => Cone::of_normals(n.iter().copied()),
        None => Cone::ALL,
    };
    let raw_len = raw.len();
    Ok(Encoded {
        stored: how.pack(raw),
        how,
        raw_len,
        header,
        radius_mean: radius_mean.clamp(header.radius_min, header.radius_max),
        cone,
    })
}

/// Totals of a disk build.
#[derive(Debug, Clone, Default)]
pub struct Written {
    /// The index array.
    pub index: Vec<IndexNode>,
    /// Uncompressed bytes of all nodes.
    pub raw_bytes: u64,
    /// Bytes of `repo.bin`.
    pub repo_bytes: u64,
}

/// Writes nodes into a repository file as they are finished, and their index entries.
pub struct RepoSink {
    writer: RepoWriter,
    index: Vec<IndexNode>,
    cones: Vec<Cone>,
    raw_bytes: u64,
}

impl RepoSink {
    /// Creates `repo` for a tree of `nodes` nodes.
    pub fn create(repo: &std::path::Path, nodes: usize) -> Result<Self, MethodError> {
        Ok(Self {
            writer: RepoWriter::create(repo)?,
            index: vec![IndexNode::default(); nodes],
            cones: vec![Cone::ALL; nodes],
            raw_bytes: 0,
        })
    }

    /// Appends node `i` of the tree, `n`, encoded as `e`.
    pub fn put(&mut self, i: usize, n: &Node, e: Encoded) -> Result<(), MethodError> {
        let chunk = self.writer.append_packed(&e.stored, e.raw_len, e.how)?;
        self.raw_bytes += e.raw_len as u64;
        self.index[i] = IndexNode {
            min: e.header.min,
            max: e.header.max,
            radius_min: e.header.radius_min,
            radius_max: e.header.radius_max,
            radius_mean: e.radius_mean,
            cone_axis: [0.0; 3],
            cone_half_angle: 0.0,
            id: i as u32,
            level: n.level,
            points: e.header.count,
            first_child: if n.child_count == 0 { 0 } else { n.first_child },
            child_count: n.child_count,
            subtree_points: n.len as u64,
            chunk,
        };
        self.cones[i] = e.cone;
        Ok(())
    }

    /// Closes the repository and completes the index with the subtrees' normal cones
    /// (`nodes`: the tree, every node put).
    pub fn finish(mut self, nodes: &[Node]) -> Result<Written, MethodError> {
        // Subtree cones: children have larger indices than their parent.
        for i in (0..self.index.len()).rev() {
            let n = &nodes[i];
            let kids = n.first_child as usize..(n.first_child + n.child_count) as usize;
            if !kids.is_empty() {
                let c =
                    Cone::union(std::iter::once(self.cones[i]).chain(kids.map(|c| self.cones[c])));
                self.cones[i] = c;
            }
            self.index[i].cone_axis = self.cones[i].axis.to_array();
            self.index[i].cone_half_angle = self.cones[i].half_angle;
        }
        let repo_bytes = self.writer.finish()?;
        Ok(Written {
            index: self.index,
            raw_bytes: self.raw_bytes,
            repo_bytes,
        })
    }
}

/// Builds the tree `tree` of `cloud` into `repo` (a repository file, nodes packed with `how`)
/// and returns the index array (not yet written).
pub fn write_repository(
    input: &Input<'_>,
    repo: &std::path::Path,
    task_points: usize,
    how: store::Compression,
    progress: &dyn Progress,
) -> Result<Written, MethodError> {
    let tree = input.tree;
    let mut out = RepoSink::create(repo, tree.nodes.len())?;
    progress.start("mwkd: nodes", tree.nodes.len() as u64);
    bottom_up(
        input,
        task_points,
        &|i, s: &Splats| encode_node(i, s, how),
        &mut |i, e: Encoded| out.put(i, &tree.nodes[i], e),
        progress,
    )?;
    progress.finish();
    out.finish(&tree.nodes)
}

/// The tree with every inner node's representatives (in memory; the disk build is
/// [`write_repository`], which runs the same [`bottom_up`]).
#[derive(Debug, Clone)]
pub struct Lod {
    /// The split.
    pub tree: Tree,
    /// Representatives of inner node `i` (index = node id; empty for leaves).
    pub inner: Vec<Splats>,
}

impl Lod {
    /// Splits `cloud` and builds the representatives bottom-up (deterministic). Leaf splat
    /// radii are the cloud's radii, or else the within-leaf k-NN spacing
    /// ([`leaf_splats`]).
    pub fn build(cloud: &PointCloud, params: &MwkdParams) -> Result<Lod, MethodError> {
        params.validate()?;
        let tree = Tree::split(cloud.positions(), params.fanout, params.vbo)?;
        let mut inner: Vec<Splats> = vec![Splats::default(); tree.nodes.len()];
        let input = Input {
            cols: Columns::of(cloud),
            tree: &tree,
            reps: params.rep_config(),
        };
        let leaf = |i: usize| tree.is_leaf(i);
        bottom_up(
            &input,
            (cloud.len() / 8).max(1),
            &|i, s: &Splats| Ok((!leaf(i)).then(|| s.clone())),
            &mut |i, s| {
                if let Some(s) = s {
                    inner[i] = s;
                }
                Ok(())
            },
            &scenes::NoProgress,
        )?;
        Ok(Lod { tree, inner })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tiny_octree_leaves_measure_among_their_parents_samples() {
        // A dense 30 × 30 grid at z = 0 and one sample just across the octree's centre
        // plane: its octant holds it alone.
        let mut p: Vec<[f32; 3]> = (0..900)
            .map(|i| [(i % 30) as f32 * 0.01, (i / 30) as f32 * 0.01, 0.0])
            .collect();
        p.push([0.3, 0.3, 0.301]);
        let cloud = PointCloud::new(glam::DVec3::ZERO, p.into(), None, None, None).unwrap();
        let tree = Tree::octree(cloud.positions(), 800, 24).unwrap();
        let lone = (0..tree.nodes.len())
            .find(|&i| tree.is_leaf(i) && tree.nodes[i].len == 1)
            .unwrap();
        let r = leaf_splats(Columns::of(&cloud), &tree, lone).radii[0];
        // Its 8th neighbour among the parent's samples, not the 1.0 fallback of a lone sample.
        assert!(r > 0.01 && r < 0.35, "{r}");
    }

    #[test]
    fn leaf_radii_cap_slivers() {
        // A 40 × 40 grid of spacing 0.01 and three samples far away in the same leaf.
        let mut p: Vec<[f32; 3]> = (0..1600)
            .map(|i| [(i % 40) as f32 * 0.01, (i / 40) as f32 * 0.01, 0.0])
            .collect();
        p.extend([[5.0, 5.0, 0.0], [5.01, 5.0, 0.0], [5.0, 5.01, 0.0]]);
        let r = leaf_radii(&p);
        let plain = scenes::spacing::knn_spacing(&p, scenes::spacing::DEFAULT_K);
        assert!(
            plain[1601] > 5.0,
            "uncapped, the sliver reaches across: {}",
            plain[1601]
        );
        let median = 0.03f32; // the 8th neighbour on a grid of spacing 0.01 is ~0.022–0.03 away
        for (i, v) in r.iter().enumerate() {
            assert!(*v <= LEAF_RADIUS_CAP * median + 1e-6, "sample {i}: {v}");
            assert!(*v > 0.0);
        }
        // Samples of the grid keep their own spacing.
        assert_eq!(r[820], plain[820]);
    }
}
