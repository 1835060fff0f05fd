// The compute rasteriser (render::compute): one invocation per splat writes a square of
// pixels into a visibility buffer with 64-bit atomics, the approach of Schütz, Kerbl and
// Wimmer (2021). Appended to interval.wgsl + clod.wgsl + splat.wgsl, whose bindings and helpers it uses
// (splat_position, splat_passes, splat_size_px, splat_linear, dispatch_index).
//
// Key of a fragment: (depth bits << 32) | sRGB8 colour (pack4x8unorm, alpha 1). The depth is
// NDC z in 0..1, whose f32 bits order like the numbers, so the smallest key is the nearest
// splat, and among splats at one depth the smallest colour value (deterministic whatever the
// order the invocations run in). The buffer stores the key's complement and keeps the
// largest (atomicMax), so that a buffer cleared to zero means "no splat".
// Mirrored by render::cpu (Raster::Compute).

@group(2) @binding(0) var<storage, read_write> visibility: array<atomic<u64>>;

// Largest footprint side in pixels (render::compute::MAX_FOOTPRINT_PX): bigger splats are
// drawn at this size.
const MAX_FOOTPRINT_PX: f32 = 64.0;

@compute @workgroup_size(64)
fn cs_raster(@builtin(global_invocation_id) gid: vec3<u32>, @builtin(num_workgroups) groups: vec3<u32>) {
    let k = dispatch_index(gid, groups);
    if (k >= draw.count) {
        return;
    }
    let ii = draw.first + k;
    let p = splat_position(ii);
    let clip = frame.view_proj * vec4<f32>(p, 1.0);
    if (clip.w <= 0.0 || !splat_passes(ii)) {
        return;
    }
    let z = clip.z / clip.w;
    if (z < 0.0 || z > 1.0) {
        return; // outside the near/far range, as the quads are clipped
    }
    let half = min(splat_size_px(ii, p, clip), MAX_FOOTPRINT_PX) * 0.5;
    let cx = (clip.x / clip.w * 0.5 + 0.5) * frame.viewport.x;
    let cy = (0.5 - clip.y / clip.w * 0.5) * frame.viewport.y;
    // Pixels whose centre lies in [c - half, c + half), the quads' top-left rule.
    let x0 = u32(clamp(ceil(cx - half - 0.5), 0.0, frame.viewport.x));
    let x1 = u32(clamp(ceil(cx + half - 0.5), 0.0, frame.viewport.x));
    let y0 = u32(clamp(ceil(cy - half - 0.5), 0.0, frame.viewport.y));
    let y1 = u32(clamp(ceil(cy + half - 0.5), 0.0, frame.viewport.y));
    if (x0 >= x1 || y0 >= y1) {
        return;
    }
    let has_normal = (draw.flags & 1u) != 0u;
    var n = vec3<f32>(0.0, 0.0, 1.0);
    if (has_normal) {
        n = oct_decode(normals[ii]);
    }
    let srgb = linear_to_srgb(splat_linear(ii, p, n, has_normal, normalize(frame.eye - p)));
    let colour = pack4x8unorm(vec4<f32>(srgb, 1.0));
    let key = (u64(bitcast<u32>(z)) << 32u) | u64(colour);
    let stored = ~key;
    let width = u32(frame.viewport.x);
    for (var y = y0; y < y1; y++) {
        for (var x = x0; x < x1; x++) {
            atomicMax(&visibility[y * width + x], stored);
        }
    }
}
