//! SPT's files: `index.json` (clusters and chunks of the list), and the layouts of
//! `nodes.bin` (the splats) and `lod.bin` (the interval-test entries), both checksummed and
//! quantised ([`super::quant`]); the README's "Files on disk" has the tables.

use std::path::Path;

use super::quant::{self, Grid, LodScale, RadiusScale};
use super::*;

/// A normal cluster: a range of the node list.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClusterInfo {
    /// Octahedral cluster id (0..128), 0 without clustering.
    pub id: u32,
    /// First node.
    pub start: u64,
    /// Nodes.
    pub count: u64,
    /// Cone axis (unit).
    pub axis: [f32; 3],
    /// Cone half-angle (radians) covering every node normal of the cluster.
    pub half_angle: f32,
    /// Bounding sphere centre of the node centres.
    pub center: [f32; 3],
    /// Bounding sphere radius.
    pub radius: f32,
}

/// A chunk: consecutive nodes of one cluster.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ChunkInfo {
    /// Index into the cluster list.
    pub cluster: u32,
    /// First node.
    pub start: u64,
    /// Nodes.
    pub count: u32,
    /// Largest `e_par` (its first node's).
    pub max_e_par: f32,
    /// Bounding sphere centre (node disks included).
    pub center: [f32; 3],
    /// Bounding sphere radius.
    pub radius: f32,
}

/// `index.json`.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Index {
    /// Total nodes.
    pub nodes: u64,
    /// Levels of the tree.
    pub levels: u32,
    /// Clusters, in list order.
    pub clusters: Vec<ClusterInfo>,
    /// Chunks, in list order (chunk id = position here).
    pub chunks: Vec<ChunkInfo>,
}

/// Magic of `nodes.bin` (format 2).
pub(super) const NODES_MAGIC: &[u8; 8] = b"SPTNOD02";
/// Magic of `lod.bin` (format 2).
pub(super) const LOD_MAGIC: &[u8; 8] = b"SPTLOD02";
/// Bytes before the first record of `nodes.bin`.
pub(super) const NODES_HEADER: usize = 64;
/// Bytes before the first record of `lod.bin`.
pub(super) const LOD_HEADER: usize = 40;
/// Where both files keep the FNV-1a 64 of every byte after the first 24.
pub(super) const CHECKSUM_AT: usize = 16;
const FLAG_NORMALS: u32 = 1;
const FLAG_COLORS: u32 = 2;
const FLAG_PHI_GAMMA: u32 = 1;
/// `lod.w` of a list without the `φ`/`γ` word (unified mode: the test reads no part of it):
/// `q_node = q_par = 0`, `q_γ` = unbounded.
pub const Q_ABSENT: f32 = select::GAMMA_UNBOUNDED as f32;

fn le_u32(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], b[at + 3]])
}

fn le_u64(b: &[u8], at: usize) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(w)
}

fn le_u24(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes([b[at], b[at + 1], b[at + 2], 0])
}

fn le_u16(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}

/// The first 24 bytes of both files: magic, count, checksum (zero until the writer knows it).
fn start(magic: &[u8; 8], count: u64, out: &mut Vec<u8>) {
    out.extend_from_slice(magic);
    out.extend_from_slice(&count.to_le_bytes());
    out.extend_from_slice(&[0; 8]);
}

/// Reads a whole file, checks its magic, header (`record` parses it and gives the record
/// size, `None` for records of varying size), count, length and checksum; returns the
/// records.
fn read_checked(
    path: &Path,
    magic: &[u8; 8],
    header: usize,
    count: u64,
    record: impl Fn(&[u8]) -> Result<Option<usize>, String>,
) -> Result<Vec<u8>, MethodError> {
    let mut bytes = std::fs::read(path).map_err(|e| MethodError::io(path, e))?;
    let bad = |m: String| MethodError::corrupt(path, m);
    if bytes.len() < header || &bytes[0..8] != magic {
        return Err(bad(format!(
            "bad magic or short header (expected {}, {header} bytes)",
            String::from_utf8_lossy(magic)
        )));
    }
    let rec = record(&bytes[..header]).map_err(bad)?;
    let n = le_u64(&bytes, 8);
    let want = match rec {
        Some(rec) => (rec as u64)
            .checked_mul(n)
            .and_then(|b| b.checked_add(header as u64)),
        None => Some(bytes.len() as u64),
    };
    if n != count || want != Some(bytes.len() as u64) {
        return Err(bad(format!(
            "{n} records of {} bytes in {} bytes, index.json says {count} nodes",
            rec.map_or("varying".into(), |r| r.to_string()),
            bytes.len()
        )));
    }
    if scenes::hash::fnv1a64(&bytes[24..]) != le_u64(&bytes, CHECKSUM_AT) {
        return Err(bad("checksum mismatch".into()));
    }
    bytes.drain(..header);
    Ok(bytes)
}

/// What a `nodes.bin` record holds: the position grid, the radius scale and the scene's
/// columns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NodeLayout {
    /// The position grid.
    pub grid: Grid,
    /// The radius codes' scale.
    pub radius: RadiusScale,
    /// A 24-bit octahedral normal per node.
    pub normals: bool,
    /// An sRGB colour per node.
    pub colors: bool,
}

impl NodeLayout {
    /// Bytes of a record: position, normal (3), colour (3), radius (2).
    pub fn record_bytes(&self) -> usize {
        self.grid.record_bytes() + 3 * self.normals as usize + 3 * self.colors as usize + 2
    }

    /// The header of a file of `count` records (checksum zero).
    pub(super) fn header(&self, count: u64) -> Vec<u8> {
        let mut h = Vec::with_capacity(NODES_HEADER);
        start(NODES_MAGIC, count, &mut h);
        let flags = FLAG_NORMALS * self.normals as u32 + FLAG_COLORS * self.colors as u32;
        h.extend_from_slice(&flags.to_le_bytes());
        h.extend_from_slice(&(self.record_bytes() as u32).to_le_bytes());
        for v in self.grid.lo {
            h.extend_from_slice(&v.to_le_bytes());
        }
        for v in self.grid.step {
            h.extend_from_slice(&v.to_le_bytes());
        }
        h.extend_from_slice(&self.grid.bytes);
        h.push(0);
        h.extend_from_slice(&self.radius.top.to_le_bytes());
        debug_assert_eq!(h.len(), NODES_HEADER);
        h
    }

    fn parse(h: &[u8]) -> Result<Self, String> {
        let flags = le_u32(h, 24);
        if flags & !(FLAG_NORMALS | FLAG_COLORS) != 0 {
            return Err(format!("unknown flags {flags:#x}"));
        }
        let f = |at: usize| f32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]]);
        let layout = NodeLayout {
            grid: Grid {
                lo: [f(32), f(36), f(40)],
                step: [f(44), f(48), f(52)],
                bytes: [h[56], h[57], h[58]],
            },
            radius: RadiusScale {
                top: le_u32(h, 60) as i32,
            },
            normals: flags & FLAG_NORMALS != 0,
            colors: flags & FLAG_COLORS != 0,
        };
        layout.grid.check()?;
        if h[59] != 0 {
            return Err("reserved header byte is not zero".into());
        }
        let top = layout.radius.top;
        if !(RadiusScale::MIN_TOP..=RadiusScale::MAX_TOP).contains(&top) {
            return Err(format!("radius scale 2^{top} out of range"));
        }
        let rec = le_u32(h, 28) as usize;
        if rec != layout.record_bytes() {
            return Err(format!(
                "records of {rec} bytes, the layout needs {}",
                layout.record_bytes()
            ));
        }
        Ok(layout)
    }

    /// Appends a record.
    pub(super) fn put(
        &self,
        pos: [u32; 3],
        normal: u32,
        color: [u8; 3],
        radius: u16,
        out: &mut Vec<u8>,
    ) {
        self.grid.put(pos, out);
        if self.normals {
            out.extend_from_slice(&normal.to_le_bytes()[..3]);
        }
        if self.colors {
            out.extend_from_slice(&color);
        }
        out.extend_from_slice(&radius.to_le_bytes());
    }

    fn normal_at(&self) -> usize {
        self.grid.record_bytes()
    }

    fn color_at(&self) -> usize {
        self.normal_at() + 3 * self.normals as usize
    }

    fn radius_at(&self) -> usize {
        self.color_at() + 3 * self.colors as usize
    }

    /// The decoded position of a record.
    pub fn position(&self, rec: &[u8]) -> Vec3 {
        self.grid.decode(self.grid.get(rec))
    }

    /// The normal code of a record (with normals).
    pub fn normal_code(&self, rec: &[u8]) -> u32 {
        le_u24(rec, self.normal_at())
    }

    /// The colour of a record (with colours).
    pub fn color(&self, rec: &[u8]) -> [u8; 3] {
        let at = self.color_at();
        [rec[at], rec[at + 1], rec[at + 2]]
    }

    /// The radius code of a record.
    pub fn radius_code(&self, rec: &[u8]) -> u16 {
        le_u16(rec, self.radius_at())
    }
}

/// `nodes.bin`, read whole and checked at `open`, decoded on demand.
pub struct NodeFile {
    layout: NodeLayout,
    rec: usize,
    records: Vec<u8>,
}

impl NodeFile {
    /// Reads and checks `path`: `count` records with the manifest's attributes, radii valid.
    pub(super) fn read(path: &Path, count: u64, attrs: Attributes) -> Result<Self, MethodError> {
        let layout = std::cell::Cell::new(None);
        let records = read_checked(path, NODES_MAGIC, NODES_HEADER, count, |h| {
            let l = NodeLayout::parse(h)?;
            layout.set(Some(l));
            Ok(Some(l.record_bytes()))
        })?;
        let layout = layout
            .get()
            .ok_or_else(|| MethodError::corrupt(path, "no layout"))?;
        let bad = |m: String| MethodError::corrupt(path, m);
        if layout.normals != attrs.normals || layout.colors != attrs.colors || !attrs.radii {
            return Err(bad(format!(
                "normals {} colours {}, method.json says attributes {attrs}",
                layout.normals, layout.colors
            )));
        }
        let rec = layout.record_bytes();
        if let Some(i) = records
            .chunks_exact(rec)
            .map(|r| layout.radius_code(r))
            .position(|c| c == 0)
        {
            return Err(bad(format!("node {i}: radius code 0")));
        }
        Ok(Self {
            layout,
            rec,
            records,
        })
    }

    /// Nodes.
    pub fn len(&self) -> usize {
        self.records.len() / self.rec
    }

    /// True without nodes.
    pub fn is_empty(&self) -> bool {
        self.records.is_empty()
    }

    /// The record layout (grid and columns).
    pub fn layout(&self) -> &NodeLayout {
        &self.layout
    }

    /// Bytes of the records (held in memory).
    pub fn bytes(&self) -> u64 {
        self.records.len() as u64
    }

    fn record(&self, i: usize) -> &[u8] {
        &self.records[i * self.rec..(i + 1) * self.rec]
    }

    /// Node `i`'s decoded centre.
    pub fn position(&self, i: usize) -> Vec3 {
        self.layout.position(self.record(i))
    }

    /// Node `i`'s normal as the GPU decodes it (`Vec3::Z` without normals).
    pub fn normal(&self, i: usize) -> Vec3 {
        if self.layout.normals {
            quant::decode_normal(self.layout.normal_code(self.record(i)))
        } else {
            Vec3::Z
        }
    }

    /// Node `i`'s decoded radius.
    pub fn radius(&self, i: usize) -> f32 {
        self.layout
            .radius
            .value(self.layout.radius_code(self.record(i)))
    }

    /// The splats `range` in the upload format (no `lod`).
    pub fn batch(&self, range: std::ops::Range<usize>) -> SplatBatch {
        let l = &self.layout;
        let recs =
            || self.records[range.start * self.rec..range.end * self.rec].chunks_exact(self.rec);
        SplatBatch {
            positions: recs().map(|r| l.position(r).to_array()).collect(),
            normals: l.normals.then(|| {
                recs()
                    .map(|r| quant::gpu_normal(l.normal_code(r)))
                    .collect()
            }),
            colors: l.colors.then(|| {
                recs()
                    .map(|r| crate::draw::pack_color(l.color(r)))
                    .collect()
            }),
            radii: Some(recs().map(|r| l.radius.value(l.radius_code(r))).collect()),
            lod: None,
        }
    }
}

/// `lod.bin`'s records: one per node in list order, of varying size.
///
/// | bytes | what |
/// |------:|------|
/// | 1 | tag: bits 0–1 how `e_par` is stored (0: equal to the previous node's, 1: a LEB128 varint `d` > 0, the `f32` bit pattern of the previous node's `e_par` less `d`, 2: raw `f32`), bit 2: `e` is a raw `f32` (else 0); bits 3–7 zero |
/// | 0, 1–5 or 4 | `e_par` as the tag says |
/// | 0 or 4 | `e` |
/// | 2 | `δ`: a code of the header's [`LodScale`] |
/// | 3 | the `φ`/`γ` word, in split mode only |
///
/// `e` and `e_par` are exact: leaves (`e` = 0) and the siblings after the first (the list
/// is sorted by `e_par`, so siblings are neighbours) store no bytes for them.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LodLayout {
    /// The `φ`/`γ` word is stored (split mode); else `lod.w` decodes as [`Q_ABSENT`].
    pub phi_gamma: bool,
    /// The `δ` codes' scale.
    pub scale: LodScale,
}

const TAG_PAR_SAME: u8 = 0;
const TAG_PAR_BELOW: u8 = 1;
const TAG_PAR_RAW: u8 = 2;
const TAG_E_RAW: u8 = 4;

impl LodLayout {
    /// The header of a file of `count` records (checksum zero).
    pub(super) fn header(&self, count: u64) -> Vec<u8> {
        let mut h = Vec::with_capacity(LOD_HEADER);
        start(LOD_MAGIC, count, &mut h);
        h.extend_from_slice(&(FLAG_PHI_GAMMA * self.phi_gamma as u32).to_le_bytes());
        h.extend_from_slice(&self.scale.0.to_le_bytes());
        h.resize(LOD_HEADER, 0);
        h
    }

    /// Appends the record of a node with `e`, `e_par` (`prev`: the previous node's, `None`
    /// for the first), the `δ` code and the `φ`/`γ` word.
    pub(super) fn put(
        &self,
        e: f32,
        e_par: f32,
        prev: Option<f32>,
        delta: u16,
        q: u32,
        out: &mut Vec<u8>,
    ) {
        let at = out.len();
        out.push(0);
        let (par, prev_bits) = (e_par.to_bits(), prev.map(f32::to_bits));
        let mut tag = match prev_bits {
            Some(b) if b == par => TAG_PAR_SAME,
            Some(b) if b > par && (b - par) < 1 << 21 => {
                let mut d = b - par;
                while d >= 0x80 {
                    out.push(d as u8 | 0x80);
                    d >>= 7;
                }
                out.push(d as u8);
                TAG_PAR_BELOW
            }
            _ => {
                out.extend_from_slice(&e_par.to_le_bytes());
                TAG_PAR_RAW
            }
        };
        if e.to_bits() != 0 {
            tag |= TAG_E_RAW;
            out.extend_from_slice(&e.to_le_bytes());
        }
        out[at] = tag;
        out.extend_from_slice(&delta.to_le_bytes());
        if self.phi_gamma {
            out.extend_from_slice(&q.to_le_bytes()[..3]);
        }
    }
}

/// Reads and checks `lod.bin`: `count` records, the `φ`/`γ` word present iff `split`, every
/// value finite and ≥ 0, every code valid; the entries decoded.
pub(super) fn read_lod(path: &Path, count: u64, split: bool) -> Result<Vec<[f32; 4]>, MethodError> {
    let layout = std::cell::Cell::new(None);
    let records = read_checked(path, LOD_MAGIC, LOD_HEADER, count, |h| {
        let flags = le_u32(h, 24);
        if flags & !FLAG_PHI_GAMMA != 0 {
            return Err(format!("unknown flags {flags:#x}"));
        }
        let l = LodLayout {
            phi_gamma: flags & FLAG_PHI_GAMMA != 0,
            scale: LodScale(f32::from_le_bytes([h[28], h[29], h[30], h[31]])),
        };
        l.scale.check()?;
        if h[32..LOD_HEADER].iter().any(|&b| b != 0) {
            return Err("reserved header bytes are not zero".into());
        }
        if l.phi_gamma != split {
            return Err(format!(
                "φ/γ word {}, but method.json's mode needs it {}",
                if l.phi_gamma { "stored" } else { "absent" },
                if split { "stored" } else { "absent" }
            ));
        }
        layout.set(Some(l));
        Ok(None)
    })?;
    let layout = layout
        .get()
        .ok_or_else(|| MethodError::corrupt(path, "no layout"))?;
    let bad = |i: usize, m: String| MethodError::corrupt(path, format!("node {i}: {m}"));
    let mut lod = Vec::with_capacity(count.min(records.len() as u64) as usize);
    let mut at = 0usize;
    let mut prev: Option<u32> = None;
    for i in 0..count as usize {
        let short = || {
            bad(
                i,
                format!("the records end early ({} bytes)", records.len()),
            )
        };
        let take = |at: &mut usize, n: usize| {
            let s = records.get(*at..*at + n).ok_or_else(short)?;
            *at += n;
            Ok::<&[u8], MethodError>(s)
        };
        let raw = |at: &mut usize| take(at, 4).map(|b| le_u32(b, 0));
        let tag = take(&mut at, 1)?[0];
        if tag & !(3 | TAG_E_RAW) != 0
            || tag & 3 == 3
            || (tag & 3 == TAG_PAR_SAME && prev.is_none())
        {
            return Err(bad(i, format!("bad tag {tag:#x}")));
        }
        let par = match tag & 3 {
            TAG_PAR_SAME => prev.unwrap_or(0),
            TAG_PAR_BELOW => {
                let (mut d, mut shift) = (0u32, 0);
                loop {
                    if shift == 21 {
                        return Err(bad(i, "e_par varint longer than 3 bytes".into()));
                    }
                    let b = take(&mut at, 1)?[0];
                    d |= u32::from(b & 0x7f) << shift;
                    shift += 7;
                    if b & 0x80 == 0 {
                        break;
                    }
                }
                match prev.and_then(|p| p.checked_sub(d)) {
                    Some(v) if d > 0 => v,
                    _ => {
                        return Err(bad(
                            i,
                            format!("e_par difference {d} is not below the previous"),
                        ));
                    }
                }
            }
            _ => raw(&mut at)?,
        };
        let e = if tag & TAG_E_RAW != 0 {
            raw(&mut at)?
        } else {
            0
        };
        let delta = le_u16(take(&mut at, 2)?, 0);
        let q = if layout.phi_gamma {
            le_u24(take(&mut at, 3)?, 0) as f32
        } else {
            Q_ABSENT
        };
        let (e, e_par) = (f32::from_bits(e), f32::from_bits(par));
        let Some(delta) = layout.scale.value(delta) else {
            return Err(bad(i, format!("δ code {delta:#x} is not finite")));
        };
        for (what, v) in [("e", e), ("e_par", e_par)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(bad(i, format!("{what} {v} is not finite ≥ 0")));
            }
        }
        prev = Some(par);
        lod.push([e, e_par, delta, q]);
    }
    if at != records.len() {
        return Err(MethodError::corrupt(
            path,
            format!("{} bytes after the last node's record", records.len() - at),
        ));
    }
    Ok(lod)
}
