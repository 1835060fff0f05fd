//! The files of a build: `octree.bin` (nodes breadth first, whatever order they were
//! built in), `hierarchy.bin` (chunks of `step` levels, proxies on their last level) and
//! `metadata.json`, from a list of node descriptions ([`Desc`]) whose points are in memory or
//! in a unit's spill file.

use std::io::Write;
use std::path::Path;

use glam::DVec3;
use scenes::PointCloud;

use super::format::{self, AttributeDesc, BoundingBox, HierarchyInfo, Metadata, NodeKind, Record};
use super::octree::{Points, Quant};
use crate::MethodError;
use crate::spill::SpillReader;

/// A node of the finished octree.
pub struct Desc {
    /// Depth.
    pub level: u32,
    /// Octant digits.
    pub path: u64,
    /// Children present.
    pub mask: u8,
    /// Points stored.
    pub points: u32,
    /// Where they are.
    pub src: Src,
}

/// Where a node's points are.
pub enum Src {
    /// In memory: their global ranks (positions and input indices from a [`Points`]).
    Ids(Vec<u32>),
    /// The next `points` records of unit `u`'s spill file (encoded already).
    Unit(usize),
    /// In memory, encoded already ([`encode_record`]): samples that are no input point
    /// (`voxel`'s averaged voxels).
    Encoded(Vec<u8>),
}

/// Every node of `root`'s tree, its points (moved out of the tree) in memory.
pub fn describe(mut root: super::octree::Node, out: &mut Vec<Desc>) {
    out.push(Desc {
        level: root.level,
        path: root.path,
        mask: root.child_mask(),
        points: root.points.len() as u32,
        src: Src::Ids(std::mem::take(&mut root.points)),
    });
    for c in root.children.into_iter().flatten() {
        describe(*c, out);
    }
}

/// Encodes the point record of input sample `i` at integer position `q` into `rec` (as long
/// as the layout's `bytes_per_point`): position, then `rgb` and `NormalX/Y/Z` if present.
pub fn encode(cloud: &PointCloud, i: usize, q: [i32; 3], rec: &mut [u8]) {
    encode_record(
        q,
        cloud.colors().map(|c| c[i]),
        cloud.normals().map(|n| n[i]),
        rec,
    );
}

/// Encodes a point record (as long as the layout's `bytes_per_point`): position `q`, then
/// the 8-bit colour `rgb` as `uint16` (`v · 257`, which the reader's `v / 256` turns back
/// into `v`) and the normal, each when given (the layout has them iff the scene has).
pub fn encode_record(q: [i32; 3], rgb: Option<[u8; 3]>, normal: Option<[f32; 3]>, rec: &mut [u8]) {
    for k in 0..3 {
        rec[4 * k..4 * k + 4].copy_from_slice(&q[k].to_le_bytes());
    }
    let mut at = 12;
    if let Some(c) = rgb {
        for k in 0..3 {
            let v = u16::from(c[k]) * 257;
            rec[at + 2 * k..at + 2 * k + 2].copy_from_slice(&v.to_le_bytes());
        }
        at += 6;
    }
    if let Some(nm) = normal {
        for k in 0..3 {
            rec[at + 4 * k..at + 4 * k + 4].copy_from_slice(&nm[k].to_le_bytes());
        }
    }
}

/// The point record's attributes for `cloud`: position, then `rgb` and `NormalX/Y/Z` if the
/// scene has colours and normals (nothing it lacks).
pub fn attribute_list(cloud: &PointCloud, quant: &Quant) -> Vec<AttributeDesc> {
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

/// What [`write_files`] wrote.
pub struct Written {
    /// Bytes of `octree.bin`.
    pub octree_bytes: u64,
    /// Bytes of `hierarchy.bin`.
    pub hierarchy_bytes: u64,
    /// Bytes of `metadata.json`.
    pub metadata_bytes: u64,
    /// Hierarchy chunks.
    pub chunks: u64,
    /// Deepest level.
    pub depth: u32,
    /// Nodes.
    pub nodes: u64,
    /// Records (points and any other samples) in `octree.bin`.
    pub samples: u64,
    /// The record layout.
    pub layout: format::Layout,
}

/// The metadata of a build of `cloud` with hierarchy chunks of `step` levels (hierarchy
/// sizes filled in by [`write_files`]).
pub fn metadata(cloud: &PointCloud, quant: &Quant, step: u32, scene: &str) -> Metadata {
    let (min, max) = (quant.min, quant.min + DVec3::splat(quant.size));
    Metadata {
        version: format::VERSION.into(),
        name: scene.into(),
        description: String::new(),
        points: cloud.len() as u64,
        projection: String::new(),
        hierarchy: HierarchyInfo {
            first_chunk_size: 0,
            step_size: step,
            depth: 0,
        },
        offset: quant.min.to_array(),
        scale: [quant.scale; 3],
        spacing: quant.size / 128.0,
        bounding_box: BoundingBox {
            min: min.to_array(),
            max: max.to_array(),
        },
        encoding: format::ENCODING.into(),
        attributes: attribute_list(cloud, quant),
    }
}

/// Writes the three files into `dir` from `descs` (sorted here, breadth first): points of
/// [`Src::Ids`] nodes encoded from `mem`, those of [`Src::Unit`] nodes copied from
/// `units` in order.
pub fn write_files(
    cloud: &PointCloud,
    mut meta: Metadata,
    descs: &mut [Desc],
    mem: &dyn Points,
    units: &mut [SpillReader<'_>],
    dir: &Path,
) -> Result<Written, MethodError> {
    descs.sort_unstable_by_key(|d| (d.level, d.path));
    let meta_path = dir.join(format::METADATA_FILE);
    let layout = meta.layout(&meta_path)?;
    let bpp = layout.bytes_per_point;
    let octree_path = dir.join(format::OCTREE_FILE);
    let file = std::fs::File::create(&octree_path).map_err(|e| MethodError::io(&octree_path, e))?;
    let mut out = std::io::BufWriter::with_capacity(1 << 20, file);
    let mut spans = Vec::with_capacity(descs.len());
    let mut offset = 0u64;
    let mut rec = vec![0u8; bpp];
    for d in descs.iter() {
        match &d.src {
            Src::Ids(ids) => {
                for &id in ids {
                    encode(cloud, mem.input(id) as usize, mem.q(id), &mut rec);
                    out.write_all(&rec)
                        .map_err(|e| MethodError::io(&octree_path, e))?;
                }
            }
            Src::Encoded(records) => {
                out.write_all(records)
                    .map_err(|e| MethodError::io(&octree_path, e))?;
            }
            Src::Unit(u) => {
                for _ in 0..d.points {
                    let r = units[*u].next_record()?.ok_or_else(|| {
                        MethodError::Bug(format!(
                            "potree build: unit {u} ran out of records at node {}",
                            format::node_name(d.level, d.path)
                        ))
                    })?;
                    out.write_all(r)
                        .map_err(|e| MethodError::io(&octree_path, e))?;
                }
            }
        }
        let size = u64::from(d.points) * bpp as u64;
        spans.push((offset, size));
        offset += size;
    }
    out.flush().map_err(|e| MethodError::io(&octree_path, e))?;
    drop(out);
    let step = meta.hierarchy.step_size;
    let chunk_list = chunks(descs, step);
    let mut chunk_at = std::collections::HashMap::new();
    let mut pos = 0u64;
    for c in &chunk_list {
        let size = (c.len() * format::RECORD_BYTES) as u64;
        chunk_at.insert(c[0], (pos, size));
        pos += size;
    }
    let mut bytes = Vec::with_capacity(pos as usize);
    for c in &chunk_list {
        let top = descs[c[0] as usize].level;
        for &id in c {
            let d = &descs[id as usize];
            let (kind, (offset, size)) = if id != c[0] && d.level == top + step {
                (NodeKind::Proxy, chunk_at[&id])
            } else if d.mask == 0 {
                (NodeKind::Leaf, spans[id as usize])
            } else {
                (NodeKind::Inner, spans[id as usize])
            };
            let record = Record {
                kind,
                child_mask: d.mask,
                points: d.points,
                offset,
                size,
            };
            bytes.extend_from_slice(&record.to_bytes());
        }
    }
    let hierarchy_path = dir.join(format::HIERARCHY_FILE);
    std::fs::write(&hierarchy_path, &bytes).map_err(|e| MethodError::io(&hierarchy_path, e))?;
    let depth = descs.iter().map(|d| d.level).max().unwrap_or(0);
    meta.hierarchy.first_chunk_size = chunk_at[&0].1;
    meta.hierarchy.depth = depth;
    crate::method::write_json(&meta_path, &meta)?;
    let metadata_bytes = std::fs::metadata(&meta_path)
        .map_err(|e| MethodError::io(&meta_path, e))?
        .len();
    Ok(Written {
        octree_bytes: offset,
        hierarchy_bytes: bytes.len() as u64,
        metadata_bytes,
        chunks: chunk_list.len() as u64,
        depth,
        nodes: descs.len() as u64,
        samples: offset / bpp as u64,
        layout,
    })
}

/// The hierarchy chunks over `descs` (sorted breadth first): per chunk root (levels 0, step,
/// 2·step, …, in order), its nodes breadth first down to `step` levels below it.
fn chunks(descs: &[Desc], step: u32) -> Vec<Vec<u32>> {
    let index: std::collections::HashMap<(u32, u64), u32> = descs
        .iter()
        .enumerate()
        .map(|(i, d)| ((d.level, d.path), i as u32))
        .collect();
    let children = |d: &Desc| {
        (0..8u64)
            .filter(move |o| d.mask & (1 << o) != 0)
            .filter_map(|o| index.get(&(d.level + 1, (d.path << 3) | o)).copied())
            .collect::<Vec<u32>>()
    };
    let mut out = Vec::new();
    for (r, root) in descs.iter().enumerate() {
        if root.level % step != 0 {
            continue;
        }
        let mut chunk = vec![r as u32];
        let mut i = 0;
        while i < chunk.len() {
            let d = &descs[chunk[i] as usize];
            if d.level < root.level + step {
                chunk.extend(children(d));
            }
            i += 1;
        }
        out.push(chunk);
    }
    out
}
