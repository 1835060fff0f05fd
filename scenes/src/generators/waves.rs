//! Building blocks shared by the generators: a portable `sincos`, sums of plane waves with
//! analytic gradients, and random directions.
//!
//! Decisions:
//! - [`sincos`] is our own branch-free `f32` implementation (Cody–Waite reduction by π/2 and
//!   the Cephes minimax polynomials, |error| < 2·10⁻⁷ + 10⁻⁷·|x| for |x| < 10⁴). It is
//!   several times faster than `f32::sin` + `f32::cos` (the loops over waves vectorise) and,
//!   unlike the platform libm, gives the same bits on every platform. (The generators still
//!   call `exp`/`powf` in a few places, so scenes are guaranteed byte-identical across thread
//!   counts and runs, not across operating systems or libm versions.)
//! - A [`WaveSum`] stores its waves as structure-of-arrays so the evaluation loop vectorises.

use glam::Vec3;

use crate::rng::Pcg32;

/// `(sin x, cos x)` in `f32`, portable and branch-free; accurate for |x| < 10⁴ (see the
/// module docs), usable (with growing absolute error) up to |x| ≈ 10⁶.
#[inline(always)]
pub fn sincos(x: f32) -> (f32, f32) {
    const FRAC_2_PI: f32 = std::f32::consts::FRAC_2_PI;
    // π/2 split in three parts; the first two have few mantissa bits so that k·PIO2_A and
    // k·PIO2_B are exact for |k| < 2¹³.
    const PIO2_A: f32 = 1.570_312_5;
    const PIO2_B: f32 = 4.837_513e-4;
    const PIO2_C: f32 = 7.549_79e-8;
    const ROUND: f32 = 12_582_912.0; // 1.5·2²³: adding and subtracting rounds to an integer
    let k = (x * FRAC_2_PI + ROUND) - ROUND;
    let q = (k as i32) as u32;
    let r = ((x - k * PIO2_A) - k * PIO2_B) - k * PIO2_C;
    let z = r * r;
    let s = r + r * z * ((-1.951_529_6e-4 * z + 8.332_161e-3) * z - 1.666_665_5e-1);
    let c = 1.0 - 0.5 * z + z * z * ((2.443_315_7e-5 * z - 1.388_731_6e-3) * z + 4.166_664_6e-2);
    let odd = q & 1 != 0;
    let (s1, c1) = if odd { (c, s) } else { (s, c) };
    let sin_sign = (q & 2) << 30;
    let cos_sign = (q.wrapping_add(1) & 2) << 30;
    (
        f32::from_bits(s1.to_bits() ^ sin_sign),
        f32::from_bits(c1.to_bits() ^ cos_sign),
    )
}

/// A uniformly distributed unit vector (using [`sincos`], so portable).
#[inline]
pub fn unit_vector(rng: &mut Pcg32) -> Vec3 {
    let z = rng.range_f32(-1.0, 1.0);
    let (s, c) = sincos(rng.range_f32(-std::f32::consts::PI, std::f32::consts::PI));
    let r = (1.0 - z * z).max(0.0).sqrt();
    Vec3::new(r * c, r * s, z)
}

/// Two unit vectors completing `n` (unit) to an orthonormal basis (Duff et al. 2017).
#[inline]
pub fn orthonormal_basis(n: Vec3) -> (Vec3, Vec3) {
    let sign = 1.0f32.copysign(n.z);
    let a = -1.0 / (sign + n.z);
    let b = n.x * n.y * a;
    (
        Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
        Vec3::new(b, sign + n.y * n.y * a, -n.y),
    )
}

/// A uniformly distributed random rotation, as the three columns of its matrix (Shoemake's
/// uniform random unit quaternion).
pub fn random_rotation(rng: &mut Pcg32) -> glam::Mat3 {
    let u0 = rng.f32();
    let (s1, c1) = sincos(std::f32::consts::TAU * rng.f32());
    let (s2, c2) = sincos(std::f32::consts::TAU * rng.f32());
    let a = (1.0 - u0).sqrt();
    let b = u0.sqrt();
    let q = glam::Quat::from_xyzw(a * s1, a * c1, b * s2, b * c2).normalize();
    glam::Mat3::from_quat(q)
}

/// Lanes of the structure-of-arrays wave storage: sums are accumulated in `LANES` partial
/// sums (a fixed order, so deterministic) and the loops vectorise.
pub const LANES: usize = 8;

/// Sum of the lanes of a partial-sum array, in a fixed order.
#[inline(always)]
pub fn lane_sum(v: [f32; LANES]) -> f32 {
    ((v[0] + v[4]) + (v[1] + v[5])) + ((v[2] + v[6]) + (v[3] + v[7]))
}

/// `f(p) = Σᵢ aᵢ sin(kᵢ·p + φᵢ)` with its analytic gradient.
///
/// Waves are stored in chunks of [`LANES`]; unused lanes have zero amplitude and wave vector.
#[derive(Debug, Clone, Default)]
pub struct WaveSum {
    kx: Vec<[f32; LANES]>,
    ky: Vec<[f32; LANES]>,
    kz: Vec<[f32; LANES]>,
    phase: Vec<[f32; LANES]>,
    amp: Vec<[f32; LANES]>,
    len: usize,
}

impl WaveSum {
    /// An empty sum (f = 0).
    pub fn new() -> WaveSum {
        WaveSum::default()
    }
    /// Adds the wave `amp · sin(k·p + phase)`.
    pub fn push(&mut self, k: Vec3, phase: f32, amp: f32) {
        if self.len.is_multiple_of(LANES) {
            for v in [
                &mut self.kx,
                &mut self.ky,
                &mut self.kz,
                &mut self.phase,
                &mut self.amp,
            ] {
                v.push([0.0; LANES]);
            }
        }
        let (c, l) = (self.len / LANES, self.len % LANES);
        self.kx[c][l] = k.x;
        self.ky[c][l] = k.y;
        self.kz[c][l] = k.z;
        self.phase[c][l] = phase;
        self.amp[c][l] = amp;
        self.len += 1;
    }
    /// Number of waves.
    pub fn len(&self) -> usize {
        self.len
    }
    /// True if there are no waves.
    pub fn is_empty(&self) -> bool {
        self.len == 0
    }
    /// The i-th wave as (k, phase, amplitude); `i < len()`.
    pub fn wave(&self, i: usize) -> (Vec3, f32, f32) {
        let (c, l) = (i / LANES, i % LANES);
        (
            Vec3::new(self.kx[c][l], self.ky[c][l], self.kz[c][l]),
            self.phase[c][l],
            self.amp[c][l],
        )
    }
    /// Σ |aᵢ|: a bound on |f|.
    pub fn amplitude_bound(&self) -> f32 {
        (0..self.len).map(|i| self.wave(i).2.abs()).sum()
    }
    /// Σ |aᵢ|·|kᵢ|: a bound on |∇f| (a Lipschitz constant of f).
    pub fn gradient_bound(&self) -> f32 {
        (0..self.len)
            .map(|i| {
                let (k, _, a) = self.wave(i);
                a.abs() * k.length()
            })
            .sum()
    }
    /// √(Σ aᵢ²/2): the standard deviation of f over random phases.
    pub fn rms(&self) -> f32 {
        ((0..self.len).map(|i| self.wave(i).2.powi(2)).sum::<f32>() * 0.5).sqrt()
    }
    /// f(p).
    #[inline]
    pub fn value(&self, p: Vec3) -> f32 {
        let mut f = [0.0f32; LANES];
        for c in 0..self.kx.len() {
            let (kx, ky, kz, ph, am) = (
                &self.kx[c],
                &self.ky[c],
                &self.kz[c],
                &self.phase[c],
                &self.amp[c],
            );
            for l in 0..LANES {
                let arg = kx[l] * p.x + ky[l] * p.y + kz[l] * p.z + ph[l];
                f[l] += am[l] * sincos(arg).0;
            }
        }
        lane_sum(f)
    }
    /// (f(p), ∇f(p)).
    #[inline]
    pub fn value_gradient(&self, p: Vec3) -> (f32, Vec3) {
        let mut f = [0.0f32; LANES];
        let mut gx = [0.0f32; LANES];
        let mut gy = [0.0f32; LANES];
        let mut gz = [0.0f32; LANES];
        for c in 0..self.kx.len() {
            let (kx, ky, kz, ph, am) = (
                &self.kx[c],
                &self.ky[c],
                &self.kz[c],
                &self.phase[c],
                &self.amp[c],
            );
            for l in 0..LANES {
                let arg = kx[l] * p.x + ky[l] * p.y + kz[l] * p.z + ph[l];
                let (s, co) = sincos(arg);
                f[l] += am[l] * s;
                let ac = am[l] * co;
                gx[l] += ac * kx[l];
                gy[l] += ac * ky[l];
                gz[l] += ac * kz[l];
            }
        }
        (
            lane_sum(f),
            Vec3::new(lane_sum(gx), lane_sum(gy), lane_sum(gz)),
        )
    }
}

impl WaveSum {
    /// The *ridged* sum `r(p) = Σᵢ aᵢ (1 − |sin(kᵢ·p + φᵢ)|)²` and its gradient: sharp crests
    /// where a sine crosses zero (the gradient jumps there; the one-sided value with
    /// `sign(0) = +1` is returned), smooth valleys.
    #[inline]
    pub fn ridged_value_gradient(&self, p: Vec3) -> (f32, Vec3) {
        let mut f = [0.0f32; LANES];
        let mut gx = [0.0f32; LANES];
        let mut gy = [0.0f32; LANES];
        let mut gz = [0.0f32; LANES];
        for c in 0..self.kx.len() {
            let (kx, ky, kz, ph, am) = (
                &self.kx[c],
                &self.ky[c],
                &self.kz[c],
                &self.phase[c],
                &self.amp[c],
            );
            for l in 0..LANES {
                let arg = kx[l] * p.x + ky[l] * p.y + kz[l] * p.z + ph[l];
                let (s, co) = sincos(arg);
                let m = 1.0 - s.abs();
                f[l] += am[l] * m * m;
                // d/dθ (1 − |s|)² = −2 (1 − |s|) sign(s) cos θ
                let d = -2.0 * am[l] * m * co * 1.0f32.copysign(s);
                gx[l] += d * kx[l];
                gy[l] += d * ky[l];
                gz[l] += d * kz[l];
            }
        }
        (
            lane_sum(f),
            Vec3::new(lane_sum(gx), lane_sum(gy), lane_sum(gz)),
        )
    }

    /// Restricts the sum to the line `o + t·d`: `g(t) = Σᵢ aᵢ sin(ωᵢ t + ψᵢ)` with
    /// `ωᵢ = kᵢ·d`, `ψᵢ = kᵢ·o + φᵢ`, written into `out` (whose buffers are reused).
    pub fn restrict(&self, o: Vec3, d: Vec3, out: &mut LineWaves) {
        let chunks = self.kx.len();
        out.omega.resize(chunks, [0.0; LANES]);
        out.psi.resize(chunks, [0.0; LANES]);
        out.amp.clear();
        out.amp.extend_from_slice(&self.amp);
        for c in 0..chunks {
            for l in 0..LANES {
                let k = Vec3::new(self.kx[c][l], self.ky[c][l], self.kz[c][l]);
                out.omega[c][l] = k.dot(d);
                out.psi[c][l] = k.dot(o) + self.phase[c][l];
            }
        }
    }
}

/// A [`WaveSum`] restricted to a line (see [`WaveSum::restrict`]), with scratch space for
/// marching along it.
#[derive(Debug, Clone, Default)]
pub struct LineWaves {
    omega: Vec<[f32; LANES]>,
    psi: Vec<[f32; LANES]>,
    amp: Vec<[f32; LANES]>,
    sin: Vec<[f32; LANES]>,
    cos: Vec<[f32; LANES]>,
    step_sin: Vec<[f32; LANES]>,
    step_cos: Vec<[f32; LANES]>,
}

impl LineWaves {
    /// Empty scratch (fill it with [`WaveSum::restrict`]).
    pub fn new() -> LineWaves {
        LineWaves::default()
    }

    /// `g(t)`, evaluated directly.
    #[inline]
    pub fn value(&self, t: f32) -> f32 {
        let mut f = [0.0f32; LANES];
        for c in 0..self.omega.len() {
            let (om, ps, am) = (&self.omega[c], &self.psi[c], &self.amp[c]);
            for l in 0..LANES {
                f[l] += am[l] * sincos(om[l] * t + ps[l]).0;
            }
        }
        lane_sum(f)
    }

    /// Calls `visit(j, t_j, g(t_j))` for `t_j = t0 + j·h`, `j = 0..=m`. Steps by rotating each
    /// wave's (sin, cos) by the fixed angle `ωᵢ h` (4 multiplies instead of a `sincos`) and
    /// re-evaluates directly every `resync` steps so the recurrence cannot drift.
    pub fn march(
        &mut self,
        t0: f32,
        h: f32,
        m: usize,
        resync: usize,
        mut visit: impl FnMut(usize, f32, f32),
    ) {
        let chunks = self.omega.len();
        for v in [
            &mut self.sin,
            &mut self.cos,
            &mut self.step_sin,
            &mut self.step_cos,
        ] {
            v.resize(chunks, [0.0; LANES]);
        }
        for c in 0..chunks {
            for l in 0..LANES {
                let (s, co) = sincos(self.omega[c][l] * h);
                self.step_sin[c][l] = s;
                self.step_cos[c][l] = co;
            }
        }
        let resync = resync.max(1);
        for j in 0..=m {
            let t = t0 + j as f32 * h;
            let mut f = [0.0f32; LANES];
            if j % resync == 0 {
                for c in 0..chunks {
                    let (om, ps, am) = (&self.omega[c], &self.psi[c], &self.amp[c]);
                    let (sn, cs) = (&mut self.sin[c], &mut self.cos[c]);
                    for l in 0..LANES {
                        let (s, co) = sincos(om[l] * t + ps[l]);
                        sn[l] = s;
                        cs[l] = co;
                        f[l] += am[l] * s;
                    }
                }
            } else {
                for c in 0..chunks {
                    let (ss, sc, am) = (&self.step_sin[c], &self.step_cos[c], &self.amp[c]);
                    let (sn, cs) = (&mut self.sin[c], &mut self.cos[c]);
                    for l in 0..LANES {
                        let s = sn[l] * sc[l] + cs[l] * ss[l];
                        let co = cs[l] * sc[l] - sn[l] * ss[l];
                        sn[l] = s;
                        cs[l] = co;
                        f[l] += am[l] * s;
                    }
                }
            }
            visit(j, t, lane_sum(f));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sincos_matches_libm() {
        let mut worst = 0.0f64;
        let mut x = -10_000.0f32;
        while x < 10_000.0 {
            let (s, c) = sincos(x);
            let xd = x as f64;
            let err = ((s as f64 - xd.sin()).abs()).max((c as f64 - xd.cos()).abs());
            worst = worst.max(err / (2e-7 + 1e-7 * xd.abs()));
            x += 0.0137;
        }
        assert!(worst < 1.0, "worst relative-to-bound error {worst}");
        for x in [
            0.0f32,
            -0.0,
            1e-30,
            std::f32::consts::FRAC_PI_2,
            -std::f32::consts::PI,
        ] {
            let (s, c) = sincos(x);
            assert!(
                (s - x.sin()).abs() < 3e-7 && (c - x.cos()).abs() < 3e-7,
                "{x}"
            );
        }
    }

    #[test]
    fn wave_gradient_matches_finite_differences() {
        let mut r = Pcg32::new(3);
        let mut w = WaveSum::new();
        for _ in 0..8 {
            w.push(unit_vector(&mut r) * 5.0, r.f32() * 6.0, r.f32());
        }
        let p = Vec3::new(0.3, -0.2, 0.7);
        let (f, g) = w.value_gradient(p);
        assert!((f - w.value(p)).abs() < 1e-6);
        let h = 1e-3;
        for a in 0..3 {
            let mut e = Vec3::ZERO;
            e[a] = h;
            let fd = (w.value(p + e) - w.value(p - e)) / (2.0 * h);
            assert!(
                (fd - g[a]).abs() < 2e-3 * g.length().max(1.0),
                "axis {a}: {fd} vs {}",
                g[a]
            );
        }
    }

    #[test]
    fn basis_is_orthonormal() {
        let mut r = Pcg32::new(9);
        for _ in 0..100 {
            let n = unit_vector(&mut r);
            let (a, b) = orthonormal_basis(n);
            assert!(a.dot(n).abs() < 1e-5 && b.dot(n).abs() < 1e-5 && a.dot(b).abs() < 1e-5);
            assert!((a.length() - 1.0).abs() < 1e-5 && (b.length() - 1.0).abs() < 1e-5);
        }
    }
}
