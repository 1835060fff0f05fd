//! The `.qs` file: QSplat's breadth-first layout of quantised nodes.
//!
//! Contract (all little-endian):
//! - header, [`HEADER_BYTES`] = 80 bytes: magic `SBQSPLAT`, version, flags (bit 0 normals,
//!   bit 1 colours), nodes, leaves, pointers, levels, sphere-table size, root sphere
//!   (4 × f32), body length, FNV-1a 64 checksum of header bytes `0..72` followed by the body;
//! - body: groups of siblings, breadth-first. A group is an optional 32-bit pointer (the byte
//!   offset within the body of the group's first child group) followed by its nodes. The
//!   pointer is present iff some node of the group has children (for the root group: iff the
//!   tree has more than one node); the child groups of a group's nodes follow each other, so
//!   one pointer finds them all. The root group is at body offset 0. The body is at most
//!   4 GiB (32-bit offsets: ≈ 10⁹ nodes, ≈ 700 M samples).
//! - node: one `u32` = sphere code (bits 0–12) | normal (13–26) | cone class (27–28) |
//!   child-count code 0/1/2/3 = 0/2/3/4 children (29–30) | all-children-are-leaves (31);
//!   then, only when the scene has colours, a `u16` RGB565 colour. 4 or 6 bytes per node.
//!
//! [`QsFile::open`] maps the file and validates it completely (checksum, then one walk over
//! every group checking pointers, codes and counts); any failure is
//! [`MethodError::Corrupt`] naming the file and the byte or node, never a panic.

use std::path::{Path, PathBuf};

use scenes::hash::Fnv64;

use super::build::{QNode, QTree};
use super::quant;
use crate::MethodError;

/// File magic.
pub const MAGIC: [u8; 8] = *b"SBQSPLAT";
/// Layout version.
pub const VERSION: u32 = 1;
/// Header length in bytes.
pub const HEADER_BYTES: usize = 80;
const CHECKSUM_AT: usize = 72;
/// Flag: nodes carry normals.
pub const FLAG_NORMALS: u32 = 1;
/// Flag: nodes carry an RGB565 colour.
pub const FLAG_COLORS: u32 = 2;

/// The parsed header.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Header {
    /// [`FLAG_NORMALS`] | [`FLAG_COLORS`].
    pub flags: u32,
    /// Nodes in the body.
    pub nodes: u64,
    /// Nodes without children.
    pub leaves: u64,
    /// Sibling groups carrying a pointer.
    pub pointers: u64,
    /// Levels of the tree.
    pub levels: u32,
    /// Entries of the sphere table the file was written with.
    pub table_entries: u32,
    /// Root sphere: centre, radius.
    pub root: [f32; 4],
    /// Body length in bytes.
    pub body_len: u64,
}

impl Header {
    /// Bytes per node: 4, or 6 with colours.
    pub fn node_bytes(&self) -> usize {
        node_bytes(self.flags & FLAG_COLORS != 0)
    }
}

/// Bytes per node.
pub fn node_bytes(colors: bool) -> usize {
    if colors { 6 } else { 4 }
}

/// Packs a node's 32-bit word.
pub fn pack(n: &QNode) -> u32 {
    let cc = match n.children {
        0 => 0,
        2 => 1,
        3 => 2,
        _ => 3,
    };
    (n.sphere as u32 & 0x1fff)
        | ((n.normal as u32 & 0x3fff) << 13)
        | ((n.cone as u32 & 3) << 27)
        | (cc << 29)
        | ((n.all_leaves as u32) << 31)
}

/// Unpacks a node word (the colour is read separately).
#[inline]
pub fn unpack(w: u32) -> QNode {
    QNode {
        sphere: (w & 0x1fff) as u16,
        normal: ((w >> 13) & 0x3fff) as u16,
        cone: ((w >> 27) & 3) as u8,
        children: [0, 2, 3, 4][((w >> 29) & 3) as usize],
        all_leaves: w >> 31 != 0,
        color: 0,
    }
}

/// Little-endian `u32` at `at`, `None` past the end.
#[inline]
pub fn read_u32(b: &[u8], at: usize) -> Option<u32> {
    Some(u32::from_le_bytes(
        b.get(at..at.checked_add(4)?)?.try_into().ok()?,
    ))
}
/// Little-endian `u16` at `at`, `None` past the end.
#[inline]
pub fn read_u16(b: &[u8], at: usize) -> Option<u16> {
    Some(u16::from_le_bytes(
        b.get(at..at.checked_add(2)?)?.try_into().ok()?,
    ))
}
fn read_u64(b: &[u8], at: usize) -> Option<u64> {
    Some(u64::from_le_bytes(b.get(at..at + 8)?.try_into().ok()?))
}
fn read_f32(b: &[u8], at: usize) -> Option<f32> {
    read_u32(b, at).map(f32::from_bits)
}

/// What [`write`] reports.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FileStats {
    /// Total file bytes.
    pub bytes: u64,
    /// Sibling groups with a pointer.
    pub pointers: u64,
}

/// The nodes of a tree, level by level in breadth-first order, as the writer reads them: in
/// memory ([`QTree`]) or from an out-of-core build's spill files.
pub trait Levels {
    /// Number of levels.
    fn count(&self) -> usize;
    /// Calls `f` with level `l`'s nodes, in order, in one or more slices.
    fn visit(
        &self,
        l: usize,
        f: &mut dyn FnMut(&[QNode]) -> Result<(), MethodError>,
    ) -> Result<(), MethodError>;
}

impl Levels for QTree {
    fn count(&self) -> usize {
        self.levels.len()
    }
    fn visit(
        &self,
        l: usize,
        f: &mut dyn FnMut(&[QNode]) -> Result<(), MethodError>,
    ) -> Result<(), MethodError> {
        f(&self.levels[l])
    }
}

/// Appends `n`'s stored bytes: its packed word, then its colour when the file has colours.
pub fn encode_node(n: &QNode, colors: bool, out: &mut Vec<u8>) {
    out.extend_from_slice(&pack(n).to_le_bytes());
    if colors {
        out.extend_from_slice(&n.color.to_le_bytes());
    }
}

/// The node [`encode_node`] wrote at the start of `b` (which must hold its bytes).
pub fn decode_node(b: &[u8], colors: bool) -> QNode {
    let mut n = unpack(u32::from_le_bytes([b[0], b[1], b[2], b[3]]));
    if colors {
        n.color = u16::from_le_bytes([b[4], b[5]]);
    }
    n
}

/// Writes `tree` to `path` (through a temporary file and a rename).
pub fn write(path: &Path, tree: &QTree) -> Result<FileStats, MethodError> {
    write_levels(path, tree, tree.root, tree.normals, tree.colors)
}

/// Bytes of the group of `n`'s children (its pointer included); 0 for a leaf.
fn child_group_bytes(n: &QNode, nb: u64) -> u64 {
    if n.children == 0 {
        0
    } else {
        n.children as u64 * nb + 4 * (!n.all_leaves) as u64
    }
}

/// Writes the tree whose nodes `levels` yields, with root sphere `root`, to `path` (through
/// a temporary file and a rename). Streams: one pass over the levels counts nodes, leaves,
/// pointers and bytes for the header, a second writes the body; besides I/O buffers it holds
/// one byte per sibling group of the level being written.
pub fn write_levels(
    path: &Path,
    levels: &dyn Levels,
    root: [f32; 4],
    normals: bool,
    colors: bool,
) -> Result<FileStats, MethodError> {
    let nb = node_bytes(colors) as u64;
    // Pass 1: the header's counts.
    let (mut nodes, mut leaves, mut pointers, mut body_len) = (0u64, 0u64, 0u64, 0u64);
    for l in 0..levels.count() {
        levels.visit(l, &mut |level| {
            for n in level {
                nodes += 1;
                leaves += (n.children == 0) as u64;
                pointers += (n.children > 0 && !n.all_leaves) as u64;
                body_len += child_group_bytes(n, nb);
            }
            Ok(())
        })?;
    }
    pointers += (nodes > 1) as u64;
    body_len += nb + 4 * (nodes > 1) as u64;
    if u32::try_from(body_len).is_err() {
        return Err(MethodError::Limit(format!(
            "{}: {body_len} bytes of nodes exceed the 32-bit offsets (4 GiB)",
            path.display()
        )));
    }
    let flags = (FLAG_NORMALS * normals as u32) | (FLAG_COLORS * colors as u32);
    let mut h = Vec::with_capacity(HEADER_BYTES);
    h.extend_from_slice(&MAGIC);
    h.extend_from_slice(&VERSION.to_le_bytes());
    h.extend_from_slice(&flags.to_le_bytes());
    h.extend_from_slice(&nodes.to_le_bytes());
    h.extend_from_slice(&leaves.to_le_bytes());
    h.extend_from_slice(&pointers.to_le_bytes());
    h.extend_from_slice(&(levels.count() as u32).to_le_bytes());
    h.extend_from_slice(&(quant::sphere_table().entries.len() as u32).to_le_bytes());
    for v in root {
        h.extend_from_slice(&v.to_le_bytes());
    }
    h.extend_from_slice(&body_len.to_le_bytes());
    debug_assert_eq!(h.len(), CHECKSUM_AT);

    // Pass 2: the body, into a temporary file removed on any error.
    let tmp = path.with_extension("qs.tmp");
    let res = write_body(path, &tmp, levels, &h, (nodes, body_len, nb, colors));
    if res.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    res?;
    std::fs::rename(&tmp, path).map_err(|e| MethodError::io(path, e))?;
    Ok(FileStats {
        bytes: HEADER_BYTES as u64 + body_len,
        pointers,
    })
}

/// Writes the header `h` (checksum last) and the body of `levels` to `tmp`.
fn write_body(
    path: &Path,
    tmp: &Path,
    levels: &dyn Levels,
    h: &[u8],
    (nodes, body_len, nb, colors): (u64, u64, u64, bool),
) -> Result<(), MethodError> {
    // Groups of the current level: one byte each, the child count in
    // bits 0–2 and "has a pointer" in bit 3 (the root group: one node, a pointer iff the
    // tree has more than one node).
    let io = |e| MethodError::io(tmp, e);
    let mut out =
        std::io::BufWriter::with_capacity(1 << 20, std::fs::File::create(tmp).map_err(io)?);
    use std::io::{Seek, Write};
    out.write_all(h).map_err(io)?;
    out.write_all(&[0u8; 8]).map_err(io)?;
    let mut sum = Fnv64::default();
    sum.write(h);
    let mut groups: Vec<u8> = vec![1 | (((nodes > 1) as u8) << 3)];
    let mut written = 0u64;
    let mut buf: Vec<u8> = Vec::with_capacity(1 << 16);
    for l in 0..levels.count() {
        let level_bytes: u64 = groups
            .iter()
            .map(|&g| (g & 7) as u64 * nb + 4 * (g >> 3) as u64)
            .sum();
        // Where the next level's first child group will start.
        let mut cursor = written + level_bytes;
        let mut next: Vec<u8> = Vec::new();
        let (mut group, mut left_in_group) = (0usize, 0u8);
        levels.visit(l, &mut |level| {
            for n in level {
                if left_in_group == 0 {
                    let g = *groups.get(group).ok_or_else(|| {
                        MethodError::Bug(format!(
                            "{}: level {l} has more nodes than its parents' children",
                            path.display()
                        ))
                    })?;
                    group += 1;
                    left_in_group = g & 7;
                    if g >> 3 != 0 {
                        let p = u32::try_from(cursor).map_err(|_| {
                            MethodError::Limit(format!(
                                "{}: level {l} needs a pointer beyond 4 GiB",
                                path.display()
                            ))
                        })?;
                        buf.extend_from_slice(&p.to_le_bytes());
                    }
                }
                left_in_group -= 1;
                encode_node(n, colors, &mut buf);
                if n.children > 0 {
                    next.push(n.children | (((!n.all_leaves) as u8) << 3));
                    cursor += child_group_bytes(n, nb);
                }
                if buf.len() >= 1 << 16 {
                    sum.write(&buf);
                    out.write_all(&buf).map_err(io)?;
                    written += buf.len() as u64;
                    buf.clear();
                }
            }
            Ok(())
        })?;
        sum.write(&buf);
        out.write_all(&buf).map_err(io)?;
        written += buf.len() as u64;
        buf.clear();
        if group != groups.len() || left_in_group != 0 {
            return Err(MethodError::Bug(format!(
                "{}: level {l} has fewer nodes than its parents' children",
                path.display()
            )));
        }
        groups = next;
    }
    if written != body_len || !groups.is_empty() {
        return Err(MethodError::Limit(format!(
            "{}: wrote {written} body bytes, counted {body_len}",
            path.display()
        )));
    }
    let checksum = sum.finish();
    let mut file = out.into_inner().map_err(|e| io(e.into_error()))?;
    file.seek(std::io::SeekFrom::Start(CHECKSUM_AT as u64))
        .map_err(io)?;
    file.write_all(&checksum.to_le_bytes()).map_err(io)?;
    file.sync_all().map_err(io)?;
    drop(file);
    Ok(())
}

/// A mapped, validated `.qs` file.
pub struct QsFile {
    map: memmap2::Mmap,
    /// The header.
    pub header: Header,
    /// The file's path (for errors).
    pub path: PathBuf,
}

impl QsFile {
    /// Maps and validates `path`.
    pub fn open(path: &Path) -> Result<Self, MethodError> {
        let file = std::fs::File::open(path).map_err(|e| MethodError::io(path, e))?;
        let map = scenes::os::map_readonly(&file).map_err(|e| MethodError::io(path, e))?;
        let header = parse_header(path, &map)?;
        let f = Self {
            map,
            header,
            path: path.to_path_buf(),
        };
        walk(&f.path, &f.header, f.body(), |_, _| {})?;
        Ok(f)
    }
    /// The body (groups of nodes).
    pub fn body(&self) -> &[u8] {
        self.map.get(HEADER_BYTES..).unwrap_or(&[])
    }
    /// Decodes the whole tree (for tests and tools).
    pub fn read_tree(&self) -> Result<QTree, MethodError> {
        let mut levels: Vec<Vec<QNode>> = Vec::new();
        walk(&self.path, &self.header, self.body(), |l, n| {
            if levels.len() <= l {
                levels.resize_with(l + 1, Vec::new);
            }
            levels[l].push(*n);
        })?;
        Ok(QTree {
            levels,
            root: self.header.root,
            normals: self.header.flags & FLAG_NORMALS != 0,
            colors: self.header.flags & FLAG_COLORS != 0,
        })
    }
}

fn parse_header(path: &Path, b: &[u8]) -> Result<Header, MethodError> {
    let bad = |m: String| MethodError::corrupt(path, m);
    if b.len() < HEADER_BYTES {
        return Err(bad(format!(
            "{} bytes, shorter than the {HEADER_BYTES}-byte header",
            b.len()
        )));
    }
    if b[..8] != MAGIC {
        return Err(bad("bad magic (not a QSplat file)".into()));
    }
    let r32 = |at| read_u32(b, at).unwrap_or(0);
    let r64 = |at| read_u64(b, at).unwrap_or(0);
    let version = r32(8);
    if version != VERSION {
        return Err(bad(format!(
            "version {version} (this build reads {VERSION})"
        )));
    }
    let h = Header {
        flags: r32(12),
        nodes: r64(16),
        leaves: r64(24),
        pointers: r64(32),
        levels: r32(40),
        table_entries: r32(44),
        root: [48, 52, 56, 60].map(|at| read_f32(b, at).unwrap_or(f32::NAN)),
        body_len: r64(64),
    };
    let actual = (b.len() - HEADER_BYTES) as u64;
    if h.body_len != actual {
        return Err(bad(format!(
            "body is {actual} bytes, header says {} (truncated?)",
            h.body_len
        )));
    }
    let sum = Fnv64::default()
        .write(&b[..CHECKSUM_AT])
        .write(&b[HEADER_BYTES..])
        .finish();
    if sum != r64(CHECKSUM_AT) {
        return Err(bad(format!(
            "checksum mismatch (stored {:016x}, computed {sum:016x})",
            r64(CHECKSUM_AT)
        )));
    }
    if h.table_entries as usize != quant::sphere_table().entries.len() {
        return Err(bad(format!(
            "written with a {}-entry sphere table, this build has {}",
            h.table_entries,
            quant::sphere_table().entries.len()
        )));
    }
    if h.flags & !(FLAG_NORMALS | FLAG_COLORS) != 0 {
        return Err(bad(format!("unknown flags {:#x}", h.flags)));
    }
    if !h.root.iter().all(|v| v.is_finite()) || h.root[3] < 0.0 {
        return Err(bad(format!("bad root sphere {:?}", h.root)));
    }
    Ok(h)
}

/// Walks every group breadth-first, validating the layout, and calls `visit(level, node)`
/// for each node in file order.
fn walk(
    path: &Path,
    h: &Header,
    body: &[u8],
    mut visit: impl FnMut(usize, &QNode),
) -> Result<(), MethodError> {
    let bad = |m: String| MethodError::corrupt(path, m);
    let nb = h.node_bytes();
    let colors = h.flags & FLAG_COLORS != 0;
    let table = quant::sphere_table().entries.len() as u16;
    // (offset, count, has pointer, children must be leaves)
    let mut groups: Vec<(usize, usize, bool, bool)> = vec![(0, 1, h.nodes > 1, false)];
    let mut cursor = nb + 4 * (h.nodes > 1) as usize;
    let (mut nodes, mut leaves, mut pointers, mut levels) = (0u64, 0u64, 0u64, 0u32);
    let mut index = 0u64;
    while !groups.is_empty() {
        let mut next = Vec::new();
        for &(off, count, has_ptr, leaves_only) in &groups {
            let mut p = off;
            if has_ptr {
                let ptr = read_u32(body, p)
                    .ok_or_else(|| bad(format!("pointer at body byte {p} past the end")))?;
                if ptr as usize != cursor {
                    return Err(bad(format!(
                        "pointer at body byte {p} is {ptr}, expected {cursor}"
                    )));
                }
                pointers += 1;
                p += 4;
            }
            let mut any_children = false;
            for _ in 0..count {
                let w = read_u32(body, p)
                    .ok_or_else(|| bad(format!("node {index} at body byte {p} past the end")))?;
                let mut n = unpack(w);
                if colors {
                    n.color = read_u16(body, p + 4).ok_or_else(|| {
                        bad(format!(
                            "node {index} colour at body byte {} past the end",
                            p + 4
                        ))
                    })?;
                }
                if index > 0 && n.sphere >= table {
                    return Err(bad(format!(
                        "node {index}: sphere code {} ≥ {table}",
                        n.sphere
                    )));
                }
                if n.normal as usize >= quant::NORMAL_CODES {
                    return Err(bad(format!("node {index}: normal code {}", n.normal)));
                }
                if leaves_only && n.children > 0 {
                    return Err(bad(format!(
                        "node {index}: has children though its parent says all are leaves"
                    )));
                }
                if n.children == 0 {
                    if n.all_leaves {
                        return Err(bad(format!("node {index}: leaf flagged all-leaves")));
                    }
                    leaves += 1;
                } else {
                    any_children = true;
                    let c = n.children as usize;
                    next.push((cursor, c, !n.all_leaves, n.all_leaves));
                    cursor += c * nb + 4 * (!n.all_leaves) as usize;
                }
                visit(levels as usize, &n);
                nodes += 1;
                index += 1;
                p += nb;
            }
            if has_ptr != any_children {
                return Err(bad(format!(
                    "group at body byte {off}: pointer {} but children {}",
                    has_ptr, any_children
                )));
            }
            if nodes > h.nodes {
                return Err(bad(format!(
                    "more than the {} nodes the header says",
                    h.nodes
                )));
            }
        }
        groups = next;
        levels += 1;
    }
    if cursor as u64 != h.body_len
        || nodes != h.nodes
        || leaves != h.leaves
        || pointers != h.pointers
        || levels != h.levels
    {
        return Err(bad(format!(
            "walk found {nodes} nodes, {leaves} leaves, {pointers} pointers, {levels} levels, \
             {cursor} bytes; header says {}, {}, {}, {}, {}",
            h.nodes, h.leaves, h.pointers, h.levels, h.body_len
        )));
    }
    Ok(())
}
