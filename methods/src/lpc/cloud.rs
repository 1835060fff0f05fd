//! The LPC cloud codec: one node's cloud as the raw bytes of one repository chunk (LZO
//! compression and the checksum are added by [`crate::store::RepoWriter`]).
//!
//! Each cloud is spatially sorted (Morton order of its quantised positions), positions are
//! quantised relative to a box — the model's (the paper's, `quantise = model`) or the cloud's
//! own (`quantise = cloud`, the paper's future work) — with per-axis bit counts chosen so that
//! the error on every axis stays below half the input spacing `r`, normals take 16 bits
//! (octahedral, 8 + 8), colours 24 bits (only if the scene has colours), radii never.
//!
//! Layout (little-endian):
//!
//! | bytes        | field                                                               |
//! |--------------|---------------------------------------------------------------------|
//! | 2            | magic `LC`                                                          |
//! | 1            | version (1)                                                         |
//! | 1            | flags: bit 0 normals, bit 1 colours                                 |
//! | 4            | `count` (u32, ≥ 1)                                                   |
//! | 3 + 1        | bits per axis `b_x, b_y, b_z` (0–32), one zero byte                 |
//! | 12           | box minimum (f32 × 3)                                               |
//! | 12           | quantisation step (f32 × 3; 0 on an axis with 0 bits)               |
//! | varints      | `count` LEB128 deltas of consecutive 96-bit Morton codes (first: the code itself) |
//! | 2 × count    | normals: the 8-bit `u` plane, then the `v` plane, each byte-delta coded |
//! | 3 × count    | colours: the `r`, `g`, `b` planes, each byte-delta coded            |
//!
//! The first four fields (8 bytes) are the preamble MWKD's nodes share
//! ([`crate::store::chunk_header`]).
//!
//! A position is `min + q · step` per axis (computed in `f64`, then rounded to `f32`).
//! The Morton code interleaves bit `i` of `q_x, q_y, q_z` at bits `3i, 3i+1, 3i+2`.
//! [`decode`] checks every field and the exact length and answers
//! [`MethodError::Corrupt`] naming the cloud, never panicking or reading out of bounds.

use std::sync::OnceLock;

use glam::Vec3;
use scenes::Attributes;

use crate::store::chunk_header::{Format, Preamble, le_u32};
use crate::{MethodError, SplatBatch, octnormal};

/// Bytes of the fixed header.
pub const HEADER_BYTES: usize = 36;
/// Magic `LC`, version 1 ([`crate::store::chunk_header`]: magic, version, flags, count).
const FORMAT: Format = Format {
    magic: *b"LC",
    version: 1,
    header_bytes: HEADER_BYTES,
};
/// Most bits per axis.
pub const MAX_BITS: u32 = 32;
/// The quantisation step is at most this fraction of the input spacing, so the error
/// (half a step) stays below `0.45 r` with room for `f32` rounding.
pub const STEP_FRACTION: f64 = 0.9;

/// One sample as the build handles it (20 bytes, the record of the temporary files).
#[derive(Debug, Clone, Copy, PartialEq, Default, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
pub struct Sample {
    /// Local position.
    pub p: [f32; 3],
    /// Octahedral 8 + 8 normal ([`oct16_encode`]); 0 without normals.
    pub normal: u16,
    /// Build flags (not stored in the repository).
    pub flags: u16,
    /// sRGB colour (`[r, g, b, 0]`); zero without colours.
    pub color: [u8; 4],
}

#[inline]
fn sign(v: f32) -> f32 {
    if v >= 0.0 { 1.0 } else { -1.0 }
}

/// Octahedral encoding of a non-zero vector into 8 + 8 bits (`u | v << 8`): of the four
/// grid points around the exact octahedral coordinates, the one whose decoded normal (as the
/// renderer sees it, [`normal_table`]) is closest to `n`.
#[inline]
pub fn oct16_encode(n: Vec3) -> u16 {
    let n = n / (n.x.abs() + n.y.abs() + n.z.abs());
    let (mut x, mut y) = (n.x, n.y);
    if n.z < 0.0 {
        (x, y) = ((1.0 - y.abs()) * sign(x), (1.0 - x.abs()) * sign(y));
    }
    let g = |v: f32| (v.clamp(-1.0, 1.0) * 0.5 + 0.5) * 255.0;
    let (gx, gy) = (g(x), g(y));
    let (x0, y0) = (gx.floor().min(254.0) as u16, gy.floor().min(254.0) as u16);
    let table = normal_table();
    let mut best = (f32::NEG_INFINITY, 0u16);
    for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
        let code = (x0 + dx) | ((y0 + dy) << 8);
        let d = Vec3::from(table[code as usize].1).dot(n);
        if d > best.0 {
            best = (d, code);
        }
    }
    best.1
}

/// Decodes [`oct16_encode`] to a unit vector.
#[inline]
pub fn oct16_decode(v: u16) -> Vec3 {
    let f = |b: u16| (b as f32 / 255.0) * 2.0 - 1.0;
    let (x, y) = (f(v & 0xff), f(v >> 8));
    let mut n = Vec3::new(x, y, 1.0 - x.abs() - y.abs());
    let t = (-n.z).max(0.0);
    n.x += if n.x >= 0.0 { -t } else { t };
    n.y += if n.y >= 0.0 { -t } else { t };
    n.normalize()
}

/// For each 16-bit normal: the renderer's packed form ([`octnormal::encode`]) and the unit
/// vector the renderer decodes from it (what normal cones must cover).
pub fn normal_table() -> &'static [(u32, [f32; 3])] {
    static TABLE: OnceLock<Vec<(u32, [f32; 3])>> = OnceLock::new();
    TABLE.get_or_init(|| {
        (0..=u16::MAX)
            .map(|v| {
                let packed = octnormal::encode(oct16_decode(v));
                (packed, octnormal::decode(packed).to_array())
            })
            .collect()
    })
}

use crate::morton::{demorton96, morton96};

/// Per-axis quantisation of a box for input spacing `spacing`: `(bits, step)`.
pub fn quantisation(min: [f32; 3], max: [f32; 3], spacing: f32) -> ([u8; 3], [f32; 3]) {
    let mut bits = [0u8; 3];
    let mut step = [0f32; 3];
    let target = spacing as f64 * STEP_FRACTION;
    for a in 0..3 {
        let e = max[a] as f64 - min[a] as f64;
        if e <= 0.0 {
            continue;
        }
        let mut b = 1u32;
        while b < MAX_BITS && e / (((1u64 << b) - 1) as f64) > target {
            b += 1;
        }
        let levels = ((1u64 << b) - 1) as f64;
        let mut s = (e / levels) as f32;
        if (s as f64) * levels < e {
            s = s.next_up();
        }
        bits[a] = b as u8;
        step[a] = s;
    }
    (bits, step)
}

#[inline]
fn quantise(x: f32, min: f32, step: f32, bits: u8) -> u32 {
    if bits == 0 {
        return 0;
    }
    let top = ((1u64 << bits) - 1) as f64;
    ((x as f64 - min as f64) / step as f64)
        .round()
        .clamp(0.0, top) as u32
}

#[inline]
fn dequantise(q: u64, min: f32, step: f32) -> f32 {
    (min as f64 + q as f64 * step as f64) as f32
}

/// Bounding box of the samples' positions.
pub fn bounds(samples: &[Sample]) -> ([f32; 3], [f32; 3]) {
    let mut lo = [f32::INFINITY; 3];
    let mut hi = [f32::NEG_INFINITY; 3];
    for s in samples {
        for a in 0..3 {
            lo[a] = lo[a].min(s.p[a]);
            hi[a] = hi[a].max(s.p[a]);
        }
    }
    (lo, hi)
}

fn put_varint(out: &mut Vec<u8>, mut v: u128) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Encodes one cloud (`samples`, at least one) for input spacing `spacing`, quantised in its
/// own bounding box ([`encode_in`] with no frame).
pub fn encode(samples: &[Sample], attrs: Attributes, spacing: f32) -> (Vec<u8>, [u8; 3]) {
    encode_in(samples, attrs, spacing, None)
}

/// Encodes one cloud (`samples`, at least one) for input spacing `spacing`, keeping the
/// columns `attrs` declares (radii are never stored), with positions quantised in the box
/// `frame` (`(min, max)`, which must hold every sample: the model's) or, without one, in
/// the cloud's own bounding box. Returns the bytes and the bits per axis used.
pub fn encode_in(
    samples: &[Sample],
    attrs: Attributes,
    spacing: f32,
    frame: Option<([f32; 3], [f32; 3])>,
) -> (Vec<u8>, [u8; 3]) {
    let n = samples.len();
    let (min, max) = match frame {
        Some(f) => f,
        None if n == 0 => ([0.0; 3], [0.0; 3]),
        None => bounds(samples),
    };
    let (bits, step) = quantisation(min, max, spacing);
    let mut keyed: Vec<(u128, u32)> = samples
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let q = [0, 1, 2].map(|a| quantise(s.p[a], min[a], step[a], bits[a]));
            (morton96(q), i as u32)
        })
        .collect();
    keyed.sort_unstable();
    let mut out = Vec::with_capacity(HEADER_BYTES + n * 9);
    let preamble = Preamble {
        count: n as u32,
        normals: attrs.normals,
        colors: attrs.colors,
    };
    FORMAT.write(&preamble, &mut out);
    out.extend_from_slice(&[bits[0], bits[1], bits[2], 0]);
    for v in min.iter().chain(&step) {
        out.extend_from_slice(&v.to_le_bytes());
    }
    let mut prev = 0u128;
    for &(k, _) in &keyed {
        put_varint(&mut out, k - prev);
        prev = k;
    }
    let plane = |out: &mut Vec<u8>, get: &dyn Fn(&Sample) -> u8| {
        let mut prev = 0u8;
        for &(_, i) in &keyed {
            let v = get(&samples[i as usize]);
            out.push(v.wrapping_sub(prev));
            prev = v;
        }
    };
    if attrs.normals {
        plane(&mut out, &|s| s.normal as u8);
        plane(&mut out, &|s| (s.normal >> 8) as u8);
    }
    if attrs.colors {
        for c in 0..3 {
            plane(&mut out, &|s| s.color[c]);
        }
    }
    (out, bits)
}

/// Decodes the bytes of cloud `id` (already decompressed and checksummed) into splats:
/// positions, normals in [`octnormal`] form and colours as the cloud has them, no radii.
pub fn decode(id: u32, bytes: &[u8]) -> Result<SplatBatch, MethodError> {
    let bad = |msg: String| MethodError::corrupt(super::REPO_FILE, format!("cloud {id}: {msg}"));
    let preamble = FORMAT.parse(bytes).map_err(bad)?;
    // The zero byte after the bits per axis counts as flags (as it always has).
    if bytes[11] != 0 {
        return Err(bad(format!("unknown flags {:#x}", preamble.flags())));
    }
    let n = preamble.count as usize;
    let bits = [bytes[8], bytes[9], bytes[10]];
    let min = [0, 1, 2].map(|a| f32::from_bits(le_u32(bytes, 12 + 4 * a)));
    let step = [0, 1, 2].map(|a| f32::from_bits(le_u32(bytes, 24 + 4 * a)));
    let (has_n, has_c) = (preamble.normals, preamble.colors);
    let per_sample = 1 + 2 * has_n as usize + 3 * has_c as usize;
    if n == 0
        || n.checked_mul(per_sample)
            .is_none_or(|m| m > bytes.len() - HEADER_BYTES)
    {
        return Err(bad(format!(
            "{n} samples do not fit in {} bytes",
            bytes.len()
        )));
    }
    for a in 0..3 {
        if bits[a] as u32 > MAX_BITS
            || !min[a].is_finite()
            || !(step[a].is_finite() && step[a] >= 0.0)
        {
            return Err(bad(format!(
                "axis {a}: {} bits, min {}, step {} invalid",
                bits[a], min[a], step[a]
            )));
        }
    }
    let mut at = HEADER_BYTES;
    let mut positions = Vec::with_capacity(n);
    let mut code = 0u128;
    for i in 0..n {
        let mut delta = 0u128;
        let mut shift = 0u32;
        loop {
            let Some(&b) = bytes.get(at) else {
                return Err(bad(format!("truncated in the position of sample {i}")));
            };
            at += 1;
            if shift > 96 {
                return Err(bad(format!("position delta of sample {i} too long")));
            }
            delta |= ((b & 0x7f) as u128) << shift;
            shift += 7;
            if b & 0x80 == 0 {
                break;
            }
        }
        code = code
            .checked_add(delta)
            .filter(|c| *c >> 96 == 0)
            .ok_or_else(|| bad(format!("position of sample {i} overflows")))?;
        let q = demorton96(code);
        let mut p = [0f32; 3];
        for a in 0..3 {
            if q[a] >> bits[a] != 0 {
                return Err(bad(format!(
                    "sample {i}: coordinate {} exceeds {} bits on axis {a}",
                    q[a], bits[a]
                )));
            }
            p[a] = dequantise(q[a], min[a], step[a]);
        }
        positions.push(p);
    }
    let need = n * (2 * has_n as usize + 3 * has_c as usize);
    if bytes.len() - at != need {
        return Err(bad(format!(
            "{} attribute bytes, expected {need}",
            bytes.len() - at
        )));
    }
    let plane = |k: usize| {
        let src = &bytes[at + k * n..at + (k + 1) * n];
        let mut prev = 0u8;
        src.iter().map(move |d| {
            prev = prev.wrapping_add(*d);
            prev
        })
    };
    let normals = has_n.then(|| {
        let table = normal_table();
        plane(0)
            .zip(plane(1))
            .map(|(u, v)| table[(u as u16 | (v as u16) << 8) as usize].0)
            .collect()
    });
    let c0 = 2 * has_n as usize;
    let colors = has_c.then(|| {
        plane(c0)
            .zip(plane(c0 + 1))
            .zip(plane(c0 + 2))
            .map(|((r, g), b)| crate::draw::pack_color([r, g, b]))
            .collect()
    });
    Ok(SplatBatch {
        positions,
        normals,
        colors,
        radii: None,
        lod: None,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn samples(n: usize) -> Vec<Sample> {
        let mut rng = scenes::rng::Pcg32::new(5);
        (0..n)
            .map(|_| Sample {
                p: [rng.range_f32(-3.0, 5.0), rng.range_f32(0.0, 1.0), 2.0],
                normal: oct16_encode(rng.unit_vec3()),
                flags: 0,
                color: [rng.below(256) as u8, 7, rng.below(256) as u8, 0],
            })
            .collect()
    }

    #[test]
    fn morton_round_trip() {
        for q in [
            [0, 0, 0],
            [1, 2, 3],
            [u32::MAX, 0, 12345],
            [0x1f_ffff, 0x20_0000, u32::MAX],
        ] {
            let d = demorton96(morton96(q));
            assert_eq!(d, q.map(|v| v as u64));
        }
    }

    #[test]
    fn oct16_error_is_small() {
        let mut rng = scenes::rng::Pcg32::new(9);
        let mut worst = 0f32;
        for _ in 0..20_000 {
            let n = rng.unit_vec3();
            let d = Vec3::from(normal_table()[oct16_encode(n) as usize].1);
            worst = worst.max(n.cross(d).length().atan2(n.dot(d)));
        }
        assert!(worst < 0.012, "worst {worst} rad");
    }

    #[test]
    fn round_trip_within_half_spacing() -> Result<(), MethodError> {
        let s = samples(3000);
        let r = 0.01f32;
        let attrs = Attributes {
            normals: true,
            colors: true,
            radii: true,
        };
        let (bytes, bits) = encode(&s, attrs, r);
        assert_eq!(bits[2], 0, "constant axis needs no bits");
        let b = decode(3, &bytes)?;
        assert_eq!(b.len(), s.len());
        assert!(b.radii.is_none());
        // Every decoded sample has an input sample with its normal and colour within r/2.
        let (nrm, col) = (b.normals.as_ref().unwrap(), b.colors.as_ref().unwrap());
        let mut worst = 0f32;
        for (i, p) in b.positions.iter().enumerate() {
            let d = s
                .iter()
                .filter(|x| {
                    normal_table()[x.normal as usize].0 == nrm[i]
                        && crate::draw::pack_color([x.color[0], x.color[1], x.color[2]]) == col[i]
                })
                .map(|x| (0..3).map(|a| (x.p[a] - p[a]).abs()).fold(0f32, f32::max))
                .fold(f32::INFINITY, f32::min);
            worst = worst.max(d);
        }
        assert!(worst < r / 2.0, "worst {worst}");
        Ok(())
    }

    #[test]
    fn corruption_is_an_error_naming_the_cloud() {
        let (bytes, _) = encode(
            &samples(200),
            Attributes {
                normals: true,
                colors: false,
                radii: false,
            },
            0.05,
        );
        for cut in [0, 10, HEADER_BYTES, HEADER_BYTES + 5, bytes.len() - 1] {
            let e = decode(42, &bytes[..cut]).unwrap_err().to_string();
            assert!(e.contains("cloud 42"), "{e}");
        }
        let mut long = bytes.clone();
        long.push(0);
        assert!(decode(42, &long).is_err());
        // Any single flipped byte: an error or a batch of the right size, never a panic.
        for i in 0..bytes.len() {
            let mut b = bytes.clone();
            b[i] ^= 0xa5;
            if let Ok(batch) = decode(1, &b) {
                assert!(batch.validate().is_ok());
            }
        }
    }
}
