// The viewer's present pass: the HUD panel across the top, and below it the frame (the
// renderer's colour target, or an image made on the CPU) in the rectangle present.rs's
// frame_rect gives (1:1 at the window's opening size; scaled, nearest pixel, with its aspect
// kept after a resize), over a dark background where no splat landed (alpha 0). A HUD that
// grew taller than its band since the window opened covers the frame's top at 85 %.

struct Present {
    frame_size: vec2<f32>,
    // The frame's rectangle on the surface: top-left corner and size, pixels.
    frame_origin: vec2<f32>,
    frame_extent: vec2<f32>,
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
    let rel = (pos.xy - u.frame_origin) / u.frame_extent;
    var c = BACKGROUND;
    if (all(rel >= vec2<f32>(0.0)) && all(rel < vec2<f32>(1.0))) {
        let src = min(vec2<i32>(rel * u.frame_size), vec2<i32>(u.frame_size) - 1);
        let f = textureLoad(frame, src, 0);
        c = mix(BACKGROUND, f.rgb, f.a);
    }
    if (pos.x < u.hud_size.x && pos.y < u.hud_size.y) {
        let h = textureLoad(hud, vec2<i32>(pos.xy), 0);
        c = mix(c, h.rgb, HUD_OPACITY);
    }
    if (u.decode_srgb > 0.5) {
        c = srgb_to_linear(c);
    }
    return vec4<f32>(c, 1.0);
}
