//! `voxel`: a colour-filtered voxel LOD after Schütz, Kerbl, Klaus, Wimmer, "GPU-Accelerated
//! LOD Generation for Point Clouds", Computer Graphics Forum 42(8), 2023: a hybrid
//! voxel–point octree whose inner nodes hold one sample per occupied cell of a 128³ grid,
//! with the mean colour (and normal) of the points below it, and whose leaves hold the
//! original points.
//!
//! It is written in the Potree 2.0 format and read by `potree`'s reader, loader and
//! selection (the same projected-size rule and budget); what differs is
//! - the inner nodes ([`grid`]: [`grid::VoxelFill`] fills them in `potree`'s shared build,
//!   in core or in units);
//! - the refinement: a drawn child **replaces** its parent's voxels in its octant
//!   ([`crate::potree::Refinement::Replacing`]), where Potree's nodes add up;
//! - the splat radii ([`radii`]): a voxel's sample is its cell's diagonal across, a leaf's
//!   points their k-NN spacing within the leaf.
//!
//! See `README.md` next to this file for what is faithful and what departs.

pub mod build;
pub mod grid;
mod params;

use std::path::Path;

use crate::potree::hierarchy::Span;
use crate::potree::{Mode, Potree, Refinement};
use crate::{Manifest, MethodError, SplatBatch};
pub use build::build;
pub use params::{MIN_NODE_PX, Position, RUNTIME_PARAMS, VoxelParams};

/// Registry name.
pub const NAME: &str = "voxel";
/// Version of what [`build()`] writes besides the Potree files (`voxel.json`).
pub const FORMAT_VERSION: u32 = 1;
/// What a build records beside the Potree files: the scene's origin (`potree::Info`).
pub const INFO_FILE: &str = "voxel.json";

/// How `potree`'s reader reads a `voxel` build.
pub const MODE: Mode = Mode {
    name: NAME,
    refinement: Refinement::Replacing,
    radii,
};

/// The splat radii of a decoded node (positions sorted by octant).
///
/// - **A voxel** (inner node at level `L`, cells of side `s = spacing / 2^L`) is drawn
///   `√3·s` across, its cell's diagonal: the disc around the cell's centre then covers the
///   cell's projection from any direction, and as every point of the surface lies in an
///   occupied cell, the voxels of a node cover the surface's projection without a hole.
/// - **A leaf's points** are the original samples: each is drawn with its distance to its
///   [`crate::leaf::LEAF_K`]-th nearest neighbour *within the leaf* (the radius every other
///   method and the reference give a sample, there over the whole cloud; within the leaf it
///   is the same or larger at the leaf's faces), isolated ones capped as
///   [`crate::leaf::cap_isolated`] does. A leaf of one point is drawn as a voxel of its
///   level.
pub fn radii(s: &Span, spacing: f64, b: &mut SplatBatch) {
    let cell = spacing / f64::from(1u32 << s.level.min(31));
    let voxel = (cell * 3f64.sqrt() * 0.5) as f32;
    let leaf = s.leaf && b.len() > 1;
    let own = leaf.then(|| {
        let mut r = scenes::spacing::knn_spacing(&b.positions, crate::leaf::LEAF_K);
        crate::leaf::cap_isolated(&mut r);
        r
    });
    if let Some(r) = b.radii.as_mut() {
        match own {
            Some(own) => *r = own,
            None => r.fill(voxel),
        }
    }
}

/// Opens a build written by [`build()`].
pub fn open(dir: &Path, manifest: Manifest) -> Result<Potree, MethodError> {
    let params = VoxelParams::from_params(&manifest.params)?;
    Potree::open_build(dir, &manifest, INFO_FILE, &params.potree(), MODE)
}
