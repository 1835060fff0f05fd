//! Writing the sorted node list: `nodes.bin`, `lod.bin` and `index.json` from the nodes in
//! list order, streamed (the in-memory build and the build in units feed the same writer,
//! so their files agree byte for byte).
//!
//! The writer quantises ([`super::quant`]): positions on the build's grid, normals to 24-bit
//! octahedral codes, radii rounded up on the build's scale, and `δ` raised by twice the
//! grid's error bound before it is rounded up; `e` and `e_par` are stored exactly.
//! Everything downstream (chunk spheres, cluster cones and spheres) is computed from the
//! decoded values, as `open` and the GPU see them.
//!
//! A cluster's axis is the normalised sum of its members' normals in list order (summed as
//! they arrive); a chunk's sphere is computed from its ≤ [`CHUNK_NODES`] members, buffered. A
//! cluster's half-angle and bounding sphere need its axis and box first: they are computed in
//! a second pass over the written node file.

use std::io::{Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};

use glam::Vec3;
use rayon::prelude::*;
use scenes::Attributes;
use scenes::hash::Fnv64;

use super::files::{
    CHECKSUM_AT, ChunkInfo, ClusterInfo, Index, LodLayout, NODES_HEADER, NodeLayout,
};
use super::quant::{self, Extent, LodScale};
use super::{CHUNK_NODES, LOD_FILE, NODES_FILE, sphere_of};
use crate::MethodError;

/// One node as the list stores it (exact values; the writer quantises).
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
    /// The `lod` entry ([`super::lod_entry`]).
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
/// Records per parallel piece of [`ListWriter::finish`]'s second pass.
const PASS_PIECE: usize = 1 << 12;

/// One of the two files, written to `<name>.tmp` and renamed when finished (removed if the
/// writer is dropped unfinished).
struct Out {
    file: std::io::BufWriter<std::fs::File>,
    tmp: PathBuf,
    path: PathBuf,
    sum: Fnv64,
    buf: Vec<u8>,
    done: bool,
}

impl Out {
    fn create(path: PathBuf, header: &[u8]) -> Result<Self, MethodError> {
        let tmp = path.with_extension("bin.tmp");
        let file = std::fs::File::create(&tmp).map_err(|e| MethodError::io(&tmp, e))?;
        let mut o = Self {
            file: std::io::BufWriter::with_capacity(1 << 20, file),
            tmp,
            path,
            sum: Fnv64::default(),
            buf: Vec::new(),
            done: false,
        };
        o.file
            .write_all(header)
            .map_err(|e| MethodError::io(&o.tmp, e))?;
        o.sum.write(&header[24..]);
        Ok(o)
    }

    /// Writes `buf` (one record) and clears it.
    fn record(&mut self) -> Result<(), MethodError> {
        self.sum.write(&self.buf);
        self.file
            .write_all(&self.buf)
            .map_err(|e| MethodError::io(&self.tmp, e))?;
        self.buf.clear();
        Ok(())
    }

    fn finish(mut self) -> Result<PathBuf, MethodError> {
        let io = |e| MethodError::io(&self.tmp, e);
        self.file.flush().map_err(io)?;
        let f = self.file.get_mut();
        f.seek(SeekFrom::Start(CHECKSUM_AT as u64)).map_err(io)?;
        f.write_all(&self.sum.finish().to_le_bytes()).map_err(io)?;
        f.sync_all().map_err(io)?;
        std::fs::rename(&self.tmp, &self.path).map_err(|e| MethodError::io(&self.path, e))?;
        self.done = true;
        Ok(self.path.clone())
    }
}

impl Drop for Out {
    fn drop(&mut self) {
        if !self.done {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Writes the list's files in list order.
pub struct ListWriter {
    normal_clusters: bool,
    nodes_layout: NodeLayout,
    lod_layout: LodLayout,
    /// What `δ` is raised by: twice the grid's error bound.
    delta_slack: f64,
    /// The previous node's `e_par` (`lod.bin` codes an equal or smaller one briefly).
    prev_e_par: Option<f32>,
    nodes: Out,
    lod: Out,
    written: u64,
    clusters: Vec<ClusterInfo>,
    axis_sum: Vec3,
    /// The box of the current cluster's decoded centres.
    cluster_box: (Vec3, Vec3),
    /// Per cluster, its box (for the second pass).
    boxes: Vec<(Vec3, Vec3)>,
    chunks: Vec<ChunkInfo>,
    chunk: Vec<(Vec3, f32)>,
    chunk_e_par: f32,
}

impl ListWriter {
    /// Creates the files for `count` nodes with the scene's attributes `attrs`, the position
    /// grid and radius scale of the nodes' `extent`, the `δ` codes' `lod_scale`, the `φ`/`γ`
    /// word stored iff `split`.
    pub fn create(
        dir: &Path,
        attrs: Attributes,
        extent: &Extent,
        lod_scale: LodScale,
        count: u64,
        normal_clusters: bool,
        split: bool,
    ) -> Result<Self, MethodError> {
        let grid = extent.grid();
        let nodes_layout = NodeLayout {
            grid,
            radius: extent.radius_scale(),
            normals: attrs.normals,
            colors: attrs.colors,
        };
        let lod_layout = LodLayout {
            phi_gamma: split,
            scale: lod_scale,
        };
        let nodes = Out::create(dir.join(NODES_FILE), &nodes_layout.header(count))?;
        let lod = Out::create(dir.join(LOD_FILE), &lod_layout.header(count))?;
        Ok(Self {
            normal_clusters,
            nodes_layout,
            lod_layout,
            delta_slack: 2.0 * grid.error_bound(),
            prev_e_par: None,
            nodes,
            lod,
            written: 0,
            clusters: Vec::new(),
            axis_sum: Vec3::ZERO,
            cluster_box: (Vec3::INFINITY, Vec3::NEG_INFINITY),
            boxes: Vec::new(),
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
        let id = self.written;
        let unstorable = |what: &str, v: f32| {
            MethodError::Limit(format!(
                "spt: node {id} (list position) has {what} {v}, which lod.bin and nodes.bin cannot hold"
            ))
        };
        // The node record.
        let l = self.nodes_layout;
        let pos = l.grid.encode(nd.p);
        let p = l.grid.decode(pos);
        let (normal, n) = if l.normals {
            let c = quant::normal_code(nd.n);
            (c, quant::decode_normal(c))
        } else {
            (0, nd.n)
        };
        let radius = l
            .radius
            .code_up(nd.r)
            .ok_or_else(|| unstorable("radius", nd.r))?;
        l.put(pos, normal, nd.color, radius, &mut self.nodes.buf);
        self.nodes.record()?;
        // The lod record: e and e_par exact, δ raised and rounded up.
        let [e, e_par, delta, q] = nd.lod;
        if !(e >= 0.0 && e_par >= 0.0 && e.is_finite() && e_par.is_finite()) {
            return Err(unstorable(
                "e / e_par",
                if e.is_finite() { e_par } else { e },
            ));
        }
        let delta = if delta > 0.0 {
            self.lod_layout
                .scale
                .code_up_f64(f64::from(delta) + self.delta_slack)
                .ok_or_else(|| unstorable("δ", delta))?
        } else {
            0
        };
        self.lod_layout.put(
            e,
            e_par,
            self.prev_e_par,
            delta,
            q as u32,
            &mut self.lod.buf,
        );
        self.prev_e_par = Some(e_par);
        self.lod.record()?;
        // What the index needs, from the decoded values.
        self.chunk.push((p, l.radius.value(radius)));
        self.axis_sum += n;
        self.cluster_box = (self.cluster_box.0.min(p), self.cluster_box.1.max(p));
        if let Some(c) = self.clusters.last_mut() {
            c.count += 1;
        }
        self.written += 1;
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
            self.boxes.push(self.cluster_box);
        }
        self.axis_sum = Vec3::ZERO;
        self.cluster_box = (Vec3::INFINITY, Vec3::NEG_INFINITY);
    }

    /// Finishes the files; returns the index (clusters and chunks) for `index.json`.
    pub fn finish(mut self, levels: u32) -> Result<Index, MethodError> {
        self.close_cluster();
        let nodes = self.nodes.finish()?;
        self.lod.finish()?;
        // Second pass: each cluster's cone and sphere from the written centres and normals
        // (the file, in blocks: it may exceed the budget).
        let l = self.nodes_layout;
        let rec = l.record_bytes();
        let io = |e| MethodError::io(&nodes, e);
        let mut f = std::fs::File::open(&nodes).map_err(io)?;
        f.seek(SeekFrom::Start(NODES_HEADER as u64)).map_err(io)?;
        let mut block = vec![0u8; BLOCK * rec];
        for (c, &(lo, hi)) in self.clusters.iter_mut().zip(&self.boxes) {
            let axis = Vec3::from(c.axis);
            let centre = (lo + hi) * 0.5;
            let (mut angle, mut r) = (0.0f32, 0.0f32);
            let mut left = c.count as usize;
            while left > 0 {
                let m = left.min(BLOCK);
                let b = &mut block[..m * rec];
                f.read_exact(b).map_err(io)?;
                // Maxima, so the block's pieces go in parallel with the same result.
                let cone = l.normals && self.normal_clusters;
                let (a, d) = b
                    .par_chunks(rec * PASS_PIECE)
                    .map(|piece| {
                        let (mut angle, mut r) = (0.0f32, 0.0f32);
                        for r_ in piece.chunks_exact(rec) {
                            // The half-angle only matters with normal clusters (else π).
                            if cone {
                                let n = quant::decode_normal(l.normal_code(r_));
                                angle = angle.max(axis.dot(n).clamp(-1.0, 1.0).acos());
                            }
                            r = r.max(l.position(r_).distance(centre) + 0.0);
                        }
                        (angle, r)
                    })
                    .reduce(|| (0.0, 0.0), |x, y| (x.0.max(y.0), x.1.max(y.1)));
                angle = angle.max(a);
                r = r.max(d);
                left -= m;
            }
            c.half_angle = if self.normal_clusters {
                angle * (1.0 + 1e-4) + 1e-4
            } else {
                std::f32::consts::PI
            };
            // `sphere_of` over the centres: the box's centre, the largest distance.
            c.center = centre.to_array();
            c.radius = r * (1.0 + 1e-5);
        }
        Ok(Index {
            nodes: self.written,
            levels,
            clusters: self.clusters,
            chunks: self.chunks,
        })
    }
}
