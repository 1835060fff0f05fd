// Sequential Point Trees: the per-splat interval test of the vertex stage (and of the
// counting compute pass). Mirrored on the CPU by `methods::spt` (the method defines what
// `lod` holds; this file must stay equal to that mirror, checked by the GPU-vs-CPU test).
//
// mode 0 (unified geometric error): lod = (e_g, e_g of the parent, -, -); with
// r = |eye − p|, the splat is drawn iff e_g·scale − overlap ≤ r < e_g_parent·scale + overlap,
// where scale = k/ε. The root's parent error is f32::MAX (always below r_max).
fn interval_pass(p: vec3<f32>, n: vec3<f32>, lod: vec4<f32>, eye: vec3<f32>, mode: u32, scale: f32, overlap: f32) -> bool {
    let r = length(eye - p);
    let r_min = lod.x * scale - overlap;
    let r_max = lod.y * scale + overlap;
    return r >= r_min && r < r_max;
}
