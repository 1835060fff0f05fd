//! `mwkd`: the multi-way kd-tree of Goswami, Erol, Mukhi, Pajarola and Gobbetti (~2010;
//! `/work/shared/papers/mwkd-multiway-kd-tree.txt`, `/work/shared/METHODS.md`).
//!
//! This module holds the first pieces of the method (the `LodMethod` build/render is not
//! written yet, so `mwkd` is **not** in the registry):
//!
//! - [`MwkdParams`]: the `--param` keys (`fanout`, `vbo`, `grid`, `theta`, …), validated with
//!   errors naming the parameter;
//! - [`tree`]: the plan of the fully balanced `N`-ary tree computed from `(n, N, s)` alone in
//!   exact integer arithmetic ([`tree::Plan`], used by `splatbench plan`, reproduces the
//!   paper's Table II), the real split of a cloud into that tree ([`tree::Tree`]) and the
//!   bottom-up LOD build with representatives ([`tree::Lod`]);
//! - [`reps`]: the `Representatives` procedure — a pure function from a set of splats to
//!   exactly the requested number of representatives (K³ grid, normal/colour clustering with
//!   a relaxed θ driven by a priority queue of per-cell cluster lists);
//! - [`codec`]: the per-node data codec (16-bit positions in the node box, 8-bit radii rounded
//!   up, 16-bit 6×104×104 cube-map normals, optional colours; strict decoding).
//!
//! See `README.md` next to this file for the rules and what is faithful or deviating.

pub mod codec;
pub mod reps;
pub mod tree;

use crate::{MethodError, Params};

/// Registry name (and `splatbench plan --method` value).
pub const NAME: &str = "mwkd";

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
}

impl Default for MwkdParams {
    fn default() -> Self {
        Self {
            fanout: 4,
            vbo: 32_768,
            grid: 35,
            theta: 30.0,
            relax: 1.5,
            color_threshold: 30.0,
            queue: QueueOrder::Length,
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
        if self.vbo < u64::from(self.fanout) {
            return bad(format!(
                "vbo must be ≥ fanout (each of the {} children passes vbo/fanout ≥ 1 \
                 representatives up), got vbo={}",
                self.fanout, self.vbo
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
        Ok(())
    }

    /// The representative-selection settings these parameters give.
    pub fn rep_config(&self) -> reps::RepConfig {
        reps::RepConfig {
            grid: self.grid,
            theta_deg: self.theta,
            relax: self.relax,
            color_threshold: self.color_threshold,
            queue: self.queue,
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
