// Gaussian splats, pass 3: the accumulated opacity (the summed weights, clamped at 1) of the
// weighted colour over the black background, encoded sRGB: Σwc / max(Σw, 1) — full opacity
// where the weights sum to 1 or more (QSplat §3.3: "full opacity in areas that started out
// as continuous surfaces"), partial below. A pixel is covered (alpha 1) from an opacity of
// GAUSS_COVERED = 1/2 on, the spline's value at the nominal radius: a lone splat covers its
// nominal disc, as a circle does; below, it stays background (alpha 0 = not covered).

const GAUSS_COVERED: f32 = 0.5;

@group(0) @binding(0) var accum: texture_2d<f32>;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let x = f32((vi << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vi & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

fn linear_to_srgb(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

@fragment
fn fs_normalize(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let a = textureLoad(accum, vec2<i32>(pos.xy), 0);
    if (a.a < GAUSS_COVERED) {
        return vec4<f32>(0.0);
    }
    return vec4<f32>(linear_to_srgb(a.rgb / max(a.a, 1.0)), 1.0);
}
