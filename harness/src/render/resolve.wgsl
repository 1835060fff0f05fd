// Resolve of the compute rasteriser's visibility buffer (render::compute) into the colour and
// depth targets: a full-screen triangle; a pixel with no splat is discarded (the targets keep
// their clear or earlier values), any other takes the colour and depth its key holds.

struct Resolve {
    width: u32,
    _p0: u32,
    _p1: u32,
    _p2: u32,
}

@group(0) @binding(0) var<uniform> resolve: Resolve;
// The 64-bit keys, complemented, as (low word, high word) = (~colour, ~depth bits).
@group(0) @binding(1) var<storage, read> visibility: array<vec2<u32>>;

@vertex
fn vs_fullscreen(@builtin(vertex_index) vi: u32) -> @builtin(position) vec4<f32> {
    let uv = vec2<f32>(f32((vi << 1u) & 2u), f32(vi & 2u));
    return vec4<f32>(uv * 2.0 - 1.0, 0.0, 1.0);
}

struct Resolved {
    @location(0) color: vec4<f32>,
    @builtin(frag_depth) depth: f32,
}

@fragment
fn fs_resolve(@builtin(position) pos: vec4<f32>) -> Resolved {
    let v = visibility[u32(pos.y) * resolve.width + u32(pos.x)];
    if (v.x == 0u && v.y == 0u) {
        discard;
    }
    var out: Resolved;
    out.color = unpack4x8unorm(~v.x);
    out.depth = bitcast<f32>(~v.y);
    return out;
}
