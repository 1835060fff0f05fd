//! The MWKD index array (`index.bin`), loaded whole at `open`: one [`IndexNode`] per tree
//! node, in level order (for the multi-way kd-tree: level by level, children of `i` at
//! `N·i + 1 … N·i + N`; for the ablation trees: breadth first, children contiguous). The
//! paper's "small index array per node: id, level, bounding box, min/max radius, byte size",
//! plus what rendering needs without touching the data: the sample count, the mean radius
//! (projected size in the `--eps` mode), the subtree's normal cone (back-face culling), the
//! children, and where the node's chunk is stored.
//!
//! File: magic `SBMWKIX1`, `u64` node count, `u64` [`crate::store::checksum`] of the node
//! bytes, then `count ×` [`IndexNode`] (104 bytes, little-endian, `#[repr(C)]`).

use std::path::Path;

use crate::MethodError;
use crate::store::{ChunkRef, records};

const MAGIC: &[u8; 8] = b"SBMWKIX1";

/// One node of the index array.
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct IndexNode {
    /// Bounding box minimum of the node's own splat centres (local coordinates).
    pub min: [f32; 3],
    /// Bounding box maximum.
    pub max: [f32; 3],
    /// Smallest splat radius of the node (as decoded: radii are rounded up, never below).
    pub radius_min: f32,
    /// Largest splat radius of the node.
    pub radius_max: f32,
    /// Mean splat radius of the node (its "LOD point size" in the `--eps` mode).
    pub radius_mean: f32,
    /// Axis of the normal cone of every sample in the subtree (zero without normals).
    pub cone_axis: [f32; 3],
    /// Its half-angle, radians; π = never back-facing.
    pub cone_half_angle: f32,
    /// Node id (= index in the array = chunk id).
    pub id: u32,
    /// Level (root = 0).
    pub level: u32,
    /// Splats stored in the node (a leaf's samples or an inner node's representatives).
    pub points: u32,
    /// Index of the first child (children are contiguous); 0 for a leaf.
    pub first_child: u32,
    /// Number of children (0 = leaf).
    pub child_count: u32,
    /// Input samples under the node.
    pub subtree_points: u64,
    /// Where the node's data are stored (byte size = `chunk.stored`).
    pub chunk: ChunkRef,
}

impl IndexNode {
    /// True for a leaf.
    pub fn is_leaf(&self) -> bool {
        self.child_count == 0
    }
    /// The children's indices.
    pub fn children(&self) -> std::ops::Range<u32> {
        self.first_child..self.first_child + self.child_count
    }
    /// Centre and radius of the sphere around the box, grown by the largest splat radius
    /// (so it contains every splat the node draws).
    pub fn sphere(&self) -> (glam::Vec3, f32) {
        let (a, b) = (glam::Vec3::from(self.min), glam::Vec3::from(self.max));
        ((a + b) * 0.5, (b - a).length() * 0.5 + self.radius_max)
    }
    /// Distance from `p` to the node's box (0 inside).
    pub fn box_distance(&self, p: glam::Vec3) -> f32 {
        let (a, b) = (glam::Vec3::from(self.min), glam::Vec3::from(self.max));
        (a - p).max(p - b).max(glam::Vec3::ZERO).length()
    }
}

/// Writes `nodes` to `path` (through a temporary file and a rename); returns the file size.
pub fn write(path: &Path, nodes: &[IndexNode]) -> Result<u64, MethodError> {
    records::write(path, MAGIC, nodes)
}

/// Reads and validates an index: magic, length, checksum, and the tree's shape (ids equal
/// indices, children after their parent and in range, every node but the root the child of
/// exactly one node, levels consistent, sizes and radii finite and ordered, leaves' sample
/// counts adding up to the subtree counts). Errors name the file and the node.
pub fn read(path: &Path) -> Result<Vec<IndexNode>, MethodError> {
    let nodes: Vec<IndexNode> = records::read(path, MAGIC, "an MWKD index", u64::from(u32::MAX))?;
    validate(&nodes).map_err(|msg| MethodError::corrupt(path, msg))?;
    Ok(nodes)
}

fn validate(nodes: &[IndexNode]) -> Result<(), String> {
    let len = nodes.len() as u64;
    if let Some(i) = (1..nodes.len()).find(|&i| nodes[i].level < nodes[i - 1].level) {
        return Err(format!("node {i}: nodes are not in level order"));
    }
    let mut has_parent = vec![false; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        let fin = |v: &[f32]| v.iter().all(|x| x.is_finite());
        let shape_ok = n.id as usize == i
            && n.points >= 1
            && fin(&n.min)
            && fin(&n.max)
            && (0..3).all(|a| n.min[a] <= n.max[a])
            && fin(&[n.radius_min, n.radius_max, n.radius_mean, n.cone_half_angle])
            && 0.0 <= n.radius_min
            && n.radius_min <= n.radius_mean * (1.0 + 1e-5)
            && n.radius_mean <= n.radius_max * (1.0 + 1e-5)
            && fin(&n.cone_axis)
            && n.subtree_points >= u64::from(n.points).min(1);
        if !shape_ok {
            return Err(format!("node {i}: invalid fields {n:?}"));
        }
        if n.is_leaf() {
            if n.subtree_points != u64::from(n.points) {
                return Err(format!(
                    "node {i}: leaf holds {} samples but its subtree count is {}",
                    n.points, n.subtree_points
                ));
            }
            continue;
        }
        let end = u64::from(n.first_child) + u64::from(n.child_count);
        if n.first_child as usize <= i || end > len {
            return Err(format!(
                "node {i}: children {}..{end} out of range",
                n.first_child
            ));
        }
        let mut sum = 0u64;
        for c in n.children() {
            let c = c as usize;
            if has_parent[c] || nodes[c].level != n.level + 1 {
                return Err(format!("node {i}: child {c} is invalid"));
            }
            has_parent[c] = true;
            sum += nodes[c].subtree_points;
        }
        if sum != n.subtree_points {
            return Err(format!(
                "node {i}: children hold {sum} samples, the node says {}",
                n.subtree_points
            ));
        }
    }
    if nodes[0].level != 0 || has_parent.iter().skip(1).any(|&p| !p) {
        return Err("the nodes do not form one tree rooted at node 0".into());
    }
    Ok(())
}

/// The parent of every node (`u32::MAX` for the root), from a validated index.
pub fn parents(nodes: &[IndexNode]) -> Vec<u32> {
    let mut p = vec![u32::MAX; nodes.len()];
    for n in nodes {
        for c in n.children() {
            p[c as usize] = n.id;
        }
    }
    p
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn tiny() -> Vec<IndexNode> {
        let mut nodes = vec![IndexNode::default(); 3];
        for (i, n) in nodes.iter_mut().enumerate() {
            n.id = i as u32;
            n.points = 2;
            n.subtree_points = 2;
            n.level = (i > 0) as u32;
            n.radius_min = 0.5;
            n.radius_mean = 0.75;
            n.radius_max = 1.0;
        }
        nodes[0].first_child = 1;
        nodes[0].child_count = 2;
        nodes[0].subtree_points = 4;
        nodes
    }

    #[test]
    fn layout_round_trip_and_corruption() {
        assert_eq!(std::mem::size_of::<IndexNode>(), 104);
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("index.bin");
        let nodes = tiny();
        write(&path, &nodes).unwrap();
        assert_eq!(read(&path).unwrap(), nodes);
        assert_eq!(parents(&nodes), vec![u32::MAX, 0, 0]);
        let mut bytes = std::fs::read(&path).unwrap();
        bytes[40] ^= 1;
        std::fs::write(&path, &bytes).unwrap();
        let e = read(&path).unwrap_err().to_string();
        assert!(e.contains("checksum") && e.contains("index.bin"), "{e}");
        std::fs::write(&path, &bytes[..100]).unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("file size"));
        // Shape errors behind a valid checksum.
        let mut n = tiny();
        n[0].subtree_points = 5;
        write(&path, &n).unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("node 0"));
        let mut n = tiny();
        n[2].level = 2;
        write(&path, &n).unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("child 2"));
        // A valid tree out of level order (levels 0, 1, 1, 2, 3, 2).
        let mut n = vec![tiny()[1]; 6];
        for (i, (level, first, count, sub)) in [
            (0, 1, 2, 4),
            (1, 3, 1, 2),
            (1, 5, 1, 2),
            (2, 4, 1, 2),
            (3, 0, 0, 2),
            (2, 0, 0, 2),
        ]
        .into_iter()
        .enumerate()
        {
            (n[i].id, n[i].level, n[i].first_child) = (i as u32, level, first);
            (n[i].child_count, n[i].subtree_points) = (count, sub);
        }
        write(&path, &n).unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("level order"));
        n[5].level = 3; // now a level-3 leaf under a level-1 node: the child check refuses it
        write(&path, &n).unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("child 5"));
        let mut n = tiny();
        n[1].radius_max = f32::NAN;
        write(&path, &n).unwrap();
        assert!(read(&path).unwrap_err().to_string().contains("node 1"));
    }
}
