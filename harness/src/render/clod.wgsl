// CLOD (Schütz, Krösl, Wimmer 2019): the per-point filter and point size of the vertex stage
// (and of the counting and compute passes) — a line-for-line port of `methods::clod::select`,
// the CPU mirror; the renderer's tests compare GPU pass counts and images with it.
//
// lod.x = the point's spacing s = spacing0 / 2^(level + u). Target spacing at the point:
// t = scale · distance / max(1 − fovea·|ndc|, CLOD_FOVEA_FLOOR); kept when s ≥ t, in front of
// the eye and within |ndc| ≤ CLOD_EXTENT. Size: CLOD_SIZE_FACTOR · point_size · t · k / w,
// clamped to CLOD_MIN_PX..CLOD_MAX_PX, faded to 0 as t rises from CLOD_BLEND·s to s.

const CLOD_FOVEA_FLOOR: f32 = 0.3;
const CLOD_EXTENT: f32 = 2.0;
const CLOD_BLEND: f32 = 0.8;
const CLOD_SIZE_FACTOR: f32 = 4.5254836;
const CLOD_MIN_PX: f32 = 1.0;
const CLOD_MAX_PX: f32 = 80.0;

// The target spacing at p (clip = view_proj · p), or -1 when the filter drops p whatever its
// spacing (behind the eye, outside the extended frustum).
fn clod_target(p: vec3<f32>, clip: vec4<f32>, eye: vec3<f32>, scale: f32, fovea: f32) -> f32 {
    if (clip.w <= 0.0) {
        return -1.0;
    }
    let ndc_x = clip.x / clip.w;
    let ndc_y = clip.y / clip.w;
    if (abs(ndc_x) > CLOD_EXTENT || abs(ndc_y) > CLOD_EXTENT) {
        return -1.0;
    }
    let dc = sqrt(ndc_x * ndc_x + ndc_y * ndc_y);
    let v = p - eye;
    let d = sqrt(dot(v, v));
    return scale * d / max(1.0 - fovea * dc, CLOD_FOVEA_FLOOR);
}

fn clod_pass(p: vec3<f32>, spacing: f32, clip: vec4<f32>, eye: vec3<f32>, scale: f32, fovea: f32) -> bool {
    let t = clod_target(p, clip, eye, scale, fovea);
    return t >= 0.0 && spacing >= t;
}

fn clod_size_px(spacing: f32, t: f32, w: f32, k: f32, point_size: f32) -> f32 {
    let full = clamp(CLOD_SIZE_FACTOR * point_size * t * k / w, CLOD_MIN_PX, CLOD_MAX_PX);
    let fade = 1.0 - clamp((t - CLOD_BLEND * spacing) / (spacing - CLOD_BLEND * spacing), 0.0, 1.0);
    return full * fade;
}
