//! Memory-mapped column files (`.sbc`): a point cloud stored column by column, opened as
//! [`Column::Mapped`] views into one shared memory map, so a cloud larger than RAM streams
//! through the page cache.
//!
//! # Format (version 1, all integers and floats little-endian)
//!
//! A 128-byte header, then one region per present column, each starting at a 64-byte-aligned
//! offset (so every column is aligned for its element type and for SIMD loads), in the order
//! positions, normals, colours, radii, packed with at most 63 bytes of zero padding between.
//!
//! | offset | size | field                                                              |
//! |-------:|-----:|--------------------------------------------------------------------|
//! |      0 |    8 | magic `SPLATCOL`                                                   |
//! |      8 |    4 | version `u32` = 1                                                  |
//! |     12 |    4 | attribute flags `u32`: bit 0 normals, bit 1 colours, bit 2 radii   |
//! |     16 |    8 | point count `u64` (≥ 1)                                            |
//! |     24 |   24 | origin `f64 × 3`                                                   |
//! |     48 |   12 | bounds min, local `f32 × 3`                                        |
//! |     60 |   12 | bounds max, local `f32 × 3`                                        |
//! |     72 |   32 | region offsets `u64 × 4`: positions, normals, colours, radii (0 = absent) |
//! |    104 |    8 | total file length `u64`                                            |
//! |    112 |    8 | reserved, zero                                                     |
//! |    120 |    8 | FNV-1a 64 checksum of bytes 0..120                                 |
//!
//! Regions: positions `[f32; 3]` (12 bytes/point), normals `[f32; 3]` (12), colours
//! `[u8; 3]` sRGB (3), radii `f32` (4).
//!
//! # Decisions
//! - The checksum covers the header only: `open` must stay O(1) in I/O for a 100 M-point file.
//!   The data are still checked once by [`PointCloud::new`] (finite positions, non-zero
//!   normals, positive radii), and the header's bounds must equal the bounds of the positions,
//!   which catches most corruption of the position column.
//! - [`open`] validates magic, version, checksum, flags, offsets, alignment and lengths before
//!   touching a column, and reports a [`SceneError::Format`] naming the file and what is wrong
//!   (a truncated file names the column that is cut short); it never panics.
//! - [`ColumnWriter`] streams blocks of points into a pre-sized file, each column at its
//!   offset, so a cloud larger than RAM can be written. It writes to `<path>.tmp.<pid>` (see
//!   [`temp_path`]) and renames only after the header is written and synced, so an interrupted
//!   write never leaves a file at `path` that looks complete. Dropping an unfinished writer
//!   removes the temporary file.
//! - A mapped file must not be truncated by another process while it is open (that is
//!   undefined behaviour for any memory map); files are replaced only by rename.

use std::fs::File;
use std::io::{Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::sync::Arc;

use glam::{DVec3, Vec3};

use crate::{Aabb, Attributes, Column, PointCloud, SceneError};

/// The 8 magic bytes every column file starts with.
pub const MAGIC: &[u8; 8] = b"SPLATCOL";
/// The format version this module reads and writes.
pub const VERSION: u32 = 1;
/// Header length in bytes; the first region starts here.
pub const HEADER_LEN: u64 = 128;
/// Every region starts at a multiple of this.
pub const ALIGN: u64 = 64;

const FLAG_NORMALS: u32 = 1;
const FLAG_COLORS: u32 = 2;
const FLAG_RADII: u32 = 4;
const CHECKSUM_AT: usize = 120;
/// Column names and element sizes, in region order.
const COLUMNS: [(&str, u64); 4] = [
    ("positions", 12),
    ("normals", 12),
    ("colors", 3),
    ("radii", 4),
];

/// Writes `cloud` to `path` (through a [`ColumnWriter`]); returns the bytes written.
pub fn write(path: &Path, cloud: &PointCloud) -> Result<u64, SceneError> {
    let mut w = ColumnWriter::create(path, cloud.attributes(), cloud.origin(), cloud.len() as u64)?;
    const CHUNK: usize = 1 << 20;
    let n = cloud.len();
    let mut start = 0;
    while start < n {
        let end = (start + CHUNK).min(n);
        w.push(
            &cloud.positions()[start..end],
            cloud.normals().map(|c| &c[start..end]),
            cloud.colors().map(|c| &c[start..end]),
            cloud.radii().map(|c| &c[start..end]),
        )?;
        start = end;
    }
    w.commit()
}

/// Opens a column file as a memory-mapped cloud (see the module docs for what is checked).
pub fn open(path: &Path) -> Result<PointCloud, SceneError> {
    let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
    let actual = file.metadata().map_err(|e| SceneError::io(path, e))?.len();
    if actual < HEADER_LEN {
        return Err(SceneError::format(
            path,
            format!(
                "file is {actual} bytes, shorter than the {HEADER_LEN}-byte column-file header \
                 (truncated, or not a column file)"
            ),
        ));
    }
    let map = crate::os::map_readonly(&file).map_err(|e| SceneError::io(path, e))?;
    let header = Header::parse(&map[..HEADER_LEN as usize], path)?;
    header.check_layout(actual, path)?;
    let map = Arc::new(map);
    let n = header.count as usize;
    let column = |i: usize| header.offsets[i].map(|o| (map.clone(), o as usize));
    let positions = Column::Mapped {
        map: map.clone(),
        offset: header.offsets[0].unwrap_or(HEADER_LEN) as usize,
        len: n,
    };
    let normals = column(1).map(|(map, offset)| Column::Mapped {
        map,
        offset,
        len: n,
    });
    let colors = column(2).map(|(map, offset)| Column::Mapped {
        map,
        offset,
        len: n,
    });
    let radii = column(3).map(|(map, offset)| Column::Mapped {
        map,
        offset,
        len: n,
    });
    let cloud = PointCloud::new(header.origin, positions, normals, colors, radii)
        .map_err(|e| SceneError::format(path, e.to_string()))?;
    let b = cloud.bounds();
    if b.min != header.bounds.min || b.max != header.bounds.max {
        return Err(SceneError::format(
            path,
            format!(
                "the bounds of the positions, {:?}..{:?}, differ from the header's bounds \
                 {:?}..{:?} (file corrupted?)",
                b.min, b.max, header.bounds.min, header.bounds.max
            ),
        ));
    }
    Ok(cloud)
}

/// The temporary file a [`ColumnWriter`] for `path` writes to: `path` with `.tmp.` and the
/// process id appended (`scene.sbc` → `scene.sbc.tmp.4242`), so that two processes writing
/// the same cached scene at once (parallel jobs sharing a cache) never write into one file:
/// each writes its own, and the last rename wins with identical content.
pub fn temp_path(path: &Path) -> PathBuf {
    let mut s = path.as_os_str().to_owned();
    s.push(format!(".tmp.{}", std::process::id()));
    PathBuf::from(s)
}

fn align_up(x: u64) -> u64 {
    x.div_ceil(ALIGN) * ALIGN
}

/// The decoded header.
#[derive(Debug, Clone)]
struct Header {
    attrs: Attributes,
    count: u64,
    origin: DVec3,
    bounds: Aabb,
    /// Region offsets in [`COLUMNS`] order; `None` for an absent column.
    offsets: [Option<u64>; 4],
    file_len: u64,
}

impl Header {
    /// The layout of a file with these attributes and this count (bounds left empty).
    fn layout(attrs: Attributes, origin: DVec3, count: u64) -> Option<Header> {
        let present = [true, attrs.normals, attrs.colors, attrs.radii];
        let mut offsets = [None; 4];
        let mut end = HEADER_LEN;
        for (i, &(_, size)) in COLUMNS.iter().enumerate() {
            if present[i] {
                let start = align_up(end);
                offsets[i] = Some(start);
                end = start.checked_add(count.checked_mul(size)?)?;
            }
        }
        Some(Header {
            attrs,
            count,
            origin,
            bounds: Aabb::EMPTY,
            offsets,
            file_len: end,
        })
    }

    fn encode(&self) -> [u8; HEADER_LEN as usize] {
        let mut h = [0u8; HEADER_LEN as usize];
        let mut at = 0;
        let mut put = |bytes: &[u8]| {
            h[at..at + bytes.len()].copy_from_slice(bytes);
            at += bytes.len();
        };
        put(MAGIC);
        put(&VERSION.to_le_bytes());
        let flags = (self.attrs.normals as u32 * FLAG_NORMALS)
            | (self.attrs.colors as u32 * FLAG_COLORS)
            | (self.attrs.radii as u32 * FLAG_RADII);
        put(&flags.to_le_bytes());
        put(&self.count.to_le_bytes());
        for v in self.origin.to_array() {
            put(&v.to_le_bytes());
        }
        for v in self
            .bounds
            .min
            .to_array()
            .into_iter()
            .chain(self.bounds.max.to_array())
        {
            put(&v.to_le_bytes());
        }
        for o in self.offsets {
            put(&o.unwrap_or(0).to_le_bytes());
        }
        put(&self.file_len.to_le_bytes());
        put(&0u64.to_le_bytes());
        let sum = crate::hash::fnv1a64(&h[..CHECKSUM_AT]);
        h[CHECKSUM_AT..].copy_from_slice(&sum.to_le_bytes());
        h
    }

    fn parse(h: &[u8], path: &Path) -> Result<Header, SceneError> {
        let bad = |msg: String| SceneError::format(path, msg);
        let u32_at = |at: usize| u32::from_le_bytes([h[at], h[at + 1], h[at + 2], h[at + 3]]);
        let u64_at = |at: usize| {
            let mut b = [0u8; 8];
            b.copy_from_slice(&h[at..at + 8]);
            u64::from_le_bytes(b)
        };
        let f32_at = |at: usize| f32::from_bits(u32_at(at));
        let f64_at = |at: usize| f64::from_bits(u64_at(at));
        if &h[..8] != MAGIC {
            return Err(bad(format!(
                "not a splatbench column file: magic is {:?}, expected \"SPLATCOL\"",
                String::from_utf8_lossy(&h[..8])
            )));
        }
        let version = u32_at(8);
        if version != VERSION {
            return Err(bad(format!(
                "column file version {version} is not supported (this build reads version {VERSION})"
            )));
        }
        let stored = u64_at(CHECKSUM_AT);
        let computed = crate::hash::fnv1a64(&h[..CHECKSUM_AT]);
        if stored != computed {
            return Err(bad(format!(
                "header checksum mismatch (stored {stored:#018x}, computed {computed:#018x}): \
                 the header is corrupted"
            )));
        }
        let flags = u32_at(12);
        if flags & !(FLAG_NORMALS | FLAG_COLORS | FLAG_RADII) != 0 {
            return Err(bad(format!("unknown attribute flags {flags:#x}")));
        }
        let attrs = Attributes {
            normals: flags & FLAG_NORMALS != 0,
            colors: flags & FLAG_COLORS != 0,
            radii: flags & FLAG_RADII != 0,
        };
        let count = u64_at(16);
        if count == 0 {
            return Err(bad("the header says the file holds 0 points".into()));
        }
        if usize::try_from(count).is_err() {
            return Err(bad(format!(
                "{count} points cannot be addressed on this machine"
            )));
        }
        let origin = DVec3::new(f64_at(24), f64_at(32), f64_at(40));
        let bounds = Aabb {
            min: Vec3::new(f32_at(48), f32_at(52), f32_at(56)),
            max: Vec3::new(f32_at(60), f32_at(64), f32_at(68)),
        };
        let mut offsets = [None; 4];
        for (i, o) in offsets.iter_mut().enumerate() {
            let v = u64_at(72 + 8 * i);
            *o = (v != 0).then_some(v);
        }
        Ok(Header {
            attrs,
            count,
            origin,
            bounds,
            offsets,
            file_len: u64_at(104),
        })
    }

    /// Offsets, alignment and lengths against the attributes and the real file length.
    fn check_layout(&self, actual: u64, path: &Path) -> Result<(), SceneError> {
        let bad = |msg: String| SceneError::format(path, msg);
        let present = [
            true,
            self.attrs.normals,
            self.attrs.colors,
            self.attrs.radii,
        ];
        let mut prev_end = HEADER_LEN;
        for (i, &(name, size)) in COLUMNS.iter().enumerate() {
            let Some(off) = self.offsets[i] else {
                if present[i] {
                    return Err(bad(format!("the flags declare {name} but its offset is 0")));
                }
                continue;
            };
            if !present[i] {
                return Err(bad(format!(
                    "the flags do not declare {name} but the header gives it an offset"
                )));
            }
            if off % ALIGN != 0 || off < prev_end {
                return Err(bad(format!(
                    "the {name} region offset {off} is not {ALIGN}-byte aligned after byte {prev_end}"
                )));
            }
            let end = self
                .count
                .checked_mul(size)
                .and_then(|b| b.checked_add(off))
                .ok_or_else(|| bad(format!("the {name} region overflows a 64-bit offset")))?;
            if end > actual {
                return Err(bad(format!(
                    "truncated: the {name} column needs bytes {off}..{end} ({} points × {size} \
                     bytes) but the file is only {actual} bytes long",
                    self.count
                )));
            }
            prev_end = end;
        }
        if self.file_len != actual || prev_end != actual {
            return Err(bad(format!(
                "the file is {actual} bytes but the header says {} and its columns end at {prev_end}",
                self.file_len
            )));
        }
        Ok(())
    }
}

/// Streams a point cloud into a column file block by block (see the module docs).
///
/// ```no_run
/// # use scenes::{colfile::ColumnWriter, Attributes};
/// # fn main() -> Result<(), scenes::SceneError> {
/// let attrs = Attributes { normals: true, ..Attributes::default() };
/// let mut w = ColumnWriter::create("big.sbc".as_ref(), attrs, glam::DVec3::ZERO, 2)?;
/// w.push(&[[0.0, 0.0, 0.0]], Some(&[[0.0, 0.0, 1.0]]), None, None)?;
/// w.push(&[[1.0, 0.0, 0.0]], Some(&[[0.0, 0.0, 1.0]]), None, None)?;
/// let cloud = w.finish()?; // memory-mapped
/// # Ok(()) }
/// ```
#[derive(Debug)]
pub struct ColumnWriter {
    path: PathBuf,
    tmp: PathBuf,
    /// `None` once finished (the Drop impl then leaves the files alone).
    file: Option<File>,
    header: Header,
    written: u64,
}

/// Refuses to start a file of `bytes` where the file system holding `path` has less room:
/// the file is sparse until written, so without this a 100-billion-point scene would fill
/// the disk at write speed before failing. Where the free space cannot be read (not unix,
/// or the call fails) the write goes ahead and fails as the OS says.
pub(crate) fn check_free_space(path: &Path, bytes: u64) -> Result<(), SceneError> {
    #[cfg(unix)]
    {
        let dir = match path.parent() {
            Some(d) if !d.as_os_str().is_empty() => d,
            _ => Path::new("."),
        };
        if let Ok(st) = rustix::fs::statvfs(dir) {
            let free = st.f_bavail.saturating_mul(st.f_frsize);
            if bytes > free {
                return Err(SceneError::format(
                    path,
                    format!(
                        "needs {bytes} bytes ({:.1} GiB) and {} has {free} free ({:.1} GiB)",
                        bytes as f64 / f64::from(1u32 << 30),
                        dir.display(),
                        free as f64 / f64::from(1u32 << 30)
                    ),
                ));
            }
        }
    }
    #[cfg(not(unix))]
    let _ = (path, bytes);
    Ok(())
}

impl ColumnWriter {
    /// Creates `<path>.tmp`, sized for `count` points with the columns `attrs` declares,
    /// after checking that the file system has room for it ([`check_free_space`]).
    pub fn create(
        path: &Path,
        attrs: Attributes,
        origin: DVec3,
        count: u64,
    ) -> Result<ColumnWriter, SceneError> {
        if count == 0 {
            return Err(SceneError::format(
                path,
                "a column file needs at least one point",
            ));
        }
        if !origin.is_finite() {
            return Err(SceneError::format(
                path,
                format!("origin {origin} is not finite"),
            ));
        }
        let header = Header::layout(attrs, origin, count).ok_or_else(|| {
            SceneError::format(path, format!("{count} points overflow a 64-bit file size"))
        })?;
        let tmp = temp_path(path);
        check_free_space(path, header.file_len)?;
        let file = File::create(&tmp).map_err(|e| SceneError::io(&tmp, e))?;
        let mut w = ColumnWriter {
            path: path.to_path_buf(),
            tmp,
            file: Some(file),
            header,
            written: 0,
        };
        let len = w.header.file_len;
        w.file_mut()?
            .set_len(len)
            .map_err(|e| SceneError::io(&w.tmp, e))?;
        Ok(w)
    }

    /// Points pushed so far.
    pub fn written(&self) -> u64 {
        self.written
    }

    /// The final path (the file exists there only after [`finish`](Self::finish)).
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// Appends a block of points. Every optional column must be given exactly when the writer's
    /// attributes declare it, with as many values as `positions`.
    pub fn push(
        &mut self,
        positions: &[[f32; 3]],
        normals: Option<&[[f32; 3]]>,
        colors: Option<&[[u8; 3]]>,
        radii: Option<&[f32]>,
    ) -> Result<(), SceneError> {
        let n = positions.len();
        let a = self.header.attrs;
        let lens = [
            Some(n),
            normals.map(<[_]>::len),
            colors.map(<[_]>::len),
            radii.map(<[_]>::len),
        ];
        let present = [true, a.normals, a.colors, a.radii];
        for (i, &(name, _)) in COLUMNS.iter().enumerate() {
            match (present[i], lens[i]) {
                (true, None) => {
                    return Err(
                        self.error(format!("push: the file has {name} but none were given"))
                    );
                }
                (false, Some(_)) => {
                    return Err(self.error(format!("push: {name} given but the file has none")));
                }
                (true, Some(l)) if l != n => {
                    return Err(self.error(format!(
                        "push: {l} {name} for {n} positions in the same block"
                    )));
                }
                _ => {}
            }
        }
        if self.written + n as u64 > self.header.count {
            return Err(self.error(format!(
                "push: {} + {n} points exceed the {} the writer was created for",
                self.written, self.header.count
            )));
        }
        let bytes: [Option<&[u8]>; 4] = [
            Some(bytemuck::cast_slice(positions)),
            normals.map(bytemuck::cast_slice),
            colors.map(bytemuck::cast_slice),
            radii.map(bytemuck::cast_slice),
        ];
        for (i, b) in bytes.iter().enumerate() {
            if let (Some(b), Some(off)) = (b, self.header.offsets[i]) {
                let at = off + self.written * COLUMNS[i].1;
                let tmp = self.tmp.clone();
                let f = self.file_mut()?;
                f.seek(SeekFrom::Start(at))
                    .and_then(|_| f.write_all(b))
                    .map_err(|e| SceneError::io(&tmp, e))?;
            }
        }
        self.header.bounds = positions
            .iter()
            .fold(self.header.bounds, |b, p| b.grow(Vec3::from(*p)));
        self.written += n as u64;
        Ok(())
    }

    /// Checks the count, writes bounds and checksum, syncs, renames `<path>.tmp` to `path` and
    /// opens the result (memory-mapped). On any error the temporary file is removed and no
    /// file is left at `path`.
    pub fn finish(mut self) -> Result<PointCloud, SceneError> {
        self.write_header()?;
        // Opened (and validated) before the rename: the map stays valid across it.
        let cloud = open(&self.tmp)?;
        self.rename()?;
        Ok(cloud)
    }

    /// Like [`finish`](Self::finish) without reopening; returns the file length.
    fn commit(mut self) -> Result<u64, SceneError> {
        self.write_header()?;
        self.rename()?;
        Ok(self.header.file_len)
    }

    fn write_header(&mut self) -> Result<(), SceneError> {
        if self.written != self.header.count {
            return Err(self.error(format!(
                "finish: {} points were written but the writer was created for {}",
                self.written, self.header.count
            )));
        }
        let h = self.header.encode();
        let tmp = self.tmp.clone();
        let f = self.file_mut()?;
        f.seek(SeekFrom::Start(0))
            .and_then(|_| f.write_all(&h))
            .and_then(|_| f.sync_all())
            .map_err(|e| SceneError::io(&tmp, e))?;
        self.file = None; // closed; the Drop impl still removes the .tmp until renamed
        Ok(())
    }

    fn rename(&mut self) -> Result<(), SceneError> {
        std::fs::rename(&self.tmp, &self.path).map_err(|e| SceneError::io(&self.path, e))?;
        self.tmp = PathBuf::new(); // renamed: nothing left to clean up
        Ok(())
    }

    fn file_mut(&mut self) -> Result<&mut File, SceneError> {
        let tmp = &self.tmp;
        self.file
            .as_mut()
            .ok_or_else(|| SceneError::format(tmp, "the column writer is already closed"))
    }

    fn error(&self, msg: String) -> SceneError {
        SceneError::format(&self.path, msg)
    }
}

impl Drop for ColumnWriter {
    fn drop(&mut self) {
        self.file = None;
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn header_round_trips_and_checksum_covers_it() {
        let a = Attributes {
            normals: true,
            colors: false,
            radii: true,
        };
        let mut h = Header::layout(a, DVec3::new(1.5, -2.0, 3.0), 10).unwrap();
        h.bounds = Aabb {
            min: Vec3::ZERO,
            max: Vec3::ONE,
        };
        assert_eq!(h.offsets, [Some(128), Some(256), None, Some(384)]);
        assert_eq!(h.file_len, 424);
        let bytes = h.encode();
        let p = Path::new("x.sbc");
        let back = Header::parse(&bytes, p).unwrap();
        assert_eq!(back.offsets, h.offsets);
        assert_eq!(back.origin, h.origin);
        assert_eq!(back.attrs, a);
        let mut bad = bytes;
        bad[20] ^= 1;
        let e = Header::parse(&bad, p).unwrap_err().to_string();
        assert!(e.contains("checksum"), "{e}");
    }
}
