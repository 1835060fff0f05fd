//! `voxel`'s parameters (`--param`): the build's (leaf capacity, voxel position, colour
//! filter, hierarchy chunks, memory) and the runtime ones ([`RUNTIME_PARAMS`], shared with `potree`, whose
//! reader and selection `voxel` uses). Defaults are the paper's (Schütz et al. 2023) where
//! it states one, Potree's where `voxel` reads the Potree format; each is argued in
//! `README.md`.

use super::NAME;
use crate::potree::{LoadMode, PotreeParams};
use crate::{MethodError, Params};

/// Parameters read at `open` only (`potree`'s, and `sizing`).
pub const RUNTIME_PARAMS: &[&str] = &[
    "min_node_px",
    "point_size",
    "min_px",
    "core_mb",
    "delay_frames",
    "in_flight",
    "load",
    "sizing",
];

/// How large a voxel's splat is (`--param sizing=`; leaves are sized by their own spacing
/// either way).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Sizing {
    /// Its cell's corners only (`√3·s` across): the paper's pixel-sized voxels taken
    /// literally, with holes where the data is sparser than the cells (the default: the
    /// paper's).
    #[default]
    Cell,
    /// A departure: its cell's corners, and across the gaps where its node's samples are
    /// sparser than its cells (`super::radii`): no holes where the data is sparse.
    Spacing,
}

/// Where an inner node's voxel sample lies (`--param position=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Position {
    /// The voxel's centre (the paper's: a voxel is a cell of its node's grid): samples on a
    /// regular grid, whose splats cover every voxel of the surface.
    #[default]
    Centre,
    /// The mean of the voxel's points (a departure): closer to the surface, off the grid.
    Mean,
}

/// What an inner node's voxel averages (`--param filter=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Filter {
    /// The mean of its children's samples in the cell: a child's voxel counts as one
    /// sample, as a leaf child's point does (the authors' "average in cell",
    /// `AVERAGE_SINGLECELL` of their published code: the default, the paper's).
    #[default]
    Children,
    /// A departure: the exact mean of every input point below it in the cell (a child's
    /// voxel weighted by the points it holds), a box filter of the input over the cell.
    Points,
}

/// Parameters of `voxel`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct VoxelParams {
    /// A node with more points than this is split into octants; leaves hold the original
    /// points (the paper's split threshold, 50,000).
    pub max_leaf: u32,
    /// Where a voxel's sample lies.
    pub position: Position,
    /// What a voxel's colour and normal average.
    pub filter: Filter,
    /// Levels per hierarchy chunk of the Potree files (PotreeConverter: 4).
    pub step: u32,
    /// Working memory of the build, MiB (≥ 1): a cloud of more than `mem_mb·2²⁰ / 64`
    /// points is built in units (`potree::ooc`); the files do not depend on it.
    pub mem_mb: u64,
    /// Smallest projected node radius, pixels, refined into under a budget: 64·√3 = 110.85,
    /// the radius of a node whose 128 voxels across project to 1 pixel each (the paper's
    /// pixel-sized voxels; Potree's 150 would stop at 1.35 px).
    pub min_node_px: f32,
    /// Scale on every splat's radius (1: a voxel's splat is its diagonal across).
    pub point_size: f32,
    /// Smallest splat drawn, pixels (1: the paper's pixel-sized voxels and points).
    pub min_px: f32,
    /// How large a voxel's splat is.
    pub sizing: Sizing,
    /// Decoded nodes kept in core, MiB.
    pub core_mb: u64,
    /// Frames between a request and the moment its node counts as loaded.
    pub delay_frames: u32,
    /// Requests in flight at once; absent: 1 for a local directory, 4 over HTTP.
    pub in_flight: Option<u32>,
    /// Asynchronous (default) or synchronous loading.
    pub load: LoadMode,
}

/// [`VoxelParams::min_node_px`]'s default: 64·√3 (a node's bounding-sphere radius is
/// `√3/2 · side`, its voxel `side / 128`).
pub const MIN_NODE_PX: f32 = 110.851_25;

impl Default for VoxelParams {
    fn default() -> Self {
        Self {
            max_leaf: 50_000,
            position: Position::Centre,
            filter: Filter::Children,
            step: 4,
            mem_mb: 256,
            min_node_px: MIN_NODE_PX,
            point_size: 1.0,
            min_px: 1.0,
            sizing: Sizing::Cell,
            core_mb: 256,
            delay_frames: 0,
            in_flight: None,
            load: LoadMode::Async,
        }
    }
}

impl VoxelParams {
    /// Parses and validates `--param` pairs (errors name the parameter).
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: VoxelParams = params.to_typed(NAME)?;
        p.potree().validate().map_err(|e| match e {
            MethodError::Param(m) => {
                MethodError::Param(m.replace("method 'potree'", "method 'voxel'"))
            }
            other => other,
        })?;
        Ok(p)
    }

    /// The same settings as `potree`'s parameters: the reader, the loader and the selection
    /// are `potree`'s.
    pub fn potree(&self) -> PotreeParams {
        PotreeParams {
            max_leaf: self.max_leaf,
            step: self.step,
            mem_mb: self.mem_mb,
            min_node_px: self.min_node_px,
            point_size: self.point_size,
            min_px: self.min_px,
            core_mb: self.core_mb,
            delay_frames: self.delay_frames,
            in_flight: self.in_flight,
            load: self.load,
            ..PotreeParams::default()
        }
    }
}
