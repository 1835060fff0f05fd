//! The LPC index tree (`index.bin`), loaded whole at `open`: one [`Node`] per cloud, in
//! repository order — by level, then by the Morton code of the bounding-sphere centre — so
//! node index = cloud id = fetch priority (coarse first, spatially coherent).
//!
//! File: magic `SBLPCIX1`, `u64` node count, `u64` [`crate::store::checksum`] of the node
//! bytes, then `count ×` [`Node`] (88 bytes, little-endian, `#[repr(C)]`).

use std::path::Path;

use crate::MethodError;
use crate::store::{ChunkRef, records};

/// No child.
pub const NONE: u32 = u32::MAX;
const MAGIC: &[u8; 8] = b"SBLPCIX1";

/// One node of the index tree.
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Node {
    /// Bounding sphere centre of every sample in the subtree (local coordinates).
    pub center: [f32; 3],
    /// Bounding sphere radius (subtree).
    pub radius: f32,
    /// Normal cone axis (unit) of every sample in the subtree; zero without normals.
    pub cone_axis: [f32; 3],
    /// Normal cone half-angle in radians; ≥ π/2 (or no normals: π) means never back-facing.
    pub cone_half_angle: f32,
    /// Average sample spacing `r_j` of the region once this node is merged (eq. 2), object
    /// units: a splat of this diameter around each sample covers the region.
    pub spacing: f32,
    /// Child node indices, [`NONE`] where absent.
    pub children: [u32; 2],
    /// Cloud id in the repository (equals the node index).
    pub cloud: u32,
    /// Samples in this node's cloud (`M_j`).
    pub points: u32,
    /// Depth (root = 0).
    pub level: u32,
    /// Samples in the subtree (`N_j`).
    pub subtree: u64,
    /// Where the cloud is stored.
    pub chunk: ChunkRef,
}

impl Node {
    /// The children present.
    pub fn child_ids(&self) -> impl Iterator<Item = u32> + '_ {
        self.children.iter().copied().filter(|&c| c != NONE)
    }
    /// True if the node has no child.
    pub fn is_leaf(&self) -> bool {
        self.children == [NONE, NONE]
    }
}

/// Writes `nodes` to `path` (through a temporary file and a rename); returns the file size.
pub fn write(path: &Path, nodes: &[Node]) -> Result<u64, MethodError> {
    records::write(path, MAGIC, nodes)
}

/// Reads and validates an index: magic, length, checksum, and the tree's shape (children
/// after their parent, in range, each node with at most one parent, levels consistent).
pub fn read(path: &Path) -> Result<Vec<Node>, MethodError> {
    let nodes: Vec<Node> = records::read(path, MAGIC, "an LPC index", u64::MAX)?;
    let bad = |msg: String| MethodError::corrupt(path, msg);
    let mut parent = vec![NONE; nodes.len()];
    for (i, n) in nodes.iter().enumerate() {
        if n.cloud as usize != i {
            return Err(bad(format!("node {i}: cloud id {} ≠ node index", n.cloud)));
        }
        if !(n.radius.is_finite() && n.radius >= 0.0 && n.spacing.is_finite() && n.spacing > 0.0) {
            return Err(bad(format!(
                "node {i}: radius {} / spacing {} invalid",
                n.radius, n.spacing
            )));
        }
        for c in n.child_ids() {
            let ok = (c as usize) < nodes.len()
                && c as usize > i
                && parent[c as usize] == NONE
                && nodes[c as usize].level == n.level + 1;
            if !ok {
                return Err(bad(format!("node {i}: child {c} is invalid")));
            }
            parent[c as usize] = i as u32;
        }
    }
    if nodes[0].level != 0 || parent.iter().skip(1).any(|&p| p == NONE) {
        return Err(bad("the nodes do not form one tree rooted at node 0".into()));
    }
    Ok(nodes)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn node_layout_is_88_bytes() {
        assert_eq!(std::mem::size_of::<Node>(), 88);
    }

    #[test]
    fn round_trip_and_corruption() -> Result<(), MethodError> {
        let dir = tempfile::tempdir().map_err(|e| MethodError::io("tempdir", e))?;
        let path = dir.path().join("index.bin");
        let mut nodes = vec![Node::default(); 3];
        for (i, n) in nodes.iter_mut().enumerate() {
            n.cloud = i as u32;
            n.spacing = 1.0;
            n.children = [NONE, NONE];
            n.level = (i > 0) as u32;
        }
        nodes[0].children = [1, 2];
        write(&path, &nodes)?;
        assert_eq!(read(&path)?, nodes);
        let mut bytes = std::fs::read(&path).map_err(|e| MethodError::io(&path, e))?;
        bytes[30] ^= 1;
        std::fs::write(&path, &bytes).map_err(|e| MethodError::io(&path, e))?;
        assert!(read(&path).unwrap_err().to_string().contains("checksum"));
        // A child listed twice is refused even with a valid checksum.
        nodes[0].children = [1, 1];
        nodes[2].level = 1;
        write(&path, &nodes)?;
        assert!(read(&path).unwrap_err().to_string().contains("child 1"));
        Ok(())
    }
}
