//! SPT's quantisation: how `nodes.bin` and `lod.bin` store positions, normals, radii and the
//! `lod` values, and which way each is rounded so that the selection keeps its guarantees.
//!
//! Contract (the reasons are in the README, "Files on disk"):
//! - **`e` and `e_par` are not rounded**: `lod.bin` codes them losslessly ([`super::files`]:
//!   a leaf's `e` = 0 in no bytes, an `e_par` equal to the previous node's in no bytes, a
//!   smaller one as the difference of the `f32` bit patterns). The selection reads the very
//!   values format 1 stored; rounding them (tried first: 16-bit codes, rounded up) moved
//!   whole sibling groups across a threshold whenever noise of the build's arithmetic put a
//!   parent's error on a code boundary, so a model's selection changed with its scale.
//! - **`δ`** is a 16-bit code relative to the build's [`LodScale`] `S` (the side of the
//!   cloud's bounding cube): the code of `x` is the 16 bits below the sign of the `f32`
//!   `x / S` (8 exponent and 8 mantissa bits, [`code_up`]), its value `S·`[`value`]`(code)`
//!   rounded to `f32`; the smallest code whose value is ≥ `x` (**rounded up**). The code
//!   order is the value order, the relative step at most 2⁻⁸, and a model scaled by any
//!   factor gets the same codes (up to the `f32` rounding of its coordinates). Code 0 is 0;
//!   codes from `0xFF00` are invalid.
//! - **Radii** are 16-bit codes on a per-build scale ([`RadiusScale`]): 5 exponent bits (32
//!   octaves below the build's largest radius) and 11 mantissa bits (relative step ≤ 2⁻¹¹),
//!   **rounded up**; a radius more than 2³¹ times below the largest takes the smallest code.
//! - **Positions** are integers on a per-build grid ([`Grid`]): per axis an origin (the box
//!   of the node centres), a step (the box's extent over the largest integer, so that the
//!   grid scales with the model) and 2, 3 or 4 bytes, the fewest that make the step at most
//!   1/8 of the 1 % quantile of the leaf radii (its binary exponent, from [`Extent`]).
//!   Rounded to the nearest: a decoded centre lies within [`Grid::error_bound`] of the
//!   node's.
//! - **Normals** are octahedral, 2 × 12 bits ([`normal_code`]; ≤ 1.1e-3 rad from the node's
//!   normal, tested); the GPU gets them as the 2 × 16-bit code [`gpu_normal`] maps them to,
//!   so the normal the CPU mirror decodes is the normal the shader decodes.
//!
//! What the selection's guarantees need (README, "Overlap defined precisely"): `e`, `e_par`
//! exact as before (a child's `e_par` is its parent's `e`, errors monotone, the list sorted
//! by them); `δ` bounding the distance between the **decoded** centres: the writer raises
//! the exact `δ` by twice [`Grid::error_bound`] before rounding it up; `γ` bounding the
//! angle between the normals the test reads ([`super::lod_entry`]). Radii are rounded up (a
//! splat never shrinks); positions and normals to the nearest.

use glam::Vec3;

use super::build::Node;

/// The first code whose bit pattern is not a finite `f32`.
pub const FIRST_NON_FINITE: u16 = 0xFF00;
/// Bits per component of an octahedral normal code.
pub const NORMAL_BITS: u32 = 12;
const NORMAL_MAX: i32 = (1 << (NORMAL_BITS - 1)) - 1;

/// The smallest code whose [`value`] is ≥ `x` (`x` ≥ 0, finite); `None` above the largest
/// finite code (≈ 3.39e38) or for a negative or non-finite `x`.
#[inline]
pub fn code_up(x: f32) -> Option<u16> {
    if x == 0.0 {
        return Some(0);
    }
    if !(x > 0.0 && x.is_finite()) {
        return None;
    }
    let c = (x.to_bits() + 0x7fff) >> 15;
    u16::try_from(c).ok().filter(|&c| c < FIRST_NON_FINITE)
}

/// The value of a finite code (`< FIRST_NON_FINITE`): an exact `f32`.
#[inline]
pub fn value(code: u16) -> f32 {
    f32::from_bits(u32::from(code) << 15)
}

/// `x` rounded up to an `f32`.
fn f32_up(x: f64) -> f32 {
    let f = x as f32;
    if f.is_finite() && f64::from(f) < x {
        f.next_up()
    } else {
        f
    }
}

/// The scale `S` of the `δ` codes: code `c` is `S·value(c)`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodScale(pub f32);

impl LodScale {
    /// The side of the bounding cube of `bounds` (1 for a cloud of one point).
    pub fn of(bounds: scenes::Aabb) -> Self {
        let s = bounds.size().max_element();
        Self(if s.is_normal() { s } else { 1.0 })
    }

    /// Why the scale is unusable (a corrupt header), if it is.
    pub fn check(&self) -> Result<(), String> {
        if self.0.is_normal() && self.0 > 0.0 {
            Ok(())
        } else {
            Err(format!("lod scale {} is not a positive normal f32", self.0))
        }
    }

    /// The value of a code below `FIRST_NON_FINITE`; `None` for another code or one whose
    /// value is not finite.
    pub fn value(&self, code: u16) -> Option<f32> {
        if code >= FIRST_NON_FINITE {
            return None;
        }
        // An f32 times an f32 is exact in f64: one rounding, monotone in the code.
        let v = (f64::from(value(code)) * f64::from(self.0)) as f32;
        v.is_finite().then_some(v)
    }

    /// The smallest code whose value is ≥ `x` (`x` ≥ 0, finite); `None` where none is.
    pub fn code_up(&self, x: f32) -> Option<u16> {
        if x == 0.0 {
            return Some(0);
        }
        if !(x > 0.0 && x.is_finite()) {
            return None;
        }
        let mut c = code_up(f32_up(f64::from(x) / f64::from(self.0)))?;
        // The ratio and the value are each rounded once: settle on the smallest code.
        while c > 0 && self.value(c - 1).is_some_and(|v| v >= x) {
            c -= 1;
        }
        loop {
            match self.value(c) {
                Some(v) if v >= x => return Some(c),
                Some(_) if c + 1 < FIRST_NON_FINITE => c += 1,
                _ => return None,
            }
        }
    }

    /// [`Self::code_up`] of `x` computed in `f64` (rounded up to `f32` first).
    pub fn code_up_f64(&self, x: f64) -> Option<u16> {
        self.code_up(f32_up(x))
    }
}

/// The 24-bit octahedral code of a non-zero vector: two 12-bit components, each stored
/// plus 2¹¹ (`x | y << 12`).
pub fn normal_code(n: Vec3) -> u32 {
    // The octahedral projection of `crate::octnormal::encode`, rounded to 12 bits.
    let p = crate::octnormal::project(n);
    let (x, y) = (p.x, p.y);
    let q = |v: f32| {
        let v = (v.clamp(-1.0, 1.0) * NORMAL_MAX as f32).round() as i32;
        (v.clamp(-NORMAL_MAX, NORMAL_MAX) + NORMAL_MAX + 1) as u32
    };
    q(x) | q(y) << NORMAL_BITS
}

/// The GPU's 2 × snorm16 octahedral code ([`crate::octnormal`]) of a [`normal_code`]
/// (any 24-bit value decodes to a unit vector).
pub fn gpu_normal(code: u32) -> u32 {
    let c = |v: u32| {
        let s = (v & 0xfff) as i32 - (NORMAL_MAX + 1);
        // round(s · 32767 / 2047), symmetric; −2048 (never written) saturates.
        let r = (s.abs() * 32767 + NORMAL_MAX / 2) / NORMAL_MAX;
        (s.signum() * r).clamp(-32767, 32767) as i16 as u16 as u32
    };
    c(code) | c(code >> NORMAL_BITS) << 16
}

/// The unit normal the GPU and the CPU mirror see for a [`normal_code`].
pub fn decode_normal(code: u32) -> Vec3 {
    crate::octnormal::decode(gpu_normal(code))
}

/// The normal the files give a node of normal `n` (`n` itself without normals, where every
/// node's is `Vec3::Z`).
pub fn stored_normal(n: Vec3, has_normals: bool) -> Vec3 {
    if has_normals {
        decode_normal(normal_code(n))
    } else {
        n
    }
}

/// The box of the node centres and the binary exponents of the leaf radii: what the
/// position [`Grid`] is chosen from. Adding is order-free, so the in-memory build and the
/// build in units (which add the same nodes in another order) get the same grid.
#[derive(Debug, Clone, PartialEq)]
pub struct Extent {
    lo: Vec3,
    hi: Vec3,
    /// The largest radius of any node.
    r_max: f32,
    /// Leaves per biased `f32` exponent of their radius.
    radius_exponents: [u64; 256],
}

impl Default for Extent {
    fn default() -> Self {
        Self {
            lo: Vec3::INFINITY,
            hi: Vec3::NEG_INFINITY,
            r_max: 0.0,
            radius_exponents: [0; 256],
        }
    }
}

impl Extent {
    /// Adds a node (its centre and radius).
    pub fn add(&mut self, nd: &Node) {
        self.lo = self.lo.min(nd.p);
        self.hi = self.hi.max(nd.p);
        self.r_max = self.r_max.max(nd.r);
        if nd.leaf {
            self.radius_exponents[((nd.r.to_bits() >> 23) & 0xff) as usize] += 1;
        }
    }

    /// The union of two extents.
    pub fn merge(mut self, other: &Extent) -> Extent {
        self.lo = self.lo.min(other.lo);
        self.hi = self.hi.max(other.hi);
        self.r_max = self.r_max.max(other.r_max);
        for (a, b) in self
            .radius_exponents
            .iter_mut()
            .zip(&other.radius_exponents)
        {
            *a += b;
        }
        self
    }

    /// The extent of `nodes` (in parallel; the result does not depend on the order).
    ///
    /// Folded per chunk in place: a 2 KB `Extent` moved through `fold` by value was a
    /// `memcpy` per node, 7 % of an SPT build's samples (`perf`, terrain 10 M).
    pub fn of(nodes: &[Node]) -> Extent {
        use rayon::prelude::*;
        nodes
            .par_chunks(1 << 14)
            .map(|chunk| {
                let mut e = Extent::default();
                for nd in chunk {
                    e.add(nd);
                }
                e
            })
            .reduce(Extent::default, |a, b| a.merge(&b))
    }

    /// The binary exponent `k` with `2ᵏ ≤` the 1 % quantile of the leaf radii (−126 without
    /// leaves).
    pub fn small_radius_exponent(&self) -> i32 {
        let total: u64 = self.radius_exponents.iter().sum();
        let want = total.div_ceil(100).max(1);
        let mut acc = 0;
        for (e, &c) in self.radius_exponents.iter().enumerate() {
            acc += c;
            if acc >= want {
                return (e as i32 - 127).max(-126);
            }
        }
        -126
    }

    /// The radius codes' scale: above the largest radius.
    pub fn radius_scale(&self) -> RadiusScale {
        RadiusScale::above(self.r_max)
    }

    /// The position grid ([`Grid::choose`]).
    pub fn grid(&self) -> Grid {
        // `+ 0.0` turns −0 into +0: min and max of ±0 depend on the order of the nodes.
        let (lo, hi) = if self.lo.cmple(self.hi).all() {
            (self.lo + Vec3::ZERO, self.hi + Vec3::ZERO)
        } else {
            (Vec3::ZERO, Vec3::ZERO)
        };
        Grid::choose(lo, hi, 2f32.powi(self.small_radius_exponent() - 3))
    }
}

/// Radius codes: `code = E·2¹¹ + m` (`E` < 32, `m` < 2¹¹) is the radius
/// `2^(top − 32 + E)·(1 + m/2¹¹)`, an exact `f32`; code 0 is not a radius.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct RadiusScale {
    /// Every radius is below `2^top`.
    pub top: i32,
}

impl RadiusScale {
    /// The lowest allowed `top` (every value a normal `f32`).
    pub const MIN_TOP: i32 = -94;
    /// The highest (`f32` radii are below 2¹²⁸).
    pub const MAX_TOP: i32 = 128;

    /// The scale whose codes hold every radius up to `r_max`.
    pub fn above(r_max: f32) -> Self {
        let e = if r_max.is_normal() {
            ((r_max.to_bits() >> 23) & 0xff) as i32 - 127
        } else {
            Self::MIN_TOP
        };
        let mut s = Self {
            top: (e + 1).clamp(Self::MIN_TOP, Self::MAX_TOP),
        };
        // Rounding up may carry `r_max` into the next octave.
        if s.code_up(r_max).is_none() && s.top < Self::MAX_TOP {
            s.top += 1;
        }
        s
    }

    /// The smallest code whose radius is ≥ `r` (`r` > 0 finite); `None` for `r` ≥ `2^top`
    /// or not positive and finite.
    pub fn code_up(&self, r: f32) -> Option<u16> {
        if !(r > 0.0 && r.is_finite()) {
            return None;
        }
        let bits = r.to_bits();
        let exp = ((bits >> 23) & 0xff) as i32 - 127;
        let mut e = exp - (self.top - 32);
        if !r.is_normal() || e < 0 {
            return Some(1);
        }
        let mut m = (bits & 0x7f_ffff).div_ceil(1 << 12);
        if m == 1 << 11 {
            (e, m) = (e + 1, 0);
        }
        if e >= 32 {
            return None;
        }
        Some(((e as u32) << 11 | m).max(1) as u16)
    }

    /// The radius of a code (not 0).
    pub fn value(&self, code: u16) -> f32 {
        let (e, m) = (i32::from(code >> 11), u32::from(code) & 0x7ff);
        f32::from_bits(((self.top - 32 + e + 127) as u32) << 23 | m << 12)
    }
}

/// Positions on a per-build grid: per axis `lo + i·step`, `i` an unsigned integer of `bytes`
/// bytes (little-endian in the records). The step is the box's extent over the largest
/// integer (rounded up to `f32`), not a power of two: a model scaled by any factor gets the
/// same integers (up to the `f32` rounding of its coordinates), so its selection does not
/// move with the scale.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Grid {
    /// Origin (the box of the node centres).
    pub lo: [f32; 3],
    /// Step, per axis.
    pub step: [f32; 3],
    /// Bytes per coordinate, 2..=4, per axis.
    pub bytes: [u8; 3],
}

impl Grid {
    /// The grid over the box `[lo, hi]`: per axis the fewest bytes (2, 3 or 4) whose step
    /// covering the box is at most `max_step` (4 bytes when none is).
    pub fn choose(lo: Vec3, hi: Vec3, max_step: f32) -> Grid {
        let mut g = Grid {
            lo: lo.to_array(),
            step: [0.0; 3],
            bytes: [4; 3],
        };
        for a in 0..3 {
            let ext = f64::from(hi[a]) - f64::from(lo[a]);
            let covering = |bytes: u8| {
                let max = ((1u64 << (8 * bytes)) - 1) as f64;
                f32_up(ext / max).max(f32::MIN_POSITIVE)
            };
            let (bytes, step) = [2u8, 3, 4]
                .into_iter()
                .map(|b| (b, covering(b)))
                .find(|&(_, step)| step <= max_step)
                .unwrap_or((4, covering(4)));
            g.bytes[a] = bytes;
            g.step[a] = step;
        }
        g
    }

    /// The step of axis `a`.
    pub fn step(&self, a: usize) -> f64 {
        f64::from(self.step[a])
    }

    /// Bytes of a position.
    pub fn record_bytes(&self) -> usize {
        self.bytes.iter().map(|&b| b as usize).sum()
    }

    /// The largest integer of axis `a`.
    pub fn max_code(&self, a: usize) -> u32 {
        ((1u64 << (8 * self.bytes[a])) - 1) as u32
    }

    /// The nearest grid point's integers (clamped to the grid).
    pub fn encode(&self, p: Vec3) -> [u32; 3] {
        std::array::from_fn(|a| {
            let i = ((f64::from(p[a]) - f64::from(self.lo[a])) / self.step(a)).round();
            i.clamp(0.0, f64::from(self.max_code(a))) as u32
        })
    }

    /// The centre of grid point `c` (rounded once, to `f32`).
    pub fn decode(&self, c: [u32; 3]) -> Vec3 {
        Vec3::from_array(std::array::from_fn(|a| {
            (f64::from(self.lo[a]) + f64::from(c[a]) * self.step(a)) as f32
        }))
    }

    /// A bound on `|decode(encode(p)) − p|` for `p` in the grid's box: half a step plus the
    /// `f32` rounding of the decoded value (one ulp of the largest coordinate), per axis.
    pub fn error_bound(&self) -> f64 {
        let sq: f64 = (0..3)
            .map(|a| {
                let far = f64::from(self.lo[a]).abs() + f64::from(self.max_code(a)) * self.step(a);
                let ulp =
                    2f64.powi(far.max(f64::from(f32::MIN_POSITIVE)).log2().ceil() as i32 - 23);
                let e = 0.5 * self.step(a) + ulp;
                e * e
            })
            .sum();
        sq.sqrt() * (1.0 + 1e-9)
    }

    /// Why the grid cannot be decoded (a corrupt header), if it cannot.
    pub fn check(&self) -> Result<(), String> {
        for a in 0..3 {
            if !(2..=4).contains(&self.bytes[a]) {
                return Err(format!("axis {a}: {} bytes per coordinate", self.bytes[a]));
            }
            if !self.step[a].is_normal() || self.step[a] < 0.0 || !self.lo[a].is_finite() {
                return Err(format!(
                    "axis {a}: origin {} and step {} out of range",
                    self.lo[a], self.step[a]
                ));
            }
            let far = f64::from(self.lo[a]) + f64::from(self.max_code(a)) * self.step(a);
            if !(far as f32).is_finite() {
                return Err(format!("axis {a}: the grid reaches {far}, beyond f32"));
            }
        }
        Ok(())
    }

    /// Appends the position's integers (little-endian, `bytes[a]` each).
    pub fn put(&self, c: [u32; 3], out: &mut Vec<u8>) {
        for (v, &n) in c.iter().zip(&self.bytes) {
            out.extend_from_slice(&v.to_le_bytes()[..n as usize]);
        }
    }

    /// Reads a position's integers from the front of `rec`.
    pub fn get(&self, rec: &[u8]) -> [u32; 3] {
        let mut at = 0;
        std::array::from_fn(|a| {
            let n = self.bytes[a] as usize;
            let mut w = [0u8; 4];
            w[..n].copy_from_slice(&rec[at..at + n]);
            at += n;
            u32::from_le_bytes(w)
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scalar_codes_round_up_and_are_ordered() {
        let mut rng = scenes::rng::Pcg32::new(5);
        let mut prev = 0u16;
        for c in 0..FIRST_NON_FINITE {
            assert!(c == 0 || value(c) > value(prev));
            assert_eq!(code_up(value(c)), Some(c), "code {c}");
            prev = c;
        }
        for _ in 0..100_000 {
            let x = f32::from_bits(rng.next_u32() & 0x7fff_ffff);
            match code_up(x) {
                Some(c) => {
                    let v = value(c);
                    assert!(v >= x && (c == 0 || value(c - 1) < x), "{x}");
                    if x.is_normal() {
                        assert!(v <= x * (1.0 + 1.0 / 256.0), "{x} -> {v}");
                    }
                }
                None => assert!(!x.is_finite() || x > value(FIRST_NON_FINITE - 1)),
            }
        }
        assert_eq!(code_up(-1.0), None);
        assert_eq!(code_up(-0.0), Some(0));
    }

    #[test]
    fn lod_codes_round_up_and_ignore_the_scale() {
        let mut rng = scenes::rng::Pcg32::new(8);
        for s in [1.0f32, 1e-9 * 1.7, 0.37, 2.5e3, 1e9 * 1.3] {
            let q = LodScale(s);
            assert!(q.check().is_ok());
            // Non-decreasing; strictly increasing where the values are normal (below, a
            // tiny scale's smallest codes underflow together).
            let mut prev = -1.0;
            for c in 0..FIRST_NON_FINITE {
                let Some(v) = q.value(c) else { break };
                assert!(
                    v > prev || (v == prev && !v.is_normal()),
                    "scale {s} code {c}"
                );
                prev = v;
            }
            for _ in 0..20_000 {
                let x = s * 4.0 * rng.f32().powi(6);
                let c = q.code_up(x).unwrap();
                let v = q.value(c).unwrap();
                assert!(
                    v >= x && (c == 0 || q.value(c - 1).unwrap() < x),
                    "{s}: {x}"
                );
                if x.is_normal() {
                    assert!(v <= x * (1.0 + 1.0 / 255.0), "{s}: {x} -> {v}");
                }
                // The same relative value at another scale gets the same code, unless it
                // lies within the f32 rounding of a code's boundary.
                let other = LodScale(s * 3.1);
                let y = (f64::from(x) * 3.1) as f32;
                let d = other.code_up(y).unwrap();
                assert!(d.abs_diff(c) <= 1, "{s}: {x} code {c}, scaled {d}");
            }
            assert_eq!(q.value(FIRST_NON_FINITE), None);
        }
        assert!(LodScale(0.0).check().is_err() && LodScale(f32::NAN).check().is_err());
    }

    #[test]
    fn radius_codes_round_up_within_2_to_the_minus_11() {
        let mut rng = scenes::rng::Pcg32::new(4);
        for r_max in [1e-30f32, 3e-5, 0.75, 1.0, 7.0e4, 3e38] {
            let s = RadiusScale::above(r_max);
            assert!(s.value(0xffff) >= r_max || s.top == RadiusScale::MAX_TOP);
            let mut prev = 0.0;
            for c in 1..=0xffffu16 {
                assert!(s.value(c) > prev && s.value(c).is_normal());
                prev = s.value(c);
            }
            for _ in 0..20_000 {
                let r = r_max * rng.f32().powi(8);
                let Some(c) = s.code_up(r) else {
                    assert!(r == 0.0 || r >= s.value(0xffff));
                    continue;
                };
                let v = s.value(c);
                assert!(v >= r && (c == 1 || s.value(c - 1) < r), "{r} -> {v}");
                if c > 1 {
                    assert!(v <= r * (1.0 + 1.0 / 2048.0), "{r} -> {v}");
                }
            }
            assert_eq!(s.code_up(r_max).map(|c| s.value(c) >= r_max), Some(true));
        }
        let s = RadiusScale::above(1.0);
        assert_eq!(s.code_up(2.0), None);
        assert_eq!(s.code_up(0.0), None);
        assert_eq!(s.code_up(1e-20), Some(1));
    }

    #[test]
    fn normals_round_trip_within_1_2_milliradians() {
        let mut rng = scenes::rng::Pcg32::new(9);
        let mut worst = 0f32;
        for _ in 0..200_000 {
            let n = rng.unit_vec3();
            let d = decode_normal(normal_code(n));
            worst = worst.max(n.cross(d).length().atan2(n.dot(d)));
        }
        for n in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y, Vec3::Z, -Vec3::Z] {
            assert!(decode_normal(normal_code(n)).dot(n) > 0.999_999, "{n}");
        }
        // 12-bit octahedral: ≈ 1.07e-3 rad at worst (the octahedron's face centres).
        assert!(worst < 1.2e-3, "worst {worst} rad");
        // Every 24-bit code decodes to a unit vector.
        for code in [0u32, 0xff_ffff, 0x80_0800, 0x12_3456] {
            assert!((decode_normal(code).length() - 1.0).abs() < 1e-5);
        }
    }

    #[test]
    fn grid_covers_the_box_within_its_bound() {
        let lo = Vec3::new(-3.0, 0.5, 1000.0);
        let hi = Vec3::new(2.0, 0.5, 1001.0);
        let g = Grid::choose(lo, hi, 2f32.powi(-12));
        assert_eq!(g.bytes, [2, 2, 2]);
        assert!(g.check().is_ok());
        let fine = Grid::choose(lo, hi, 2f32.powi(-20));
        assert_eq!(fine.bytes[0], 3, "{fine:?}");
        let mut rng = scenes::rng::Pcg32::new(2);
        for grid in [g, fine] {
            let bound = grid.error_bound();
            for _ in 0..10_000 {
                let t = Vec3::new(rng.f32(), rng.f32(), rng.f32());
                let p = lo + (hi - lo) * t;
                let d = grid.decode(grid.encode(p));
                assert!(f64::from(d.distance(p)) <= bound, "{p} -> {d}");
                for a in 0..3 {
                    let e = (f64::from(d[a]) - f64::from(p[a])).abs();
                    assert!(e <= 0.5 * grid.step(a) + f64::from(p[a].abs()) * 1.2e-7);
                }
            }
            let mut rec = Vec::new();
            let c = grid.encode(hi);
            grid.put(c, &mut rec);
            assert_eq!(rec.len(), grid.record_bytes());
            assert_eq!(grid.get(&rec), c);
        }
    }
}
