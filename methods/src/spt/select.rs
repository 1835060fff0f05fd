//! SPT's per-frame selection: the per-splat interval test (the function the renderer ports to
//! WGSL), the `lod` layout it reads, the O(log n) prefix search, normal clusters and their
//! back-face test.
//!
//! # `lod` layout (one `[f32; 4]` per node, same for both modes)
//!
//! | index | meaning |
//! |------:|---------|
//! | 0 | `e` — the node's geometric error `e_g` (object units; 0 for leaves) |
//! | 1 | `e_par` — the parent's `e_g`; [`ROOT_PARENT_ERROR`] (= `f32::MAX`) for the root |
//! | 2 | `δ` — distance from the node's centre to its parent's centre, both as stored (rounded up; 0 for the root) |
//! | 3 | `q = (256·q_node + q_par)·256 + q_γ` (an integer < 2²⁴, exact in f32): `q_node, q_par ∈ 0..=255` quantise `φ = atan2(e_t, e_p) ∈ [0, π/2]` of the node and of its parent as `φ = q·(π/2)/255`; `q_γ ∈ 0..=255` bounds the angle `γ` between the node's and the parent's normals: `γ ≤ q_γ·(π/2)/254` (rounded up; 255 = no bound, also the root's) |
//!
//! Split errors follow from `e_g` and `φ`: `e_p = e_g·cos φ`, `e_t = e_g·sin φ`, so
//! `e_p·sin α + e_t·cos α = e_g·sin(α + φ)`.
//!
//! In the files ([`super::quant`]) indices 0 and 1 are exact, 2 is a 16-bit code rounded up,
//! and 3 is stored only in split mode: the unified test reads no part of it, and a unified
//! list decodes it as [`super::files::Q_ABSENT`].
//!
//! # The test ([`interval_pass`])
//!
//! `test.scale = s = ε / k` (object-space error allowed per unit of view distance; ε the
//! tolerance in pixels, `k` the projection scale; `s = 0` at ε = 0), `test.overlap = o ≥ 0`
//! (a factor on `δ`), `test.mode` = [`MODE_UNIFIED`] or [`MODE_SPLIT`]. With `r = |eye − p|`:
//!
//! - unified: `g = g_par = 1`;
//! - split: `c = |n·(eye − p)| / r` (cos α; 1 when r = 0), `sα = sqrt(max(0, 1 − c²))`,
//!   `g = sα·cos φ_node + c·sin φ_node`, and for the parent, evaluated with the node's own
//!   normal and view vector and widened by the overlap for the angle the parent may see
//!   differently: `g_par = min(1, sα·cos φ_par + c·sin φ_par + o·(γ + τ))`, `γ = q_γ·(π/2)/254`
//!   (π when `q_γ = 255`), `τ = (π/2)·δ/r` when `δ < r`, else π (the turn of the view vector);
//! - pass ⇔ `e·g ≤ s·r` **and** (`e_par ≥ ROOT_PARENT_ERROR` **or**
//!   `s·max(r − o·δ, 0) < e_par·g_par`).
//!
//! This is the paper's `r ∈ [r_min, r_max)` with `r_min = e·g/s` and `r_max = e_par·g_par/s`,
//! written on the error side so that ε = 0 needs no infinity (shaders may assume none).
//! `o ≥ 1` makes the unified test hole-free: if no ancestor passes at the distance of a
//! child `j−1`, then `s·(r_{j−1} − δ) ≥ e_j` and `r_j ≥ r_{j−1} − δ` give `e_j ≤ s·r_j`, so
//! every leaf's chain has a passing node (induction from the leaf, whose `e = 0`). In split
//! mode the same argument holds because `sin(α + φ)` is 1-Lipschitz in α and the angle α seen
//! at the parent differs from the node's by at most `γ + τ`, so the widened `g_par` bounds the
//! parent's own factor (`γ` is the larger of the angles between the exact and between the
//! stored normals, plus 1e-3 rad, rounded up; the test reads the stored ones).
//!
//! # Prefix search
//!
//! Nodes are sorted by `e_par` descending inside each cluster. A node can pass only if
//! `e_par + s·o·D_i > s·r_lo`, where `r_lo` is a lower bound of the view distance over the
//! cluster's bounding sphere ([`sphere_distance_lower_bound`]; with `bound=box` the larger of
//! that and [`box_distance_lower_bound`] of the box of the cluster's node centres) and `D_i = max_{j ≥ i} δ_j` (suffix maximum within the cluster);
//! the left side is non-increasing in `i`, so the candidates are a prefix found by binary
//! search (a relative slack of 1e-5 keeps it conservative in f32).

use glam::Vec3;

use crate::IntervalTest;

/// `test.mode` of the unified (view-angle independent) geometric error.
pub const MODE_UNIFIED: u32 = 0;
/// `test.mode` of the split (perpendicular + tangential) error.
pub const MODE_SPLIT: u32 = 1;
/// `lod[1]` of the root: always passes the upper test.
pub const ROOT_PARENT_ERROR: f32 = f32::MAX;
/// Quantisation steps of `φ` (8 bits).
pub const PHI_STEPS: f32 = 255.0;
/// Quantisation step of `γ` (8 bits; code 255 = unbounded).
pub const GAMMA_STEP: f32 = std::f32::consts::FRAC_PI_2 / 254.0;
/// The `q_γ` code meaning "no bound on γ".
pub const GAMMA_UNBOUNDED: u32 = 255;
/// Clusters of normal clustering (8 octahedron faces × 4²).
pub const CLUSTERS: usize = 128;

/// Quantises `φ = atan2(e_t, e_p)` to `0..=255`.
pub fn quantize_phi(e_p: f32, e_t: f32) -> u32 {
    let phi = e_t.max(0.0).atan2(e_p.max(0.0));
    (phi / std::f32::consts::FRAC_PI_2 * PHI_STEPS)
        .round()
        .clamp(0.0, PHI_STEPS) as u32
}

/// Quantises the angle `γ` between a node's normal and its parent's, rounded up, to
/// `0..=255` (step `(π/2)/254`; 255 = "γ > π/2", no bound).
pub fn quantize_gamma(gamma: f32) -> u32 {
    let q = (gamma.max(0.0) / GAMMA_STEP).ceil();
    if q.is_finite() && q < GAMMA_UNBOUNDED as f32 {
        q as u32
    } else {
        GAMMA_UNBOUNDED
    }
}

/// Packs the `lod` entry of a node (see the module doc).
pub fn pack_lod(e: f32, e_par: f32, delta: f32, q_node: u32, q_par: u32, q_gamma: u32) -> [f32; 4] {
    [
        e,
        e_par,
        delta,
        ((q_node.min(255) * 256 + q_par.min(255)) * 256 + q_gamma.min(GAMMA_UNBOUNDED)) as f32,
    ]
}

/// The interval test of one splat (CPU mirror of the vertex stage; see the module doc).
/// `p` centre, `n` unit normal (ignored in unified mode), `eye` the camera position.
#[inline]
pub fn interval_pass(p: Vec3, n: Vec3, lod: [f32; 4], eye: Vec3, test: &IntervalTest) -> bool {
    let v = eye - p;
    let r = v.length();
    let s = test.scale;
    let hi = (lod[3] / 256.0).floor();
    let q_gamma = lod[3] - 256.0 * hi;
    let q_node = (hi / 256.0).floor();
    let q_par = hi - 256.0 * q_node;
    let phi = q_node * (std::f32::consts::FRAC_PI_2 / PHI_STEPS);
    let phi_par = q_par * (std::f32::consts::FRAC_PI_2 / PHI_STEPS);
    let c = if r > 0.0 {
        (n.dot(v) / r).abs().min(1.0)
    } else {
        1.0
    };
    let sa = (1.0 - c * c).max(0.0).sqrt();
    let split = test.mode == MODE_SPLIT;
    let g = if split {
        sa * phi.cos() + c * phi.sin()
    } else {
        1.0
    };
    // Slack of the parent's angle: normal change γ plus view-direction change ≤ (π/2)·δ/r.
    let view_turn = if lod[2] < r {
        std::f32::consts::FRAC_PI_2 * lod[2] / r
    } else {
        std::f32::consts::PI
    };
    let turn = if q_gamma > 254.5 {
        std::f32::consts::PI
    } else {
        q_gamma * GAMMA_STEP + view_turn
    };
    let g_par = if split {
        (sa * phi_par.cos() + c * phi_par.sin() + test.overlap * turn).min(1.0)
    } else {
        1.0
    };
    let lower = lod[0] * g <= s * r;
    let upper =
        lod[1] >= ROOT_PARENT_ERROR || s * (r - test.overlap * lod[2]).max(0.0) < lod[1] * g_par;
    lower && upper
}

/// The cluster (0..128) of a unit normal: octahedron face (sign octant) × one of 16
/// triangles of that face subdivided 4×4.
pub fn cluster_of(n: Vec3) -> usize {
    let face = (n.x < 0.0) as usize | ((n.y < 0.0) as usize) << 1 | ((n.z < 0.0) as usize) << 2;
    let a = n.abs();
    let sum = (a.x + a.y + a.z).max(f32::MIN_POSITIVE);
    let u = (a.x / sum * 4.0).clamp(0.0, 3.999_999);
    let v = (a.y / sum * 4.0).clamp(0.0, 3.999_999);
    let (mut i, mut j) = (u.floor() as usize, v.floor() as usize);
    if i + j > 3 {
        // Rounding at the face's far edge: step back into the triangle.
        if i >= j { i = 3 - j } else { j = 3 - i }
    }
    let upper = i + j < 3 && (u - i as f32) + (v - j as f32) > 1.0;
    // Row j holds 4−j lower and 3−j upper triangles; rows before j: Σ (7 − 2j').
    let row_start = (0..j).map(|jj| 7 - 2 * jj).sum::<usize>();
    let within = if upper { (4 - j) + i } else { i };
    face * 16 + row_start + within
}

/// Number of leading entries of a cluster that can pass: `e_par[i] + s·o·d_suffix[i] > s·r_lo`
/// (both sides slackened by 1e-5 relative); `e_par` non-increasing, `d_suffix` non-increasing.
pub fn prefix_len(e_par: &[f32], d_suffix: &[f32], s: f32, overlap: f32, r_lo: f64) -> usize {
    let s = s as f64;
    let rhs = s * r_lo * (1.0 - 1e-5);
    let ov = overlap.max(0.0) as f64;
    let pred = |i: usize| {
        e_par[i] as f64 * (1.0 + 1e-5) + s * ov * d_suffix[i] as f64 * (1.0 + 1e-5) > rhs
    };
    partition(e_par.len(), pred)
}

/// First index in `0..n` where the monotone predicate (true…true false…false) is false.
fn partition(n: usize, pred: impl Fn(usize) -> bool) -> usize {
    let (mut lo, mut hi) = (0usize, n);
    while lo < hi {
        let mid = lo + (hi - lo) / 2;
        if pred(mid) {
            lo = mid + 1;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Lower bound of the distance from `eye` to a sphere (0 inside), slackened by 1e-5 relative.
pub fn sphere_distance_lower_bound(eye: Vec3, center: Vec3, radius: f32) -> f64 {
    let l = eye.as_dvec3().distance(center.as_dvec3());
    (l * (1.0 - 1e-5) - radius as f64 * (1.0 + 1e-5)).max(0.0)
}

/// Lower bound of the distance from `eye` to the axis-aligned box `[lo, hi]` (0 inside),
/// slackened by 1e-5 relative.
pub fn box_distance_lower_bound(eye: Vec3, lo: Vec3, hi: Vec3) -> f64 {
    let (e, lo, hi) = (eye.as_dvec3(), lo.as_dvec3(), hi.as_dvec3());
    let d = (lo - e).max(e - hi).max(glam::DVec3::ZERO);
    d.length() * (1.0 - 1e-5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clusters_cover_128_ids() {
        let mut rng = scenes::rng::Pcg32::new(1);
        let mut seen = [0u32; CLUSTERS];
        for _ in 0..200_000 {
            seen[cluster_of(rng.unit_vec3())] += 1;
        }
        assert!(seen.iter().all(|&c| c > 0), "{seen:?}");
        for n in [Vec3::X, -Vec3::Y, Vec3::Z, Vec3::ONE.normalize()] {
            assert!(cluster_of(n) < CLUSTERS);
        }
    }

    #[test]
    fn phi_round_trip() {
        let t = IntervalTest {
            mode: MODE_SPLIT,
            scale: 1.0,
            overlap: 0.0,
        };
        // Pure tangential error seen head-on: e·sin(0 + π/2) = e.
        let lod = pack_lod(
            1.0,
            10.0,
            0.0,
            quantize_phi(0.0, 1.0),
            quantize_phi(0.0, 1.0),
            0,
        );
        let eye = Vec3::new(0.0, 0.0, 1.0);
        assert!(interval_pass(Vec3::ZERO, Vec3::Z, lod, eye, &t));
        let eye = Vec3::new(0.0, 0.0, 0.999);
        assert!(!interval_pass(Vec3::ZERO, Vec3::Z, lod, eye, &t));
    }
}
