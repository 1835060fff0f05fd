//! `potree`'s parameters (`--param`): the build's (sampling, node size, hierarchy chunks)
//! and the runtime ones ([`RUNTIME_PARAMS`]). Defaults are PotreeConverter 2.0's and the
//! Potree viewer's.

use super::NAME;
use crate::{MethodError, Params};

/// Parameters read at `open` only: a run of an existing build (or of a PotreeConverter
/// output directory) may change them.
pub const RUNTIME_PARAMS: &[&str] = &[
    "min_node_px",
    "point_size",
    "min_px",
    "core_mb",
    "delay_frames",
    "in_flight",
    "load",
];

/// How an inner node's points are chosen from its children's (`--param sampling=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Sampling {
    /// Poisson-disk: candidates by distance from the node's centre, each accepted if no
    /// accepted point lies within the level's spacing (PotreeConverter's default).
    #[default]
    Poisson,
    /// Random: candidates in a seeded random order, at most one per cell of the node's 128³
    /// grid, and only near the cell's centre (PotreeConverter's `-m random`).
    Random,
}

/// How nodes that are not in core are handled (`--param load=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LoadMode {
    /// As the viewer: request them, draw what is loaded (the parent covers a loading child).
    #[default]
    Async,
    /// Read every wanted node before drawing, traversing again until nothing is missing: the
    /// converged frame in one frame (stalls show in `cpu_select_ms`).
    Sync,
}

/// Parameters of `potree`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct PotreeParams {
    /// Subsampling of inner nodes.
    pub sampling: Sampling,
    /// A node with more points than this is split into octants (PotreeConverter: 10,000).
    pub max_leaf: u32,
    /// Levels per hierarchy chunk (PotreeConverter: 4).
    pub step: u32,
    /// Seed of `sampling=random` (the converter seeds from the clock; ours is reproducible).
    pub seed: u64,
    /// Working memory of the build, MiB (≥ 1): a cloud of more than `mem_mb·2²⁰ / 64`
    /// points is built in units ([`super::ooc`]); the files do not depend on it.
    pub mem_mb: u64,
    /// Smallest projected node radius, pixels, refined into (Potree's
    /// `minimumNodePixelSize`, 150); budget targets only.
    pub min_node_px: f32,
    /// Point size factor (Potree's material `size`, 1): a splat is `1.7 · size · spacing`
    /// of its node across, projected.
    pub point_size: f32,
    /// Smallest splat drawn, pixels (Potree's material `minSize`, 2).
    pub min_px: f32,
    /// Decoded nodes kept in core, MiB.
    pub core_mb: u64,
    /// Frames between a request and the moment its node counts as loaded (simulated
    /// latency; 0 = as soon as decoded).
    pub delay_frames: u32,
    /// Requests in flight at once; absent: 1 for a local directory, 4 over HTTP (Potree's
    /// `maxNodesLoading`).
    pub in_flight: Option<u32>,
    /// Asynchronous (default) or synchronous loading.
    pub load: LoadMode,
}

impl Default for PotreeParams {
    fn default() -> Self {
        Self {
            sampling: Sampling::Poisson,
            max_leaf: 10_000,
            step: 4,
            seed: 0,
            mem_mb: 256,
            min_node_px: 150.0,
            point_size: 1.0,
            min_px: 2.0,
            core_mb: 256,
            delay_frames: 0,
            in_flight: None,
            load: LoadMode::Async,
        }
    }
}

impl PotreeParams {
    /// Parses and validates `--param` pairs (errors name the parameter).
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: PotreeParams = params.to_typed(NAME)?;
        p.validate()?;
        Ok(p)
    }

    /// Checks every field; the error names the parameter and the accepted range.
    pub fn validate(&self) -> Result<(), MethodError> {
        let bad = |msg: String| Err(MethodError::Param(format!("method '{NAME}': {msg}")));
        if self.max_leaf < 1 {
            return bad(format!("max_leaf must be ≥ 1, got {}", self.max_leaf));
        }
        crate::params::check_mb(NAME, "mem_mb", self.mem_mb, 1)?;
        crate::params::check_mb(NAME, "core_mb", self.core_mb, 1)?;
        if !(1..=super::format::MAX_LEVEL).contains(&self.step) {
            return bad(format!(
                "step must be in 1..={}, got {}",
                super::format::MAX_LEVEL,
                self.step
            ));
        }
        for (name, v) in [
            ("min_node_px", self.min_node_px),
            ("point_size", self.point_size),
            ("min_px", self.min_px),
        ] {
            if !v.is_finite() || v < 0.0 {
                return bad(format!("{name} must be a finite number ≥ 0, got {v}"));
            }
        }
        if self.point_size == 0.0 {
            return bad("point_size must be > 0".into());
        }
        crate::store::access::check_in_flight(NAME, self.in_flight)
    }
}
