//! The Potree 2.0 file format, as PotreeConverter 2.0 writes it and the Potree viewer reads
//! it (`potree/src/modules/loader/2.0/`): three files in one directory.
//!
//! - `metadata.json` ([`Metadata`]): version `"2.0"`, point count, the position quantisation
//!   (`offset`, `scale`: world = `int32 · scale + offset`), the root `spacing`, the cubic
//!   `boundingBox`, the `encoding` of `octree.bin` and the point `attributes` in the order
//!   their bytes follow each other in a point record ([`Layout`]).
//! - `hierarchy.bin`: the octree as 22-byte records ([`Record`]: type, child mask, point
//!   count, byte offset, byte size), in *chunks* of `stepSize` levels. A chunk lists its root
//!   node and the descendants of the next `stepSize` levels breadth first (children in
//!   octant order); nodes on its last level are *proxies* whose offset and size point at
//!   their own chunk in `hierarchy.bin`, read when the node is first needed. The first chunk
//!   (offset 0, `hierarchy.firstChunkSize` bytes) starts at the root. A child's box is its
//!   parent's octant `i`: bit 2 of `i` selects the upper half in x, bit 1 in y, bit 0 in z.
//! - `octree.bin`: each node's points, at the offset and size its record gives. With the
//!   `DEFAULT` encoding a node is `points × bytes_per_point` bytes of whole point records,
//!   attributes interleaved. (`BROTLI`, the converter's compressed option, stores attributes
//!   column-wise and Morton-coded positions; it is refused with an error naming it.)
//!
//! Node names follow the converter: `r` for the root, then one octant digit per level
//! (`r0`, `r07`, …); errors name nodes this way.

use std::path::Path;

use glam::DVec3;

use crate::MethodError;

/// The metadata file.
pub const METADATA_FILE: &str = "metadata.json";
/// The hierarchy file.
pub const HIERARCHY_FILE: &str = "hierarchy.bin";
/// The point data file.
pub const OCTREE_FILE: &str = "octree.bin";
/// The only format version read and written.
pub const VERSION: &str = "2.0";
/// The only encoding read and written.
pub const ENCODING: &str = "DEFAULT";
/// Bytes of one hierarchy record.
pub const RECORD_BYTES: usize = 22;
/// Deepest level a node may have: names are kept as 3 bits per level in a `u64` (PotreeConverter
/// itself stops far earlier: its positions are 32-bit integers).
pub const MAX_LEVEL: u32 = 20;

/// `metadata.json`. Keys beyond these (a converter's additions) are ignored; missing or
/// mistyped ones are errors naming the key.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct Metadata {
    /// Format version (`"2.0"`).
    pub version: String,
    /// Data set name.
    #[serde(default)]
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Points in all nodes together.
    pub points: u64,
    /// Coordinate reference system (free text, often empty).
    #[serde(default)]
    pub projection: String,
    /// How `hierarchy.bin` is chunked.
    pub hierarchy: HierarchyInfo,
    /// Position offset (world = int · scale + offset).
    pub offset: [f64; 3],
    /// Position scale.
    pub scale: [f64; 3],
    /// Minimum point distance of the root's subsample; level `l` has `spacing / 2^l`.
    pub spacing: f64,
    /// The root node's box (a cube when PotreeConverter wrote it), world coordinates.
    pub bounding_box: BoundingBox,
    /// `DEFAULT` (raw records) or `BROTLI`.
    pub encoding: String,
    /// The point record, in byte order.
    pub attributes: Vec<AttributeDesc>,
}

/// `metadata.json` → `hierarchy`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct HierarchyInfo {
    /// Bytes of the first chunk (the root's), at offset 0 of `hierarchy.bin`.
    pub first_chunk_size: u64,
    /// Levels per chunk.
    pub step_size: u32,
    /// Deepest level of the octree.
    pub depth: u32,
}

/// `metadata.json` → `boundingBox`.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct BoundingBox {
    /// Lower corner.
    pub min: [f64; 3],
    /// Upper corner.
    pub max: [f64; 3],
}

/// One entry of `metadata.json` → `attributes`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "camelCase")]
pub struct AttributeDesc {
    /// `position`, `rgb`, `intensity`, `NormalX`, …
    pub name: String,
    /// Free text.
    #[serde(default)]
    pub description: String,
    /// Bytes per point.
    pub size: u32,
    /// Components.
    pub num_elements: u32,
    /// Bytes per component.
    pub element_size: u32,
    /// Component type: `int8` … `uint64`, `float`, `double`.
    #[serde(rename = "type")]
    pub type_name: String,
    /// Smallest value per component (informative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub min: Option<Vec<f64>>,
    /// Largest value per component (informative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max: Option<Vec<f64>>,
    /// Component scale (informative; positions use the top-level `scale`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Vec<f64>>,
    /// Component offset (informative).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<Vec<f64>>,
}

/// A component type of an attribute.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ElemType {
    /// `int8`
    I8,
    /// `int16`
    I16,
    /// `int32`
    I32,
    /// `int64`
    I64,
    /// `uint8`
    U8,
    /// `uint16`
    U16,
    /// `uint32`
    U32,
    /// `uint64`
    U64,
    /// `float`
    F32,
    /// `double`
    F64,
}

impl ElemType {
    /// The type named `name` in `metadata.json`, if known.
    pub fn from_name(name: &str) -> Option<Self> {
        Some(match name {
            "int8" => Self::I8,
            "int16" => Self::I16,
            "int32" => Self::I32,
            "int64" => Self::I64,
            "uint8" => Self::U8,
            "uint16" => Self::U16,
            "uint32" => Self::U32,
            "uint64" => Self::U64,
            "float" => Self::F32,
            "double" => Self::F64,
            _ => return None,
        })
    }
    /// Bytes of one component.
    pub fn size(self) -> u32 {
        match self {
            Self::I8 | Self::U8 => 1,
            Self::I16 | Self::U16 => 2,
            Self::I32 | Self::U32 | Self::F32 => 4,
            Self::I64 | Self::U64 | Self::F64 => 8,
        }
    }
    /// The component at the start of `b` (at least [`ElemType::size`] bytes), as `f64`.
    pub fn read(self, b: &[u8]) -> f64 {
        let a = |n: usize| -> [u8; 8] {
            let mut out = [0u8; 8];
            out[..n].copy_from_slice(&b[..n]);
            out
        };
        match self {
            Self::I8 => f64::from(b[0] as i8),
            Self::U8 => f64::from(b[0]),
            Self::I16 => f64::from(i16::from_le_bytes([b[0], b[1]])),
            Self::U16 => f64::from(u16::from_le_bytes([b[0], b[1]])),
            Self::I32 => f64::from(i32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::U32 => f64::from(u32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::F32 => f64::from(f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
            Self::I64 => i64::from_le_bytes(a(8)) as f64,
            Self::U64 => u64::from_le_bytes(a(8)) as f64,
            Self::F64 => f64::from_le_bytes(a(8)),
        }
    }
}

/// Where the normal of a point record is.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum NormalAt {
    /// One `normal` (or `NORMAL`) attribute of three `float`s at this byte offset.
    Vector(usize),
    /// Three scalar attributes `NormalX`, `NormalY`, `NormalZ` (the Potree viewer's
    /// convention for extra attributes), each at its offset with its type.
    Scalars([(usize, ElemType); 3]),
}

/// What of a point record splatbench uses: positions always, colour and normal when the
/// data set has them. Every other attribute (intensity, classification, GPS time, extra
/// bytes) is skipped: its bytes are counted, never decoded, stored or uploaded.
#[derive(Debug, Clone, PartialEq)]
pub struct Layout {
    /// Bytes of one point record.
    pub bytes_per_point: usize,
    /// Byte offset of the `int32 × 3` position.
    pub position: usize,
    /// Byte offset of `rgb` (`uint16 × 3`), if present.
    pub rgb: Option<usize>,
    /// The normal, if present.
    pub normal: Option<NormalAt>,
    /// Attributes present but not used, by name.
    pub skipped: Vec<String>,
}

impl Layout {
    /// Which attributes the decoded splats carry: the data set's colour and normal if it
    /// has them, and a radius per splat (the node's spacing, see the method's README).
    pub fn attributes(&self) -> scenes::Attributes {
        scenes::Attributes {
            normals: self.normal.is_some(),
            colors: self.rgb.is_some(),
            radii: true,
        }
    }
}

impl Metadata {
    /// Reads and validates `metadata.json` of `dir`.
    pub fn read(dir: &Path) -> Result<Self, MethodError> {
        let path = dir.join(METADATA_FILE);
        let meta: Metadata = crate::method::read_json(&path)?;
        meta.validate(&path)?;
        Ok(meta)
    }

    /// Checks everything the reader relies on; errors name the key. `path` names the file.
    pub fn validate(&self, path: &Path) -> Result<(), MethodError> {
        let bad = |msg: String| Err(MethodError::corrupt(path, msg));
        if self.version != VERSION {
            return bad(format!(
                "version \"{}\" is not supported (splatbench reads Potree {VERSION}, the format \
                 of PotreeConverter 2.x)",
                self.version
            ));
        }
        if self.encoding != ENCODING {
            return bad(format!(
                "encoding \"{}\" is not supported (only {ENCODING}: convert without \
                 --encoding BROTLI)",
                self.encoding
            ));
        }
        let h = self.hierarchy;
        if h.first_chunk_size == 0 || !h.first_chunk_size.is_multiple_of(RECORD_BYTES as u64) {
            return bad(format!(
                "hierarchy.firstChunkSize {} is not a positive multiple of the {RECORD_BYTES}-byte \
                 record",
                h.first_chunk_size
            ));
        }
        if h.step_size == 0 {
            return bad("hierarchy.stepSize is 0".into());
        }
        if h.depth > MAX_LEVEL {
            return bad(format!(
                "hierarchy.depth {} exceeds the {MAX_LEVEL} levels splatbench reads",
                h.depth
            ));
        }
        if self.scale.iter().any(|s| !s.is_finite() || *s <= 0.0) {
            return bad(format!("scale {:?} must be finite and > 0", self.scale));
        }
        if self.offset.iter().any(|o| !o.is_finite()) {
            return bad(format!("offset {:?} is not finite", self.offset));
        }
        if !self.spacing.is_finite() || self.spacing <= 0.0 {
            return bad(format!("spacing {} must be finite and > 0", self.spacing));
        }
        let b = self.bounding_box;
        if (0..3).any(|i| !b.min[i].is_finite() || !b.max[i].is_finite() || b.min[i] > b.max[i]) {
            return bad(format!(
                "boundingBox min {:?} max {:?} is not a finite box",
                b.min, b.max
            ));
        }
        self.layout(path).map(drop)
    }

    /// The point record's layout; errors name the attribute.
    pub fn layout(&self, path: &Path) -> Result<Layout, MethodError> {
        let mut offset = 0usize;
        let mut position = None;
        let mut rgb = None;
        let mut vector = None;
        let mut scalars: [Option<(usize, ElemType)>; 3] = [None; 3];
        let mut skipped = Vec::new();
        for a in &self.attributes {
            let err =
                |msg: String| MethodError::corrupt(path, format!("attribute '{}': {msg}", a.name));
            let ty = ElemType::from_name(&a.type_name)
                .ok_or_else(|| err(format!("unknown type \"{}\"", a.type_name)))?;
            if a.num_elements == 0
                || a.element_size != ty.size()
                || u64::from(a.size) != u64::from(a.num_elements) * u64::from(ty.size())
            {
                return Err(err(format!(
                    "size {} ≠ numElements {} × elementSize {} of type {} ({} bytes)",
                    a.size,
                    a.num_elements,
                    a.element_size,
                    a.type_name,
                    ty.size()
                )));
            }
            let shape = |want: ElemType, n: u32| -> Result<(), MethodError> {
                if ty == want && a.num_elements == n {
                    Ok(())
                } else {
                    Err(err(format!(
                        "is {} × {}, expected {n} × {want:?}",
                        a.num_elements, a.type_name
                    )))
                }
            };
            match a.name.as_str() {
                "position" | "POSITION_CARTESIAN" => {
                    shape(ElemType::I32, 3)?;
                    position = Some(offset);
                }
                "rgb" | "rgba" | "RGBA" => {
                    shape(ElemType::U16, 3)?;
                    rgb = Some(offset);
                }
                "normal" | "NORMAL" => {
                    shape(ElemType::F32, 3)?;
                    vector = Some(offset);
                }
                "NormalX" | "NormalY" | "NormalZ" => {
                    if a.num_elements != 1 {
                        return Err(err(format!(
                            "has {} components, expected 1",
                            a.num_elements
                        )));
                    }
                    let axis = usize::from(a.name.as_bytes()[6] - b'X');
                    scalars[axis] = Some((offset, ty));
                }
                _ => skipped.push(a.name.clone()),
            }
            offset += a.size as usize;
        }
        let position = position.ok_or_else(|| {
            MethodError::corrupt(path, "attributes: no 'position' (int32 × 3) attribute")
        })?;
        let normal = match (vector, scalars) {
            (Some(v), _) => Some(NormalAt::Vector(v)),
            (None, [Some(x), Some(y), Some(z)]) => Some(NormalAt::Scalars([x, y, z])),
            (None, [None, None, None]) => None,
            (None, _) => {
                return Err(MethodError::corrupt(
                    path,
                    "attributes: NormalX, NormalY and NormalZ must come together",
                ));
            }
        };
        Ok(Layout {
            bytes_per_point: offset,
            position,
            rgb,
            normal,
            skipped,
        })
    }

    /// The root node's box, world coordinates.
    pub fn root_box(&self) -> (DVec3, DVec3) {
        (
            DVec3::from(self.bounding_box.min),
            DVec3::from(self.bounding_box.max),
        )
    }
}

/// The kind of a hierarchy record.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NodeKind {
    /// An inner node (type 0).
    Inner,
    /// A leaf (type 1). PotreeConverter 2.0 also writes type 1 for nodes that have children:
    /// the child mask, not the type, says whether a node has children.
    Leaf,
    /// A proxy (type 2): offset and size name its hierarchy chunk.
    Proxy,
}

/// One 22-byte record of `hierarchy.bin`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Record {
    /// Inner, leaf or proxy.
    pub kind: NodeKind,
    /// Bit `i` set: child `i` exists.
    pub child_mask: u8,
    /// Points stored in the node itself.
    pub points: u32,
    /// Byte offset in `octree.bin` (in `hierarchy.bin` for a proxy).
    pub offset: u64,
    /// Byte size there.
    pub size: u64,
}

impl Record {
    /// The record's 22 bytes.
    pub fn to_bytes(&self) -> [u8; RECORD_BYTES] {
        let mut b = [0u8; RECORD_BYTES];
        b[0] = match self.kind {
            NodeKind::Inner => 0,
            NodeKind::Leaf => 1,
            NodeKind::Proxy => 2,
        };
        b[1] = self.child_mask;
        b[2..6].copy_from_slice(&self.points.to_le_bytes());
        b[6..14].copy_from_slice(&self.offset.to_le_bytes());
        b[14..22].copy_from_slice(&self.size.to_le_bytes());
        b
    }

    /// Parses one record; `Err` says what is wrong (an unknown type).
    pub fn parse(b: &[u8; RECORD_BYTES]) -> Result<Self, String> {
        let kind = match b[0] {
            0 => NodeKind::Inner,
            1 => NodeKind::Leaf,
            2 => NodeKind::Proxy,
            t => return Err(format!("unknown node type {t} (0 inner, 1 leaf, 2 proxy)")),
        };
        let u64_at = |i: usize| {
            let mut a = [0u8; 8];
            a.copy_from_slice(&b[i..i + 8]);
            u64::from_le_bytes(a)
        };
        Ok(Record {
            kind,
            child_mask: b[1],
            points: u32::from_le_bytes([b[2], b[3], b[4], b[5]]),
            offset: u64_at(6),
            size: u64_at(14),
        })
    }
}

/// The name of the node at `level` whose octant digits, root first, are the low
/// `3·level` bits of `path` (the first digit highest): `r`, `r0`, `r07`, …
pub fn node_name(level: u32, path: u64) -> String {
    let mut s = String::with_capacity(level as usize + 1);
    s.push('r');
    for l in (0..level).rev() {
        s.push(char::from(b'0' + ((path >> (3 * l)) & 7) as u8));
    }
    s
}

/// The box of octant `i` of the box `(min, max)` (bit 2: upper x, bit 1: upper y, bit 0:
/// upper z).
pub fn child_box(min: DVec3, max: DVec3, i: u8) -> (DVec3, DVec3) {
    let c = (min + max) * 0.5;
    let pick = |bit: u8, lo: f64, mid: f64, hi: f64| {
        if i & bit != 0 { (mid, hi) } else { (lo, mid) }
    };
    let (x0, x1) = pick(0b100, min.x, c.x, max.x);
    let (y0, y1) = pick(0b010, min.y, c.y, max.y);
    let (z0, z1) = pick(0b001, min.z, c.z, max.z);
    (DVec3::new(x0, y0, z0), DVec3::new(x1, y1, z1))
}

/// The octant of the box `(min, max)` that `p` falls in ([`child_box`]'s numbering; a point
/// on the middle plane goes to the upper half).
pub fn octant_of(min: DVec3, max: DVec3, p: DVec3) -> u8 {
    let c = (min + max) * 0.5;
    (u8::from(p.x >= c.x) << 2) | (u8::from(p.y >= c.y) << 1) | u8::from(p.z >= c.z)
}

/// How [`decode`] turns records into splats.
#[derive(Debug, Clone, PartialEq)]
pub struct Decoding {
    /// The record layout.
    pub layout: Layout,
    /// Position scale.
    pub scale: DVec3,
    /// Position offset.
    pub offset: DVec3,
    /// Subtracted from world positions (the scene's origin).
    pub origin: DVec3,
}

impl Decoding {
    /// Which attributes a decoded batch carries ([`Layout::attributes`]).
    pub fn attributes(&self) -> scenes::Attributes {
        self.layout.attributes()
    }

    /// The `int32` position of record `i` of `bytes` (whole records).
    pub fn raw_position(&self, bytes: &[u8], i: usize) -> [i32; 3] {
        let at = i * self.layout.bytes_per_point + self.layout.position;
        let c = |k: usize| {
            let b = &bytes[at + 4 * k..at + 4 * k + 4];
            i32::from_le_bytes([b[0], b[1], b[2], b[3]])
        };
        [c(0), c(1), c(2)]
    }

    /// The colour of record `i` as the Potree viewer shows it: 16-bit values above 255 are
    /// divided by 256 (8-bit data stored as such is kept).
    pub fn color(&self, bytes: &[u8], i: usize) -> Option<[u8; 3]> {
        let at = i * self.layout.bytes_per_point + self.layout.rgb?;
        Some(std::array::from_fn(|k| {
            let v = u16::from_le_bytes([bytes[at + 2 * k], bytes[at + 2 * k + 1]]);
            if v > 255 { (v / 256) as u8 } else { v as u8 }
        }))
    }

    /// The normal of record `i`, if the layout has one (not normalised).
    pub fn normal(&self, bytes: &[u8], i: usize) -> Option<[f64; 3]> {
        let base = i * self.layout.bytes_per_point;
        Some(match self.layout.normal? {
            NormalAt::Vector(o) => {
                std::array::from_fn(|k| ElemType::F32.read(&bytes[base + o + 4 * k..]))
            }
            NormalAt::Scalars(s) => std::array::from_fn(|k| s[k].1.read(&bytes[base + s[k].0..])),
        })
    }

    /// The splats of a node of `points` records in `bytes`, each with radius `radius`;
    /// `Err` says what is wrong (the caller names file and node).
    pub fn decode(
        &self,
        bytes: &[u8],
        points: u32,
        radius: f32,
    ) -> Result<crate::SplatBatch, String> {
        let n = points as usize;
        if bytes.len() != n * self.layout.bytes_per_point {
            return Err(format!(
                "{} bytes for {n} points of {} bytes",
                bytes.len(),
                self.layout.bytes_per_point
            ));
        }
        let mut b = crate::SplatBatch::with_attributes(self.attributes(), n);
        let shift = self.offset - self.origin;
        for i in 0..n {
            let q = self.raw_position(bytes, i);
            let w =
                DVec3::new(f64::from(q[0]), f64::from(q[1]), f64::from(q[2])) * self.scale + shift;
            b.positions.push(w.as_vec3().to_array());
            if let (Some(cols), Some(c)) = (b.colors.as_mut(), self.color(bytes, i)) {
                cols.push(crate::draw::pack_color(c));
            }
            if let (Some(ns), Some(v)) = (b.normals.as_mut(), self.normal(bytes, i)) {
                let v = DVec3::from(v).as_vec3();
                let v = if v.is_finite() && v.length_squared() > 0.0 {
                    v.normalize()
                } else {
                    glam::Vec3::Z
                };
                ns.push(crate::octnormal::encode(v));
            }
        }
        if let Some(r) = b.radii.as_mut() {
            r.resize(n, radius);
        }
        Ok(b)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_round_trip_and_unknown_types_are_named() {
        let r = Record {
            kind: NodeKind::Proxy,
            child_mask: 0b1010_0001,
            points: 12_345,
            offset: 1 << 40,
            size: 22 * 9,
        };
        assert_eq!(Record::parse(&r.to_bytes()).unwrap(), r);
        let mut b = r.to_bytes();
        b[0] = 7;
        assert!(
            Record::parse(&b)
                .unwrap_err()
                .contains("unknown node type 7")
        );
    }

    #[test]
    fn names_and_octants_follow_the_converter() {
        assert_eq!(node_name(0, 0), "r");
        assert_eq!(node_name(3, 0o074), "r074");
        let (min, max) = (DVec3::ZERO, DVec3::splat(2.0));
        // Bit 2 is x, bit 0 is z.
        assert_eq!(child_box(min, max, 0b100).0, DVec3::new(1.0, 0.0, 0.0));
        assert_eq!(child_box(min, max, 0b001).0, DVec3::new(0.0, 0.0, 1.0));
        for i in 0..8 {
            let (lo, hi) = child_box(min, max, i);
            assert_eq!(octant_of(min, max, (lo + hi) * 0.5), i);
        }
    }

    #[test]
    fn element_types_read_little_endian() {
        assert_eq!(ElemType::I32.read(&(-5i32).to_le_bytes()), -5.0);
        assert_eq!(ElemType::U16.read(&600u16.to_le_bytes()), 600.0);
        assert_eq!(ElemType::F64.read(&1.5f64.to_le_bytes()), 1.5);
        assert_eq!(ElemType::from_name("float"), Some(ElemType::F32));
        assert_eq!(ElemType::from_name("half"), None);
    }
}
