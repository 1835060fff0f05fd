//! Octahedral unit-vector encoding into two signed 16-bit values (Cigolle et al. 2014), the
//! format normals travel in to the GPU (`unpack2x16snorm` + octahedral decode in WGSL).
//! Worst-case angular error ≈ 5e-5 rad, far below any LOD normal quantisation.

use glam::{Vec2, Vec3};

/// The octahedral projection of a (not necessarily normalised, non-zero) vector: a point of
/// the square `[-1, 1]²` (the lower hemisphere folded over the diagonals).
#[inline]
pub fn project(n: Vec3) -> Vec2 {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs());
    let p = Vec2::new(n.x, n.y);
    if n.z < 0.0 {
        (Vec2::ONE - Vec2::new(p.y.abs(), p.x.abs())) * Vec2::new(sign(p.x), sign(p.y))
    } else {
        p
    }
}

/// Encodes a (not necessarily normalised, non-zero) vector as a packed `u32` = two snorm16.
#[inline]
pub fn encode(n: Vec3) -> u32 {
    let p = project(n);
    let q = |v: f32| ((v.clamp(-1.0, 1.0) * 32767.0).round() as i16) as u16 as u32;
    q(p.x) | (q(p.y) << 16)
}

/// Decodes a packed `u32` from [`encode`] to a unit vector (the CPU mirror of the shader).
#[inline]
pub fn decode(packed: u32) -> Vec3 {
    let f = |b: u32| ((b as u16 as i16) as f32 / 32767.0).max(-1.0);
    let e = Vec2::new(f(packed & 0xffff), f(packed >> 16));
    let mut v = Vec3::new(e.x, e.y, 1.0 - e.x.abs() - e.y.abs());
    let t = (-v.z).max(0.0);
    v.x += if v.x >= 0.0 { -t } else { t };
    v.y += if v.y >= 0.0 { -t } else { t };
    v.normalize()
}

#[inline]
fn sign(v: f32) -> f32 {
    if v >= 0.0 { 1.0 } else { -1.0 }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn round_trip_error_is_tiny() {
        let mut rng = scenes::rng::Pcg32::new(3);
        let mut worst = 0f32;
        for _ in 0..100_000 {
            let n = rng.unit_vec3();
            let d = decode(encode(n));
            // atan2 of |a×b| and a·b: acos in f32 cannot resolve angles below ≈ 3e-4 rad.
            worst = worst.max(n.cross(d).length().atan2(n.dot(d)));
        }
        for n in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            assert!(decode(encode(n)).dot(n) > 0.999_999, "{n}");
        }
        assert!(worst < 1e-4, "worst {worst} rad");
    }
}
