//! The columnar point cloud.
//!
//! World position of sample `i` = `origin + positions[i]` (in `f64`). Local positions are
//! `f32`; with the origin at the bounding-box corner or centre, a 10 km scene keeps ≈ 1 mm
//! precision, where raw UTM coordinates in `f32` would keep ≈ 0.5 m.

use std::ops::Deref;
use std::sync::Arc;

use glam::{DVec3, Vec3};
use memmap2::Mmap;

use crate::SceneError;

/// Which optional attributes a cloud carries. Positions are always present.
#[derive(
    Debug, Clone, Copy, PartialEq, Eq, Hash, Default, serde::Serialize, serde::Deserialize,
)]
pub struct Attributes {
    /// Unit normals.
    pub normals: bool,
    /// 8-bit sRGB colours.
    pub colors: bool,
    /// Per-sample radii (local spacing / splat radius, object units).
    pub radii: bool,
}

impl std::fmt::Display for Attributes {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "position")?;
        if self.normals {
            write!(f, "+normal")?;
        }
        if self.colors {
            write!(f, "+color")?;
        }
        if self.radii {
            write!(f, "+radius")?;
        }
        Ok(())
    }
}

/// A column of plain data: owned, or a typed view into a shared memory map.
#[derive(Clone)]
pub enum Column<T: bytemuck::Pod> {
    /// In memory.
    Owned(Vec<T>),
    /// `len` elements starting at byte `offset` of `map`; `offset` is aligned for `T`.
    Mapped {
        /// The mapping (shared by all columns of a file).
        map: Arc<Mmap>,
        /// Byte offset of the first element.
        offset: usize,
        /// Element count.
        len: usize,
    },
}

impl<T: bytemuck::Pod> Column<T> {
    /// The elements as a slice (pages of a mapped column are read on first touch).
    pub fn as_slice(&self) -> &[T] {
        match self {
            Column::Owned(v) => v,
            Column::Mapped { map, offset, len } => {
                let bytes = &map[*offset..*offset + *len * std::mem::size_of::<T>()];
                bytemuck::cast_slice(bytes)
            }
        }
    }
    /// True if this column lives in a memory map.
    pub fn is_mapped(&self) -> bool {
        matches!(self, Column::Mapped { .. })
    }
    /// Drops the resident pages of elements `range` of a mapped column from this process
    /// (they stay in the OS page cache and are read again on the next touch); does nothing
    /// for an owned column. Streaming builds call it behind their scan cursor so that the
    /// resident set measures the method's working memory, not the pages of the scene file.
    pub fn release(&self, range: std::ops::Range<usize>) {
        if let Column::Mapped { map, offset, len } = self {
            let size = std::mem::size_of::<T>();
            let start = offset + range.start.min(*len) * size;
            let end = offset + range.end.min(*len) * size;
            crate::os::release_pages(map, start, end);
        }
    }
}

impl<T: bytemuck::Pod> Deref for Column<T> {
    type Target = [T];
    fn deref(&self) -> &[T] {
        self.as_slice()
    }
}

impl<T: bytemuck::Pod> From<Vec<T>> for Column<T> {
    fn from(v: Vec<T>) -> Self {
        Column::Owned(v)
    }
}

impl<T: bytemuck::Pod + std::fmt::Debug> std::fmt::Debug for Column<T> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "Column<{}>[{}{}]",
            std::any::type_name::<T>(),
            self.len(),
            if self.is_mapped() { ", mapped" } else { "" }
        )
    }
}

/// Axis-aligned bounding box in local (`f32`) coordinates.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Aabb {
    /// Minimum corner.
    pub min: Vec3,
    /// Maximum corner.
    pub max: Vec3,
}

impl Aabb {
    /// The empty box (min = +∞, max = −∞); growing it by a point gives that point.
    pub const EMPTY: Aabb = Aabb {
        min: Vec3::splat(f32::INFINITY),
        max: Vec3::splat(f32::NEG_INFINITY),
    };
    /// Bounds of a set of points.
    pub fn from_points(points: &[[f32; 3]]) -> Aabb {
        points
            .iter()
            .fold(Aabb::EMPTY, |b, p| b.grow(Vec3::from(*p)))
    }
    /// This box grown to contain `p`.
    pub fn grow(self, p: Vec3) -> Aabb {
        Aabb {
            min: self.min.min(p),
            max: self.max.max(p),
        }
    }
    /// Union of two boxes.
    pub fn union(self, o: Aabb) -> Aabb {
        Aabb {
            min: self.min.min(o.min),
            max: self.max.max(o.max),
        }
    }
    /// Centre.
    pub fn center(&self) -> Vec3 {
        (self.min + self.max) * 0.5
    }
    /// Edge lengths.
    pub fn size(&self) -> Vec3 {
        self.max - self.min
    }
    /// Radius of the bounding sphere around the centre.
    pub fn radius(&self) -> f32 {
        self.size().length() * 0.5
    }
    /// Index (0, 1, 2) of the longest axis.
    pub fn longest_axis(&self) -> usize {
        let s = self.size();
        if s.x >= s.y && s.x >= s.z {
            0
        } else if s.y >= s.z {
            1
        } else {
            2
        }
    }
    /// True if the box contains no point.
    pub fn is_empty(&self) -> bool {
        self.min.x > self.max.x
    }
}

/// A point cloud: positions plus the optional columns its [`Attributes`] declare.
#[derive(Debug, Clone)]
pub struct PointCloud {
    origin: DVec3,
    positions: Column<[f32; 3]>,
    normals: Option<Column<[f32; 3]>>,
    colors: Option<Column<[u8; 3]>>,
    radii: Option<Column<f32>>,
    bounds: Aabb,
}

impl PointCloud {
    /// Builds a cloud, validating every column: equal lengths, at least one sample, finite
    /// positions, finite non-zero normals (renormalised by callers, checked here), finite
    /// positive radii. The error names the column and the first bad index.
    pub fn new(
        origin: DVec3,
        positions: Column<[f32; 3]>,
        normals: Option<Column<[f32; 3]>>,
        colors: Option<Column<[u8; 3]>>,
        radii: Option<Column<f32>>,
    ) -> Result<Self, SceneError> {
        let n = positions.len();
        if n == 0 {
            return Err(SceneError::InvalidCloud("the cloud has no samples".into()));
        }
        if !origin.is_finite() {
            return Err(SceneError::InvalidCloud(format!(
                "origin {origin} is not finite"
            )));
        }
        let check_len = |name: &str, len: Option<usize>| match len {
            Some(l) if l != n => Err(SceneError::InvalidCloud(format!(
                "column '{name}' has {l} values but there are {n} positions"
            ))),
            _ => Ok(()),
        };
        check_len("normal", normals.as_ref().map(|c| c.len()))?;
        check_len("color", colors.as_ref().map(|c| c.len()))?;
        check_len("radius", radii.as_ref().map(|c| c.len()))?;
        // Validate in blocks and release each block's pages once checked: a mapped 100 M
        // sample scene is never resident all at once (its columns are 2.4 GB). Blocks of
        // 2¹⁶ samples (≤ 1.8 MiB of columns): a build that writes and reopens a file of
        // nodes within a small `mem_mb` holds one block.
        const BLOCK: usize = 1 << 16;
        let mut bounds = Aabb::EMPTY;
        for lo in (0..n).step_by(BLOCK) {
            let hi = (lo + BLOCK).min(n);
            if let Some(i) = positions[lo..hi]
                .iter()
                .position(|p| !p.iter().all(|c| c.is_finite()))
            {
                let i = lo + i;
                return Err(SceneError::InvalidCloud(format!(
                    "position {i} is not finite: {:?}",
                    positions[i]
                )));
            }
            if let Some(nrm) = &normals
                && let Some(i) = nrm[lo..hi].iter().position(|v| {
                    let l = Vec3::from(*v).length_squared();
                    !l.is_finite() || l < 1e-12
                })
            {
                let i = lo + i;
                return Err(SceneError::InvalidCloud(format!(
                    "normal {i} is zero or not finite: {:?}",
                    nrm[i]
                )));
            }
            if let Some(r) = &radii
                && let Some(i) = r[lo..hi].iter().position(|r| !(r.is_finite() && *r > 0.0))
            {
                let i = lo + i;
                return Err(SceneError::InvalidCloud(format!(
                    "radius {i} must be finite and > 0, got {}",
                    r[i]
                )));
            }
            bounds = bounds.union(bounds_parallel(&positions[lo..hi]));
            positions.release(lo..hi);
            if let Some(c) = &normals {
                c.release(lo..hi);
            }
            if let Some(c) = &radii {
                c.release(lo..hi);
            }
        }
        let cloud = Self {
            origin,
            positions,
            normals,
            colors,
            radii,
            bounds,
        };
        Ok(cloud)
    }

    /// Number of samples.
    pub fn len(&self) -> usize {
        self.positions.len()
    }
    /// Always false (a cloud has at least one sample); here for clippy's `len_without_is_empty`.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }
    /// World origin added to every local position.
    pub fn origin(&self) -> DVec3 {
        self.origin
    }
    /// Local positions.
    pub fn positions(&self) -> &[[f32; 3]] {
        &self.positions
    }
    /// Unit normals, if the cloud has them.
    pub fn normals(&self) -> Option<&[[f32; 3]]> {
        self.normals.as_deref()
    }
    /// sRGB colours, if the cloud has them.
    pub fn colors(&self) -> Option<&[[u8; 3]]> {
        self.colors.as_deref()
    }
    /// Per-sample radii, if the cloud has them.
    pub fn radii(&self) -> Option<&[f32]> {
        self.radii.as_deref()
    }
    /// Which optional columns are present.
    pub fn attributes(&self) -> Attributes {
        Attributes {
            normals: self.normals.is_some(),
            colors: self.colors.is_some(),
            radii: self.radii.is_some(),
        }
    }
    /// Bounds of the local positions.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
    /// Releases the resident pages of samples `range` of every mapped column
    /// ([`Column::release`]); a no-op for an in-memory cloud.
    pub fn release_pages(&self, range: std::ops::Range<usize>) {
        self.positions.release(range.clone());
        if let Some(c) = &self.normals {
            c.release(range.clone());
        }
        if let Some(c) = &self.colors {
            c.release(range.clone());
        }
        if let Some(c) = &self.radii {
            c.release(range);
        }
    }
    /// True if the positions are memory-mapped.
    pub fn is_mapped(&self) -> bool {
        self.positions.is_mapped()
    }
    /// World position of sample `i` in `f64`.
    pub fn world_position(&self, i: usize) -> DVec3 {
        self.origin + Vec3::from(self.positions[i]).as_dvec3()
    }
    /// Bytes of the stored columns (what this cloud costs in memory or on disk).
    pub fn column_bytes(&self) -> u64 {
        let n = self.len() as u64;
        let a = self.attributes();
        n * (12
            + if a.normals { 12 } else { 0 }
            + if a.colors { 3 } else { 0 }
            + if a.radii { 4 } else { 0 })
    }
    /// Returns this cloud with a radius column (replacing any existing one).
    pub fn with_radii(mut self, radii: Vec<f32>) -> Result<Self, SceneError> {
        if radii.len() != self.len() {
            return Err(SceneError::InvalidCloud(format!(
                "column 'radius' has {} values but there are {} positions",
                radii.len(),
                self.len()
            )));
        }
        if let Some(i) = radii.iter().position(|r| !(r.is_finite() && *r > 0.0)) {
            return Err(SceneError::InvalidCloud(format!(
                "radius {i} must be finite and > 0, got {}",
                radii[i]
            )));
        }
        self.radii = Some(Column::Owned(radii));
        Ok(self)
    }
    /// Returns this cloud turned so that the file's `up` axis is +Z ([`crate::Up`]): origin,
    /// positions and normals rotated (exactly: a signed axis permutation); the bounds follow.
    pub fn with_up(self, up: crate::Up) -> Result<Self, SceneError> {
        if up == crate::Up::Z {
            return Ok(self);
        }
        let turn = |c: &Column<[f32; 3]>| -> Column<[f32; 3]> {
            c.iter().map(|v| up.to_z_up(*v)).collect::<Vec<_>>().into()
        };
        let positions = turn(&self.positions);
        let normals = self.normals.as_ref().map(turn);
        let origin = DVec3::from(up.to_z_up(self.origin.to_array()));
        PointCloud::new(origin, positions, normals, self.colors, self.radii)
    }
    /// Returns this cloud with a colour column (replacing any existing one).
    pub fn with_colors(mut self, colors: Vec<[u8; 3]>) -> Result<Self, SceneError> {
        if colors.len() != self.len() {
            return Err(SceneError::InvalidCloud(format!(
                "column 'color' has {} values but there are {} positions",
                colors.len(),
                self.len()
            )));
        }
        self.colors = Some(Column::Owned(colors));
        Ok(self)
    }
    /// Returns this cloud without its colour column.
    pub fn without_colors(mut self) -> Self {
        self.colors = None;
        self
    }
    /// Returns this cloud without its normal column.
    pub fn without_normals(mut self) -> Self {
        self.normals = None;
        self
    }
    /// Splits into columns (origin, positions, normals, colours, radii).
    #[expect(
        clippy::type_complexity,
        reason = "a plain destructuring of the five columns"
    )]
    pub fn into_columns(
        self,
    ) -> (
        DVec3,
        Column<[f32; 3]>,
        Option<Column<[f32; 3]>>,
        Option<Column<[u8; 3]>>,
        Option<Column<f32>>,
    ) {
        (
            self.origin,
            self.positions,
            self.normals,
            self.colors,
            self.radii,
        )
    }
}

/// World positions as `f32` offsets from the centre of their bounds (of their inliers' when
/// far outliers would pull it away: [`crate::framing::inlier_origin`]), and that centre: how
/// the readers that decode `f64` coordinates keep georeferenced data precise.
pub(crate) fn centred(world: &[[f64; 3]]) -> (DVec3, Vec<[f32; 3]>) {
    let (lo, hi) = world
        .iter()
        .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(DVec3::from(*p)), hi.max(DVec3::from(*p)))
        });
    let origin = crate::framing::inlier_origin(world, lo, hi).unwrap_or((lo + hi) * 0.5);
    let local = world
        .iter()
        .map(|p| (DVec3::from(*p) - origin).as_vec3().to_array())
        .collect();
    (origin, local)
}

fn bounds_parallel(p: &[[f32; 3]]) -> Aabb {
    use rayon::prelude::*;
    p.par_chunks(1 << 16)
        .map(Aabb::from_points)
        .reduce(|| Aabb::EMPTY, Aabb::union)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn rejects_nan_and_mismatched_columns() {
        let p = vec![[0.0, 0.0, 0.0], [f32::NAN, 1.0, 0.0]];
        let e = PointCloud::new(DVec3::ZERO, p.into(), None, None, None).unwrap_err();
        assert!(e.to_string().contains("position 1"), "{e}");
        let p = vec![[0.0, 0.0, 0.0]; 3];
        let e = PointCloud::new(
            DVec3::ZERO,
            p.into(),
            Some(vec![[0.0, 0.0, 1.0]; 2].into()),
            None,
            None,
        )
        .unwrap_err();
        assert!(e.to_string().contains("'normal' has 2"), "{e}");
        let e = PointCloud::new(DVec3::ZERO, Vec::new().into(), None, None, None).unwrap_err();
        assert!(e.to_string().contains("no samples"), "{e}");
    }

    #[test]
    fn origin_keeps_precision() {
        let origin = DVec3::new(500_000.0, 4_100_000.0, 10.0);
        let c =
            PointCloud::new(origin, vec![[0.001, 0.002, 0.0]].into(), None, None, None).unwrap();
        let w = c.world_position(0);
        assert!((w.x - 500_000.001).abs() < 1e-6 && (w.y - 4_100_000.002).abs() < 1e-6);
        assert_eq!(c.attributes(), Attributes::default());
    }
}
