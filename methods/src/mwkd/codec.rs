//! The MWKD per-node data codec: one node's splats as the raw bytes of one repository chunk
//! (LZO compression and the checksum are added by [`crate::store::RepoWriter`]; a flipped
//! stored byte is a checksum error from [`crate::store::Repository::read`] naming the node).
//!
//! Paper, section III-C: "Vertex positions and splat radii of all the points are
//! contiguously aligned, followed by normals and, if available, color data." Positions are
//! 16 bits per axis in the node's box, radii 8 bits between the node's smallest and largest
//! radius, normals 16 bits on a cube map of 6 faces × 104 × 104 cells, colours 24 bits.
//! Points keep their input order (no sorting: indices into a node stay valid).
//!
//! Layout (little-endian), `n` = count:
//!
//! | bytes  | field                                                                      |
//! |--------|----------------------------------------------------------------------------|
//! | 2      | magic `MW`                                                                 |
//! | 1      | version (1)                                                                |
//! | 1      | flags: bit 0 normals, bit 1 colours (other bits must be 0)                 |
//! | 4      | `n` (u32, ≥ 1)                                                             |
//! | 12     | box minimum (f32 × 3, finite)                                              |
//! | 12     | box maximum (f32 × 3, finite, ≥ minimum per axis)                          |
//! | 4 + 4  | radius minimum, radius maximum (f32, finite, 0 ≤ min ≤ max)                |
//! | 6 n    | positions: per axis x, y, z the plane of high bytes, then the plane of low bytes of the 16-bit codes |
//! | n      | radii: 8-bit codes                                                         |
//! | 2 n    | normals (flag bit 0): plane of high bytes, then plane of low bytes          |
//! | 3 n    | colours (flag bit 1): the `r`, `g`, `b` planes                             |
//!
//! The first four fields (8 bytes) are the preamble LPC's clouds share
//! ([`crate::store::chunk_header`]).
//!
//! Splitting every 16-bit value into a high-byte and a low-byte plane puts the slowly
//! varying high bytes of nearby points next to each other, where LZO finds repetition.
//! Size: exactly [`HEADER_BYTES`] + `n · (7 + 2·normals + 3·colours)` bytes.
//!
//! Bounds (see the constants and the tests):
//!
//! - **positions**: code `q = round((x − min)/(max − min) · 65535)`, decoded as
//!   `min + q · (max − min)/65535` (in `f64`, rounded to `f32`, clamped into the box): error
//!   ≤ half a step, `(max − min)/65535/2` per axis, plus the final `f32` rounding (½ ulp);
//!   0 on an axis of zero extent;
//! - **radii**: code `q = ⌈(r − min)/(max − min) · 255⌉` (raised further if `f32` rounding
//!   would decode below `r`; code 255 decodes to `max` exactly): the decoded radius is
//!   **never smaller** than the input, so decoded splats still cover what the input covered,
//!   and at most one step `(max − min)/255` larger (plus `f32` rounding); exact when all radii
//!   are equal;
//! - **normals**: the face of the largest absolute component, the cell of the gnomonic
//!   projection on it (104 × 104 cells over `[−1, 1]²`), code `face·104² + row·104 + col`
//!   (< 64,896 < 2¹⁶), decoded to the normalised cell centre (then to the renderer's
//!   [`octnormal`] form): angle ≤ [`MAX_NORMAL_ERROR_RAD`] (0.78° at the face centre, where
//!   cells subtend the largest angle; the octahedral packing adds ≤ 5·10⁻⁵ rad);
//! - **colours**: exact.
//!
//! [`decode`] checks every header field, the exact length and every normal code and answers
//! [`MethodError::Corrupt`] naming "node {id}", never panicking or reading out of bounds;
//! whatever it accepts lies inside the header's box and radius range.

use glam::Vec3;

use crate::store::chunk_header::{Format, Preamble, le_u32};
use crate::{MethodError, SplatBatch, draw::pack_color, octnormal};

/// File named in [`MethodError::Corrupt`] (the repository the nodes are stored in).
pub const REPO_FILE: &str = "repo.bin";
/// Bytes of the fixed header.
pub const HEADER_BYTES: usize = 40;
/// Magic `MW`, version 1 ([`crate::store::chunk_header`]: magic, version, flags, count).
const FORMAT: Format = Format {
    magic: *b"MW",
    version: 1,
    header_bytes: HEADER_BYTES,
};
/// Largest 16-bit position code.
pub const POSITION_LEVELS: u32 = 65_535;
/// Largest 8-bit radius code.
pub const RADIUS_LEVELS: u32 = 255;
/// Cells per side of a cube face in the normal map.
pub const NORMAL_GRID: u32 = 104;
/// Number of valid normal codes, `6 · 104 · 104` (codes are `0..NORMAL_CODES`).
pub const NORMAL_CODES: u32 = 6 * NORMAL_GRID * NORMAL_GRID;
/// Largest angle (radians) between an input normal and the decoded one (cube-map cell
/// centre, then the renderer's octahedral packing). The cube-map part is at most
/// `atan(√2/104)` ≈ 0.013598 rad at the face centre; 0.01365 leaves room for the ≤ 5·10⁻⁵ rad
/// of [`octnormal`].
pub const MAX_NORMAL_ERROR_RAD: f32 = 0.013_65;

/// The fixed header of an encoded node.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeHeader {
    /// Number of points (≥ 1).
    pub count: u32,
    /// Normals are stored.
    pub normals: bool,
    /// Colours are stored.
    pub colors: bool,
    /// Box minimum (of the input positions).
    pub min: [f32; 3],
    /// Box maximum.
    pub max: [f32; 3],
    /// Smallest input radius.
    pub radius_min: f32,
    /// Largest input radius.
    pub radius_max: f32,
}

impl NodeHeader {
    /// Bytes per point: 6 (positions) + 1 (radius) + 2 (normal) + 3 (colour).
    pub fn bytes_per_point(&self) -> usize {
        7 + 2 * self.normals as usize + 3 * self.colors as usize
    }
    /// Exact length of the encoded node, header included (`None` on overflow).
    pub fn encoded_len(&self) -> Option<usize> {
        (self.count as usize)
            .checked_mul(self.bytes_per_point())?
            .checked_add(HEADER_BYTES)
    }
    fn write(&self, out: &mut Vec<u8>) {
        let preamble = Preamble {
            count: self.count,
            normals: self.normals,
            colors: self.colors,
        };
        FORMAT.write(&preamble, out);
        for v in self
            .min
            .iter()
            .chain(&self.max)
            .chain([&self.radius_min, &self.radius_max])
        {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    /// Reads and validates the header of node `id` against the length of `bytes` (errors
    /// name the node).
    pub fn parse(id: u32, bytes: &[u8]) -> Result<Self, MethodError> {
        let bad = |msg: String| corrupt(id, msg);
        let preamble = FORMAT.parse(bytes).map_err(bad)?;
        let flags = preamble.flags();
        let float = |at: usize| f32::from_bits(le_u32(bytes, at));
        let h = Self {
            count: preamble.count,
            normals: preamble.normals,
            colors: preamble.colors,
            min: [0, 1, 2].map(|a| float(8 + 4 * a)),
            max: [0, 1, 2].map(|a| float(20 + 4 * a)),
            radius_min: float(32),
            radius_max: float(36),
        };
        if h.count == 0 {
            return Err(bad("count 0".into()));
        }
        match h.encoded_len() {
            Some(len) if len == bytes.len() => {}
            len => {
                return Err(bad(format!(
                    "{} points with flags {flags:#x} need {} bytes, got {}",
                    h.count,
                    len.map_or_else(|| "more than usize".into(), |l| l.to_string()),
                    bytes.len()
                )));
            }
        }
        for a in 0..3 {
            if !(h.min[a].is_finite() && h.max[a].is_finite() && h.min[a] <= h.max[a]) {
                return Err(bad(format!(
                    "axis {a}: box {}..{} is not finite or inverted",
                    h.min[a], h.max[a]
                )));
            }
        }
        if !(h.radius_min.is_finite()
            && h.radius_max.is_finite()
            && 0.0 <= h.radius_min
            && h.radius_min <= h.radius_max)
        {
            return Err(bad(format!(
                "radius range {}..{} is not finite, negative or inverted",
                h.radius_min, h.radius_max
            )));
        }
        Ok(h)
    }
}

fn corrupt(id: u32, msg: String) -> MethodError {
    MethodError::corrupt(REPO_FILE, format!("node {id}: {msg}"))
}

/// 16-bit code of coordinate `x` in `min..=max`.
#[inline]
fn quantise_position(x: f32, min: f32, max: f32) -> u16 {
    let e = max as f64 - min as f64;
    if e <= 0.0 {
        return 0;
    }
    ((x as f64 - min as f64) / e * POSITION_LEVELS as f64)
        .round()
        .clamp(0.0, POSITION_LEVELS as f64) as u16
}

/// Coordinate of code `q` (always inside `min..=max`).
#[inline]
pub fn dequantise_position(q: u16, min: f32, max: f32) -> f32 {
    let e = max as f64 - min as f64;
    ((min as f64 + q as f64 * e / POSITION_LEVELS as f64) as f32).clamp(min, max)
}

/// Radius of code `q` (always inside `min..=max`; 255 gives `max` exactly).
#[inline]
pub fn dequantise_radius(q: u8, min: f32, max: f32) -> f32 {
    if q as u32 == RADIUS_LEVELS {
        return max;
    }
    let e = max as f64 - min as f64;
    ((min as f64 + q as f64 * e / RADIUS_LEVELS as f64) as f32).clamp(min, max)
}

/// 8-bit code of radius `r` in `min..=max`: the smallest code whose decoded radius is ≥ `r`.
#[inline]
fn quantise_radius(r: f32, min: f32, max: f32) -> u8 {
    let e = max as f64 - min as f64;
    if e <= 0.0 {
        return 0;
    }
    let mut q = ((r as f64 - min as f64) / e * RADIUS_LEVELS as f64)
        .ceil()
        .clamp(0.0, RADIUS_LEVELS as f64) as u8;
    // `f32` rounding of the decoded value may land just below `r`: step up (code 255 is
    // `max` ≥ `r`, so this ends).
    while (q as u32) < RADIUS_LEVELS && dequantise_radius(q, min, max) < r {
        q += 1;
    }
    // …and the ceiling may overshoot by one code when rounding favours the code below.
    while q > 0 && dequantise_radius(q - 1, min, max) >= r {
        q -= 1;
    }
    q
}

/// Cube-map code of a non-zero finite vector (`None` otherwise): face `2a + [n_a < 0]` of
/// the largest absolute component `a`, cell of the projection of the other two components
/// (in the order `a+1`, `a+2` mod 3) divided by `|n_a|`.
pub fn encode_normal(n: [f32; 3]) -> Option<u16> {
    let v = Vec3::from(n);
    if !v.is_finite() || v == Vec3::ZERO {
        return None;
    }
    let abs = v.abs();
    let a = if abs.x >= abs.y && abs.x >= abs.z {
        0
    } else if abs.y >= abs.z {
        1
    } else {
        2
    };
    let face = 2 * a + (n[a] < 0.0) as usize;
    let g = NORMAL_GRID as f32;
    let cell = |c: f32| (((c / abs[a]) + 1.0) * 0.5 * g).floor().clamp(0.0, g - 1.0) as u32;
    let (row, col) = (cell(n[(a + 1) % 3]), cell(n[(a + 2) % 3]));
    Some((face as u32 * NORMAL_GRID * NORMAL_GRID + row * NORMAL_GRID + col) as u16)
}

/// Unit vector at the centre of the cell of normal code `code` (`None` for codes ≥
/// [`NORMAL_CODES`]).
pub fn decode_normal(code: u16) -> Option<Vec3> {
    let code = code as u32;
    if code >= NORMAL_CODES {
        return None;
    }
    let face = code / (NORMAL_GRID * NORMAL_GRID);
    let cell = code % (NORMAL_GRID * NORMAL_GRID);
    let centre = |i: u32| (i as f32 + 0.5) / NORMAL_GRID as f32 * 2.0 - 1.0;
    let a = (face / 2) as usize;
    let mut v = [0f32; 3];
    v[a] = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
    v[(a + 1) % 3] = centre(cell / NORMAL_GRID);
    v[(a + 2) % 3] = centre(cell % NORMAL_GRID);
    Some(Vec3::from(v).normalize())
}

/// The renderer's [`octnormal`] form of every cube-map code, `decode_normal` then
/// `octnormal::encode` (built once, 254 KiB): decoding a node's normals is then a gather
/// (the conversion was ≈ 88 % of a node's decode time).
fn octahedral_table() -> &'static [u32] {
    static TABLE: std::sync::OnceLock<Vec<u32>> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        (0..NORMAL_CODES)
            .map(|c| decode_normal(c as u16).map_or(0, octnormal::encode))
            .collect()
    })
}

fn input_error(msg: String) -> MethodError {
    MethodError::Limit(format!("mwkd node codec: {msg}"))
}

/// Encodes one node: `points` (at least one, finite), one finite non-negative radius per
/// point, and optionally one non-zero finite normal and one sRGB colour per point. Returns
/// the bytes and their header; an error names the offending input (empty node, column
/// lengths, a non-finite value, more than `u32::MAX` points).
pub fn encode(
    points: &[[f32; 3]],
    radii: &[f32],
    normals: Option<&[[f32; 3]]>,
    colors: Option<&[[u8; 3]]>,
) -> Result<(Vec<u8>, NodeHeader), MethodError> {
    let n = points.len();
    let count = u32::try_from(n)
        .ok()
        .filter(|&c| c > 0)
        .ok_or_else(|| input_error(format!("{n} points (need 1..=u32::MAX)")))?;
    for (name, len) in [
        ("radii", Some(radii.len())),
        ("normals", normals.map(<[_]>::len)),
        ("colors", colors.map(<[_]>::len)),
    ] {
        if let Some(len) = len.filter(|&l| l != n) {
            return Err(input_error(format!("{len} {name} for {n} points")));
        }
    }
    let mut min = [f32::INFINITY; 3];
    let mut max = [f32::NEG_INFINITY; 3];
    for (i, p) in points.iter().enumerate() {
        for a in 0..3 {
            if !p[a].is_finite() {
                return Err(input_error(format!("point {i} is not finite: {p:?}")));
            }
            min[a] = min[a].min(p[a]);
            max[a] = max[a].max(p[a]);
        }
    }
    let (mut rmin, mut rmax) = (f32::INFINITY, f32::NEG_INFINITY);
    for (i, &r) in radii.iter().enumerate() {
        if !(r.is_finite() && r >= 0.0) {
            return Err(input_error(format!("radius {i} is {r}")));
        }
        rmin = rmin.min(r);
        rmax = rmax.max(r);
    }
    let normal_codes = normals
        .map(|ns| {
            ns.iter()
                .enumerate()
                .map(|(i, v)| {
                    encode_normal(*v).ok_or_else(|| {
                        input_error(format!("normal {i} is zero or not finite: {v:?}"))
                    })
                })
                .collect::<Result<Vec<u16>, _>>()
        })
        .transpose()?;
    let header = NodeHeader {
        count,
        normals: normals.is_some(),
        colors: colors.is_some(),
        min,
        max,
        radius_min: rmin,
        radius_max: rmax,
    };
    let mut out = Vec::with_capacity(HEADER_BYTES + n * header.bytes_per_point());
    header.write(&mut out);
    let plane16 = |out: &mut Vec<u8>, codes: &mut dyn Iterator<Item = u16>| {
        let codes: Vec<u16> = codes.collect();
        out.extend(codes.iter().map(|c| (c >> 8) as u8));
        out.extend(codes.iter().map(|&c| c as u8));
    };
    for a in 0..3 {
        plane16(
            &mut out,
            &mut points
                .iter()
                .map(|p| quantise_position(p[a], min[a], max[a])),
        );
    }
    out.extend(radii.iter().map(|&r| quantise_radius(r, rmin, rmax)));
    if let Some(codes) = &normal_codes {
        plane16(&mut out, &mut codes.iter().copied());
    }
    if let Some(cs) = colors {
        for c in 0..3 {
            out.extend(cs.iter().map(|rgb| rgb[c]));
        }
    }
    debug_assert_eq!(Some(out.len()), header.encoded_len());
    Ok((out, header))
}

/// Decodes the bytes of node `id` (already decompressed and checksummed): positions and
/// radii always, normals (in [`octnormal`] form) and colours iff the header flags them.
/// Every inconsistency is [`MethodError::Corrupt`] naming "node {id}".
pub fn decode(id: u32, bytes: &[u8]) -> Result<SplatBatch, MethodError> {
    let h = NodeHeader::parse(id, bytes)?;
    let n = h.count as usize;
    // `parse` checked the exact length, so every plane below is in bounds.
    let body = &bytes[HEADER_BYTES..];
    let plane16 = |k: usize| {
        let (hi, lo) = (
            &body[2 * k * n..(2 * k + 1) * n],
            &body[(2 * k + 1) * n..(2 * k + 2) * n],
        );
        hi.iter().zip(lo).map(|(&h, &l)| u16::from_be_bytes([h, l]))
    };
    let mut positions = vec![[0f32; 3]; n];
    for a in 0..3 {
        for (p, q) in positions.iter_mut().zip(plane16(a)) {
            p[a] = dequantise_position(q, h.min[a], h.max[a]);
        }
    }
    let radii = body[6 * n..7 * n]
        .iter()
        .map(|&q| dequantise_radius(q, h.radius_min, h.radius_max))
        .collect();
    let normals = if h.normals {
        let codes = {
            let (hi, lo) = (&body[7 * n..8 * n], &body[8 * n..9 * n]);
            hi.iter().zip(lo).map(|(&h, &l)| u16::from_be_bytes([h, l]))
        };
        let table = octahedral_table();
        let mut out = Vec::with_capacity(n);
        for (i, code) in codes.enumerate() {
            let v = table.get(usize::from(code)).ok_or_else(|| {
                corrupt(
                    id,
                    format!("normal code {code} of point {i} is not below {NORMAL_CODES}"),
                )
            })?;
            out.push(*v);
        }
        Some(out)
    } else {
        None
    };
    let colors = h.colors.then(|| {
        let c0 = (7 + 2 * h.normals as usize) * n;
        let plane = |k: usize| &body[c0 + k * n..c0 + (k + 1) * n];
        plane(0)
            .iter()
            .zip(plane(1))
            .zip(plane(2))
            .map(|((&r, &g), &b)| pack_color([r, g, b]))
            .collect()
    });
    Ok(SplatBatch {
        positions,
        normals,
        colors,
        radii: Some(radii),
        lod: None,
    })
}

#[cfg(test)]
#[path = "codec_tests.rs"]
mod tests;
