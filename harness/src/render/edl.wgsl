// Eye-dome lighting (render::edl): darkens a covered pixel by how far its 8 neighbours lie in
// front of it, in log2 of the linear view depth. Mirrored on the CPU by `edl::apply_cpu`.

struct Edl {
    near: f32,
    far: f32,
    strength: f32,
    _pad: f32,
}

@group(0) @binding(0) var color: texture_2d<f32>;
// The Depth32Float buffer bound as an unfilterable float texture (WebGPU allows it), so that
// `textureLoad` translates to GLSL `texelFetch` on the GL backend too.
@group(0) @binding(1) var depth: texture_2d<f32>;
@group(0) @binding(2) var<uniform> edl: Edl;

fn depth_at(q: vec2<i32>) -> f32 {
    return textureLoad(depth, q, 0).r;
}

@vertex
fn vs_fullscreen(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let x = f32((vi << 1u) & 2u) * 2.0 - 1.0;
    let y = f32(vi & 2u) * 2.0 - 1.0;
    return vec4<f32>(x, y, 0.0, 1.0);
}

// log2 of the view distance of NDC depth z (0 near, 1 far; D3D-style perspective).
fn log_depth(z: f32) -> f32 {
    return log2(edl.near * edl.far / (edl.far - z * (edl.far - edl.near)));
}

const OFFSETS = array<vec2<i32>, 8>(
    vec2<i32>(1, 0), vec2<i32>(1, 1), vec2<i32>(0, 1), vec2<i32>(-1, 1),
    vec2<i32>(-1, 0), vec2<i32>(-1, -1), vec2<i32>(0, -1), vec2<i32>(1, -1),
);

@fragment
fn fs_edl(@builtin(position) pos: vec4<f32>) -> @location(0) vec4<f32> {
    let p = vec2<i32>(pos.xy);
    let c = textureLoad(color, p, 0);
    if (c.a <= 0.0) {
        return c;
    }
    let size = vec2<i32>(textureDimensions(color));
    let here = log_depth(depth_at(p));
    var sum = 0.0;
    for (var i = 0; i < 8; i++) {
        let q = p + OFFSETS[i];
        if (any(q < vec2<i32>(0)) || any(q >= size) || textureLoad(color, q, 0).a <= 0.0) {
            continue;
        }
        sum += max(0.0, here - log_depth(depth_at(q)));
    }
    let shade = exp(-300.0 * edl.strength * sum / 8.0);
    return vec4<f32>(c.rgb * shade, c.a);
}
