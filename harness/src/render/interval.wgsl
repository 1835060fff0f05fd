// Sequential Point Trees: the per-splat interval test of the vertex stage (and of the
// counting compute pass) — a line-for-line port of `methods::spt::select::interval_pass`,
// the CPU mirror; the renderer's tests compare GPU pass counts with it.
//
// lod = (e, e_par, δ, codes): the node's geometric error, its parent's (f32::MAX at the
// root), the distance to the parent's centre, and 8-bit codes (256·q_n + q_p)·256 + q_γ of
// the node's and parent's error angles φ = atan2(e_t, e_p) and of the normal change γ.
// scale = ε/k, mode 0 = unified, 1 = split, overlap = factor on δ (1 = provably no holes).

const HALF_PI: f32 = 1.5707963267948966;
const PI: f32 = 3.141592653589793;
const PHI_STEPS: f32 = 255.0;
const GAMMA_STEP: f32 = 1.5707963267948966 / 254.0;
const ROOT_PARENT_ERROR: f32 = 3.4028234663852886e38;

fn interval_pass(p: vec3<f32>, n: vec3<f32>, lod: vec4<f32>, eye: vec3<f32>, mode: u32, scale: f32, overlap: f32) -> bool {
    let v = eye - p;
    let r = length(v);
    let hi = floor(lod.w / 256.0);
    let q_gamma = lod.w - 256.0 * hi;
    let q_node = floor(hi / 256.0);
    let q_par = hi - 256.0 * q_node;
    let phi = q_node * (HALF_PI / PHI_STEPS);
    let phi_par = q_par * (HALF_PI / PHI_STEPS);
    var c = 1.0;
    if (r > 0.0) {
        c = min(abs(dot(n, v) / r), 1.0);
    }
    let sa = sqrt(max(1.0 - c * c, 0.0));
    let split = mode == 1u;
    var g = 1.0;
    if (split) {
        g = sa * cos(phi) + c * sin(phi);
    }
    var view_turn = PI;
    if (lod.z < r) {
        view_turn = HALF_PI * lod.z / r;
    }
    var turn = PI;
    if (q_gamma <= 254.5) {
        turn = q_gamma * GAMMA_STEP + view_turn;
    }
    var g_par = 1.0;
    if (split) {
        g_par = min(sa * cos(phi_par) + c * sin(phi_par) + overlap * turn, 1.0);
    }
    let lower = lod.x * g <= scale * r;
    let upper = lod.y >= ROOT_PARENT_ERROR || scale * max(r - overlap * lod.z, 0.0) < lod.y * g_par;
    return lower && upper;
}
