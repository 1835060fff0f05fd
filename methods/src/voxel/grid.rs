//! The inner nodes of `voxel`'s octree: one sample per occupied cell of a 128³ grid over the
//! node ([`GRID`]), carrying the mean colour and the mean normal of what lies below it in
//! the cell (the paper's colour filtering), at the cell's centre or at its points' mean
//! ([`Position`]).
//!
//! **What is averaged** ([`Filter`]). The default is the authors' "average in cell": a
//! voxel averages its children's samples in the cell, a child's voxel counting as one
//! sample as a leaf child's point does ([`Voxel::as_sample`]: a mean of means, as their
//! code computes it). `filter=points` averages every input point below it instead.
//!
//! **Sums, bottom up.** A voxel keeps sums (integer colour sums, `f64` normal sums, integer
//! position sums) and a count. A parent's voxel is the union of 2×2×2 cells of one child's
//! grid, so its sums are the sums of those cells' contributions: with `filter=points` their
//! sums (the parent's mean is then the mean of *all* the points below it, exactly), with
//! `filter=children` each cell's sample. Either way a voxel is computed from its children
//! only, which is what lets a unit of an out-of-core build fill its nodes alone and hand its
//! root's voxels to the top, into the same files as in core.
//!
//! **Cells are Morton prefixes.** A point's cell in a node of level `L` is its 63-bit
//! Morton code (`potree::octree::Quant::morton`, 21 bits per axis) cut to `L + 7` levels:
//! integer arithmetic, the same cut the octree's split uses, so a cell never straddles two
//! children. Below level 14 the Morton grid is the finest there is (`2^(21−L)` cells per
//! axis, fewer than 128): such nodes exist only over piles of near-duplicates.

use glam::DVec3;
use rayon::prelude::*;
use scenes::PointCloud;

use super::{Filter, Position};
use crate::potree::octree::{Fill, MORTON_BITS, Node, Points, Quant};
use crate::potree::write::{self, Desc, Src};

/// Cells per axis of an inner node's grid (the paper's 128³).
pub const GRID: u32 = 128;
/// `log2(GRID)`: the grid's levels below its node.
pub const GRID_LEVELS: u32 = 7;

/// Levels of Morton code that cut a point's cell in a node at `level`.
pub fn cell_depth(level: u32) -> u32 {
    (level + GRID_LEVELS).min(MORTON_BITS)
}

/// The cell key (Morton prefix) at `depth` levels of the Morton code `code`.
pub fn cell_key(code: u64, depth: u32) -> u64 {
    code >> (3 * (MORTON_BITS - depth))
}

/// The sums of one voxel: what its sample averages.
#[derive(Debug, Clone, PartialEq)]
pub struct Voxel {
    /// Cell key ([`cell_key`]) at its node's [`cell_depth`].
    pub key: u64,
    /// Input points in it.
    pub count: u64,
    /// Sum of their integer positions.
    pub q: [i64; 3],
    /// Sum of their 8-bit colours, if the scene has colours.
    pub rgb: Option<[u64; 3]>,
    /// Sum of their normals, if the scene has normals.
    pub normal: Option<NormalSum>,
}

/// The normals of a voxel's points: their sum, and the first one's for a sum that cancels.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NormalSum {
    /// Sum of the normals.
    pub sum: [f64; 3],
    /// Morton rank of the first point (the lowest).
    pub first_rank: u32,
    /// Its normal.
    pub first: [f32; 3],
}

impl Voxel {
    /// The voxel of point `id` alone, in the cell `key`.
    fn of_point<P: Points>(cloud: &PointCloud, s: &P, id: u32, key: u64) -> Self {
        let i = s.input(id) as usize;
        let q = s.q(id);
        Voxel {
            key,
            count: 1,
            q: q.map(i64::from),
            rgb: cloud.colors().map(|c| c[i].map(u64::from)),
            normal: cloud.normals().map(|n| NormalSum {
                sum: n[i].map(f64::from),
                first_rank: id,
                first: n[i],
            }),
        }
    }

    /// Adds `o`'s sums (same cell).
    fn add(&mut self, o: &Voxel) {
        self.count += o.count;
        self.q.iter_mut().zip(o.q).for_each(|(a, b)| *a += b);
        if let (Some(a), Some(b)) = (self.rgb.as_mut(), o.rgb) {
            a.iter_mut().zip(b).for_each(|(a, b)| *a += b);
        }
        if let (Some(a), Some(b)) = (self.normal.as_mut(), o.normal) {
            a.sum.iter_mut().zip(b.sum).for_each(|(a, b)| *a += b);
            if b.first_rank < a.first_rank {
                (a.first_rank, a.first) = (b.first_rank, b.first);
            }
        }
    }

    /// This voxel (at `depth`) as one sample of its parent's cell `key`: a count of one, its
    /// sample's integer position, its rounded mean colour and its mean normal (the authors'
    /// "average in cell" averages a child's voxels as it averages a leaf's points). Rounded
    /// to nearest where their code truncates (`R / count`), which would darken every level
    /// by half a step on average, compounding up the tree.
    fn as_sample(&self, quant: &Quant, depth: u32, position: Position, key: u64) -> Self {
        Voxel {
            key,
            count: 1,
            q: self.position(quant, depth, position).map(i64::from),
            rgb: self.mean_rgb().map(|c| c.map(u64::from)),
            normal: self.normal.zip(self.mean_normal()).map(|(n, m)| NormalSum {
                sum: m.map(f64::from),
                ..n
            }),
        }
    }

    /// The mean 8-bit colour, rounded to nearest (halves up).
    pub fn mean_rgb(&self) -> Option<[u8; 3]> {
        let n = self.count;
        self.rgb
            .map(|s| s.map(|v| ((v + n / 2) / n).min(255) as u8))
    }

    /// The mean normal, normalised; the first point's if the sum cancels.
    pub fn mean_normal(&self) -> Option<[f32; 3]> {
        self.normal.map(|n| {
            let v = DVec3::from(n.sum);
            let len = v.length();
            if len.is_finite() && len > 1e-9 * self.count as f64 {
                (v / len).as_vec3().to_array()
            } else {
                n.first
            }
        })
    }

    /// The integer position of the sample: the cell's centre at `depth`, or the mean of
    /// the points' integer positions (rounded to nearest).
    pub fn position(&self, quant: &Quant, depth: u32, position: Position) -> [i32; 3] {
        match position {
            Position::Mean => {
                let n = self.count as i64;
                self.q.map(|v| ((v + n / 2) / n) as i32)
            }
            Position::Centre => {
                let k = self.key;
                // Quant::morton puts x in bit 2 and z in bit 0 of each digit.
                let c = [
                    crate::morton::compact21(k >> 2),
                    crate::morton::compact21(k >> 1),
                    crate::morton::compact21(k),
                ];
                let cell = quant.size / f64::from(1u32 << depth);
                let w = quant.min
                    + DVec3::new(f64::from(c[0]), f64::from(c[1]), f64::from(c[2])) * cell
                    + DVec3::splat(0.5 * cell);
                quant.quantise(w)
            }
        }
    }
}

/// `voxel`'s [`Fill`]: an inner node's voxels from its children's voxels and leaf points.
pub struct VoxelFill<'a> {
    /// The cloud (colours and normals).
    pub cloud: &'a PointCloud,
    /// The quantisation.
    pub quant: Quant,
    /// Where a voxel's sample lies.
    pub position: Position,
    /// What a voxel averages.
    pub filter: Filter,
    /// Bytes of a record in the files.
    pub bytes_per_point: usize,
}

impl Fill for VoxelFill<'_> {
    type Extra = Vec<Voxel>;

    fn name(&self) -> &'static str {
        super::NAME
    }

    /// The paper's coarsest level is a 128³ grid of voxels: a cloud that fits one leaf still
    /// gets its root grid over the leaves of its octants (else such a cloud would have no
    /// level of detail at all, its root every sample).
    fn splits_root(&self) -> bool {
        true
    }

    fn fill<P: Points>(&self, node: &mut Node<Vec<Voxel>>, s: &P) {
        node.children
            .par_iter_mut()
            .flatten()
            .for_each(|c| self.fill(c, s));
        if !node.has_children_here() {
            return;
        }
        let depth = cell_depth(node.level);
        // Every child's cells cut to this node's depth, in octant order, then each child's
        // voxels (by key) or points (by rank): a fixed order, so the sums are the same
        // whatever the threads and whether in core or in units.
        let mut parts: Vec<Voxel> = Vec::new();
        for c in node.children.iter().flatten() {
            let child_depth = cell_depth(c.level);
            let shift = 3 * (child_depth - depth);
            parts.extend(c.extra.iter().map(|v| {
                let key = v.key >> shift;
                match self.filter {
                    Filter::Children => v.as_sample(&self.quant, child_depth, self.position, key),
                    Filter::Points => Voxel { key, ..v.clone() },
                }
            }));
            parts.extend(c.points.iter().map(|&id| {
                let key = cell_key(s.quant().morton(s.q(id)), depth);
                Voxel::of_point(self.cloud, s, id, key)
            }));
        }
        parts.sort_by_key(|v| v.key);
        let mut out: Vec<Voxel> = Vec::new();
        for v in parts {
            match out.last_mut() {
                Some(last) if last.key == v.key => last.add(&v),
                _ => out.push(v),
            }
        }
        node.extra = out;
    }

    fn describe(&self, mut node: Node<Vec<Voxel>>, out: &mut Vec<Desc>) {
        let mask = node.child_mask();
        let (points, src) = if node.extra.is_empty() {
            let ids = std::mem::take(&mut node.points);
            (ids.len() as u32, Src::Ids(ids))
        } else {
            let voxels = std::mem::take(&mut node.extra);
            (
                voxels.len() as u32,
                Src::Encoded(self.encode(&voxels, node.level)),
            )
        };
        out.push(Desc {
            level: node.level,
            path: node.path,
            mask,
            points,
            src,
        });
        for c in node.children.into_iter().flatten() {
            self.describe(*c, out);
        }
    }
}

impl VoxelFill<'_> {
    /// The records of a node's voxels at `level`.
    fn encode(&self, voxels: &[Voxel], level: u32) -> Vec<u8> {
        let bpp = self.bytes_per_point;
        let depth = cell_depth(level);
        let mut bytes = vec![0u8; voxels.len() * bpp];
        for (v, rec) in voxels.iter().zip(bytes.chunks_exact_mut(bpp)) {
            write::encode_record(
                v.position(&self.quant, depth, self.position),
                v.mean_rgb(),
                v.mean_normal(),
                rec,
            );
        }
        bytes
    }
}
