//! SPT's files beside the node columns: `index.json` (clusters and chunks of the list) and
//! `lod.bin` (the interval-test entries, checksummed).

use std::path::Path;

use super::*;

/// A normal cluster: a range of the node list.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterInfo {
    /// Octahedral cluster id (0..128), 0 without clustering.
    pub id: u32,
    /// First node.
    pub start: u64,
    /// Nodes.
    pub count: u64,
    /// Cone axis (unit).
    pub axis: [f32; 3],
    /// Cone half-angle (radians) covering every node normal of the cluster.
    pub half_angle: f32,
    /// Bounding sphere centre of the node centres.
    pub center: [f32; 3],
    /// Bounding sphere radius.
    pub radius: f32,
}

/// A chunk: consecutive nodes of one cluster.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChunkInfo {
    /// Index into the cluster list.
    pub cluster: u32,
    /// First node.
    pub start: u64,
    /// Nodes.
    pub count: u32,
    /// Largest `e_par` (its first node's).
    pub max_e_par: f32,
    /// Bounding sphere centre (node disks included).
    pub center: [f32; 3],
    /// Bounding sphere radius.
    pub radius: f32,
}

/// `index.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Index {
    /// Total nodes.
    pub nodes: u64,
    /// Levels of the tree.
    pub levels: u32,
    /// Clusters, in list order.
    pub clusters: Vec<ClusterInfo>,
    /// Chunks, in list order (chunk id = position here).
    pub chunks: Vec<ChunkInfo>,
}

pub(super) fn read_lod(path: &Path, count: u64) -> Result<Vec<[f32; 4]>, MethodError> {
    let bytes = std::fs::read(path).map_err(|e| MethodError::io(path, e))?;
    let bad = |m: String| MethodError::corrupt(path, m);
    if bytes.len() < 24 || &bytes[0..8] != LOD_MAGIC {
        return Err(bad("bad magic (expected SPTLOD01)".into()));
    }
    let word = |o: usize| u64::from_le_bytes(bytes[o..o + 8].try_into().unwrap_or([0; 8]));
    let n = word(8);
    if n != count || bytes.len() as u64 != 24 + 16 * n {
        return Err(bad(format!(
            "{n} entries in {} bytes, index.json says {count} nodes",
            bytes.len()
        )));
    }
    let data = &bytes[24..];
    if scenes::hash::fnv1a64(data) != word(16) {
        return Err(bad("checksum mismatch in the lod entries".into()));
    }
    let lod: Vec<[f32; 4]> = data
        .chunks_exact(16)
        .map(|c| {
            let f = |k: usize| f32::from_le_bytes([c[k], c[k + 1], c[k + 2], c[k + 3]]);
            [f(0), f(4), f(8), f(12)]
        })
        .collect();
    if let Some(i) = lod
        .iter()
        .position(|l| !l.iter().all(|v| v.is_finite() && *v >= 0.0))
    {
        return Err(bad(format!(
            "node {i}: lod entry {:?} is not finite ≥ 0",
            lod[i]
        )));
    }
    Ok(lod)
}
