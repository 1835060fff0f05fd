// The viewer's present pass: the frame (the renderer's colour target, or an image made on the
// CPU) scaled to the window, nearest pixel, over a dark background where no splat landed
// (alpha 0), with the HUD laid over the top-left corner.

struct Present {
    frame_size: vec2<f32>,
    surface_size: vec2<f32>,
    hud_size: vec2<f32>,
    // 1 when the surface encodes sRGB itself: the frame's sRGB values are decoded first.
    decode_srgb: f32,
    _pad: f32,
}

@group(0) @binding(0) var frame: texture_2d<f32>;
@group(0) @binding(1) var hud: texture_2d<f32>;
@group(0) @binding(2) var<uniform> u: Present;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let x = f32((vi << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vi & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

const BACKGROUND: vec3<f32> = vec3<f32>(0.12, 0.12, 0.14);
const HUD_OPACITY: f32 = 0.85;

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

@fragment
fn fs_present(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let src = min(vec2<i32>(pos.xy * u.frame_size / u.surface_size), vec2<i32>(u.frame_size) - 1);
    let f = textureLoad(frame, src, 0);
    var c = mix(BACKGROUND, f.rgb, f.a);
    if (pos.x < u.hud_size.x && pos.y < u.hud_size.y) {
        let h = textureLoad(hud, vec2<i32>(pos.xy), 0);
        c = mix(c, h.rgb, HUD_OPACITY);
    }
    if (u.decode_srgb > 0.5) {
        c = srgb_to_linear(c);
    }
    return vec4<f32>(c, 1.0);
}
