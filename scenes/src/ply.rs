//! PLY reader and writer (Stanford polygon format), written for speed and precise errors.
//!
//! # What is read
//! - Formats `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0`; header lines
//!   `comment` / `obj_info` (ignored), `element NAME COUNT`, `property TYPE NAME`,
//!   `property list CTYPE ITYPE NAME`, `end_header`. Every PLY scalar type: `char`/`int8`,
//!   `uchar`/`uint8`, `short`/`int16`, `ushort`/`uint16`, `int`/`int32`, `uint`/`uint32`,
//!   `float`/`float32`, `double`/`float64`. Elements other than `vertex` and `face` (`edge`,
//!   `material`, …) are skipped in all three formats, list properties included; elements after
//!   the last one needed are not read at all.
//! - `vertex`: `x`, `y`, `z` (required, any numeric type, read as `f64`); `nx`, `ny`, `nz`
//!   (optional, renormalised; if any is zero or not finite the column is dropped with a
//!   warning naming the count and the first such vertex — with faces, normals are then
//!   derived from them as below; see [`read_noted`]);
//!   colour from `red`/`green`/`blue`, else `diffuse_red`/`diffuse_green`/`diffuse_blue`, else
//!   `r`/`g`/`b` (all three needed, otherwise the file has no colour): 8-bit and 32-bit integer
//!   values are clamped to 0‥255, 16-bit integer values are divided by 257 (rounded), `float`
//!   / `double` values in 0‥1 are multiplied by 255 and rounded; optional `radius`. Other vertex
//!   properties (alpha, intensity, …) are skipped.
//! - Ascii bodies hold one record per line, as every writer emits them; blank lines are
//!   skipped, `\r\n` line ends accepted.
//! - `face`: the list `vertex_indices` (or `vertex_index`), any integer count/index types.
//!   Polygons are fan-triangulated (`v0 vk vk+1`); faces with fewer than 3 indices add no
//!   triangle (some exporters write them); an index outside `0..vertex_count` is an error
//!   naming the face.
//!
//! # What is derived
//! - Origin = centre of the `f64` bounding box of all vertices; local positions =
//!   `(p − origin)` rounded to `f32`, so georeferenced files keep their precision.
//! - When the file has triangles and no normals: vertex normal = area-weighted sum of the
//!   incident face normals (the unnormalised cross products), normalised. A vertex whose sum
//!   is zero (its faces cancel) takes the normal of its largest incident face; a vertex with no
//!   incident face of non-zero area (unreferenced, or only degenerate faces) gets +Z. Never NaN.
//! - When the file has triangles and no `radius`: vertex radius = the largest minimal
//!   bounding-sphere radius of its incident triangles (QSplat's rule, so the splats of
//!   neighbouring vertices touch). A vertex with no incident triangle of non-zero size takes
//!   the median of the other vertices' radii (unreferenced vertices in meshes are leftovers;
//!   the median keeps the read O(n) where a k-nearest-neighbour search would not). Only when
//!   no vertex has a usable radius (every triangle degenerate) is
//!   [`crate::spacing::knn_spacing`] used, and a last resort of 1/1000 of the bounding-box
//!   diagonal (or 1 for a single point) keeps every radius finite and > 0.
//! - Without faces nothing is invented: a file with positions only gives a cloud with
//!   `Attributes::default()`.
//! - [`PlyOptions::sample`] = `Some(N)` resamples the triangle surface to exactly `N` points,
//!   area-weighted (CDF over triangle areas + binary search), with uniform barycentric
//!   coordinates (`√r₁` trick). Block `b` of 65 536 samples draws from
//!   `Pcg32::stream(seed, b)` (block 0 is `Pcg32::new(seed)`), so the output depends on the
//!   seed only, not on the thread count. Normal = interpolated vertex normals (renormalised)
//!   when the file has normals, else the face normal; colour interpolated when the file has
//!   colours; no radius column (downstream estimates spacing). The origin stays the centre of
//!   the vertex bounding box.
//!
//! # Errors
//! Every problem is a [`SceneError::Format`] naming the file and the header line, body line
//! (ascii; numbered from the top of the file), or element, record index and property
//! (binary): missing `ply` magic, unknown format, no `end_header`, no `vertex` element or a
//! count of 0, missing `x`/`y`/`z`, truncated data ("unexpected end of file in vertex 17 of
//! 100"), too few / too many / non-numeric values on an ascii line, negative or oversized list
//! counts, face indices out of range, non-finite coordinates. Reading never
//! panics, and no allocation is sized by a header count alone: pre-allocation is capped by
//! what the remaining file bytes can hold.
//!
//! # Speed
//! The body is streamed through a 4 MiB buffer (no memory map: the workspace denies `unsafe`).
//! A binary vertex element without list properties is decoded record by record from a
//! precomputed `(offset, type)` layout, monomorphised per endianness. Measured by criterion
//! (`cargo bench -p methods --bench kernels -- scene_io/`, figures in
//! `results/measurements/issue-2-spine.md`).
//!
//! # Writing
//! [`write()`] writes a cloud (world `double x,y,z`; `float nx,ny,nz`, `uchar red,green,blue`,
//! `float radius` only for the columns the cloud has) and [`write_mesh`] a triangle mesh, in any
//! of the three formats, through a temporary file renamed into place, so a failed write never
//! leaves a complete-looking file. Ascii output uses shortest round-trip formatting, so an
//! ascii file holds exactly the values a binary one would.

use std::fs::File;
use std::io::{self, BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};

use glam::DVec3;
use rayon::prelude::*;

use crate::rng::Pcg32;
use crate::{PointCloud, SceneError};

/// Reading options.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlyOptions {
    /// Resample the mesh surface to this many points (area-weighted, seeded). Needs faces.
    pub sample: Option<usize>,
    /// Seed for resampling.
    pub seed: u64,
}

/// The body encoding of a PLY file (for [`write()`] and [`write_mesh`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlyFormat {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl PlyFormat {
    fn header_name(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

/// Longest header line accepted (a binary file without newlines fails fast).
const MAX_HEADER_LINE: usize = 64 * 1024;
/// Largest header accepted.
const MAX_HEADER_BYTES: u64 = 1 << 20;
/// Size of the read buffer.
const READ_BUFFER: usize = 4 << 20;
/// Samples per independently seeded block when resampling.
const SAMPLE_BLOCK: usize = 1 << 16;

// ---------------------------------------------------------------------------------------------
// Header model
// ---------------------------------------------------------------------------------------------

/// A PLY scalar type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }
}

#[derive(Debug, Clone, Copy)]
enum PropType {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug)]
struct Property {
    name: String,
    ty: PropType,
}

#[derive(Debug)]
struct Element {
    name: String,
    count: u64,
    props: Vec<Property>,
}

impl Element {
    /// Record size in bytes when no property is a list.
    fn fixed_size(&self) -> Option<usize> {
        self.props.iter().try_fold(0usize, |acc, p| match p.ty {
            PropType::Scalar(s) => Some(acc + s.size()),
            PropType::List { .. } => None,
        })
    }
    /// Smallest possible record in bytes (lists empty), at least 1.
    fn min_record_bytes(&self, ascii: bool) -> u64 {
        let b: usize = if ascii {
            // Every value needs at least one character and one separator.
            2 * self.props.len()
        } else {
            self.props
                .iter()
                .map(|p| match p.ty {
                    PropType::Scalar(s) => s.size(),
                    PropType::List { count, .. } => count.size(),
                })
                .sum()
        };
        b.max(1) as u64
    }
    fn find(&self, name: &str) -> Option<usize> {
        self.props.iter().position(|p| p.name == name)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    Binary { big_endian: bool },
}

#[derive(Debug)]
struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Number of header lines (the first body line is `lines + 1`).
    lines: u64,
}

fn ferr(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::format(path, msg)
}

/// `s` shortened for an error message.
fn excerpt(s: &str) -> String {
    let mut out: String = s.chars().take(40).collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Buffered input
// ---------------------------------------------------------------------------------------------

/// A file streamed through one large buffer, handing out slices of it.
struct Input {
    file: File,
    buf: Vec<u8>,
    /// Start of the unread bytes in `buf`.
    pos: usize,
    /// End of the valid bytes in `buf`.
    end: usize,
    /// File offset of `buf[end]`.
    file_pos: u64,
    /// File length when opened.
    file_len: u64,
}

enum LineRead<T> {
    Line(T),
    Eof,
    TooLong,
}

impl Input {
    fn new(file: File, file_len: u64) -> Input {
        Input {
            file,
            buf: Vec::new(),
            pos: 0,
            end: 0,
            file_pos: 0,
            file_len,
        }
    }
    /// File offset of the next unread byte.
    fn position(&self) -> u64 {
        self.file_pos - (self.end - self.pos) as u64
    }
    /// Bytes between the next unread byte and the end of the file.
    fn remaining(&self) -> u64 {
        self.file_len.saturating_sub(self.position())
    }
    fn avail(&self) -> &[u8] {
        &self.buf[self.pos..self.end]
    }
    fn consume(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.end);
    }
    /// Makes at least `need` unread bytes available; false if the file ends first (everything
    /// left is then in the buffer). Never allocates more than the file can fill.
    fn fill(&mut self, need: usize) -> io::Result<bool> {
        if self.end - self.pos >= need {
            return Ok(true);
        }
        // Compact.
        self.buf.copy_within(self.pos..self.end, 0);
        self.end -= self.pos;
        self.pos = 0;
        // Grow geometrically (long ascii lines), never beyond what the file can fill.
        let reachable = usize::try_from(self.remaining()).unwrap_or(usize::MAX);
        if self.buf.len() < need.min(reachable) || self.buf.len() < READ_BUFFER.min(reachable) {
            let target = need
                .max(self.buf.len().saturating_mul(2))
                .max(READ_BUFFER)
                .min(reachable);
            self.buf.resize(target.max(self.buf.len()), 0);
        }
        while self.end < need && self.end < self.buf.len() {
            match self.file.read(&mut self.buf[self.end..]) {
                Ok(0) => break,
                Ok(n) => {
                    self.end += n;
                    self.file_pos += n as u64;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(self.end >= need)
    }
    /// The next `n` bytes, consumed; `None` if the file ends first.
    fn take(&mut self, n: usize) -> io::Result<Option<&[u8]>> {
        if !self.fill(n)? {
            return Ok(None);
        }
        let start = self.pos;
        self.pos += n;
        Ok(Some(&self.buf[start..start + n]))
    }
    /// Skips `n` bytes; false if the file is shorter.
    fn skip(&mut self, n: u64) -> io::Result<bool> {
        if n > self.remaining() {
            return Ok(false);
        }
        let in_buf = (self.end - self.pos) as u64;
        if n <= in_buf {
            self.pos += n as usize;
            return Ok(true);
        }
        let rest = n - in_buf;
        self.pos = 0;
        self.end = 0;
        let rest = i64::try_from(rest).map_err(|_| io::Error::other("skip too large"))?;
        self.file_pos = self.file.seek(SeekFrom::Current(rest))?;
        Ok(true)
    }
    /// The byte range in `buf` of the next line without its `\n` (a final line without one is
    /// returned too). The range is valid until the next read.
    fn next_line_range(&mut self, max: usize) -> io::Result<LineRead<std::ops::Range<usize>>> {
        let mut scanned = 0;
        loop {
            let avail = &self.buf[self.pos..self.end];
            if let Some(k) = avail[scanned..].iter().position(|&b| b == b'\n') {
                let start = self.pos;
                let len = scanned + k;
                self.pos += len + 1;
                return Ok(LineRead::Line(start..start + len));
            }
            scanned = avail.len();
            if scanned > max {
                return Ok(LineRead::TooLong);
            }
            if !self.fill(scanned + 1)? {
                if self.end == self.pos {
                    return Ok(LineRead::Eof);
                }
                let start = self.pos;
                self.pos = self.end;
                return Ok(LineRead::Line(start..self.end));
            }
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Header parsing
// ---------------------------------------------------------------------------------------------

fn parse_header(input: &mut Input, path: &Path) -> Result<Header, SceneError> {
    let mut line_no: u64 = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if input.position() > MAX_HEADER_BYTES {
            return Err(ferr(
                path,
                format!("no end_header line within the first {MAX_HEADER_BYTES} bytes"),
            ));
        }
        line_no += 1;
        let raw = match input
            .next_line_range(MAX_HEADER_LINE)
            .map_err(|e| SceneError::io(path, e))?
        {
            LineRead::Line(r) => &input.buf[r],
            LineRead::Eof if line_no == 1 => {
                return Err(ferr(
                    path,
                    "not a PLY file: the file is empty (no 'ply' magic)",
                ));
            }
            LineRead::Eof => {
                return Err(ferr(
                    path,
                    format!("the header ends at line {line_no} without an end_header line"),
                ));
            }
            LineRead::TooLong if line_no == 1 => {
                return Err(ferr(path, "not a PLY file: line 1 is not the 'ply' magic"));
            }
            LineRead::TooLong => {
                return Err(ferr(
                    path,
                    format!(
                        "line {line_no}: header line longer than {MAX_HEADER_LINE} bytes \
                         (missing end_header?)"
                    ),
                ));
            }
        };
        let Ok(text) = std::str::from_utf8(raw) else {
            return Err(if line_no == 1 {
                ferr(path, "not a PLY file: line 1 is not the 'ply' magic")
            } else {
                ferr(
                    path,
                    format!(
                        "line {line_no}: the header contains non-text bytes (missing end_header?)"
                    ),
                )
            });
        };
        let text = text.trim_end_matches('\r');
        if line_no == 1 {
            if text.trim() != "ply" {
                return Err(ferr(
                    path,
                    format!(
                        "not a PLY file: line 1 is '{}', expected the 'ply' magic",
                        excerpt(text)
                    ),
                ));
            }
            continue;
        }
        let mut toks = text.split_ascii_whitespace();
        let Some(keyword) = toks.next() else {
            continue; // blank line
        };
        match keyword {
            "comment" | "obj_info" => {}
            "format" => {
                let name = toks.next().unwrap_or("");
                let version = toks.next().unwrap_or("");
                let enc = match name {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::Binary { big_endian: false },
                    "binary_big_endian" => Encoding::Binary { big_endian: true },
                    other => {
                        return Err(ferr(
                            path,
                            format!(
                                "line {line_no}: unknown format '{}' (expected ascii, \
                                 binary_little_endian or binary_big_endian)",
                                excerpt(other)
                            ),
                        ));
                    }
                };
                if !(version == "1.0" || version == "1") {
                    return Err(ferr(
                        path,
                        format!(
                            "line {line_no}: unsupported format version '{}' (expected 1.0)",
                            excerpt(version)
                        ),
                    ));
                }
                if encoding.is_some() {
                    return Err(ferr(path, format!("line {line_no}: second 'format' line")));
                }
                encoding = Some(enc);
            }
            "element" => {
                let (Some(name), Some(count)) = (toks.next(), toks.next()) else {
                    return Err(ferr(
                        path,
                        format!("line {line_no}: expected 'element NAME COUNT'"),
                    ));
                };
                let Ok(count) = count.parse::<u64>() else {
                    return Err(ferr(
                        path,
                        format!(
                            "line {line_no}: element '{name}' has count '{}', expected a \
                             non-negative integer",
                            excerpt(count)
                        ),
                    ));
                };
                elements.push(Element {
                    name: name.to_owned(),
                    count,
                    props: Vec::new(),
                });
            }
            "property" => {
                let Some(el) = elements.last_mut() else {
                    return Err(ferr(
                        path,
                        format!("line {line_no}: 'property' before any 'element'"),
                    ));
                };
                let toks: Vec<&str> = toks.collect();
                let bad_type = |t: &str| {
                    ferr(
                        path,
                        format!(
                            "line {line_no}: unknown property type '{}' (expected char, uchar, \
                             short, ushort, int, uint, float, double or their int8…float64 names)",
                            excerpt(t)
                        ),
                    )
                };
                let prop = match toks.as_slice() {
                    ["list", ct, it, name] => {
                        let count = Scalar::parse(ct).ok_or_else(|| bad_type(ct))?;
                        let item = Scalar::parse(it).ok_or_else(|| bad_type(it))?;
                        if !count.is_integer() {
                            return Err(ferr(
                                path,
                                format!(
                                    "line {line_no}: list '{name}' has count type '{ct}', which \
                                     is not an integer type"
                                ),
                            ));
                        }
                        Property {
                            name: (*name).to_owned(),
                            ty: PropType::List { count, item },
                        }
                    }
                    [ty, name] if *ty != "list" => Property {
                        name: (*name).to_owned(),
                        ty: PropType::Scalar(Scalar::parse(ty).ok_or_else(|| bad_type(ty))?),
                    },
                    _ => {
                        return Err(ferr(
                            path,
                            format!(
                                "line {line_no}: expected 'property TYPE NAME' or 'property list \
                                 COUNT_TYPE ITEM_TYPE NAME', found '{}'",
                                excerpt(text)
                            ),
                        ));
                    }
                };
                el.props.push(prop);
            }
            "end_header" => break,
            other => {
                return Err(ferr(
                    path,
                    format!(
                        "line {line_no}: unexpected '{}' in the header (expected format, element, \
                         property, comment, obj_info or end_header; is end_header missing?)",
                        excerpt(other)
                    ),
                ));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(ferr(path, "the header has no 'format' line"));
    };
    Ok(Header {
        encoding,
        elements,
        lines: line_no,
    })
}

// ---------------------------------------------------------------------------------------------
// Scalar decoding
// ---------------------------------------------------------------------------------------------

#[inline(always)]
fn bytes_at<const N: usize>(s: &[u8], off: usize) -> [u8; N] {
    let mut a = [0u8; N];
    if let Some(src) = s.get(off..off + N) {
        a.copy_from_slice(src);
    }
    a
}

macro_rules! rd {
    ($be:expr, $t:ty, $s:expr, $off:expr) => {{
        let b = bytes_at::<{ std::mem::size_of::<$t>() }>($s, $off);
        if $be {
            <$t>::from_be_bytes(b)
        } else {
            <$t>::from_le_bytes(b)
        }
    }};
}

/// The scalar of type `ty` at `s[off..]` as `f64`.
#[inline(always)]
fn scalar_f64<const BE: bool>(s: &[u8], off: usize, ty: Scalar) -> f64 {
    match ty {
        Scalar::I8 => rd!(BE, i8, s, off) as f64,
        Scalar::U8 => rd!(BE, u8, s, off) as f64,
        Scalar::I16 => rd!(BE, i16, s, off) as f64,
        Scalar::U16 => rd!(BE, u16, s, off) as f64,
        Scalar::I32 => rd!(BE, i32, s, off) as f64,
        Scalar::U32 => rd!(BE, u32, s, off) as f64,
        Scalar::F32 => rd!(BE, f32, s, off) as f64,
        Scalar::F64 => rd!(BE, f64, s, off),
    }
}

/// An integer scalar as `i64`; floats are truncated (only integer types reach here for counts
/// and indices, which the header checks).
#[inline(always)]
fn scalar_i64<const BE: bool>(s: &[u8], off: usize, ty: Scalar) -> i64 {
    match ty {
        Scalar::I8 => rd!(BE, i8, s, off) as i64,
        Scalar::U8 => rd!(BE, u8, s, off) as i64,
        Scalar::I16 => rd!(BE, i16, s, off) as i64,
        Scalar::U16 => rd!(BE, u16, s, off) as i64,
        Scalar::I32 => rd!(BE, i32, s, off) as i64,
        Scalar::U32 => rd!(BE, u32, s, off) as i64,
        Scalar::F32 => rd!(BE, f32, s, off) as i64,
        Scalar::F64 => rd!(BE, f64, s, off) as i64,
    }
}

/// A colour channel value of type `ty` as 8 bits (see the module docs).
#[inline(always)]
fn color_u8(v: f64, ty: Scalar) -> u8 {
    let x = match ty {
        // Already an integer in 0..=255: no rounding (and no libm call) on the common path.
        Scalar::U8 => return v as u8,
        Scalar::F32 | Scalar::F64 => v * 255.0,
        Scalar::I16 | Scalar::U16 => v / 257.0,
        Scalar::I8 | Scalar::I32 | Scalar::U32 => v,
    };
    // Round half up on the clamped (non-negative) value; NaN casts to 0.
    (x.clamp(0.0, 255.0) + 0.5) as u8
}

// ---------------------------------------------------------------------------------------------
// Generic records (ascii lines, variable-size binary records)
// ---------------------------------------------------------------------------------------------

/// Why a binary record could not be read.
enum RecErr {
    Io(io::Error),
    /// The file ends inside property `prop`.
    Eof {
        prop: usize,
    },
    /// A negative list count.
    Negative {
        prop: usize,
        count: i64,
    },
    /// A list count larger than the rest of the file can hold.
    TooBig {
        prop: usize,
        count: i64,
        bytes: u64,
        left: u64,
    },
}

/// Reads one binary record of `el`: scalars into `values` (lists leave NaN), the items of list
/// property `list` (if any) into `items`.
fn read_binary_record<const BE: bool>(
    input: &mut Input,
    el: &Element,
    values: &mut [f64],
    list: Option<usize>,
    items: &mut Vec<i64>,
) -> Result<(), RecErr> {
    for (k, p) in el.props.iter().enumerate() {
        match p.ty {
            PropType::Scalar(s) => {
                let b = input
                    .take(s.size())
                    .map_err(RecErr::Io)?
                    .ok_or(RecErr::Eof { prop: k })?;
                values[k] = scalar_f64::<BE>(b, 0, s);
            }
            PropType::List { count, item } => {
                let b = input
                    .take(count.size())
                    .map_err(RecErr::Io)?
                    .ok_or(RecErr::Eof { prop: k })?;
                let n = scalar_i64::<BE>(b, 0, count);
                if n < 0 {
                    return Err(RecErr::Negative { prop: k, count: n });
                }
                let bytes = (n as u64).saturating_mul(item.size() as u64);
                if bytes > input.remaining() {
                    return Err(RecErr::TooBig {
                        prop: k,
                        count: n,
                        bytes,
                        left: input.remaining(),
                    });
                }
                let bytes = bytes as usize;
                if Some(k) == list {
                    let b = input
                        .take(bytes)
                        .map_err(RecErr::Io)?
                        .ok_or(RecErr::Eof { prop: k })?;
                    items.clear();
                    items.extend(
                        (0..n as usize).map(|j| scalar_i64::<BE>(b, j * item.size(), item)),
                    );
                } else if !input.skip(bytes as u64).map_err(RecErr::Io)? {
                    return Err(RecErr::Eof { prop: k });
                }
                values[k] = f64::NAN;
            }
        }
    }
    Ok(())
}

fn rec_err(path: &Path, el: &Element, i: u64, e: RecErr) -> SceneError {
    let what = |prop: usize| {
        el.props
            .get(prop)
            .map_or_else(String::new, |p| format!(", property '{}'", p.name))
    };
    match e {
        RecErr::Io(e) => SceneError::io(path, e),
        RecErr::Eof { prop } => ferr(
            path,
            format!(
                "unexpected end of file in {} {i} of {}{}",
                el.name,
                el.count,
                what(prop)
            ),
        ),
        RecErr::Negative { prop, count } => ferr(
            path,
            format!("{} {i}{}: negative list count {count}", el.name, what(prop)),
        ),
        RecErr::TooBig {
            prop,
            count,
            bytes,
            left,
        } => ferr(
            path,
            format!(
                "unexpected end of file in {} {i} of {}{}: list count {count} needs {bytes} \
                 bytes, only {left} remain",
                el.name,
                el.count,
                what(prop)
            ),
        ),
    }
}

/// Parses one ascii line of `el`: scalars into `values`, items of list `list` into `items`.
/// Errors are messages without the file name.
fn parse_ascii_record(
    line: &str,
    el: &Element,
    values: &mut [f64],
    list: Option<usize>,
    items: &mut Vec<i64>,
) -> Result<(), String> {
    let mut toks = line.split_ascii_whitespace();
    let mut seen = 0usize;
    let mut next = |what: &str| -> Result<&str, String> {
        seen += 1;
        toks.next()
            .ok_or_else(|| format!("too few values (property '{what}' is missing)"))
    };
    for (k, p) in el.props.iter().enumerate() {
        match p.ty {
            PropType::Scalar(_) => {
                let t = next(&p.name)?;
                values[k] = t.parse::<f64>().map_err(|_| {
                    format!("property '{}': '{}' is not a number", p.name, excerpt(t))
                })?;
            }
            PropType::List { .. } => {
                let t = next(&p.name)?;
                let n = parse_int(t).filter(|n| *n >= 0).ok_or_else(|| {
                    format!(
                        "property '{}': list count '{}' is not a non-negative integer",
                        p.name,
                        excerpt(t)
                    )
                })?;
                if Some(k) == list {
                    items.clear();
                }
                for _ in 0..n {
                    let t = next(&p.name)?;
                    if Some(k) == list {
                        let v = parse_int(t).ok_or_else(|| {
                            format!("property '{}': '{}' is not an integer", p.name, excerpt(t))
                        })?;
                        items.push(v);
                    }
                }
                values[k] = f64::NAN;
            }
        }
    }
    let extra = toks.count();
    if extra > 0 {
        return Err(format!(
            "too many values: {} found, the header declares {seen}",
            seen + extra
        ));
    }
    Ok(())
}

/// An integer token (`12`, also `12.0` as some writers emit).
fn parse_int(t: &str) -> Option<i64> {
    if let Ok(v) = t.parse::<i64>() {
        return Some(v);
    }
    let f = t.parse::<f64>().ok()?;
    (f.fract() == 0.0 && f.abs() < 9.0e15).then_some(f as i64)
}

/// The next non-blank ascii body line, with its number.
fn next_ascii_line<'a>(
    input: &'a mut Input,
    line_no: &mut u64,
    path: &Path,
) -> Result<Option<(u64, &'a str)>, SceneError> {
    loop {
        *line_no += 1;
        let n = *line_no;
        let range = match input
            .next_line_range(usize::MAX)
            .map_err(|e| SceneError::io(path, e))?
        {
            LineRead::Line(r) => r,
            LineRead::Eof | LineRead::TooLong => return Ok(None),
        };
        let Ok(text) = std::str::from_utf8(&input.buf[range.clone()]) else {
            return Err(ferr(path, format!("line {n}: not ASCII text")));
        };
        if !text.trim().is_empty() {
            // Re-slice outside the loop's conditional borrow.
            let text = std::str::from_utf8(&input.buf[range]).unwrap_or_default();
            return Ok(Some((n, text)));
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Vertices
// ---------------------------------------------------------------------------------------------

/// Which vertex properties feed which column.
struct VertexSel {
    xyz: [usize; 3],
    normal: Option<[usize; 3]>,
    color: Option<([usize; 3], [Scalar; 3])>,
    radius: Option<usize>,
}

fn select_vertex(el: &Element, path: &Path) -> Result<VertexSel, SceneError> {
    let scalar = |name: &str| -> Result<Option<(usize, Scalar)>, SceneError> {
        match el.find(name) {
            None => Ok(None),
            Some(k) => match el.props[k].ty {
                PropType::Scalar(s) => Ok(Some((k, s))),
                PropType::List { .. } => Err(ferr(
                    path,
                    format!("vertex property '{name}' is a list; expected a number"),
                )),
            },
        }
    };
    let mut xyz = [0usize; 3];
    for (slot, name) in xyz.iter_mut().zip(["x", "y", "z"]) {
        *slot = scalar(name)?
            .ok_or_else(|| {
                ferr(
                    path,
                    format!("element vertex has no property '{name}' (x, y and z are required)"),
                )
            })?
            .0;
    }
    let triple = |names: [&str; 3]| -> Result<Option<[(usize, Scalar); 3]>, SceneError> {
        let (a, b, c) = (scalar(names[0])?, scalar(names[1])?, scalar(names[2])?);
        Ok(match (a, b, c) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        })
    };
    let normal = triple(["nx", "ny", "nz"])?.map(|t| t.map(|(k, _)| k));
    let color = match triple(["red", "green", "blue"])? {
        Some(t) => Some(t),
        None => match triple(["diffuse_red", "diffuse_green", "diffuse_blue"])? {
            Some(t) => Some(t),
            None => triple(["r", "g", "b"])?,
        },
    }
    .map(|t| (t.map(|(k, _)| k), t.map(|(_, s)| s)));
    let radius = scalar("radius")?.map(|(k, _)| k);
    Ok(VertexSel {
        xyz,
        normal,
        color,
        radius,
    })
}

/// Decoded vertex columns (positions in world `f64`).
struct Vertices {
    pos: Vec<[f64; 3]>,
    normals: Option<Vec<[f32; 3]>>,
    colors: Option<Vec<[u8; 3]>>,
    radii: Option<Vec<f32>>,
    /// Vertices whose normal is zero or not finite (a placeholder stands in their place).
    bad_normals: u64,
    /// The first of them: index and normal.
    first_bad: Option<(u64, [f64; 3])>,
}

impl Vertices {
    fn with_capacity(sel: &VertexSel, cap: usize) -> Vertices {
        Vertices {
            pos: Vec::with_capacity(cap),
            normals: sel.normal.map(|_| Vec::with_capacity(cap)),
            colors: sel.color.map(|_| Vec::with_capacity(cap)),
            radii: sel.radius.map(|_| Vec::with_capacity(cap)),
            bad_normals: 0,
            first_bad: None,
        }
    }
}

/// Property values of one record, by property index.
trait Record {
    fn get(&self, k: usize) -> f64;
}

/// A record already parsed into one value per property.
struct Parsed<'a>(&'a [f64]);

impl Record for Parsed<'_> {
    #[inline(always)]
    fn get(&self, k: usize) -> f64 {
        self.0.get(k).copied().unwrap_or(f64::NAN)
    }
}

/// A fixed-size binary record and the `(offset, type)` layout of its properties.
struct Fixed<'a, const BE: bool> {
    rec: &'a [u8],
    layout: &'a [(usize, Scalar)],
}

impl<const BE: bool> Record for Fixed<'_, BE> {
    #[inline(always)]
    fn get(&self, k: usize) -> f64 {
        match self.layout.get(k) {
            Some(&(off, ty)) => scalar_f64::<BE>(self.rec, off, ty),
            None => f64::NAN,
        }
    }
}

/// Appends one vertex, reading its properties from `rec`. A zero or non-finite normal is
/// counted (the column is dropped at the end) and a placeholder keeps the columns aligned.
#[inline(always)]
fn push_vertex(out: &mut Vertices, sel: &VertexSel, rec: &impl Record) {
    let get = |k: usize| rec.get(k);
    out.pos.push(sel.xyz.map(get));
    if let (Some(idx), Some(col)) = (sel.normal, out.normals.as_mut()) {
        let n = idx.map(get);
        let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
        if l.is_finite() && l > 1e-30 {
            col.push(n.map(|c| (c / l) as f32));
        } else {
            out.bad_normals += 1;
            if out.first_bad.is_none() {
                out.first_bad = Some((out.pos.len() as u64 - 1, n));
            }
            col.push([0.0, 0.0, 1.0]);
        }
    }
    if let (Some((idx, ty)), Some(col)) = (sel.color, out.colors.as_mut()) {
        col.push([
            color_u8(get(idx[0]), ty[0]),
            color_u8(get(idx[1]), ty[1]),
            color_u8(get(idx[2]), ty[2]),
        ]);
    }
    if let (Some(k), Some(col)) = (sel.radius, out.radii.as_mut()) {
        col.push(get(k) as f32);
    }
}

fn read_vertices(
    input: &mut Input,
    header: &Header,
    el: &Element,
    sel: &VertexSel,
    line_no: &mut u64,
    path: &Path,
) -> Result<Vertices, SceneError> {
    let ascii = header.encoding == Encoding::Ascii;
    let cap = el
        .count
        .min(input.remaining() / el.min_record_bytes(ascii) + 1);
    let mut out = Vertices::with_capacity(sel, usize::try_from(cap).unwrap_or(0));
    match header.encoding {
        Encoding::Ascii => {
            let mut values = vec![0.0f64; el.props.len()];
            let mut items = Vec::new();
            for i in 0..el.count {
                let Some((n, line)) = next_ascii_line(input, line_no, path)? else {
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in vertex {i} of {}", el.count),
                    ));
                };
                parse_ascii_record(line, el, &mut values, None, &mut items)
                    .map_err(|m| ferr(path, format!("line {n} (vertex {i}): {m}")))?;
                push_vertex(&mut out, sel, &Parsed(&values));
            }
        }
        Encoding::Binary { big_endian } => match (el.fixed_size(), big_endian) {
            (Some(rs), false) => read_fixed::<false>(input, el, rs, sel, &mut out, path)?,
            (Some(rs), true) => read_fixed::<true>(input, el, rs, sel, &mut out, path)?,
            (None, false) => read_variable::<false>(input, el, sel, &mut out, path)?,
            (None, true) => read_variable::<true>(input, el, sel, &mut out, path)?,
        },
    }
    Ok(out)
}

/// The fast path: fixed-size binary records decoded from a precomputed layout.
fn read_fixed<const BE: bool>(
    input: &mut Input,
    el: &Element,
    rs: usize,
    sel: &VertexSel,
    out: &mut Vertices,
    path: &Path,
) -> Result<(), SceneError> {
    // (offset, type) of every property.
    let mut layout = Vec::with_capacity(el.props.len());
    let mut off = 0;
    for p in &el.props {
        if let PropType::Scalar(s) = p.ty {
            layout.push((off, s));
            off += s.size();
        }
    }
    let count = el.count;
    let mut i: u64 = 0;
    while i < count {
        if !input.fill(rs).map_err(|e| SceneError::io(path, e))? {
            let have = input.avail().len();
            let prop = layout
                .iter()
                .position(|(o, s)| o + s.size() > have)
                .unwrap_or(0);
            return Err(rec_err(path, el, i, RecErr::Eof { prop }));
        }
        let avail = input.avail();
        let k = ((avail.len() / rs) as u64).min(count - i) as usize;
        for rec in avail[..k * rs].chunks_exact(rs) {
            let rec = Fixed::<BE> {
                rec,
                layout: &layout,
            };
            push_vertex(out, sel, &rec);
        }
        input.consume(k * rs);
        i += k as u64;
    }
    Ok(())
}

/// Binary vertex records with list properties (rare): one property at a time.
fn read_variable<const BE: bool>(
    input: &mut Input,
    el: &Element,
    sel: &VertexSel,
    out: &mut Vertices,
    path: &Path,
) -> Result<(), SceneError> {
    let mut values = vec![0.0f64; el.props.len()];
    let mut items = Vec::new();
    for i in 0..el.count {
        read_binary_record::<BE>(input, el, &mut values, None, &mut items)
            .map_err(|e| rec_err(path, el, i, e))?;
        push_vertex(out, sel, &Parsed(&values));
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Faces and other elements
// ---------------------------------------------------------------------------------------------

/// Index of the face element's vertex index list.
fn face_list(el: &Element, path: &Path) -> Result<usize, SceneError> {
    let k = el
        .find("vertex_indices")
        .or_else(|| el.find("vertex_index"))
        .ok_or_else(|| {
            ferr(
                path,
                "element face has no list property 'vertex_indices' (or 'vertex_index')",
            )
        })?;
    match el.props[k].ty {
        PropType::List { item, .. } if item.is_integer() => Ok(k),
        PropType::List { .. } => Err(ferr(
            path,
            format!(
                "face property '{}' holds floating-point values; vertex indices must be integers",
                el.props[k].name
            ),
        )),
        PropType::Scalar(_) => Err(ferr(
            path,
            format!("face property '{}' is not a list", el.props[k].name),
        )),
    }
}

/// Fan-triangulates one face, checking its indices.
fn push_face(
    tris: &mut Vec<[u32; 3]>,
    items: &[i64],
    nverts: u64,
    face: u64,
) -> Result<(), String> {
    if let Some(bad) = items.iter().find(|&&v| v < 0 || v as u64 >= nverts) {
        return Err(format!(
            "face {face}: vertex index {bad} is out of range (the file has {nverts} vertices)"
        ));
    }
    if items.len() < 3 {
        return Ok(());
    }
    let v0 = items[0] as u32;
    for w in items[1..].windows(2) {
        tris.push([v0, w[0] as u32, w[1] as u32]);
    }
    Ok(())
}

fn read_faces(
    input: &mut Input,
    header: &Header,
    el: &Element,
    list: usize,
    nverts: u64,
    line_no: &mut u64,
    path: &Path,
) -> Result<Vec<[u32; 3]>, SceneError> {
    let ascii = header.encoding == Encoding::Ascii;
    let cap = el
        .count
        .min(input.remaining() / el.min_record_bytes(ascii) + 1);
    let mut tris = Vec::with_capacity(usize::try_from(cap).unwrap_or(0));
    let mut values = vec![0.0f64; el.props.len()];
    let mut items = Vec::new();
    for i in 0..el.count {
        match header.encoding {
            Encoding::Ascii => {
                let Some((n, line)) = next_ascii_line(input, line_no, path)? else {
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in face {i} of {}", el.count),
                    ));
                };
                parse_ascii_record(line, el, &mut values, Some(list), &mut items)
                    .map_err(|m| ferr(path, format!("line {n} (face {i}): {m}")))?;
                push_face(&mut tris, &items, nverts, i)
                    .map_err(|m| ferr(path, format!("line {n}: {m}")))?;
            }
            Encoding::Binary { big_endian } => {
                let r = if big_endian {
                    read_binary_record::<true>(input, el, &mut values, Some(list), &mut items)
                } else {
                    read_binary_record::<false>(input, el, &mut values, Some(list), &mut items)
                };
                r.map_err(|e| rec_err(path, el, i, e))?;
                push_face(&mut tris, &items, nverts, i).map_err(|m| ferr(path, m))?;
            }
        }
    }
    Ok(tris)
}

/// Skips every record of an element nobody needs.
fn skip_element(
    input: &mut Input,
    header: &Header,
    el: &Element,
    line_no: &mut u64,
    path: &Path,
) -> Result<(), SceneError> {
    match header.encoding {
        Encoding::Ascii => {
            for i in 0..el.count {
                if next_ascii_line(input, line_no, path)?.is_none() {
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in {} {i} of {}", el.name, el.count),
                    ));
                }
            }
        }
        Encoding::Binary { big_endian } => {
            if let Some(rs) = el.fixed_size() {
                let total = el.count.saturating_mul(rs as u64);
                if !input.skip(total).map_err(|e| SceneError::io(path, e))? {
                    let i = input.remaining() / (rs.max(1) as u64);
                    return Err(ferr(
                        path,
                        format!("unexpected end of file in {} {i} of {}", el.name, el.count),
                    ));
                }
            } else {
                let mut values = vec![0.0f64; el.props.len()];
                let mut items = Vec::new();
                for i in 0..el.count {
                    let r = if big_endian {
                        read_binary_record::<true>(input, el, &mut values, None, &mut items)
                    } else {
                        read_binary_record::<false>(input, el, &mut values, None, &mut items)
                    };
                    r.map_err(|e| rec_err(path, el, i, e))?;
                }
            }
        }
    }
    Ok(())
}

// ---------------------------------------------------------------------------------------------
// Reading: the entry point
// ---------------------------------------------------------------------------------------------

/// Reads a PLY file into a [`PointCloud`] (see the module docs for what is read, derived and
/// rejected). With `opts.sample = Some(N)` the triangle surface is resampled to exactly `N`
/// points. What was dropped on the way is not reported: use [`read_noted`] where a user
/// should hear of it.
pub fn read(path: &Path, opts: &PlyOptions) -> Result<PointCloud, SceneError> {
    read_noted(path, opts).map(|(cloud, _)| cloud)
}

/// [`read`], with one warning per column dropped (a normal column with a zero or non-finite
/// normal), naming the file, the count and the first such vertex.
pub fn read_noted(path: &Path, opts: &PlyOptions) -> Result<(PointCloud, Vec<String>), SceneError> {
    if opts.sample == Some(0) {
        return Err(ferr(
            path,
            "cannot resample to 0 points: the sample count must be at least 1",
        ));
    }
    let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| SceneError::io(path, e))?.len();
    let mut input = Input::new(file, file_len);
    let header = parse_header(&mut input, path)?;

    let vi = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| ferr(path, "the header declares no 'vertex' element"))?;
    let vel = &header.elements[vi];
    if vel.count == 0 {
        return Err(ferr(
            path,
            "element vertex has count 0: the file holds no points",
        ));
    }
    let sel = select_vertex(vel, path)?;
    let fi = header.elements.iter().position(|e| e.name == "face");
    let face = match fi {
        Some(fi) => Some((fi, face_list(&header.elements[fi], path)?)),
        None => None,
    };
    if face.is_some() && vel.count > u64::from(u32::MAX) {
        return Err(ferr(
            path,
            format!(
                "{} vertices with faces: at most {} vertices are supported in a mesh",
                vel.count,
                u32::MAX
            ),
        ));
    }
    if opts.sample.is_some() && face.is_none_or(|(fi, _)| header.elements[fi].count == 0) {
        return Err(ferr(
            path,
            "cannot resample the surface: the file has no faces (it is a point cloud, not a mesh)",
        ));
    }

    let mut verts = None;
    let mut tris = None;
    let mut line_no = header.lines;
    for (ei, el) in header.elements.iter().enumerate() {
        if verts.is_some() && (face.is_none() || tris.is_some()) {
            break; // the rest of the file is not needed
        }
        if ei == vi {
            verts = Some(read_vertices(
                &mut input,
                &header,
                el,
                &sel,
                &mut line_no,
                path,
            )?);
        } else if let Some((fi, list)) = face
            && ei == fi
        {
            tris = Some(read_faces(
                &mut input,
                &header,
                el,
                list,
                vel.count,
                &mut line_no,
                path,
            )?);
        } else {
            skip_element(&mut input, &header, el, &mut line_no, path)?;
        }
    }
    let mut verts = verts.ok_or_else(|| ferr(path, "the vertex element could not be read"))?;
    let tris = tris.unwrap_or_default();
    let mut warnings = Vec::new();
    if let Some((i, n)) = verts.first_bad {
        warnings.push(format!(
            "{}: normals dropped: {} of {} vertices have a zero or non-finite normal (first: \
             vertex {i}, ({}, {}, {})){}",
            path.display(),
            verts.bad_normals,
            verts.pos.len(),
            n[0],
            n[1],
            n[2],
            if tris.is_empty() {
                ""
            } else {
                "; normals are derived from the faces instead"
            }
        ));
        verts.normals = None;
    }
    Ok((assemble(path, verts, &tris, opts)?, warnings))
}

/// Maps a [`SceneError::InvalidCloud`] from validation to a format error naming the file.
fn cloud_err(path: &Path, e: SceneError) -> SceneError {
    match e {
        SceneError::InvalidCloud(m) => ferr(path, format!("invalid vertex data: {m}")),
        other => other,
    }
}

fn assemble(
    path: &Path,
    v: Vertices,
    tris: &[[u32; 3]],
    opts: &PlyOptions,
) -> Result<PointCloud, SceneError> {
    if let Some(i) = v.pos.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        let p = v.pos[i];
        return Err(ferr(
            path,
            format!(
                "vertex {i}: position ({}, {}, {}) is not finite",
                p[0], p[1], p[2]
            ),
        ));
    }
    let (lo, hi) = v
        .pos
        .par_iter()
        .fold_with(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                    [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
                )
            },
        )
        .reduce(
            || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(a, b), (c, d)| {
                (
                    [a[0].min(c[0]), a[1].min(c[1]), a[2].min(c[2])],
                    [b[0].max(d[0]), b[1].max(d[1]), b[2].max(d[2])],
                )
            },
        );
    let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
    let origin = (lo + hi) * 0.5;

    if let Some(n) = opts.sample {
        return sample_surface(path, &v, tris, origin, n, opts.seed);
    }

    let o = origin;
    let local: Vec<[f32; 3]> = v
        .pos
        .par_iter()
        .map(|p| {
            [
                (p[0] - o.x) as f32,
                (p[1] - o.y) as f32,
                (p[2] - o.z) as f32,
            ]
        })
        .collect();
    let Vertices {
        pos,
        normals,
        colors,
        radii,
        ..
    } = v;
    let (normals, radii) = if tris.is_empty() {
        (normals, radii)
    } else {
        let normals = match normals {
            Some(n) => n,
            None => mesh_normals(&pos, tris),
        };
        let radii = match radii {
            Some(r) => r,
            None => mesh_radii(&pos, tris, &local, (hi - lo).length()),
        };
        (Some(normals), Some(radii))
    };
    drop(pos);
    PointCloud::new(
        origin,
        local.into(),
        normals.map(Into::into),
        colors.map(Into::into),
        radii.map(Into::into),
    )
    .map_err(|e| cloud_err(path, e))
}

// ---------------------------------------------------------------------------------------------
// Mesh-derived attributes
// ---------------------------------------------------------------------------------------------

#[inline(always)]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// `v / |v|` as `f32`, or `None` for a zero / non-finite vector.
#[inline(always)]
fn unit_f32(v: [f64; 3]) -> Option<[f32; 3]> {
    let l = dot(v, v).sqrt();
    if !(l.is_finite() && l > 0.0) {
        return None;
    }
    let n = v.map(|c| (c / l) as f32);
    let l2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    (l2.is_finite() && l2 > 0.5).then_some(n)
}

/// Twice the area vector of triangle `t` (winding order `a → b → c`).
#[inline(always)]
fn tri_cross(pos: &[[f64; 3]], t: [u32; 3]) -> [f64; 3] {
    let a = pos[t[0] as usize];
    cross(sub(pos[t[1] as usize], a), sub(pos[t[2] as usize], a))
}

/// Area-weighted vertex normals (see the module docs for the fallbacks).
fn mesh_normals(pos: &[[f64; 3]], tris: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut sum = vec![[0.0f64; 3]; pos.len()];
    for &t in tris {
        let c = tri_cross(pos, t);
        for &v in &t {
            let s = &mut sum[v as usize];
            s[0] += c[0];
            s[1] += c[1];
            s[2] += c[2];
        }
    }
    let mut normals: Vec<Option<[f32; 3]>> = sum.par_iter().map(|s| unit_f32(*s)).collect();
    drop(sum);
    if normals.iter().any(Option::is_none) {
        // Faces that cancel: take the largest incident face's normal.
        let mut best = vec![0.0f64; pos.len()];
        let mut best_n: Vec<Option<[f32; 3]>> = vec![None; pos.len()];
        for &t in tris {
            if t.iter().all(|&v| normals[v as usize].is_some()) {
                continue;
            }
            let c = tri_cross(pos, t);
            let a = dot(c, c);
            for &v in &t {
                let v = v as usize;
                if normals[v].is_none()
                    && a > best[v]
                    && let Some(n) = unit_f32(c)
                {
                    best[v] = a;
                    best_n[v] = Some(n);
                }
            }
        }
        for (n, b) in normals.iter_mut().zip(best_n) {
            if n.is_none() {
                *n = b;
            }
        }
    }
    normals
        .into_iter()
        .map(|n| n.unwrap_or([0.0, 0.0, 1.0]))
        .collect()
}

/// Radius of the smallest sphere enclosing triangle `t`.
#[inline(always)]
fn tri_sphere_radius(pos: &[[f64; 3]], t: [u32; 3]) -> f64 {
    let (a, b, c) = (pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]);
    let (ab, bc, ca) = (sub(b, a), sub(c, b), sub(a, c));
    let mut e = [dot(bc, bc), dot(ca, ca), dot(ab, ab)];
    e.sort_by(f64::total_cmp);
    if e[2] >= e[0] + e[1] {
        // Right, obtuse or degenerate: the longest edge is a diameter.
        return 0.5 * e[2].sqrt();
    }
    // Acute: circumradius = |ab||bc||ca| / (2 |ab × ac|).
    let cr = cross(ab, sub(c, a));
    let denom = 2.0 * dot(cr, cr).sqrt();
    let r = (e[0] * e[1] * e[2]).sqrt() / denom;
    if r.is_finite() { r } else { 0.5 * e[2].sqrt() }
}

/// QSplat leaf radii: the largest bounding-sphere radius of the incident triangles.
fn mesh_radii(pos: &[[f64; 3]], tris: &[[u32; 3]], local: &[[f32; 3]], diag: f64) -> Vec<f32> {
    let mut r = vec![0.0f64; pos.len()];
    for &t in tris {
        let s = tri_sphere_radius(pos, t);
        for &v in &t {
            let v = v as usize;
            if s > r[v] {
                r[v] = s;
            }
        }
    }
    let ok = |x: f32| x.is_finite() && x > 0.0;
    let mut radii: Vec<f32> = r.par_iter().map(|&x| x as f32).collect();
    drop(r);
    if radii.iter().all(|&x| ok(x)) {
        return radii;
    }
    let mut good: Vec<f32> = radii.iter().copied().filter(|&x| ok(x)).collect();
    if !good.is_empty() {
        let mid = good.len() / 2;
        let (_, m, _) = good.select_nth_unstable_by(mid, f32::total_cmp);
        let median = *m;
        for x in &mut radii {
            if !ok(*x) {
                *x = median;
            }
        }
        return radii;
    }
    // Every triangle is degenerate: nearest-neighbour spacing, then a fraction of the extent.
    let knn = crate::spacing::knn_spacing(local, 1);
    let last = if diag.is_finite() && diag > 0.0 {
        (diag * 1e-3) as f32
    } else {
        1.0
    };
    let last = if ok(last) { last } else { 1.0 };
    for (i, x) in radii.iter_mut().enumerate() {
        if !ok(*x) {
            *x = knn.get(i).copied().filter(|&k| ok(k)).unwrap_or(last);
        }
    }
    radii
}

// ---------------------------------------------------------------------------------------------
// Surface resampling
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Default)]
struct Sample {
    p: [f32; 3],
    n: [f32; 3],
    c: [u8; 3],
}

fn sample_surface(
    path: &Path,
    v: &Vertices,
    tris: &[[u32; 3]],
    origin: DVec3,
    count: usize,
    seed: u64,
) -> Result<PointCloud, SceneError> {
    if tris.is_empty() {
        return Err(ferr(
            path,
            "cannot resample the surface: the faces hold no triangle (every face has fewer than 3 vertices)",
        ));
    }
    let o = origin.to_array();
    // Positions relative to the origin keep the area sums well conditioned.
    let rel: Vec<[f64; 3]> = v.pos.par_iter().map(|p| sub(*p, o)).collect();
    let mut cdf = Vec::with_capacity(tris.len());
    let mut total = 0.0f64;
    let mut last_positive = None;
    for (i, &t) in tris.iter().enumerate() {
        let c = tri_cross(&rel, t);
        let area = 0.5 * dot(c, c).sqrt();
        if area > 0.0 && area.is_finite() {
            total += area;
            last_positive = Some(i);
        }
        cdf.push(total);
    }
    let Some(last_positive) = last_positive.filter(|_| total.is_finite() && total > 0.0) else {
        return Err(ferr(
            path,
            "cannot resample the surface: every triangle has zero area",
        ));
    };
    let mut out = vec![Sample::default(); count];
    out.par_chunks_mut(SAMPLE_BLOCK)
        .enumerate()
        .for_each(|(b, chunk)| {
            let mut rng = Pcg32::stream(seed, b as u64);
            for s in chunk {
                let u = rng.f64() * total;
                let ti = cdf.partition_point(|&c| c <= u).min(last_positive);
                let t = tris[ti];
                let r1 = rng.f64();
                let r2 = rng.f64();
                let sq = r1.sqrt();
                let w = [1.0 - sq, sq * (1.0 - r2), sq * r2];
                let (a, bb, c) = (rel[t[0] as usize], rel[t[1] as usize], rel[t[2] as usize]);
                let p: [f64; 3] = std::array::from_fn(|k| w[0] * a[k] + w[1] * bb[k] + w[2] * c[k]);
                s.p = p.map(|x| x as f32);
                let face_n = || unit_f32(tri_cross(&rel, t)).unwrap_or([0.0, 0.0, 1.0]);
                s.n = match &v.normals {
                    Some(n) => {
                        let (na, nb, nc) = (n[t[0] as usize], n[t[1] as usize], n[t[2] as usize]);
                        let m: [f64; 3] = std::array::from_fn(|k| {
                            w[0] * f64::from(na[k])
                                + w[1] * f64::from(nb[k])
                                + w[2] * f64::from(nc[k])
                        });
                        unit_f32(m).unwrap_or_else(face_n)
                    }
                    None => face_n(),
                };
                if let Some(col) = &v.colors {
                    let (ca, cb, cc) = (col[t[0] as usize], col[t[1] as usize], col[t[2] as usize]);
                    s.c = std::array::from_fn(|k| {
                        (w[0] * f64::from(ca[k])
                            + w[1] * f64::from(cb[k])
                            + w[2] * f64::from(cc[k]))
                        .round()
                        .clamp(0.0, 255.0) as u8
                    });
                }
            }
        });
    let positions: Vec<[f32; 3]> = out.par_iter().map(|s| s.p).collect();
    let normals: Vec<[f32; 3]> = out.par_iter().map(|s| s.n).collect();
    let colors: Option<Vec<[u8; 3]>> = v
        .colors
        .as_ref()
        .map(|_| out.par_iter().map(|s| s.c).collect());
    drop(out);
    PointCloud::new(
        origin,
        positions.into(),
        Some(normals.into()),
        colors.map(Into::into),
        None,
    )
    .map_err(|e| cloud_err(path, e))
}

// ---------------------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------------------

static TEMP_COUNTER: AtomicU64 = AtomicU64::new(0);

/// Writes `path` through a temporary file in the same directory that is renamed into place
/// only after `write` succeeded and the data was flushed; on failure the temporary file is
/// removed and `path` is untouched. Returns the size of the written file.
pub(crate) fn write_atomically(
    path: &Path,
    write: impl FnOnce(File) -> Result<(), SceneError>,
) -> Result<u64, SceneError> {
    let name = path
        .file_name()
        .ok_or_else(|| ferr(path, "the output path has no file name"))?;
    let dir = match path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let mut tmp_name = std::ffi::OsString::from(".");
    tmp_name.push(name);
    tmp_name.push(format!(
        ".{}.{}.tmp",
        std::process::id(),
        TEMP_COUNTER.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = dir.join(tmp_name);
    let result = (|| {
        let file = File::create(&tmp).map_err(|e| SceneError::io(path, e))?;
        write(file)?;
        let len = std::fs::metadata(&tmp)
            .map_err(|e| SceneError::io(path, e))?
            .len();
        std::fs::rename(&tmp, path).map_err(|e| SceneError::io(path, e))?;
        Ok(len)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

/// Flushes a buffered file to disk, reporting errors against `path`.
pub(crate) fn finish(w: BufWriter<File>, path: &Path) -> Result<(), SceneError> {
    let file = w
        .into_inner()
        .map_err(|e| SceneError::io(path, e.into_error()))?;
    file.sync_data().map_err(|e| SceneError::io(path, e))
}

/// Appends `v` in the chosen byte order.
trait PutBytes {
    fn put(self, out: &mut Vec<u8>, big_endian: bool);
}
macro_rules! put_impl {
    ($($t:ty),*) => {$(
        impl PutBytes for $t {
            #[inline(always)]
            fn put(self, out: &mut Vec<u8>, big_endian: bool) {
                if big_endian {
                    out.extend_from_slice(&self.to_be_bytes());
                } else {
                    out.extend_from_slice(&self.to_le_bytes());
                }
            }
        }
    )*};
}
put_impl!(u8, u32, f32, f64);

/// Writes a cloud as PLY: `double x,y,z` world coordinates (origin + local), then
/// `float nx,ny,nz`, `uchar red,green,blue` and `float radius` for the columns the cloud has.
/// Returns the number of bytes written. The file appears atomically (temporary file + rename).
pub fn write(path: &Path, cloud: &PointCloud, format: PlyFormat) -> Result<u64, SceneError> {
    write_atomically(path, |file| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        let io_err = |e| SceneError::io(path, e);
        let normals = cloud.normals();
        let colors = cloud.colors();
        let radii = cloud.radii();
        let mut head = format!(
            "ply\nformat {} 1.0\ncomment written by splatbench\nelement vertex {}\n\
             property double x\nproperty double y\nproperty double z\n",
            format.header_name(),
            cloud.len()
        );
        if normals.is_some() {
            head.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        }
        if colors.is_some() {
            head.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
        }
        if radii.is_some() {
            head.push_str("property float radius\n");
        }
        head.push_str("end_header\n");
        w.write_all(head.as_bytes()).map_err(io_err)?;
        let origin = cloud.origin();
        let world = |i: usize| {
            let p = cloud.positions()[i];
            [
                origin.x + f64::from(p[0]),
                origin.y + f64::from(p[1]),
                origin.z + f64::from(p[2]),
            ]
        };
        match format {
            PlyFormat::Ascii => {
                let mut line = String::with_capacity(128);
                for i in 0..cloud.len() {
                    use std::fmt::Write as _;
                    line.clear();
                    let p = world(i);
                    let _ = write!(line, "{} {} {}", p[0], p[1], p[2]);
                    if let Some(n) = normals {
                        let _ = write!(line, " {} {} {}", n[i][0], n[i][1], n[i][2]);
                    }
                    if let Some(c) = colors {
                        let _ = write!(line, " {} {} {}", c[i][0], c[i][1], c[i][2]);
                    }
                    if let Some(r) = radii {
                        let _ = write!(line, " {}", r[i]);
                    }
                    line.push('\n');
                    w.write_all(line.as_bytes()).map_err(io_err)?;
                }
            }
            PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                let be = format == PlyFormat::BinaryBigEndian;
                let mut buf = Vec::with_capacity(1 << 20);
                for i in 0..cloud.len() {
                    for c in world(i) {
                        c.put(&mut buf, be);
                    }
                    if let Some(n) = normals {
                        for c in n[i] {
                            c.put(&mut buf, be);
                        }
                    }
                    if let Some(c) = colors {
                        buf.extend_from_slice(&c[i]);
                    }
                    if let Some(r) = radii {
                        r[i].put(&mut buf, be);
                    }
                    if buf.len() >= (1 << 20) - 64 {
                        w.write_all(&buf).map_err(io_err)?;
                        buf.clear();
                    }
                }
                w.write_all(&buf).map_err(io_err)?;
            }
        }
        finish(w, path)
    })
}

/// Writes a triangle mesh as PLY: `double x,y,z` vertices (world coordinates) and faces as
/// `list uchar int vertex_indices`. Every index must be below `vertices_world.len()`.
/// Returns the number of bytes written. The file appears atomically (temporary file + rename).
pub fn write_mesh(
    path: &Path,
    vertices_world: &[[f64; 3]],
    faces: &[[u32; 3]],
    format: PlyFormat,
) -> Result<u64, SceneError> {
    let n = vertices_world.len();
    if let Some((i, f)) = faces
        .iter()
        .enumerate()
        .find(|(_, f)| f.iter().any(|&v| v as usize >= n))
    {
        return Err(ferr(
            path,
            format!("cannot write face {i} {f:?}: there are only {n} vertices"),
        ));
    }
    if u32::try_from(n).is_err() || i32::try_from(n).is_err() {
        return Err(ferr(
            path,
            format!("{n} vertices do not fit 'int' face indices"),
        ));
    }
    write_atomically(path, |file| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        let io_err = |e| SceneError::io(path, e);
        let head = format!(
            "ply\nformat {} 1.0\ncomment written by splatbench\nelement vertex {n}\n\
             property double x\nproperty double y\nproperty double z\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            format.header_name(),
            faces.len()
        );
        w.write_all(head.as_bytes()).map_err(io_err)?;
        match format {
            PlyFormat::Ascii => {
                for p in vertices_world {
                    writeln!(w, "{} {} {}", p[0], p[1], p[2]).map_err(io_err)?;
                }
                for f in faces {
                    writeln!(w, "3 {} {} {}", f[0], f[1], f[2]).map_err(io_err)?;
                }
            }
            PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                let be = format == PlyFormat::BinaryBigEndian;
                let mut buf = Vec::with_capacity(1 << 16);
                for p in vertices_world {
                    for c in p {
                        c.put(&mut buf, be);
                    }
                    if buf.len() >= (1 << 16) - 32 {
                        w.write_all(&buf).map_err(io_err)?;
                        buf.clear();
                    }
                }
                for f in faces {
                    3u8.put(&mut buf, be);
                    for &v in f {
                        v.put(&mut buf, be);
                    }
                    if buf.len() >= (1 << 16) - 32 {
                        w.write_all(&buf).map_err(io_err)?;
                        buf.clear();
                    }
                }
                w.write_all(&buf).map_err(io_err)?;
            }
        }
        finish(w, path)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_radius_of_right_and_equilateral_triangles() {
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        let r = tri_sphere_radius(&pos, [0, 1, 2]);
        assert!((r - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        let h = 3.0f64.sqrt() / 2.0;
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, h, 0.0]];
        let r = tri_sphere_radius(&pos, [0, 1, 2]);
        assert!((r - 1.0 / 3.0f64.sqrt()).abs() < 1e-12, "{r}");
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!((tri_sphere_radius(&pos, [0, 1, 2]) - 1.0).abs() < 1e-12);
    }

    #[test]
    fn color_conversion() {
        assert_eq!(color_u8(200.0, Scalar::U8), 200);
        assert_eq!(color_u8(1.0, Scalar::F32), 255);
        assert_eq!(color_u8(0.5, Scalar::F64), 128);
        assert_eq!(color_u8(65535.0, Scalar::U16), 255);
        assert_eq!(color_u8(-3.0, Scalar::I32), 0);
        assert_eq!(color_u8(f64::NAN, Scalar::F32), 0);
    }
}
