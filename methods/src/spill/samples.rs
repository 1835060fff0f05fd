//! Sample records in spill files: a cloud's samples (with their input index) as the builds
//! in units stream them, and their loading back into columns.

use glam::Vec3;
use rayon::prelude::*;
use scenes::PointCloud;

use super::Spill;
use crate::MethodError;

/// Which columns a sample record carries (those the scene has).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct SampleLayout {
    /// The scene's own radii.
    pub radii: bool,
    /// Normals.
    pub normals: bool,
    /// Colours.
    pub colors: bool,
}

impl SampleLayout {
    /// The layout of `cloud`'s samples.
    pub fn of(cloud: &PointCloud) -> Self {
        Self {
            radii: cloud.radii().is_some(),
            normals: cloud.normals().is_some(),
            colors: cloud.colors().is_some(),
        }
    }

    /// Bytes of a record: index `u32`, position `f32 × 3`, then the radius `f32`, the normal
    /// `f32 × 3` and the colour `u8 × 3` + 1 pad byte when the scene has them.
    pub fn bytes(self) -> usize {
        16 + 4 * self.radii as usize + 12 * self.normals as usize + 4 * self.colors as usize
    }

    /// Appends sample `i` of `cloud` as a record.
    pub fn encode(self, cloud: &PointCloud, i: usize, out: &mut Vec<u8>) {
        out.extend_from_slice(&(i as u32).to_le_bytes());
        for v in cloud.positions()[i] {
            out.extend_from_slice(&v.to_le_bytes());
        }
        if let Some(rs) = cloud.radii() {
            out.extend_from_slice(&rs[i].to_le_bytes());
        }
        if let Some(ns) = cloud.normals() {
            for v in ns[i] {
                out.extend_from_slice(&v.to_le_bytes());
            }
        }
        if let Some(cs) = cloud.colors() {
            out.extend_from_slice(&cs[i]);
            out.push(0);
        }
    }
}

/// The little-endian `f32` at byte `at` of `r`.
pub fn f32_at(r: &[u8], at: usize) -> f32 {
    f32::from_le_bytes([r[at], r[at + 1], r[at + 2], r[at + 3]])
}

/// The little-endian `u32` at byte `at` of `r`.
pub fn u32_at(r: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([r[at], r[at + 1], r[at + 2], r[at + 3]])
}

/// The little-endian `f32`s of `b`, in order.
pub fn f32s(b: &[u8]) -> impl Iterator<Item = f32> + '_ {
    b.chunks_exact(4)
        .map(|v| f32::from_le_bytes([v[0], v[1], v[2], v[3]]))
}

/// A record's input index.
pub fn index_of(r: &[u8]) -> u32 {
    u32_at(r, 0)
}

/// A record's position.
pub fn pos_of(r: &[u8]) -> [f32; 3] {
    [f32_at(r, 4), f32_at(r, 8), f32_at(r, 12)]
}

/// Grows the box `b` by `p`.
pub fn grow(b: &mut (Vec3, Vec3), p: [f32; 3]) {
    let p = Vec3::from(p);
    b.0 = b.0.min(p);
    b.1 = b.1.max(p);
}

/// The empty box (growing it by a point gives that point).
pub const EMPTY_BOX: (Vec3, Vec3) = (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY));

/// Per-sample inputs of a tree build, borrowed, indexed `0..n` in input order: a whole
/// cloud in memory, or a unit's [`SampleColumns`].
#[derive(Debug, Clone, Copy)]
pub struct SampleView<'a> {
    /// Positions.
    pub pos: &'a [[f32; 3]],
    /// Leaf radii.
    pub radii: &'a [f32],
    /// Normals, when the scene has them.
    pub normals: Option<&'a [[f32; 3]]>,
    /// Colours, when the scene has them.
    pub colors: Option<&'a [[u8; 3]]>,
}

impl<'a> SampleView<'a> {
    /// The samples of `cloud` with leaf radii `radii`.
    pub fn of_cloud(cloud: &'a PointCloud, radii: &'a [f32]) -> Self {
        Self {
            pos: cloud.positions(),
            radii,
            normals: cloud.normals(),
            colors: cloud.colors(),
        }
    }
}

/// A unit's samples as columns, in input order.
#[derive(Debug, Default)]
pub struct SampleColumns {
    /// Input indices, increasing.
    pub idx: Vec<u32>,
    /// Positions.
    pub pos: Vec<[f32; 3]>,
    /// Radii (the scene's, or given to [`load`]).
    pub radii: Vec<f32>,
    /// Normals, when the scene has them.
    pub normals: Option<Vec<[f32; 3]>>,
    /// Colours, when the scene has them.
    pub colors: Option<Vec<[u8; 3]>>,
}

impl SampleColumns {
    /// Reorders the columns so that sample `i` becomes `perm[i]`'s (a permutation of
    /// `0..len`); the input indices are dropped. One column at a time, in parallel: at most
    /// one column is held twice.
    pub fn permute(&mut self, perm: &[u32]) {
        fn gather<T: Copy + Send + Sync>(v: &mut Vec<T>, perm: &[u32]) {
            let out: Vec<T> = perm.par_iter().map(|&i| v[i as usize]).collect();
            *v = out;
        }
        self.idx = Vec::new();
        gather(&mut self.pos, perm);
        gather(&mut self.radii, perm);
        if let Some(n) = &mut self.normals {
            gather(n, perm);
        }
        if let Some(c) = &mut self.colors {
            gather(c, perm);
        }
    }

    /// The columns as a [`SampleView`].
    pub fn view(&self) -> SampleView<'_> {
        SampleView {
            pos: &self.pos,
            radii: &self.radii,
            normals: self.normals.as_deref(),
            colors: self.colors.as_deref(),
        }
    }
}

/// Loads the `n` sample records of `spill`; the radii from the records, or `radii` when the
/// scene has none. Records must be in increasing input order (the builds' tie-breaks by
/// index rely on it); anything else is an error naming the file.
pub fn load(
    spill: &Spill,
    layout: SampleLayout,
    n: usize,
    radii: Option<Vec<f32>>,
) -> Result<SampleColumns, MethodError> {
    let given = radii.is_some();
    let mut s = SampleColumns {
        idx: Vec::with_capacity(n),
        pos: Vec::with_capacity(n),
        radii: radii.unwrap_or_else(|| Vec::with_capacity(n)),
        normals: layout.normals.then(|| Vec::with_capacity(n)),
        colors: layout.colors.then(|| Vec::with_capacity(n)),
    };
    let rb = layout.bytes();
    spill.read(|block| {
        for r in block.chunks_exact(rb) {
            let idx = index_of(r);
            if s.idx.last().is_some_and(|&l| l >= idx) {
                return Err(MethodError::corrupt(
                    &spill.path,
                    format!("temporary file: sample index {idx} out of order"),
                ));
            }
            s.idx.push(idx);
            s.pos.push(pos_of(r));
            let mut at = 16;
            if layout.radii {
                s.radii.push(f32_at(r, at));
                at += 4;
            }
            if let Some(ns) = &mut s.normals {
                ns.push([f32_at(r, at), f32_at(r, at + 4), f32_at(r, at + 8)]);
                at += 12;
            }
            if let Some(cs) = &mut s.colors {
                cs.push([r[at], r[at + 1], r[at + 2]]);
            }
        }
        Ok(())
    })?;
    if s.pos.len() != n || (given && s.radii.len() != n) {
        return Err(MethodError::corrupt(
            &spill.path,
            format!("temporary file holds {} samples, {n} expected", s.pos.len()),
        ));
    }
    Ok(s)
}

/// The input indices and positions of `spill`'s sample records.
pub fn positions(
    spill: &Spill,
    layout: SampleLayout,
) -> Result<(Vec<u32>, Vec<[f32; 3]>), MethodError> {
    let mut idx = Vec::new();
    let mut pos = Vec::new();
    spill.read(|block| {
        for r in block.chunks_exact(layout.bytes()) {
            idx.push(index_of(r));
            pos.push(pos_of(r));
        }
        Ok(())
    })?;
    Ok((idx, pos))
}
