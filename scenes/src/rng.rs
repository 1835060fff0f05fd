//! A small, fixed, portable PRNG (PCG-XSH-RR 64/32 seeded through SplitMix64).
//!
//! Generators use this rather than an external crate so that "same seed ⇒ identical bytes"
//! cannot change under a dependency update. `Pcg32::stream(seed, i)` gives independent,
//! reproducible streams for parallel blocks.

/// PCG32 (O'Neill 2014), 64-bit state, 32-bit output.
#[derive(Debug, Clone)]
pub struct Pcg32 {
    state: u64,
    inc: u64,
}

/// SplitMix64 step, used to spread seeds.
pub fn splitmix64(x: &mut u64) -> u64 {
    *x = x.wrapping_add(0x9E37_79B9_7F4A_7C15);
    let mut z = *x;
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

impl Pcg32 {
    /// A generator for `seed`.
    pub fn new(seed: u64) -> Self {
        Self::stream(seed, 0)
    }
    /// Stream `stream` of `seed`: independent sequences for parallel work.
    pub fn stream(seed: u64, stream: u64) -> Self {
        let mut s = seed ^ stream.wrapping_mul(0xD1B5_4A32_D192_ED03);
        let state = splitmix64(&mut s);
        let inc = (splitmix64(&mut s) << 1) | 1;
        let mut r = Self { state: 0, inc };
        r.next_u32();
        r.state = r.state.wrapping_add(state);
        r.next_u32();
        r
    }
    /// Next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old
            .wrapping_mul(6_364_136_223_846_793_005)
            .wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }
    /// Uniform in [0, 1) with 24 bits.
    #[inline]
    pub fn f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / 16_777_216.0)
    }
    /// Uniform in [0, 1) with 53 bits.
    #[inline]
    pub fn f64(&mut self) -> f64 {
        let hi = (self.next_u32() as u64) << 21;
        let lo = (self.next_u32() >> 11) as u64;
        (hi | lo) as f64 * (1.0 / 9_007_199_254_740_992.0)
    }
    /// Uniform in [lo, hi).
    #[inline]
    pub fn range_f32(&mut self, lo: f32, hi: f32) -> f32 {
        lo + (hi - lo) * self.f32()
    }
    /// Uniform integer in [0, n) (Lemire's method, unbiased).
    #[inline]
    pub fn below(&mut self, n: u32) -> u32 {
        let mut m = self.next_u32() as u64 * n as u64;
        if (m as u32) < n {
            let t = n.wrapping_neg() % n;
            while (m as u32) < t {
                m = self.next_u32() as u64 * n as u64;
            }
        }
        (m >> 32) as u32
    }
    /// Uniform unit vector.
    pub fn unit_vec3(&mut self) -> glam::Vec3 {
        let z = self.range_f32(-1.0, 1.0);
        let phi = self.range_f32(0.0, std::f32::consts::TAU);
        let s = (1.0 - z * z).max(0.0).sqrt();
        glam::Vec3::new(s * phi.cos(), s * phi.sin(), z)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    #[test]
    fn deterministic_and_streams_differ() {
        let a: Vec<u32> = (0..4).map(|_| Pcg32::new(7).next_u32()).collect();
        assert!(a.windows(2).all(|w| w[0] == w[1]));
        let mut s0 = Pcg32::stream(7, 0);
        let mut s1 = Pcg32::stream(7, 1);
        assert_ne!(s0.next_u32(), s1.next_u32());
        let mut r = Pcg32::new(1);
        for _ in 0..1000 {
            let x = r.f32();
            assert!((0.0..1.0).contains(&x));
            assert!(r.below(10) < 10);
        }
    }
}
