//! `voxel`'s build: `potree`'s shared build in the Potree 2.0 format
//! ([`crate::potree::build::build_format`]: the cube and its `int32` quantisation, the
//! octree split at `max_leaf` points, in core or in units, the files breadth first) with
//! the inner nodes filled by [`VoxelFill`]: one sample per occupied cell of the node's 128³
//! grid, the mean of its children's samples in it (or of every input point below it:
//! [`super::Filter`]). Leaves keep the original points; no point is
//! moved, so a cloud's `N` points are all in the leaves and the voxels come on top.

use std::path::Path;

use scenes::{PointCloud, Progress};

use super::grid::VoxelFill;
use super::{FORMAT_VERSION, INFO_FILE, NAME, VoxelParams};
use crate::potree::build::{Format, Input, build_format};
use crate::{BuildStats, MethodError, Params};

/// Builds the voxel octree of `cloud` into `dir`: `octree.bin`, `hierarchy.bin`,
/// `metadata.json`, `voxel.json`, then the manifest last.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let p = VoxelParams::from_params(params)?;
    let format = Format::of(NAME, FORMAT_VERSION, INFO_FILE, &p.potree());
    let mut extra = serde_json::Map::new();
    extra.insert(
        "position".into(),
        serde_json::to_value(p.position).unwrap_or_default(),
    );
    extra.insert(
        "filter".into(),
        serde_json::to_value(p.filter).unwrap_or_default(),
    );
    extra.insert("grid".into(), super::grid::GRID.into());
    let fill = |quant: &crate::potree::octree::Quant, bytes_per_point: usize| VoxelFill {
        cloud,
        quant: *quant,
        position: p.position,
        filter: p.filter,
        bytes_per_point,
    };
    let input = Input {
        cloud,
        params,
        scene,
        dir,
        hook: None,
    };
    build_format(input, &format, fill, extra, progress)
}
