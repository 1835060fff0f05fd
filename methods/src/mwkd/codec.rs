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

use crate::{MethodError, SplatBatch, draw::pack_color, octnormal};

/// File named in [`MethodError::Corrupt`] (the repository the nodes are stored in).
pub const REPO_FILE: &str = "repo.bin";
/// Bytes of the fixed header.
pub const HEADER_BYTES: usize = 40;
const MAGIC: &[u8; 2] = b"MW";
const VERSION: u8 = 1;
const FLAG_NORMALS: u8 = 1;
const FLAG_COLORS: u8 = 2;
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
        out.extend_from_slice(MAGIC);
        out.push(VERSION);
        out.push(
            if self.normals { FLAG_NORMALS } else { 0 } | if self.colors { FLAG_COLORS } else { 0 },
        );
        out.extend_from_slice(&self.count.to_le_bytes());
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
        if bytes.len() < HEADER_BYTES {
            return Err(bad(format!(
                "{} bytes, shorter than the {HEADER_BYTES}-byte header",
                bytes.len()
            )));
        }
        if &bytes[..2] != MAGIC || bytes[2] != VERSION {
            return Err(bad("bad magic or version".into()));
        }
        let flags = bytes[3];
        if flags & !(FLAG_NORMALS | FLAG_COLORS) != 0 {
            return Err(bad(format!("unknown flags {flags:#x}")));
        }
        let word = |at: usize| {
            u32::from_le_bytes([bytes[at], bytes[at + 1], bytes[at + 2], bytes[at + 3]])
        };
        let float = |at: usize| f32::from_bits(word(at));
        let h = Self {
            count: word(4),
            normals: flags & FLAG_NORMALS != 0,
            colors: flags & FLAG_COLORS != 0,
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
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use scenes::rng::Pcg32;

    /// Angle between two vectors (atan2 of |a×b| and a·b: exact for small angles).
    fn angle(a: Vec3, b: Vec3) -> f32 {
        a.cross(b).length().atan2(a.dot(b))
    }

    struct Node {
        points: Vec<[f32; 3]>,
        radii: Vec<f32>,
        normals: Vec<[f32; 3]>,
        colors: Vec<[u8; 3]>,
    }

    fn random_node(n: usize, seed: u64) -> Node {
        let mut rng = Pcg32::new(seed);
        Node {
            points: (0..n)
                .map(|_| {
                    [
                        rng.range_f32(-3.0, 5.0),
                        rng.range_f32(0.0, 1e-3),
                        rng.range_f32(100.0, 101.5),
                    ]
                })
                .collect(),
            radii: (0..n).map(|_| rng.range_f32(0.001, 0.05)).collect(),
            normals: (0..n)
                .map(|_| (rng.unit_vec3() * rng.range_f32(0.1, 10.0)).to_array())
                .collect(),
            colors: (0..n)
                .map(|_| [0, 1, 2].map(|_| rng.below(256) as u8))
                .collect(),
        }
    }

    fn ulp(x: f32) -> f32 {
        x.abs().next_up() - x.abs()
    }

    /// Encodes `node` with every combination of optional columns, decodes, and checks every
    /// bound of the module documentation and the exact size.
    fn check_round_trip(node: &Node) {
        let n = node.points.len();
        for (with_n, with_c) in [(false, false), (true, false), (false, true), (true, true)] {
            let (bytes, h) = encode(
                &node.points,
                &node.radii,
                with_n.then_some(&node.normals[..]),
                with_c.then_some(&node.colors[..]),
            )
            .unwrap();
            let per_point = 6 + 1 + if with_n { 2 } else { 0 } + if with_c { 3 } else { 0 };
            assert_eq!(bytes.len(), HEADER_BYTES + n * per_point);
            assert_eq!(NodeHeader::parse(7, &bytes).unwrap(), h);
            let b = decode(7, &bytes).unwrap();
            b.validate().unwrap();
            assert_eq!(b.len(), n);
            for a in 0..3 {
                let e = h.max[a] as f64 - h.min[a] as f64;
                let tol = (e / 65_535.0 / 2.0) as f32 + ulp(h.min[a]).max(ulp(h.max[a]));
                for (p, d) in node.points.iter().zip(&b.positions) {
                    assert!(
                        (p[a] - d[a]).abs() <= tol,
                        "axis {a}: {p:?} → {d:?}, tol {tol}"
                    );
                    assert!(h.min[a] <= d[a] && d[a] <= h.max[a]);
                    if e == 0.0 {
                        assert_eq!(d[a], p[a]);
                    }
                }
            }
            let radii = b.radii.as_ref().unwrap();
            let step = (h.radius_max - h.radius_min) / 255.0;
            for (r, d) in node.radii.iter().zip(radii) {
                assert!(d >= r, "radius {r} decoded smaller: {d}");
                assert!(
                    d - r <= step + ulp(h.radius_max),
                    "radius {r} → {d}, step {step}"
                );
            }
            if h.radius_min == h.radius_max {
                assert!(radii.iter().all(|&d| d == h.radius_min));
            }
            assert_eq!(b.normals.is_some(), with_n);
            if let Some(nrm) = &b.normals {
                for (v, &p) in node.normals.iter().zip(nrm) {
                    let a = angle(Vec3::from(*v), octnormal::decode(p));
                    assert!(a <= MAX_NORMAL_ERROR_RAD, "{v:?}: {a} rad");
                }
            }
            assert_eq!(b.colors.is_some(), with_c);
            if let Some(col) = &b.colors {
                for (c, &p) in node.colors.iter().zip(col) {
                    assert_eq!(pack_color(*c), p);
                }
            }
        }
    }

    #[test]
    fn round_trip_random_within_bounds() {
        check_round_trip(&random_node(5000, 11));
        check_round_trip(&random_node(37, 12));
    }

    #[test]
    fn round_trip_degenerate_nodes() {
        // One point.
        check_round_trip(&random_node(1, 21));
        // All points identical (zero extent on every axis, equal radii).
        let mut node = random_node(64, 22);
        let (p, r, nv, c) = (
            node.points[0],
            node.radii[0],
            node.normals[0],
            node.colors[0],
        );
        node.points.fill(p);
        node.radii.fill(r);
        node.normals.fill(nv);
        node.colors.fill(c);
        check_round_trip(&node);
        // Zero-extent axis, equal radii, zero radii, axis-aligned and tie normals.
        let mut node = random_node(300, 23);
        node.points.iter_mut().for_each(|p| p[1] = -7.25);
        node.radii.fill(0.03);
        check_round_trip(&node);
        node.radii.fill(0.0);
        let specials = [
            [1.0, 0.0, 0.0],
            [-1.0, 0.0, 0.0],
            [0.0, 1.0, 0.0],
            [0.0, -1.0, 0.0],
            [0.0, 0.0, 1.0],
            [0.0, 0.0, -1.0],
            [1.0, 1.0, 1.0],
            [-1.0, 1.0, -1.0],
            [1.0, -1.0, 0.0],
            [1e-30, 0.0, -1e-30],
        ];
        for (v, s) in node.normals.iter_mut().zip(specials) {
            *v = s;
        }
        check_round_trip(&node);
        // Large coordinates and a huge radius range.
        let mut node = random_node(200, 24);
        node.points.iter_mut().for_each(|p| p[0] = p[0] * 1e6 + 3e7);
        node.radii[0] = 1e6;
        node.radii[1] = 0.0;
        check_round_trip(&node);
    }

    #[test]
    fn radius_is_never_smaller_and_at_most_one_step_larger() {
        let mut rng = Pcg32::new(31);
        for (lo, hi) in [
            (0.01f32, 0.05f32),
            (1.0, 1.0f32.next_up().next_up().next_up()),
            (0.0, 1e-30),
            (3.0, 3.000_01),
            (0.0, 1e30),
            (12.5, 12.5),
        ] {
            let step = (hi - lo) / 255.0;
            let mut rs: Vec<f32> = (0..20_000).map(|_| rng.range_f32(lo, hi)).collect();
            // Exactly on and next to every code's value.
            for q in 0..=255u8 {
                let v = dequantise_radius(q, lo, hi);
                rs.extend([v, v.next_up(), v.next_down()]);
            }
            for r in rs.into_iter().map(|r| r.clamp(lo, hi)) {
                let d = dequantise_radius(quantise_radius(r, lo, hi), lo, hi);
                assert!(d >= r, "[{lo}, {hi}]: {r} → {d}");
                assert!(d - r <= step + ulp(hi), "[{lo}, {hi}]: {r} → {d}");
            }
        }
    }

    #[test]
    fn octahedral_table_is_the_decoded_code_of_every_code() {
        let t = octahedral_table();
        assert_eq!(t.len(), NORMAL_CODES as usize);
        for c in 0..NORMAL_CODES {
            let v = decode_normal(c as u16).unwrap();
            assert_eq!(t[c as usize], octnormal::encode(v), "code {c}");
        }
        assert!(decode_normal(NORMAL_CODES as u16).is_none());
    }

    #[test]
    fn normal_cube_map_bound() {
        // The farthest point of a cell from its centre is a corner (the angle to the centre
        // is quasi-convex on the face plane): check every corner of every cell of every face.
        let g = NORMAL_GRID as f32;
        let corner = |i: u32| i as f32 / g * 2.0 - 1.0;
        let mut worst = 0f32;
        for code in 0..NORMAL_CODES as u16 {
            let c = decode_normal(code).unwrap();
            let face = code as u32 / (NORMAL_GRID * NORMAL_GRID);
            let cell = code as u32 % (NORMAL_GRID * NORMAL_GRID);
            let (row, col) = (cell / NORMAL_GRID, cell % NORMAL_GRID);
            let a = (face / 2) as usize;
            for (dr, dc) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                let mut v = [0f32; 3];
                v[a] = if face.is_multiple_of(2) { 1.0 } else { -1.0 };
                v[(a + 1) % 3] = corner(row + dr);
                v[(a + 2) % 3] = corner(col + dc);
                worst = worst.max(angle(Vec3::from(v), c));
            }
            // The centre encodes to its own code.
            assert_eq!(encode_normal(c.to_array()), Some(code));
        }
        let cube_bound = (2f32.sqrt() / g).atan();
        assert!(worst <= cube_bound + 1e-6, "worst {worst} vs {cube_bound}");
        assert!(
            worst > cube_bound - 1e-4,
            "the stated bound is tight: {worst}"
        );
        assert!(cube_bound + 5e-5 <= MAX_NORMAL_ERROR_RAD);
        // Random directions through the whole path to the renderer's packing.
        let mut rng = Pcg32::new(41);
        let mut worst = 0f32;
        for _ in 0..200_000 {
            let v = rng.unit_vec3();
            let code = encode_normal(v.to_array()).unwrap();
            assert!((code as u32) < NORMAL_CODES);
            let d = octnormal::decode(octnormal::encode(decode_normal(code).unwrap()));
            worst = worst.max(angle(v, d));
        }
        assert!(worst <= MAX_NORMAL_ERROR_RAD, "worst {worst} rad");
        assert!(decode_normal(NORMAL_CODES as u16).is_none());
        assert!(decode_normal(u16::MAX).is_none());
        assert_eq!(encode_normal([0.0; 3]), None);
        assert_eq!(encode_normal([f32::NAN, 1.0, 0.0]), None);
    }

    #[test]
    fn encode_rejects_bad_input() {
        let node = random_node(10, 51);
        let (p, r) = (&node.points[..], &node.radii[..]);
        let cases: Vec<(Result<_, _>, &str)> = vec![
            (encode(&[], &[], None, None), "0 points"),
            (encode(p, &r[..9], None, None), "9 radii"),
            (encode(p, r, Some(&node.normals[..3]), None), "3 normals"),
            (encode(p, r, None, Some(&node.colors[..2])), "2 colors"),
            (
                encode(&[[f32::NAN, 0.0, 0.0]], &[1.0], None, None),
                "point 0",
            ),
            (encode(&[[0.0; 3]], &[-1.0], None, None), "radius 0"),
            (
                encode(&[[0.0; 3]], &[f32::INFINITY], None, None),
                "radius 0",
            ),
            (
                encode(&[[0.0; 3]], &[1.0], Some(&[[0.0; 3]]), None),
                "normal 0",
            ),
        ];
        for (res, needle) in cases {
            let e = res.unwrap_err().to_string();
            assert!(e.contains(needle), "{needle}: {e}");
        }
    }

    fn set_f32(bytes: &mut [u8], at: usize, v: f32) {
        bytes[at..at + 4].copy_from_slice(&v.to_le_bytes());
    }

    #[test]
    fn corruption_is_an_error_naming_the_node() {
        let node = random_node(120, 61);
        let (bytes, h) = encode(
            &node.points,
            &node.radii,
            Some(&node.normals),
            Some(&node.colors),
        )
        .unwrap();
        let is_corrupt = |b: &[u8], needle: &str| {
            let e = decode(9, b).unwrap_err();
            assert!(matches!(e, MethodError::Corrupt { .. }), "{e}");
            let s = e.to_string();
            assert!(s.contains("node 9") && s.contains(needle), "{needle}: {s}");
        };
        for cut in [
            0,
            3,
            HEADER_BYTES - 1,
            HEADER_BYTES,
            HEADER_BYTES + 7,
            bytes.len() - 1,
        ] {
            is_corrupt(&bytes[..cut], "bytes");
        }
        let mut long = bytes.clone();
        long.push(0);
        is_corrupt(&long, "need");
        let edit = |f: &dyn Fn(&mut Vec<u8>)| {
            let mut b = bytes.clone();
            f(&mut b);
            b
        };
        is_corrupt(&edit(&|b| b[0] = b'X'), "magic");
        is_corrupt(&edit(&|b| b[2] = 2), "version");
        is_corrupt(&edit(&|b| b[3] |= 4), "flags");
        is_corrupt(&edit(&|b| b[3] = FLAG_NORMALS), "need");
        is_corrupt(
            &edit(&|b| b[4..8].copy_from_slice(&0u32.to_le_bytes())),
            "count 0",
        );
        is_corrupt(
            &edit(&|b| b[4..8].copy_from_slice(&121u32.to_le_bytes())),
            "need",
        );
        is_corrupt(
            &edit(&|b| b[4..8].copy_from_slice(&u32::MAX.to_le_bytes())),
            "need",
        );
        is_corrupt(&edit(&|b| set_f32(b, 12, f32::NAN)), "axis 1");
        is_corrupt(&edit(&|b| set_f32(b, 20, f32::INFINITY)), "axis 0");
        is_corrupt(&edit(&|b| set_f32(b, 28, h.min[2] - 1.0)), "axis 2");
        is_corrupt(&edit(&|b| set_f32(b, 32, h.radius_max * 2.0)), "radius");
        is_corrupt(&edit(&|b| set_f32(b, 32, -0.5)), "radius");
        is_corrupt(&edit(&|b| set_f32(b, 36, f32::NAN)), "radius");
        let n = node.points.len();
        let nrm = HEADER_BYTES + 7 * n;
        // Point 5's normal code: high byte plane then low byte plane.
        is_corrupt(
            &edit(&|b| (b[nrm + 5], b[nrm + n + 5]) = (0xfd, 0x80)),
            "64896",
        );
        is_corrupt(
            &edit(&|b| (b[nrm + 5], b[nrm + n + 5]) = (0xff, 0xff)),
            "point 5",
        );
        assert!(decode(9, &edit(&|b| (b[nrm + 5], b[nrm + n + 5]) = (0xfd, 0x7f))).is_ok());
        // Every single flipped byte (three patterns): a `Corrupt` error naming the node, or a
        // batch inside the box and radius range its (possibly altered) header declares.
        for i in 0..bytes.len() {
            for x in [0x01u8, 0x80, 0xa5] {
                let mut b = bytes.clone();
                b[i] ^= x;
                match decode(9, &b) {
                    Err(e) => {
                        assert!(matches!(e, MethodError::Corrupt { .. }), "{e}");
                        assert!(e.to_string().contains("node 9"), "{e}");
                    }
                    Ok(batch) => {
                        let h = NodeHeader::parse(9, &b).unwrap();
                        batch.validate().unwrap();
                        assert_eq!(batch.len(), h.count as usize);
                        for p in &batch.positions {
                            for (a, &x) in p.iter().enumerate() {
                                assert!(h.min[a] <= x && x <= h.max[a], "byte {i}");
                            }
                        }
                        for r in batch.radii.as_ref().unwrap() {
                            assert!(h.radius_min <= *r && *r <= h.radius_max, "byte {i}");
                        }
                        for &v in batch.normals.iter().flatten() {
                            assert!((octnormal::decode(v).length() - 1.0).abs() < 1e-5);
                        }
                    }
                }
            }
        }
    }
}
