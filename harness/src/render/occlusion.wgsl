// Occlusion queries of three-phase occlusion culling (LPC §4, `render::occlusion`).
//
// Each candidate's bounding sphere is drawn as the icosahedron that circumscribes it; its 12
// world-space vertices come from a vertex buffer computed on the CPU (the CPU mirror
// rasterises exactly those); the instance index is the query's index. Depth test Less
// against the depth phase 1 left (attached read-only), no depth or colour writes, back faces
// culled, inside a hardware occlusion query. The fragment stage also counts the fragments
// that pass the same test against the same depth (bound as a texture) into one atomic
// counter per query: an exact count on every adapter, where wgpu's occlusion queries may
// answer 0/1 (they never ask Vulkan for precise results; lavapipe then returns booleans).

struct QueryFrame {
    view_proj: mat4x4<f32>, // offset 0: the first member of splat.wgsl's Frame (same buffer)
}                           // size 64

@group(0) @binding(0) var<uniform> qframe: QueryFrame;
@group(0) @binding(1) var phase1_depth: texture_depth_2d;
@group(0) @binding(2) var<storage, read_write> samples: array<atomic<u32>>;
@group(0) @binding(3) var depth_less: sampler_comparison; // compare Less, nearest

struct QueryOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) @interpolate(flat) query: u32,
}

@vertex
fn vs_query(@location(0) p: vec3<f32>, @builtin(instance_index) query: u32) -> QueryOut {
    var out: QueryOut;
    out.pos = qframe.view_proj * vec4<f32>(p, 1.0);
    out.query = query;
    return out;
}

@fragment
fn fs_query(in: QueryOut) {
    // The fixed-function test (Less) may run after this stage: repeat it on the stored depth,
    // sampled at this pixel's centre (nearest) with a comparison sampler — `textureLoad` of a
    // depth texture has no GLSL translation, and the GL backend must work too.
    let uv = in.pos.xy / vec2<f32>(textureDimensions(phase1_depth));
    if (textureSampleCompareLevel(phase1_depth, depth_less, uv, in.pos.z) > 0.5) {
        atomicAdd(&samples[in.query], 1u);
    }
}
