//! CLOD's per-point filter and point size (Schütz, Krösl, Wimmer 2019, §4 and the authors'
//! published shaders `filter_points.cs` and `pointcloud_clod.vs`): the CPU mirror of
//! `harness/src/render/clod.wgsl`, a line-for-line port (the renderer's tests compare the GPU's
//! pass counts and images with this).
//!
//! Every point carries its *spacing* `s = spacing₀ / 2^(level + u)` (`lod[0]`): `spacing₀` the
//! root's spacing of the octree the levels come from, `level` the depth of the node that
//! holds the point, `u ∈ [0, 1)` a fixed random offset per point — what makes the level of
//! detail continuous: a level is not switched on at one distance, its points come in one by
//! one as the distance shrinks. At distance `d` from the eye the *target spacing* is
//!
//! `t = scale · d / max(1 − fovea · |ndc|, FOVEA_FLOOR)`
//!
//! (`scale` = ε/k: ε pixels over the projection scale, so `t` is the size of ε pixels at `d`;
//! the denominator lowers the density away from the screen's centre, the paper's foveation,
//! `|ndc|` the point's distance from the centre in normalised device coordinates). A point is
//! kept when `s ≥ t`, it lies in front of the eye and within the *extended frustum*
//! `|ndc.x|, |ndc.y| ≤ EXTENT`. Its size in pixels fades in as `t` falls from `s` to
//! `BLEND · s`: `0.8 · u_b · clamp(SIZE_FACTOR · point_size · t · k / w, MIN_PX, MAX_PX)`, with
//! `u_b = 1 − clamp((t − BLEND·s) / (s − BLEND·s), 0, 1)` and `w` the view depth.

use glam::{Mat4, Vec3, Vec4};

/// The foveation's floor: density never falls below this share of the centre's (the shader's
/// `max(1 − 0.7·dc, 0.3)`).
pub const FOVEA_FLOOR: f32 = 0.3;
/// The extended frustum, in NDC: points up to twice the screen's half-extent are kept
/// (`filter_points.cs`: `extent = 2`; the paper reuses a filtered buffer over several
/// frames, during which the view may turn).
pub const EXTENT: f32 = 2.0;
/// Where a point's size reaches its full value: at a target spacing of `BLEND` × its own
/// spacing (`fullAt = 0.8 · pointSpacing`; zero at `t = s`).
pub const BLEND: f32 = 0.8;
/// The point size before the fade, per unit of target spacing at unit projection: the
/// shader's `2 · ws · pointSize` world diagonal projected (`2√2` in pixels of a square
/// viewport, hence `4√2`), times its final `0.8`.
pub const SIZE_FACTOR: f32 = 4.0 * std::f32::consts::SQRT_2 * 0.8;
/// The size clamp before the fade, pixels (`minPixels`, `maxPixels`).
pub const MIN_PX: f32 = 1.0;
/// See [`MIN_PX`].
pub const MAX_PX: f32 = 80.0;

/// The target spacing at `p` for a view whose `view_proj` maps `p` to `clip`, or `None`
/// when the filter drops `p` whatever its spacing (behind the eye, outside the extended
/// frustum).
#[inline]
pub fn target_spacing(p: Vec3, clip: Vec4, eye: Vec3, scale: f32, fovea: f32) -> Option<f32> {
    if clip.w <= 0.0 {
        return None;
    }
    let ndc_x = clip.x / clip.w;
    let ndc_y = clip.y / clip.w;
    if ndc_x.abs() > EXTENT || ndc_y.abs() > EXTENT {
        return None;
    }
    let dc = (ndc_x * ndc_x + ndc_y * ndc_y).sqrt();
    let v = p - eye;
    let d = v.dot(v).sqrt();
    Some(scale * d / (1.0 - fovea * dc).max(FOVEA_FLOOR))
}

/// True if a point of spacing `spacing` at `p` is kept.
#[inline]
pub fn keeps(p: Vec3, spacing: f32, view_proj: &Mat4, eye: Vec3, scale: f32, fovea: f32) -> bool {
    let clip = *view_proj * p.extend(1.0);
    target_spacing(p, clip, eye, scale, fovea).is_some_and(|t| spacing >= t)
}

/// The size in pixels of a kept point of spacing `spacing` whose target spacing is `t`, at
/// view depth `w` with projection scale `k`.
#[inline]
pub fn size_px(spacing: f32, t: f32, w: f32, k: f32, point_size: f32) -> f32 {
    let full = (SIZE_FACTOR * point_size * t * k / w).clamp(MIN_PX, MAX_PX);
    let fade = 1.0 - ((t - BLEND * spacing) / (spacing - BLEND * spacing)).clamp(0.0, 1.0);
    full * fade
}

/// The largest `scale` (ε/k) at which the point is still kept, or `None` when no scale keeps
/// it: `s · max(1 − fovea·|ndc|, floor) / d` (∞ at the eye). For choosing a scale that meets
/// a budget; the decision itself is [`keeps`].
#[inline]
pub fn scale_limit(p: Vec3, spacing: f32, view_proj: &Mat4, eye: Vec3, fovea: f32) -> Option<f32> {
    let clip = *view_proj * p.extend(1.0);
    let t = target_spacing(p, clip, eye, 1.0, fovea)?;
    Some(if t > 0.0 { spacing / t } else { f32::INFINITY })
}
