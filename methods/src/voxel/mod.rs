//! `voxel`: a colour-filtered voxel LOD after Schütz, Kerbl, Klaus, Wimmer, "GPU-Accelerated
//! LOD Generation for Point Clouds", Computer Graphics Forum 42(8), 2023: a hybrid
//! voxel–point octree whose inner nodes hold one sample per occupied cell of a 128³ grid,
//! with the mean colour (and normal) of its children's samples in the cell (or of every input
//! point below it: [`Filter`]), and whose leaves hold the
//! original points.
//!
//! It is written in the Potree 2.0 format and read by `potree`'s reader, loader and
//! selection (the same projected-size rule and budget); what differs is
//! - the inner nodes ([`grid`]: [`grid::VoxelFill`] fills them in `potree`'s shared build,
//!   in core or in units);
//! - the refinement: a drawn child **replaces** its parent's voxels in its octant
//!   ([`crate::potree::Refinement::Replacing`]), where Potree's nodes add up;
//! - the splat radii ([`radii`]): a voxel's sample reaches its cell's corners (and bridges
//!   the gaps where its node's samples are sparse), a leaf's points their k-NN spacing within
//!   the leaf.
//!
//! See `README.md` next to this file for what is faithful and what departs.

pub mod build;
pub mod grid;
mod params;

use std::path::Path;

use crate::potree::hierarchy::Span;
use crate::potree::{Mode, Potree, Refinement};
use crate::store::access::RepoAt;
use crate::{Manifest, MethodError, SplatBatch};
pub use build::build;
pub use params::{Filter, MIN_NODE_PX, Position, RUNTIME_PARAMS, Sizing, VoxelParams};

/// Registry name.
pub const NAME: &str = "voxel";
/// Version of what [`build()`] writes besides the Potree files (`voxel.json`).
pub const FORMAT_VERSION: u32 = 1;
/// What a build records beside the Potree files: the scene's origin (`potree::Info`).
pub const INFO_FILE: &str = "voxel.json";

/// How `potree`'s reader reads a `voxel` build with `sizing=spacing` (a departure: voxels
/// also bridge sparse gaps).
pub const MODE: Mode = Mode {
    name: NAME,
    refinement: Refinement::Replacing,
    radii,
};

/// [`MODE`] with `sizing=cell` (the default): every voxel its cell's diagonal across,
/// however sparse.
pub const MODE_CELL: Mode = Mode {
    name: NAME,
    refinement: Refinement::Replacing,
    radii: cell_radii,
};

/// The splat radii of a decoded node (positions sorted by octant), `sizing=spacing`.
///
/// - **A voxel** (inner node at level `L`, cells of side `s = spacing / 2^L`) reaches at
///   least its cell's corners, `√3/2 · s` (its disc covers the cell's projection from any
///   direction, so where the node's cells are contiguous they cover the surface without a
///   hole). On a contiguous surface a sample's [`crate::leaf::LEAF_K`]-th nearest sample in
///   the node is at most `√2 · s` away (the in-plane neighbours of its cell); where the
///   node's samples are sparser than its cells (few points, one per cell, cells apart) it is
///   farther, and the radius grows by the excess, bridging the gap as the reference's
///   spacing does for points: `√3/2 · s + max(0, d_k − √2 · s)`.
/// - **A leaf's points** are the original samples: each is drawn with its distance to its
///   [`crate::leaf::LEAF_K`]-th nearest neighbour *within the leaf* (the radius every other
///   method and the reference give a sample, there over the whole cloud; within the leaf it
///   is the same or larger at the leaf's faces).
///
/// Distances are capped for isolated samples as [`crate::leaf::cap_isolated`] does; a node
/// of one sample is drawn as a voxel of its level.
pub fn radii(s: &Span, spacing: f64, b: &mut SplatBatch) {
    let cell = spacing / f64::from(1u32 << s.level.min(31));
    let voxel = cell_radius(s, spacing);
    let own = (b.len() > 1).then(|| {
        let mut r = scenes::spacing::knn_spacing(&b.positions, crate::leaf::LEAF_K);
        crate::leaf::cap_isolated(&mut r);
        r
    });
    if let Some(r) = b.radii.as_mut() {
        match own {
            Some(own) if s.leaf => *r = own,
            Some(own) => {
                let contiguous = (cell * std::f64::consts::SQRT_2) as f32;
                for (r, d) in r.iter_mut().zip(own) {
                    *r = voxel + (d - contiguous).max(0.0);
                }
            }
            None => r.fill(voxel),
        }
    }
}

/// `sizing=cell`: leaves as [`radii`], every voxel `√3/2 · s` (the cell's half diagonal).
pub fn cell_radii(s: &Span, spacing: f64, b: &mut SplatBatch) {
    if s.leaf {
        return radii(s, spacing, b);
    }
    let voxel = cell_radius(s, spacing);
    if let Some(r) = b.radii.as_mut() {
        r.fill(voxel);
    }
}

/// Half the diagonal of a cell of the node's grid.
fn cell_radius(s: &Span, spacing: f64) -> f32 {
    let cell = spacing / f64::from(1u32 << s.level.min(31));
    (cell * 3f64.sqrt() * 0.5) as f32
}

/// Opens a build written by [`build()`].
pub fn open(dir: &Path, manifest: Manifest) -> Result<Potree, MethodError> {
    let octree = RepoAt::Local(dir.join(crate::potree::format::OCTREE_FILE));
    open_at(dir, manifest, &octree)
}

/// [`open`] with `octree.bin` read at `octree` (served elsewhere: `--build-url`).
pub fn open_at(dir: &Path, manifest: Manifest, octree: &RepoAt) -> Result<Potree, MethodError> {
    let params = VoxelParams::from_params(&manifest.params)?;
    let mode = match params.sizing {
        Sizing::Spacing => MODE,
        Sizing::Cell => MODE_CELL,
    };
    Potree::open_build(dir, &manifest, INFO_FILE, &params.potree(), mode, octree)
}
