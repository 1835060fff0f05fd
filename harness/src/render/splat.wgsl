// Instanced screen-aligned quad splats with vertex pulling.
//
// One instance = one splat; four vertices, drawn indexed as two triangles (0 1 2, 0 2 3) so
// the vertex stage runs 4 times per splat, not 6. Attributes come from
// storage buffers so that a scene without normals, colours or radii uploads none: the absent
// bindings point at a 16-byte dummy buffer and `draw.flags` says which are real.
// Mirrored on the CPU by `render::cpu` (splat size, shading) and checked by tests.

struct Frame {
    view_proj: mat4x4<f32>, // offset 0
    eye: vec3<f32>,         // offset 64
    proj_scale: f32,        // offset 76: k = height / (2 tan(fov_y/2))
    viewport: vec2<f32>,    // offset 80
    ambient: f32,           // offset 88
    ellipse_min_ratio: f32, // offset 92: smallest minor/major ratio of an ellipse (1/clamp)
    base_color: vec4<f32>,  // offset 96: linear RGB used when the scene has no colour
    view: mat4x4<f32>,      // offset 112: world → view (ellipse axes)
    depth_offset: f32,      // offset 176: gaussian depth pass pushes splats back by this × radius
    shading: u32,           // offset 180: 0 Lambert, 1 unlit, 2 elevation ramp (render::shading)
    elevation_lo: f32,      // offset 184: local Z at the bottom of the ramp
    elevation_scale: f32,   // offset 188: 1 / the ramp's height range
}                           // size 192

struct Draw {
    size_px: f32,      // offset 0: mode 0, splat size in pixels
    radius_scale: f32, // offset 4: mode 1, multiplier on the stored radius; mode 2, CLOD's point size
    min_px: f32,       // offset 8: mode 1, smallest size in pixels
    mode: u32,         // offset 12: 0 = pixels, 1 = per-splat radius, 2 = CLOD's (clod.wgsl)
    flags: u32,        // offset 16: bit 0 normals, bit 1 colours, bit 2 radii, bit 3 lod
    test_kind: u32,    // offset 20: 0 = none, 1 = SPT interval test (interval.wgsl), 2 = CLOD filter (clod.wgsl)
    test_mode: u32,    // offset 24: SPT's error mode
    test_scale: f32,   // offset 28: SPT's and CLOD's ε/k
    test_overlap: f32, // offset 32: SPT's overlap; CLOD's fovea
    count: u32,        // offset 36: splats sent (counting pass)
    slot: u32,         // offset 40: counter slot of this draw (counting pass)
    first: u32,        // offset 44: first splat sent of this part
    tint: vec4<f32>,   // offset 48: a > 0: linear RGB replacing the base colour (the viewer's level colours)
}                      // size 64

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<uniform> draw: Draw;
@group(1) @binding(0) var<storage, read> positions: array<f32>;
@group(1) @binding(1) var<storage, read> normals: array<u32>;
@group(1) @binding(2) var<storage, read> colors: array<u32>;
@group(1) @binding(3) var<storage, read> radii: array<f32>;
@group(1) @binding(4) var<storage, read> lods: array<vec4<f32>>;
@group(2) @binding(0) var<storage, read_write> counters: array<atomic<u32>>;

struct VsOut {
    @builtin(position) pos: vec4<f32>,
    @location(0) uv: vec2<f32>,
    @location(1) @interpolate(flat) color: vec4<f32>,  // sRGB-encoded (opaque kernels)
    @location(2) @interpolate(flat) linear: vec4<f32>, // linear (gaussian accumulation)
}

const CORNERS = array<vec2<f32>, 4>(
    vec2<f32>(-1.0, -1.0), vec2<f32>(1.0, -1.0), vec2<f32>(1.0, 1.0), vec2<f32>(-1.0, 1.0),
);

fn oct_decode(p: u32) -> vec3<f32> {
    let e = unpack2x16snorm(p);
    var v = vec3<f32>(e.x, e.y, 1.0 - abs(e.x) - abs(e.y));
    let t = max(-v.z, 0.0);
    v.x += select(t, -t, v.x >= 0.0);
    v.y += select(t, -t, v.y >= 0.0);
    return normalize(v);
}

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let lo = c / 12.92;
    let hi = pow((c + 0.055) / 1.055, vec3<f32>(2.4));
    return select(hi, lo, c <= vec3<f32>(0.04045));
}

fn linear_to_srgb(c: vec3<f32>) -> vec3<f32> {
    let lo = c * 12.92;
    let hi = 1.055 * pow(c, vec3<f32>(1.0 / 2.4)) - 0.055;
    return select(hi, lo, c <= vec3<f32>(0.0031308));
}

// The elevation ramp (render::shading::elevation_colour): five viridis stops, sRGB, linear
// in between; t clamped to 0..1.
const RAMP = array<vec3<f32>, 5>(
    vec3<f32>(68.0, 1.0, 84.0), vec3<f32>(59.0, 82.0, 139.0), vec3<f32>(33.0, 145.0, 140.0),
    vec3<f32>(94.0, 201.0, 98.0), vec3<f32>(253.0, 231.0, 37.0),
);

fn elevation_colour(t: f32) -> vec3<f32> {
    let s = clamp(t, 0.0, 1.0) * 4.0;
    let i = min(u32(floor(s)), 3u);
    let f = s - f32(i);
    return mix(RAMP[i], RAMP[i + 1u], f) / 255.0;
}

fn splat_position(ii: u32) -> vec3<f32> {
    return vec3<f32>(positions[3u * ii], positions[3u * ii + 1u], positions[3u * ii + 2u]);
}

// The draw's per-splat LOD test (SPT's, CLOD's); true when the draw has none.
fn splat_passes(ii: u32) -> bool {
    if (draw.test_kind == 0u) {
        return true;
    }
    if (draw.test_kind == 2u) {
        let p = splat_position(ii);
        let clip = frame.view_proj * vec4<f32>(p, 1.0);
        return clod_pass(p, lods[ii].x, clip, frame.eye, draw.test_scale, draw.test_overlap);
    }
    var n = vec3<f32>(0.0, 0.0, 1.0);
    if ((draw.flags & 1u) != 0u) {
        n = oct_decode(normals[ii]);
    }
    return interval_pass(splat_position(ii), n, lods[ii], frame.eye, draw.test_mode, draw.test_scale, draw.test_overlap);
}

// The splat a compute invocation handles: dispatches are 2-D when one dimension's 65,535
// workgroups of 64 are too few (render::dispatch_size), rows of workgroups laid end to end.
fn dispatch_index(gid: vec3<u32>, groups: vec3<u32>) -> u32 {
    return gid.y * groups.x * 64u + gid.x;
}

// Counts the splats of a draw that pass its test (one thread per splat sent).
@compute @workgroup_size(64)
fn cs_count(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let i = dispatch_index(gid, groups);
    if (i < draw.count && splat_passes(draw.first + i)) {
        atomicAdd(&counters[draw.slot], 1u);
    }
}

// The size in pixels of splat ii at p, clip = view_proj · p (mirrored by render::cpu::splat_px
// and, for CLOD's, render::cpu::clod_px).
fn splat_size_px(ii: u32, p: vec3<f32>, clip: vec4<f32>) -> f32 {
    if (draw.mode == 1u) {
        return max(draw.min_px, 2.0 * radii[ii] * draw.radius_scale * frame.proj_scale / clip.w);
    }
    if (draw.mode == 2u) {
        let t = clod_target(p, clip, frame.eye, draw.test_scale, draw.test_overlap);
        return clod_size_px(lods[ii].x, t, clip.w, frame.proj_scale, draw.radius_scale);
    }
    return draw.size_px;
}

// The splat's shaded linear colour (mirrored by render::cpu::shade_linear): base colour,
// stored colour or elevation ramp, times the two-sided Lambert headlight when it has a
// normal and the shading is Lambert. `l`: unit vector from the splat to the eye.
fn splat_linear(ii: u32, p: vec3<f32>, n: vec3<f32>, has_normal: bool, l: vec3<f32>) -> vec3<f32> {
    var base = frame.base_color.rgb;
    if (frame.shading == 2u) {
        base = srgb_to_linear(elevation_colour((p.z - frame.elevation_lo) * frame.elevation_scale));
    } else if ((draw.flags & 2u) != 0u) {
        base = srgb_to_linear(unpack4x8unorm(colors[ii]).rgb);
    }
    // The viewer's level colours only (runs never tint: the CPU mirror has no tint).
    if (draw.tint.a > 0.0) {
        base = draw.tint.rgb;
    }
    var shade = 1.0;
    if (has_normal && frame.shading == 0u) {
        // Lambert, headlight at the eye, two-sided (scans carry normals of either sign).
        shade = frame.ambient + (1.0 - frame.ambient) * abs(dot(n, l));
    }
    return base * shade;
}

// How far the gaussian's footprint reaches, in nominal radii (`gauss_weight`).
const GAUSS_SUPPORT: f32 = 2.0;

// Shared vertex work. `ellipse`: orient and squash the quad by the normal. `depth_push`:
// move the splat's depth back by depth_offset × its object-space size (gaussian pass 1).
// `support`: the quad's half-size in nominal radii (1; the gaussian's pass 2: GAUSS_SUPPORT),
// `uv` in nominal radii.
fn splat_vertex(vi: u32, ii: u32, ellipse: bool, depth_push: bool, support: f32) -> VsOut {
    var out: VsOut;
    let p = splat_position(ii);
    var clip = frame.view_proj * vec4<f32>(p, 1.0);
    if (clip.w <= 0.0 || !splat_passes(ii)) {
        // Behind the eye, or culled by the LOD test: a degenerate primitive outside the clip volume.
        out.pos = vec4<f32>(2.0, 2.0, 2.0, 1.0);
        out.uv = vec2<f32>(0.0);
        out.color = vec4<f32>(0.0);
        out.linear = vec4<f32>(0.0);
        return out;
    }
    let size = splat_size_px(ii, p, clip);
    let has_normal = (draw.flags & 1u) != 0u;
    var n = vec3<f32>(0.0, 0.0, 1.0);
    if (has_normal) {
        n = oct_decode(normals[ii]);
    }
    let l = normalize(frame.eye - p);
    let c = CORNERS[vi] * support;
    var offset = c * size * 0.5; // pixels
    if (ellipse && has_normal) {
        // Minor axis along the projected normal, minor/major = |n̂·v̂| clamped at 1/clamp.
        let nv = (frame.view * vec4<f32>(n, 0.0)).xy;
        var d = vec2<f32>(1.0, 0.0);
        if (dot(nv, nv) > 1e-12) {
            d = normalize(nv);
        }
        let ratio = max(abs(dot(n, l)), frame.ellipse_min_ratio);
        let major = vec2<f32>(-d.y, d.x);
        offset = (c.x * major + c.y * d * ratio) * size * 0.5;
    }
    clip.x += offset.x * 2.0 / frame.viewport.x * clip.w;
    clip.y += offset.y * 2.0 / frame.viewport.y * clip.w;
    if (depth_push) {
        let world = size * clip.w / frame.proj_scale; // object-space splat diameter
        let back = frame.view_proj * vec4<f32>(p - l * frame.depth_offset * world, 1.0);
        clip.z = back.z / back.w * clip.w;
    }
    out.pos = clip;
    out.uv = c;

    let linear = splat_linear(ii, p, n, has_normal, l);
    out.linear = vec4<f32>(linear, 1.0);
    out.color = vec4<f32>(linear_to_srgb(linear), 1.0);
    return out;
}

@vertex
fn vs_main(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_vertex(vi, ii, false, false, 1.0);
}

@vertex
fn vs_ellipse(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_vertex(vi, ii, true, false, 1.0);
}

@vertex
fn vs_gauss_depth(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_vertex(vi, ii, false, true, 1.0);
}

@vertex
fn vs_gauss_accum(@builtin(vertex_index) vi: u32, @builtin(instance_index) ii: u32) -> VsOut {
    return splat_vertex(vi, ii, false, false, GAUSS_SUPPORT);
}

@fragment
fn fs_square(in: VsOut) -> @location(0) vec4<f32> {
    return in.color;
}

@fragment
fn fs_circle(in: VsOut) -> @location(0) vec4<f32> {
    if (dot(in.uv, in.uv) > 1.0) {
        discard;
    }
    return in.color;
}

/// QSplat's "spline in opacity that falls to 1/2 at the nominal radius of the splat" (§3.3):
/// 1 − smoothstep(0, GAUSS_SUPPORT, r), the cubic Hermite spline 1 − 3t² + 2t³ in t = r / 2,
/// at `uv` in nominal radii: 1 at the centre, 1/2 at r = 1, 0 with zero slope at r = 2.
fn gauss_weight(uv: vec2<f32>) -> f32 {
    let t = length(uv) / GAUSS_SUPPORT;
    if (t >= 1.0) {
        return 0.0;
    }
    return 1.0 - t * t * (3.0 - 2.0 * t);
}

@fragment
fn fs_gauss_depth(in: VsOut) {
    if (dot(in.uv, in.uv) > 1.0) {
        discard;
    }
}

@fragment
fn fs_gauss_accum(in: VsOut) -> @location(0) vec4<f32> {
    let w = gauss_weight(in.uv);
    if (w <= 0.0) {
        discard;
    }
    return vec4<f32>(in.linear.rgb * w, w);
}
