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
//! each in post-order with its own output buffer; buffers are written in task order, then
//! the nodes above the tasks in post-order on the calling thread. The repository is thus
//! byte-identical for any thread count (test `mwkd_build_is_deterministic_for_any_thread_count`).
//!
//! **The split is in core**: [`Tree::split`] permutes a 4-byte index per sample over the
//! (memory-mapped) positions, e.g. 400 MB for 100 M samples, and reads positions at random.
//! A streaming split (quantile histograms, temporary files as in LPC) is not written.
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
use super::tree::{Tree, child_targets};
use crate::MethodError;
use crate::cull::Cone;
use crate::store::{self, RepoWriter};

/// Leaves with fewer samples than this take their k-NN radii from their parent's samples.
pub const LEAF_KNN_MIN: usize = 64;

/// What a leaf holds: its samples, with the scene's radii or the within-leaf k-NN spacing
/// ([`leaf_radii`]; a leaf of fewer than [`LEAF_KNN_MIN`] samples — an octree octant that
/// clips a corner of the surface — measures among its parent's samples, of which its own are
/// a contiguous run: alone, one sample has no neighbour and three have only each other).
pub fn leaf_splats(cloud: &PointCloud, tree: &Tree, i: usize) -> Splats {
    let node = &tree.nodes[i];
    let idx = &tree.order[node.range()];
    let pos = cloud.positions();
    let gather = |idx: &[u32]| -> Vec<[f32; 3]> { idx.iter().map(|&j| pos[j as usize]).collect() };
    let positions = gather(idx);
    let radii = match (cloud.radii(), tree.parent(i)) {
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
        normals: cloud
            .normals()
            .map(|n| idx.iter().map(|&j| Vec3::from(n[j as usize])).collect()),
        colors: cloud
            .colors()
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

/// The tree and what the build needs to read for it.
pub struct Input<'a> {
    /// The samples.
    pub cloud: &'a PointCloud,
    /// Their split.
    pub tree: &'a Tree,
    /// Representative selection settings.
    pub reps: RepConfig,
}

impl Input<'_> {
    fn empty(&self) -> Splats {
        Splats::empty(
            self.cloud.normals().is_some(),
            self.cloud.colors().is_some(),
        )
    }

    /// What child number `k` of `i`, holding `held`, passes up: its `t_k` representatives.
    fn pass_up(&self, i: usize, k: usize, held: &Splats) -> Splats {
        let targets = child_targets(self.tree.children(i).len() as u64, self.tree.vbo);
        representatives(held, targets[k] as usize, &self.reps).reps
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
            return Ok(leaf_splats(self.cloud, self.tree, i));
        }
        let mut held = self.empty();
        for (k, c) in self.tree.children(i).enumerate() {
            let h = self.subtree(c, emit)?;
            emit(c, &h)?;
            held.append(&self.pass_up(i, k, &h));
        }
        Ok(held)
    }
}

/// What a task returns: what its root holds, and every node's mapped output in post-order.
type TaskOutput<T> = (Splats, Vec<(usize, T)>);

/// Runs the bottom-up build: every node's held splats go through `map` (on worker threads)
/// and the results through `sink` (on the calling thread, in a deterministic order that
/// puts every node after its children). `task_points` bounds the samples under one task
/// (see the module docs).
pub fn bottom_up<T: Send>(
    input: &Input<'_>,
    task_points: usize,
    map: &(dyn Fn(usize, &Splats) -> Result<T, MethodError> + Sync),
    sink: &mut dyn FnMut(usize, T) -> Result<(), MethodError>,
    progress: &dyn Progress,
) -> Result<(), MethodError> {
    let tree = input.tree;
    // Task roots, depth first; `top` = the nodes above them, in post-order.
    let mut tasks = Vec::new();
    let mut top = Vec::new();
    let mut stack = vec![(0usize, false)];
    while let Some((i, expanded)) = stack.pop() {
        if expanded {
            top.push(i);
        } else if tree.is_leaf(i) || tree.nodes[i].len <= task_points.max(1) {
            tasks.push(i);
        } else {
            stack.push((i, true));
            stack.extend(tree.children(i).rev().map(|c| (c, false)));
        }
    }
    progress.start("mwkd: nodes", tree.nodes.len() as u64);
    let threads = rayon::current_num_threads().max(1);
    let mut task_held: std::collections::HashMap<usize, Splats> = Default::default();
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
            progress.inc(out.len() as u64);
            for (i, v) in out {
                sink(i, v)?;
            }
            task_held.insert(t, held);
        }
    }
    // The nodes above the tasks, children first: each gathers from its children's held data.
    let mut held_of = task_held;
    for &i in &top {
        let mut held = input.empty();
        for (k, c) in tree.children(i).enumerate() {
            let h = held_of
                .remove(&c)
                .ok_or_else(|| MethodError::Limit(format!("mwkd build: node {c} missing")))?;
            held.append(&input.pass_up(i, k, &h));
        }
        sink(i, map(i, &held)?)?;
        progress.inc(1);
        held_of.insert(i, held);
    }
    progress.finish();
    Ok(())
}

/// One node, encoded and compressed (the output of the disk build's `map`).
pub struct Encoded {
    /// LZO-compressed bytes ([`store::compress`]).
    pub stored: Vec<u8>,
    /// Uncompressed length.
    pub raw_len: usize,
    /// The codec header (box, radius range, count).
    pub header: codec::NodeHeader,
    /// Mean radius.
    pub radius_mean: f32,
    /// Cone of the node's own normals.
    pub cone: Cone,
}

/// Encodes and compresses what node `id` holds.
pub fn encode_node(id: usize, s: &Splats) -> Result<Encoded, MethodError> {
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
    Ok(Encoded {
        stored: store::compress(&raw),
        raw_len: raw.len(),
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

/// Builds the tree `tree` of `cloud` into `repo` (a repository file) and returns the index
/// array (not yet written).
pub fn write_repository(
    input: &Input<'_>,
    repo: &std::path::Path,
    task_points: usize,
    progress: &dyn Progress,
) -> Result<Written, MethodError> {
    let tree = input.tree;
    let mut writer = RepoWriter::create(repo)?;
    let mut index = vec![IndexNode::default(); tree.nodes.len()];
    let mut cones = vec![Cone::ALL; tree.nodes.len()];
    let mut raw_bytes = 0u64;
    bottom_up(
        input,
        task_points,
        &encode_node,
        &mut |i, e: Encoded| {
            let chunk = writer.append_compressed(&e.stored, e.raw_len)?;
            raw_bytes += e.raw_len as u64;
            let n = &tree.nodes[i];
            index[i] = IndexNode {
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
            cones[i] = e.cone;
            Ok(())
        },
        progress,
    )?;
    // Subtree cones: children have larger indices than their parent.
    for i in (0..index.len()).rev() {
        let kids = tree.children(i);
        if !kids.is_empty() {
            let c = Cone::union(std::iter::once(cones[i]).chain(kids.map(|c| cones[c])));
            cones[i] = c;
        }
        index[i].cone_axis = cones[i].axis.to_array();
        index[i].cone_half_angle = cones[i].half_angle;
    }
    let repo_bytes = writer.finish()?;
    Ok(Written {
        index,
        raw_bytes,
        repo_bytes,
    })
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
            cloud,
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
        let r = leaf_splats(&cloud, &tree, lone).radii[0];
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
