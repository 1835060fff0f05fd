//! Checks of a LAS / LAZ file's header fields before the `las` and `laz` crates see it.
//!
//! The crates size allocations by fields read from the file and trust them: a chunk count of
//! 2³² in a corrupted `.laz` made `laz` (`ChunkTable::read`) ask for 64 GiB and the process
//! abort ("memory allocation of … bytes failed"), which no `Result` can catch. [`check`] reads
//! those fields itself and rejects a file whose fields cannot be true of any file of its size,
//! with a [`SceneError::Format`] naming the file, the field and the byte. A field the check
//! cannot read (a file shorter than its header, say) is left to the crates, which report it
//! cleanly; the check only ever rejects, it never decodes.
//!
//! What is checked, and the rule for each:
//! - **Scale factors and offsets** (`x scale factor`, …): finite, and scale factors non-zero.
//!   A zero scale collapses every point onto the offset.
//! - **Point count × record length**: fits a 64-bit file offset (the `las` crate multiplies
//!   them unchecked). For uncompressed files the records must fit in the file after the
//!   offset to point data: a shorter file is truncated, and the error says how many whole
//!   records are there.
//! - **Trailing bytes after the point records** (uncompressed files): accepted when the
//!   header declares EVLRs (LAS 1.4) or internal waveform data (LAS 1.3+) — the bytes between
//!   the records and them are padding, which the `las` crate keeps — and when they are fewer
//!   than one record (padding some writers add). One whole record's worth or more without
//!   EVLRs is an error: that is what a header that under-counts its points looks like, and
//!   reading it would silently drop those points. Compressed files are not checked for this
//!   (their point data has no size to compare against).
//! - **The first EVLR** (LAS 1.4), which the `las` crate reads into a buffer of its declared
//!   (64-bit) size: its header and data must lie inside the file.
//! - **The laszip VLR** of a compressed file (point format with bit 7 set): each item's
//!   declared size is its type's size, and the items add up to the header's point record
//!   length (the crates size the decompression buffer from one and the records from the
//!   other).
//! - **The LAZ chunk table**, found as the `laz` crate finds it (the `i64` offset in the first 8
//!   bytes of the point data, else in the last 8 bytes of the file): when it lies inside the
//!   file, its chunk count is at most the bytes between the point data and the table plus one
//!   (every chunk but an empty last one holds at least one byte), and, for fixed-size chunks,
//!   at most ⌈points / chunk size⌉ + 1. The crate allocates 16 bytes per declared chunk.
//! - **Panics**: what the checks cannot see — a corrupted compressed chunk, on which the `laz`
//!   decoder trips its own assertions (`decoders.rs`: `sym < (1 << 16)`) — is contained by
//!   [`contained`], which turns a panic inside the crates into an error naming the file.
//! - **Layered chunks** (items of version 3 or 4, point formats 6–10): every chunk's layer
//!   sizes, which the crate allocates as read, must fit in the rest of the file. The chunks
//!   are walked as the crate reads them — the layered decoder is chosen by the first item's
//!   version whatever the compressor field says (a pointwise compressor then has no chunk
//!   table offset before the first chunk), and a chunk is first point, point count, layer
//!   sizes, layers, the next one starting where its last layer ends — with the crate's
//!   count of points per chunk: the chunk size, all points for the pointwise compressor, the
//!   table's counts for variable-size chunks (decoded with `laz`'s own `ChunkTable::read`
//!   once the count above is sane), else the count stored in the chunk.
//! - **The laszip items**: at least one byte per point (the crate splits its buffer into
//!   records of that size).

use std::fs::File;
use std::io::{Read, Seek, SeekFrom};
use std::path::Path;

use crate::SceneError;

/// `user_id` and `record_id` of the laszip VLR.
const LASZIP_USER_ID: &[u8] = b"laszip encoded";
const LASZIP_RECORD_ID: u16 = 22204;
/// Bytes of a VLR header and of an EVLR header.
const VLR_HEADER: u64 = 54;
const EVLR_HEADER: u64 = 60;
/// Bytes of the laszip VLR before its item list.
const LASZIP_FIXED: usize = 34;

/// Reads `buf.len()` bytes at `pos`; `Ok(false)` when the file ends first.
fn read_at(file: &mut File, pos: u64, buf: &mut [u8]) -> Result<bool, std::io::Error> {
    file.seek(SeekFrom::Start(pos))?;
    match file.read_exact(buf) {
        Ok(()) => Ok(true),
        Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => Ok(false),
        Err(e) => Err(e),
    }
}

fn u16_at(b: &[u8], at: usize) -> u16 {
    u16::from_le_bytes([b[at], b[at + 1]])
}
fn u32_at(b: &[u8], at: usize) -> u32 {
    let mut w = [0u8; 4];
    w.copy_from_slice(&b[at..at + 4]);
    u32::from_le_bytes(w)
}
fn u64_at(b: &[u8], at: usize) -> u64 {
    let mut w = [0u8; 8];
    w.copy_from_slice(&b[at..at + 8]);
    u64::from_le_bytes(w)
}
fn f64_at(b: &[u8], at: usize) -> f64 {
    f64::from_bits(u64_at(b, at))
}

/// A laszip item: type code, declared size, version.
#[derive(Debug, Clone, Copy)]
struct Item {
    kind: u16,
    size: u16,
    version: u16,
}

impl Item {
    /// The type's name and fixed size (`None` for extra bytes, whose size is declared).
    fn describe(self) -> Option<(&'static str, Option<u16>)> {
        Some(match self.kind {
            0 => ("Byte", None),
            6 => ("Point10", Some(20)),
            7 => ("GpsTime", Some(8)),
            8 => ("RGB12", Some(6)),
            9 => ("WavePacket13", Some(29)),
            10 => ("Point14", Some(30)),
            11 => ("RGB14", Some(6)),
            12 => ("RGBNIR14", Some(8)),
            13 => ("WavePacket14", Some(29)),
            14 => ("Byte14", None),
            _ => return None,
        })
    }
    /// Layers of the item in a layered chunk; `None` if the item is not a layered one.
    fn layers(self) -> Option<u64> {
        if !matches!(self.version, 3 | 4) {
            return None;
        }
        match self.kind {
            10 => Some(9),
            11 | 13 => Some(1),
            12 => Some(2),
            14 => Some(u64::from(self.size)),
            _ => None,
        }
    }
}

/// Runs `read` (the whole read through the `las` and `laz` crates) and turns a panic inside
/// it into a [`SceneError::Format`] naming the file and the panic's message. The crates'
/// state is dropped with the panic; nothing of it is used afterwards.
pub fn contained<T>(
    path: &Path,
    read: impl FnOnce() -> Result<T, SceneError>,
) -> Result<T, SceneError> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(read)).unwrap_or_else(|payload| {
        let msg = crate::error::panic_message(&*payload).unwrap_or_else(|| "no message".into());
        Err(SceneError::format(
            path,
            format!("the LAS/LAZ decoder failed on corrupted data ({msg})"),
        ))
    })
}

/// Checks the fields of the LAS / LAZ file at `path` that the `las` and `laz` crates allocate
/// by (see the module docs). `Ok(())` also when a field cannot be read: the crates then
/// report the file as unreadable.
pub fn check(path: &Path) -> Result<(), SceneError> {
    let io = |e| SceneError::io(path, e);
    let mut file = File::open(path).map_err(io)?;
    let len = file.metadata().map_err(io)?.len();
    let Some(h) = Header::read(&mut file).map_err(io)? else {
        return Ok(());
    };
    let mut las = LasFile { path, file, len };
    las.check_scales(&h)?;
    let end_of_points = las.end_of_points(&h)?;
    if !h.compressed {
        las.check_point_extent(&h, end_of_points)?;
    }
    if let Some(start) = h.evlr {
        las.check_first_evlr(start)?;
    }
    if !h.compressed {
        return Ok(());
    }
    las.check_compressed(&h).map(|_| ())
}

/// What a step of the check found: `Ok(None)` when a field it needs cannot be read (or is of
/// a kind the crates name themselves), which ends the check without an error and leaves the
/// file to the crates.
type Step<T> = Result<Option<T>, SceneError>;

/// The fields of the public header block the checks use.
struct Header {
    /// Scale factors and offsets of x, y, z.
    scales: [f64; 3],
    offsets: [f64; 3],
    /// Where the VLRs start: the header's declared size, at least its version's size.
    vlr_start: u64,
    offset_to_points: u64,
    vlr_count: u32,
    /// Point format bit 7: laszip-compressed point data.
    compressed: bool,
    record_len: u16,
    /// The point count (the 64-bit one of LAS 1.4 when the legacy field is 0).
    points: u64,
    /// Start of the first EVLR, when LAS 1.4 declares any.
    evlr: Option<u64>,
    /// Start of internal waveform data, when LAS 1.3+ declares it.
    waveform: Option<u64>,
}

impl Header {
    /// Reads the header from the start of `file`; `None` when the file is not LAS or is
    /// shorter than its version's header.
    fn read(file: &mut File) -> Result<Option<Header>, std::io::Error> {
        let mut h = Vec::with_capacity(375);
        file.take(375).read_to_end(&mut h)?;
        let got = h.len();
        h.resize(375, 0);
        if got < 227 || &h[..4] != b"LASF" {
            return Ok(None);
        }
        let version = (h[24], h[25]);
        let v13 = version >= (1, 3);
        let v14 = version >= (1, 4);
        if v14 && got < 375 || v13 && got < 235 {
            return Ok(None);
        }
        let header_size = u64::from(u16_at(&h, 94));
        let version_header = if v14 {
            375
        } else if v13 {
            235
        } else {
            227
        };
        let legacy_points = u64::from(u32_at(&h, 107));
        let points = if legacy_points == 0 && v14 {
            u64_at(&h, 247)
        } else {
            legacy_points
        };
        // The EVLRs (1.4) and internal waveform data (1.3+).
        let evlr = if v14 {
            let start = u64_at(&h, 235);
            let count = u32_at(&h, 243);
            (start > 0 && count > 0).then_some(start)
        } else {
            None
        };
        let waveform = if v13 {
            Some(u64_at(&h, 227)).filter(|&w| w > 0)
        } else {
            None
        };
        Ok(Some(Header {
            scales: std::array::from_fn(|i| f64_at(&h, 131 + 8 * i)),
            offsets: std::array::from_fn(|i| f64_at(&h, 155 + 8 * i)),
            vlr_start: header_size.max(version_header),
            offset_to_points: u64::from(u32_at(&h, 96)),
            vlr_count: u32_at(&h, 100),
            compressed: h[104] & 0x80 != 0,
            record_len: u16_at(&h, 105),
            points,
            evlr,
            waveform,
        }))
    }
}

/// The laszip VLR's fields the checks use.
struct Laszip {
    /// Byte of the file the VLR (its header) starts at.
    at: u64,
    compressor: u16,
    /// Points per chunk; `None` for variable-size chunks.
    chunk_size: Option<u64>,
    items: Vec<Item>,
}

impl Laszip {
    /// Parses the VLR's data (`at`: where the VLR starts); `None` when it is too short for
    /// the item list it declares.
    fn parse(at: u64, data: &[u8]) -> Option<Laszip> {
        if data.len() < LASZIP_FIXED {
            return None;
        }
        let chunk_size = match u32_at(data, 12) {
            0 | u32::MAX => None,
            n => Some(u64::from(n)),
        };
        let n_items = usize::from(u16_at(data, 32));
        if data.len() < LASZIP_FIXED + 6 * n_items {
            return None;
        }
        let items = (0..n_items)
            .map(|k| {
                let at = LASZIP_FIXED + 6 * k;
                Item {
                    kind: u16_at(data, at),
                    size: u16_at(data, at + 2),
                    version: u16_at(data, at + 4),
                }
            })
            .collect();
        Some(Laszip {
            at,
            compressor: u16_at(data, 0),
            chunk_size,
            items,
        })
    }

    /// Compressors 2 and 3 (pointwise and layered chunked) have a chunk table and start the
    /// point data with its offset; 1 (pointwise) has neither.
    fn chunked(&self) -> bool {
        matches!(self.compressor, 2 | 3)
    }
}

/// The open file under check, with what every step needs to read it and to name it in an
/// error.
struct LasFile<'a> {
    path: &'a Path,
    file: File,
    /// The file's length in bytes.
    len: u64,
}

impl LasFile<'_> {
    /// A [`SceneError::Format`] naming the file.
    fn bad(&self, msg: String) -> SceneError {
        SceneError::format(self.path, msg)
    }

    /// [`read_at`] on the file, its I/O errors naming the file.
    fn read_at(&mut self, pos: u64, buf: &mut [u8]) -> Result<bool, SceneError> {
        read_at(&mut self.file, pos, buf).map_err(|e| SceneError::io(self.path, e))
    }

    /// Scale factors and offsets: finite, and scale factors non-zero.
    fn check_scales(&self, h: &Header) -> Result<(), SceneError> {
        for (i, axis) in ["x", "y", "z"].into_iter().enumerate() {
            let scale = h.scales[i];
            let offset = h.offsets[i];
            if scale == 0.0 {
                return Err(self.bad(format!(
                    "{axis} scale factor is 0 (header byte {}): every point would collapse onto \
                     the offset",
                    131 + 8 * i
                )));
            }
            if !scale.is_finite() {
                return Err(self.bad(format!(
                    "{axis} scale factor is {scale} (header byte {}), not a finite number",
                    131 + 8 * i
                )));
            }
            if !offset.is_finite() {
                return Err(self.bad(format!(
                    "{axis} offset is {offset} (header byte {}), not a finite number",
                    155 + 8 * i
                )));
            }
        }
        Ok(())
    }

    /// Point count × record length: the byte the point records end at, which must fit a
    /// 64-bit file offset.
    fn end_of_points(&self, h: &Header) -> Result<u64, SceneError> {
        let (points, record_len) = (h.points, h.record_len);
        let point_bytes = points.checked_mul(u64::from(record_len));
        let end_of_points = point_bytes.and_then(|b| b.checked_add(h.offset_to_points));
        end_of_points.ok_or_else(|| {
            self.bad(format!(
                "the header declares {points} points of {record_len} bytes: more bytes than a \
                 file can hold"
            ))
        })
    }

    /// Uncompressed point data: the records fit in the file, and no whole record's worth of
    /// undeclared bytes follows them.
    fn check_point_extent(&self, h: &Header, end_of_points: u64) -> Result<(), SceneError> {
        let (points, record_len, offset_to_points) = (h.points, h.record_len, h.offset_to_points);
        let file_len = self.len;
        if end_of_points > file_len {
            let have = file_len.saturating_sub(offset_to_points) / u64::from(record_len.max(1));
            return Err(self.bad(format!(
                "point data truncated: the header declares {points} points of {record_len} \
                 bytes from byte {offset_to_points} (to byte {end_of_points}), but the file \
                 ends at byte {file_len}: only {} of {points} points are there",
                have.min(points)
            )));
        }
        let trailing = file_len - end_of_points;
        let declared = h.evlr.is_some() || h.waveform.is_some_and(|w| w >= end_of_points);
        if !declared && record_len > 0 && trailing >= u64::from(record_len) {
            return Err(self.bad(format!(
                "{trailing} bytes follow the last of the {points} point records the header \
                 declares (from byte {end_of_points} to the end, {} records' worth) and the \
                 header declares no EVLRs: the point count is likely wrong",
                trailing / u64::from(record_len)
            )));
        }
        Ok(())
    }

    /// The first EVLR (at byte `start`): its header and data lie inside the file.
    fn check_first_evlr(&mut self, start: u64) -> Result<(), SceneError> {
        let file_len = self.len;
        let mut e = [0u8; EVLR_HEADER as usize];
        if start
            .checked_add(EVLR_HEADER)
            .is_none_or(|end| end > file_len)
        {
            return Err(self.bad(format!(
                "the first EVLR starts at byte {start} (header byte 235), but the file is \
                 {file_len} bytes: no room for its {EVLR_HEADER}-byte header"
            )));
        }
        if self.read_at(start, &mut e)? {
            let len = u64_at(&e, 20);
            let left = file_len - start - EVLR_HEADER;
            if len > left {
                return Err(self.bad(format!(
                    "the EVLR at byte {start} declares {len} bytes of data, more than the \
                     {left} bytes left in the file"
                )));
            }
        }
        Ok(())
    }

    /// The checks of a compressed file: the laszip VLR's items, the chunk table, the layered
    /// chunks, in that order.
    fn check_compressed(&mut self, h: &Header) -> Step<()> {
        let Some(lz) = self.laszip_vlr(h)? else {
            return Ok(None);
        };
        let Some(items_size) = self.check_items(h, &lz)? else {
            return Ok(None);
        };
        let Some(entries) = self.check_chunk_table(h, &lz)? else {
            return Ok(None);
        };
        self.check_layered_chunks(h, &lz, items_size, entries.as_deref())
    }

    /// Finds and parses the laszip VLR among the header's VLRs.
    fn laszip_vlr(&mut self, h: &Header) -> Step<Laszip> {
        let mut pos = h.vlr_start;
        for _ in 0..h.vlr_count {
            let mut v = [0u8; VLR_HEADER as usize];
            if !self.read_at(pos, &mut v)? {
                return Ok(None);
            }
            let user = &v[2..18];
            let user = &user[..user.iter().position(|&b| b == 0).unwrap_or(16)];
            let id = u16_at(&v, 18);
            let len = u16_at(&v, 20);
            if user == LASZIP_USER_ID && id == LASZIP_RECORD_ID {
                let mut data = vec![0u8; usize::from(len)];
                if !self.read_at(pos + VLR_HEADER, &mut data)? {
                    return Ok(None);
                }
                return Ok(Laszip::parse(pos, &data));
            }
            pos += VLR_HEADER + u64::from(len);
        }
        Ok(None)
    }

    /// The laszip items: each of its type's size, together the header's point record
    /// length, and not 0 bytes. Returns the bytes per point.
    fn check_items(&self, h: &Header, lz: &Laszip) -> Step<u64> {
        let (vlr_at, record_len, n_items) = (lz.at, h.record_len, lz.items.len());
        let mut items_size: u64 = 0;
        for (k, item) in lz.items.iter().enumerate() {
            let Some((name, fixed)) = item.describe() else {
                return Ok(None); // an unknown item type: the crate names it
            };
            if let Some(fixed) = fixed
                && item.size != fixed
            {
                return Err(self.bad(format!(
                    "the laszip VLR (at byte {vlr_at}) declares item {k} ({name}) as {} bytes; \
                     the type has {fixed}",
                    item.size
                )));
            }
            items_size += u64::from(item.size);
        }
        if items_size != u64::from(record_len) {
            return Err(self.bad(format!(
                "the laszip VLR (at byte {vlr_at}) lists {n_items} items of {items_size} bytes \
                 per point, but the header's point record length is {record_len} bytes"
            )));
        }
        if items_size == 0 {
            return Err(self.bad(format!(
                "the laszip VLR (at byte {vlr_at}) lists {n_items} items of 0 bytes per point"
            )));
        }
        Ok(Some(items_size))
    }

    /// The LAZ chunk table, found as the `laz` crate finds it: its chunk count fits the point
    /// data before it and, for fixed-size chunks, the point count. Returns the table's
    /// entries — how many points each chunk holds — when the chunks are of variable size and
    /// the table decodes (decoded as the crate decodes them, once their count is known to be
    /// sane).
    fn check_chunk_table(&mut self, h: &Header, lz: &Laszip) -> Step<Option<Vec<u64>>> {
        let (points, file_len) = (h.points, self.len);
        let data_start = h.offset_to_points;
        let mut w = [0u8; 8];
        if !self.read_at(data_start, &mut w)? {
            return Ok(None);
        }
        let mut table = i64::from_le_bytes(w);
        let mut table_field = data_start;
        if table <= data_start as i64 {
            // As the crate does: a writer that could not seek back stores it at the end.
            if file_len < 8 || !self.read_at(file_len - 8, &mut w)? {
                return Ok(None);
            }
            table = i64::from_le_bytes(w);
            table_field = file_len - 8;
        }
        let mut entries: Option<Vec<u64>> = None;
        if lz.chunked() && table > data_start as i64 {
            let table = table as u64;
            let mut t = [0u8; 8];
            if table.checked_add(8).is_some_and(|e| e <= file_len) && self.read_at(table, &mut t)? {
                let chunks = u64::from(u32_at(&t, 4));
                let room = table.saturating_sub(data_start + 8);
                if chunks > room + 1 {
                    return Err(self.bad(format!(
                        "LAZ chunk table at byte {table} (offset read at byte {table_field}) \
                         claims {chunks} chunks, more than the {room} bytes of point data \
                         before it can hold (the file is {file_len} bytes)"
                    )));
                }
                if let Some(cs) = lz.chunk_size {
                    let most = points.div_ceil(cs) + 1;
                    if chunks > most {
                        return Err(self.bad(format!(
                            "LAZ chunk table at byte {table} claims {chunks} chunks, but \
                             {points} points in chunks of {cs} need at most {most}"
                        )));
                    }
                } else {
                    self.file
                        .seek(SeekFrom::Start(table))
                        .map_err(|e| SceneError::io(self.path, e))?;
                    let mut src = std::io::BufReader::new(&mut self.file);
                    if let Ok(t) = laz::laszip::ChunkTable::read(&mut src, true) {
                        entries = Some(t.as_ref().iter().map(|e| e.point_count).collect());
                    }
                }
            }
        }
        Ok(Some(entries))
    }

    /// Layered chunks: the layer sizes the crate allocates as it reads them. The crate picks
    /// the layered decoder by the first item's version, whatever the compressor, reads the
    /// chunks one after the other (a chunk ends where its last layer does), and counts a
    /// chunk's points as below (the count stored in the chunk only without a table).
    fn check_layered_chunks(
        &mut self,
        h: &Header,
        lz: &Laszip,
        items_size: u64,
        entries: Option<&[u64]>,
    ) -> Step<()> {
        let layered = lz.items.first().is_some_and(|i| matches!(i.version, 3 | 4));
        let Some(layers) = lz
            .items
            .iter()
            .map(|i| i.layers())
            .try_fold(0u64, |acc, l| l.map(|l| acc + l))
            .filter(|_| layered)
        else {
            return Ok(None); // pointwise items, or items the layered decoder refuses
        };
        let points_in = |chunk: usize, stored: u64| -> u64 {
            match (lz.chunk_size, entries) {
                _ if lz.compressor == 1 => u64::from(u32::MAX),
                (Some(cs), _) => cs,
                (None, Some(e)) => e.get(chunk).copied().unwrap_or(u64::MAX),
                (None, None) => stored,
            }
        };
        let file_len = self.len;
        let mut pos = h.offset_to_points + if lz.chunked() { 8 } else { 0 };
        let mut left = h.points;
        let mut chunk = 0usize;
        let mut sizes = vec![0u8; 4 * layers as usize];
        while left > 0 {
            let sizes_at = pos + items_size + 4;
            let mut c = [0u8; 4];
            if !self.read_at(pos + items_size, &mut c)? || !self.read_at(sizes_at, &mut sizes)? {
                return Ok(None);
            }
            let mut at = sizes_at + 4 * layers;
            for (l, s) in sizes.chunks_exact(4).enumerate() {
                let size = u64::from(u32_at(s, 0));
                let rest = file_len.saturating_sub(at);
                if size > rest {
                    return Err(self.bad(format!(
                        "LAZ chunk {chunk} (at byte {pos}): layer {l} declares {size} bytes, \
                         more than the {rest} bytes left in the file"
                    )));
                }
                at += size;
            }
            // A chunk of 0 points never ends: the crate reads every point left from it.
            let n = points_in(chunk, u64::from(u32_at(&c, 0)));
            left = left.saturating_sub(if n == 0 { u64::MAX } else { n });
            pos = at;
            chunk += 1;
        }
        Ok(Some(()))
    }
}
