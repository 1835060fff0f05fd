//! MWKD's parameters (`--param`): the build's (split, representatives, memory) and the
//! runtime ones a run of an existing build may change ([`RUNTIME_PARAMS`]).

use super::select::Metric;
use super::{NAME, reps, tree};
use crate::{MethodError, Params};

/// Deepest level of an ablation octree (deeper nodes stay leaves: piles of duplicates).
pub const OCTREE_MAX_DEPTH: u32 = 24;

/// Parameters read at `open` only (rendering, data access): a run of an existing build may
/// change them ([`crate::MethodKind::open_with`]).
pub const RUNTIME_PARAMS: &[&str] = &[
    "c0",
    "c1",
    "c2",
    "core_mb",
    "delay_frames",
    "in_flight",
    "occlusion",
    "occlusion_threshold",
    "load",
];

/// How front nodes that are not in core are handled (`--param load=`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum LoadMode {
    /// The paper's asynchronous loading with the four transitions (stand-ins, never a hole).
    #[default]
    Async,
    /// Every missing front node is read synchronously before the frame is drawn: the
    /// "fully loaded" frame (the reference of the delayed-loader test), and the naive
    /// behaviour the paper's scheme avoids (stalls show in `cpu_select_ms`).
    Sync,
}

/// The hierarchy built (`--param tree=`): the paper's multi-way kd-tree, or one of the
/// structures its Table IV compares it with, under the same representatives and renderer.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum TreeKind {
    /// Fully balanced `N`-ary kd-tree (fan-out `fanout`).
    #[default]
    Mwkd,
    /// Binary kd-tree: the same median split with `N = 2` (`fanout` is ignored).
    Kd,
    /// Octree: regular subdivision of the bounding cube until a node holds ≤ `vbo` samples.
    Octree,
}

/// How the priority queue of per-cell cluster lists is ordered (paper: "the maximum normal
/// deviation of a point from its neighbors in l, or alternatively simply the length of l").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum QueueOrder {
    /// Longest list first.
    #[default]
    Length,
    /// List with the largest normal deviation (cluster normal vs the list's mean) first.
    Deviation,
}

/// How a node's representatives are chosen (paper, Fig. 2: "a simple grid based sampling
/// approach … and our adaptive clustering").
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Clustering {
    /// The paper's: clusters merged within grid cells by normal (and colour) until exactly
    /// `s/N` remain ([`reps`]).
    #[default]
    Adaptive,
    /// Fig. 2's comparison: one representative per occupied cell, the average of the cell's
    /// splats, with the grid lowered until at most `s/N` cells are occupied (so a node may
    /// pass fewer than `s/N` up).
    Grid,
}

/// Parameters of `mwkd`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct MwkdParams {
    /// Fan-out `N` of the kd-tree (≥ 2).
    pub fanout: u32,
    /// Target VBO size `s`: samples per leaf (±1, see [`tree::leaf_depth`]) and
    /// representatives per inner node (each of the `N` children passes `s/N` up). `s ≥ N`.
    pub vbo: u64,
    /// `K` of the auxiliary K³ clustering grid (paper: 35, 35–45).
    pub grid: u32,
    /// Normal-deviation threshold θ, degrees, in `(0, 180]`.
    pub theta: f32,
    /// Factor θ (and the colour threshold) is multiplied by each time it is relaxed (> 1).
    pub relax: f32,
    /// Colour threshold: largest per-channel difference of cluster mean colours (0..=255)
    /// allowed in a merge before relaxation (> 0; ignored when the scene has no colours).
    pub color_threshold: f32,
    /// Order of the priority queue of cluster lists.
    pub queue: QueueOrder,
    /// Representatives by adaptive clustering (default) or plain grid averaging (Fig. 2).
    pub clustering: Clustering,
    /// Hierarchy: `mwkd` (default), `kd` or `octree` (the paper's Table IV).
    pub tree: TreeKind,
    /// Working memory of the build, MiB (≥ 16): a cloud of more than
    /// `mem_mb·2²⁰ / `[`super::ooc::UNIT_BYTES_PER_SAMPLE`] samples is split by streaming
    /// and built in units of at most that many ([`super::ooc`]; not `tree=octree`); the
    /// files do not depend on it.
    pub mem_mb: u64,
    /// `c₀` of `ε_l = c₀(l_max − l + 1)/(c₁d + c₂d²)` (> 0).
    pub c0: f32,
    /// `c₁` (≥ 0).
    pub c1: f32,
    /// `c₂` (≥ 0; `c₁ + c₂ > 0`).
    pub c2: f32,
    /// Decoded nodes kept in core, MiB.
    pub core_mb: u64,
    /// Frames between a request and the moment its node counts as available: simulated
    /// latency, exact for d ≥ 1 (the frame waits for a late decode, so counts repeat); 0 = as
    /// soon as the loader thread has decoded it.
    pub delay_frames: u32,
    /// Requests in flight at once (loader threads); 1 for a local repository, 4 for one
    /// served over HTTP when absent ([`crate::store::access::RepoAt::in_flight`]).
    pub in_flight: Option<u32>,
    /// Occlusion culling with occlusion queries (as LPC's three phases).
    pub occlusion: bool,
    /// Fragments a node's sphere must pass to count as visible.
    pub occlusion_threshold: u64,
    /// Asynchronous loading with stand-ins (default) or synchronous reads.
    pub load: LoadMode,
    /// Store nodes LZO-compressed (the paper's choice, default) or, `lzo=false`, as is: the
    /// comparison behind §V-B's "performance … and display quality are hardly affected at
    /// all due to the current compression". A build parameter (the files differ).
    pub lzo: bool,
}

impl Default for MwkdParams {
    fn default() -> Self {
        Self {
            fanout: 4,
            vbo: 8192,
            grid: 35,
            theta: 30.0,
            relax: 1.5,
            color_threshold: 30.0,
            queue: QueueOrder::Length,
            clustering: Clustering::Adaptive,
            tree: TreeKind::Mwkd,
            mem_mb: crate::params::BUILD_MEM_MB,
            c0: 1.0,
            c1: 1.0,
            c2: 0.0,
            core_mb: 256,
            delay_frames: 0,
            in_flight: None,
            occlusion: false,
            occlusion_threshold: 0,
            load: LoadMode::Async,
            lzo: true,
        }
    }
}

impl MwkdParams {
    /// Parses and validates `--param` pairs (errors name the parameter).
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: MwkdParams = params.to_typed(NAME)?;
        p.validate()?;
        Ok(p)
    }

    /// Checks every field; the error names the parameter and the accepted range.
    pub fn validate(&self) -> Result<(), MethodError> {
        let bad = |msg: String| Err(MethodError::Param(format!("method '{NAME}': {msg}")));
        if self.fanout < 2 {
            return bad(format!("fanout must be ≥ 2, got {}", self.fanout));
        }
        if self.vbo < 1 {
            return bad(format!("vbo must be ≥ 1, got {}", self.vbo));
        }
        if self.vbo < u64::from(self.effective_fanout()) {
            return bad(format!(
                "vbo must be ≥ fanout (each of the {} children passes vbo/fanout ≥ 1 \
                 representatives up), got vbo={}",
                self.effective_fanout(),
                self.vbo
            ));
        }
        if self.grid < 1 || self.grid > 1024 {
            return bad(format!("grid must be in 1..=1024, got {}", self.grid));
        }
        if !(self.theta.is_finite() && self.theta > 0.0 && self.theta <= 180.0) {
            return bad(format!(
                "theta must be in (0, 180] degrees, got {}",
                self.theta
            ));
        }
        if !(self.relax.is_finite() && self.relax > 1.0) {
            return bad(format!(
                "relax must be a finite number > 1, got {}",
                self.relax
            ));
        }
        if !(self.color_threshold.is_finite() && self.color_threshold > 0.0) {
            return bad(format!(
                "color_threshold must be a finite number > 0, got {}",
                self.color_threshold
            ));
        }
        crate::params::check_mb(NAME, "mem_mb", self.mem_mb, 16)?;
        if !(self.c0.is_finite() && self.c0 > 0.0) {
            return bad(format!("c0 must be a finite number > 0, got {}", self.c0));
        }
        for (name, v) in [("c1", self.c1), ("c2", self.c2)] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(format!("{name} must be a finite number ≥ 0, got {v}"));
            }
        }
        if self.c1 + self.c2 <= 0.0 {
            return bad("c1 + c2 must be > 0 (ε_l divides by c1·d + c2·d²)".into());
        }
        crate::params::check_mb(NAME, "core_mb", self.core_mb, 1)?;
        crate::store::access::check_in_flight(NAME, self.in_flight)?;
        Ok(())
    }

    /// The fan-out the split uses (`2` for `tree=kd`, `8` at most for `tree=octree`).
    pub fn effective_fanout(&self) -> u32 {
        match self.tree {
            TreeKind::Mwkd => self.fanout,
            TreeKind::Kd => 2,
            TreeKind::Octree => 8,
        }
    }

    /// The split of `positions` these parameters ask for.
    pub fn split(&self, positions: &[[f32; 3]]) -> Result<tree::Tree, MethodError> {
        match self.tree {
            TreeKind::Mwkd | TreeKind::Kd => {
                tree::Tree::split(positions, self.effective_fanout(), self.vbo)
            }
            TreeKind::Octree => tree::Tree::octree(positions, self.vbo, OCTREE_MAX_DEPTH),
        }
    }

    pub(super) fn metric(&self) -> Metric {
        Metric {
            c0: self.c0,
            c1: self.c1,
            c2: self.c2,
        }
    }

    /// What the unit build ([`super::ooc`]) needs of these parameters.
    pub fn ooc_shape(&self) -> super::ooc::Shape {
        super::ooc::Shape {
            fanout: self.effective_fanout(),
            vbo: self.vbo,
            reps: self.rep_config(),
            compression: self.compression(),
        }
    }

    /// How nodes are stored.
    pub fn compression(&self) -> crate::store::Compression {
        if self.lzo {
            crate::store::Compression::Lzo
        } else {
            crate::store::Compression::None
        }
    }

    /// The representative-selection settings these parameters give.
    pub fn rep_config(&self) -> reps::RepConfig {
        reps::RepConfig {
            grid: self.grid,
            theta_deg: self.theta,
            relax: self.relax,
            color_threshold: self.color_threshold,
            queue: self.queue,
            clustering: self.clustering,
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn parse(pairs: &[&str]) -> Result<MwkdParams, MethodError> {
        MwkdParams::from_params(&Params::parse(pairs).unwrap())
    }

    #[test]
    fn params_defaults_and_validation() {
        let p = parse(&[]).unwrap();
        assert_eq!(p, MwkdParams::default());
        let p = parse(&["fanout=6", "vbo=4009", "grid=45", "queue=deviation"]).unwrap();
        assert_eq!((p.fanout, p.vbo, p.grid), (6, 4009, 45));
        assert_eq!(p.queue, QueueOrder::Deviation);
        for (args, needle) in [
            (&["fanout=1"][..], "fanout"),
            (&["vbo=0"][..], "vbo"),
            (&["fanout=8", "vbo=7"][..], "vbo must be ≥ fanout"),
            (&["grid=0"][..], "grid"),
            (&["theta=0"][..], "theta"),
            (&["theta=181"][..], "theta"),
            (&["relax=1"][..], "relax"),
            (&["color_threshold=-1"][..], "color_threshold"),
            (&["fanuot=3"][..], "fanuot"),
            (&["fanout=-3"][..], "mwkd"),
        ] {
            let e = parse(args).unwrap_err().to_string();
            assert!(e.contains(needle), "{args:?}: {e}");
        }
    }
}
