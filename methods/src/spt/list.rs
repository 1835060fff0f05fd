//! Writing the sorted node list: `nodes.sbc`, `lod.bin` and `index.json` from the nodes in
//! list order, streamed (the in-memory build and the build in units feed the same writer,
//! so their files agree byte for byte).
//!
//! A cluster's axis is the normalised sum of its members' normals in list order (summed as
//! they arrive); a chunk's sphere is computed from its ≤ [`CHUNK_NODES`] members, buffered. A
//! cluster's half-angle and bounding sphere need its axis and box first: they are computed in
//! a second pass over the written (memory-mapped) node file.

use std::io::{Seek, SeekFrom, Write};
use std::path::Path;

use glam::{DVec3, Vec3};
use scenes::colfile::ColumnWriter;
use scenes::hash::Fnv64;
use scenes::{Attributes, PointCloud};

use super::files::{ChunkInfo, ClusterInfo, Index};
use super::{CHUNK_NODES, LOD_FILE, LOD_MAGIC, NODES_FILE, sphere_of};
use crate::MethodError;

/// One node as the list stores it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ListNode {
    /// Centre.
    pub p: Vec3,
    /// Unit normal (`Vec3::Z` without normals).
    pub n: Vec3,
    /// Colour (ignored without colours).
    pub color: [u8; 3],
    /// Disk radius.
    pub r: f32,
    /// The `lod` entry.
    pub lod: [f32; 4],
    /// Normal cluster.
    pub cluster: u32,
}

impl ListNode {
    /// Tree node `nd` as the list stores it, with its `lod` entry and normal cluster.
    pub fn of(nd: &super::build::Node, lod: [f32; 4], cluster: u32) -> Self {
        Self {
            p: nd.p,
            n: nd.n,
            color: nd.color,
            r: nd.r,
            lod,
            cluster,
        }
    }
}

const BLOCK: usize = 1 << 16;

/// Writes the list's files in list order.
pub struct ListWriter {
    attrs: Attributes,
    normal_clusters: bool,
    columns: ColumnWriter,
    pos: Vec<[f32; 3]>,
    nrm: Vec<[f32; 3]>,
    col: Vec<[u8; 3]>,
    rad: Vec<f32>,
    lod: std::io::BufWriter<std::fs::File>,
    lod_tmp: std::path::PathBuf,
    lod_path: std::path::PathBuf,
    lod_sum: Fnv64,
    written: u64,
    clusters: Vec<ClusterInfo>,
    axis_sum: Vec3,
    chunks: Vec<ChunkInfo>,
    chunk: Vec<(Vec3, f32)>,
    chunk_e_par: f32,
}

impl ListWriter {
    /// Creates the files for `count` nodes with the scene's attributes `attrs` (radii
    /// added) and origin.
    pub fn create(
        dir: &Path,
        attrs: Attributes,
        origin: DVec3,
        count: u64,
        normal_clusters: bool,
    ) -> Result<Self, MethodError> {
        let columns = ColumnWriter::create(&dir.join(NODES_FILE), attrs, origin, count)?;
        let lod_path = dir.join(LOD_FILE);
        let lod_tmp = lod_path.with_extension("bin.tmp");
        let io = |e| MethodError::io(&lod_tmp, e);
        let mut lod = std::io::BufWriter::new(std::fs::File::create(&lod_tmp).map_err(io)?);
        lod.write_all(LOD_MAGIC).map_err(io)?;
        lod.write_all(&count.to_le_bytes()).map_err(io)?;
        lod.write_all(&[0u8; 8]).map_err(io)?;
        Ok(Self {
            attrs,
            normal_clusters,
            columns,
            pos: Vec::with_capacity(BLOCK),
            nrm: Vec::new(),
            col: Vec::new(),
            rad: Vec::with_capacity(BLOCK),
            lod,
            lod_tmp,
            lod_path,
            lod_sum: Fnv64::default(),
            written: 0,
            clusters: Vec::new(),
            axis_sum: Vec3::ZERO,
            chunks: Vec::new(),
            chunk: Vec::with_capacity(CHUNK_NODES),
            chunk_e_par: 0.0,
        })
    }

    /// Appends the next node of the list.
    pub fn push(&mut self, nd: &ListNode) -> Result<(), MethodError> {
        if self.clusters.last().is_none_or(|c| c.id != nd.cluster) {
            self.close_cluster();
            self.clusters.push(ClusterInfo {
                id: nd.cluster,
                start: self.written,
                count: 0,
                axis: [0.0; 3],
                half_angle: 0.0,
                center: [0.0; 3],
                radius: 0.0,
            });
        }
        if self.chunk.len() == CHUNK_NODES {
            self.close_chunk();
        }
        if self.chunk.is_empty() {
            self.chunk_e_par = nd.lod[1];
        }
        self.chunk.push((nd.p, nd.r));
        self.axis_sum += nd.n;
        if let Some(c) = self.clusters.last_mut() {
            c.count += 1;
        }
        self.pos.push(nd.p.to_array());
        if self.attrs.normals {
            self.nrm.push(nd.n.to_array());
        }
        if self.attrs.colors {
            self.col.push(nd.color);
        }
        self.rad.push(nd.r);
        let bytes: &[u8] = bytemuck::cast_slice(&nd.lod);
        self.lod_sum.write(bytes);
        self.lod
            .write_all(bytes)
            .map_err(|e| MethodError::io(&self.lod_tmp, e))?;
        self.written += 1;
        if self.pos.len() == BLOCK {
            self.flush()?;
        }
        Ok(())
    }

    fn flush(&mut self) -> Result<(), MethodError> {
        self.columns.push(
            &self.pos,
            self.attrs.normals.then_some(self.nrm.as_slice()),
            self.attrs.colors.then_some(self.col.as_slice()),
            Some(&self.rad),
        )?;
        self.pos.clear();
        self.nrm.clear();
        self.col.clear();
        self.rad.clear();
        Ok(())
    }

    fn close_chunk(&mut self) {
        if self.chunk.is_empty() {
            return;
        }
        let (center, radius) = sphere_of(self.chunk.iter().copied());
        let count = self.chunk.len() as u32;
        self.chunks.push(ChunkInfo {
            cluster: self.clusters.len() as u32 - 1,
            start: self.written - count as u64,
            count,
            max_e_par: self.chunk_e_par,
            center,
            radius,
        });
        self.chunk.clear();
    }

    fn close_cluster(&mut self) {
        self.close_chunk();
        if let Some(c) = self.clusters.last_mut() {
            c.axis = self.axis_sum.try_normalize().unwrap_or(Vec3::Z).to_array();
        }
        self.axis_sum = Vec3::ZERO;
    }

    /// Finishes the files; returns the index (clusters and chunks) for `index.json` and
    /// the node file, opened.
    pub fn finish(mut self, levels: u32) -> Result<(Index, PointCloud), MethodError> {
        self.close_cluster();
        if !self.pos.is_empty() {
            self.flush()?;
        }
        let nodes = self.columns.finish()?;
        let io = |e| MethodError::io(&self.lod_tmp, e);
        let mut f = self
            .lod
            .into_inner()
            .map_err(|e| MethodError::io(&self.lod_tmp, e.into_error()))?;
        f.seek(SeekFrom::Start(16)).map_err(io)?;
        f.write_all(&self.lod_sum.finish().to_le_bytes())
            .map_err(io)?;
        f.sync_all().map_err(io)?;
        drop(f);
        std::fs::rename(&self.lod_tmp, &self.lod_path)
            .map_err(|e| MethodError::io(&self.lod_path, e))?;
        // Second pass: each cluster's cone and sphere from the written centres and normals,
        // in blocks whose pages are released behind (the file may exceed the budget).
        let pos = nodes.positions();
        let nrm = nodes.normals();
        for c in &mut self.clusters {
            let (start, end) = (c.start as usize, (c.start + c.count) as usize);
            let axis = Vec3::from(c.axis);
            let (mut angle, mut lo, mut hi) = (0.0f32, Vec3::INFINITY, Vec3::NEG_INFINITY);
            for b in (start..end).step_by(BLOCK) {
                let e = (b + BLOCK).min(end);
                for i in b..e {
                    let n = nrm.map_or(Vec3::Z, |v| Vec3::from(v[i]));
                    angle = angle.max(axis.dot(n).clamp(-1.0, 1.0).acos());
                    lo = lo.min(Vec3::from(pos[i]));
                    hi = hi.max(Vec3::from(pos[i]));
                }
                nodes.release_pages(b..e);
            }
            c.half_angle = if self.normal_clusters {
                angle * (1.0 + 1e-4) + 1e-4
            } else {
                std::f32::consts::PI
            };
            // `sphere_of` over the centres, its two passes split: the box above, the radius
            // here.
            let centre = (lo + hi) * 0.5;
            let mut r = 0.0f32;
            for b in (start..end).step_by(BLOCK) {
                let e = (b + BLOCK).min(end);
                for p in &pos[b..e] {
                    r = r.max(Vec3::from(*p).distance(centre) + 0.0);
                }
                nodes.release_pages(b..e);
            }
            c.center = centre.to_array();
            c.radius = r * (1.0 + 1e-5);
        }
        Ok((
            Index {
                nodes: self.written,
                levels,
                clusters: self.clusters,
                chunks: self.chunks,
            },
            nodes,
        ))
    }
}
