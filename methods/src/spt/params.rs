//! SPT's parameters: the interval test's error mode, the bounding volume of the prefix, and
//! their parsing from `--param`.

use super::*;

/// Error mode of the interval test.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SptMode {
    /// `ẽ_g = e_g / r` (view-angle independent).
    #[default]
    Unified,
    /// `ẽ_p + ẽ_t = (e_p·sin α + e_t·cos α) / r` (needs normals).
    Split,
}

/// Which bounding volume of a cluster's node centres gives the per-frame lower bound `r_lo`
/// of the view distance (the prefix search's only view input).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum SptBound {
    /// The cluster's bounding sphere (`index.json`): the nearest point of the sphere.
    #[default]
    Sphere,
    /// The larger of the sphere's bound and the distance to the axis-aligned box of the
    /// cluster's node centres (computed at `open`). A departure: tighter on elongated objects.
    Box,
}

/// Parameters of `spt`.
#[derive(Debug, Clone, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct SptParams {
    /// `unified` or `split`.
    pub mode: SptMode,
    /// Overlap factor `o` on each node's distance `δ` to its parent (1 = hole-free in
    /// unified mode, 0 = the paper's bare intervals).
    pub overlap: f32,
    /// 128 lists by normal, back-facing lists skipped per frame (needs normals).
    pub normal_clusters: bool,
    /// Colour rule threshold, largest per-channel difference among children in 0..=255
    /// (≥ 255 disables the rule; ignored without colours).
    pub color_threshold: f32,
    /// GPU memory the whole model may take, MiB (`open` refuses larger models).
    pub gpu_limit_mb: u64,
    /// Compute the `cpu_passed` counter (O(prefix) per frame); NaN otherwise.
    pub cpu_mirror: bool,
    /// Bounding volume of the per-frame lower bound `r_lo` (`sphere`, the default, or `box`).
    pub bound: SptBound,
    /// Working memory of the build in MiB (≥ 16): a larger cloud is built in units
    /// ([`super::ooc`]); the files are the same for any value.
    pub mem_mb: u64,
}

impl Default for SptParams {
    fn default() -> Self {
        Self {
            mode: SptMode::Unified,
            overlap: 1.0,
            normal_clusters: false,
            color_threshold: 40.0,
            gpu_limit_mb: 4096,
            cpu_mirror: false,
            bound: SptBound::Sphere,
            mem_mb: crate::params::BUILD_MEM_MB,
        }
    }
}

impl SptParams {
    /// Parses and checks `--param` values, as far as they can be checked without the scene
    /// (`check`, `--param` typos before a build).
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: SptParams = params.to_typed(NAME)?;
        if !(p.overlap.is_finite() && p.overlap >= 0.0) {
            return Err(MethodError::Param(format!(
                "method 'spt': overlap must be a finite number ≥ 0, got {}",
                p.overlap
            )));
        }
        if !(p.color_threshold.is_finite() && p.color_threshold >= 0.0) {
            return Err(MethodError::Param(format!(
                "method 'spt': color_threshold must be a finite number ≥ 0, got {}",
                p.color_threshold
            )));
        }
        crate::params::check_mb(NAME, "mem_mb", p.mem_mb, 16)?;
        crate::params::check_mb(NAME, "gpu_limit_mb", p.gpu_limit_mb, 1)?;
        Ok(p)
    }

    /// [`Self::from_params`], then what needs the scene's attributes.
    pub(super) fn parse(params: &Params, attrs: Attributes) -> Result<Self, MethodError> {
        let p = Self::from_params(params)?;
        if !attrs.normals && p.mode == SptMode::Split {
            return Err(MethodError::Param(
                "method 'spt': mode=split needs normals and the scene has none (use mode=unified)"
                    .into(),
            ));
        }
        if !attrs.normals && p.normal_clusters {
            return Err(MethodError::Param(
                "method 'spt': normal_clusters=true needs normals and the scene has none".into(),
            ));
        }
        Ok(p)
    }
}
