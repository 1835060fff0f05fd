//! The chunk store shared by the out-of-core methods (LPC, MWKD): each chunk (an LPC cloud,
//! an MWKD node) is encoded by its method, LZO-compressed ([`lzo1x`]) and appended to one
//! repository file with a checksum of the stored bytes; the index (kept by the method) holds a
//! [`ChunkRef`] per chunk. Reading maps the repository, checks bounds and checksum, then
//! decompresses: a flipped byte is an error naming the chunk and the file, never garbage or a
//! panic.
//!
//! Layout of a repository file: the magic [`REPO_MAGIC`], then the stored chunks back to back
//! (offsets in [`ChunkRef::offset`]). Nothing else: the index is the method's.
//!
//! [`access`] is the data-access layer on top: a trait with "request asynchronously", "is it
//! available now" and "get it", and a local implementation that decodes on a loader thread.
//! [`chunk_header`] is the preamble both methods' chunk codecs start with.

pub mod access;
pub mod chunk_header;
pub mod records;
pub mod remote;
pub mod source;

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use memmap2::Mmap;

use crate::MethodError;

/// First bytes of a repository file.
pub const REPO_MAGIC: &[u8; 8] = b"SBREPO01";

/// Where a chunk lives in the repository and how to check it.
#[derive(
    Debug,
    Clone,
    Copy,
    PartialEq,
    Eq,
    Default,
    bytemuck::Pod,
    bytemuck::Zeroable,
    serde::Serialize,
    serde::Deserialize,
)]
#[repr(C)]
pub struct ChunkRef {
    /// Byte offset of the stored (compressed) bytes in the repository file.
    pub offset: u64,
    /// Stored (compressed) length in bytes.
    pub stored: u32,
    /// Decompressed length in bytes; bit 31 ([`VERBATIM`]) set: the chunk is stored as is,
    /// not compressed (written with [`Compression::None`]; repositories from before that
    /// option never set it, their chunks being far below 2 GiB).
    pub raw: u32,
    /// [`checksum`] of the stored bytes.
    pub checksum: u64,
}

/// [`ChunkRef::raw`]'s flag for a chunk stored without compression.
pub const VERBATIM: u32 = 1 << 31;

impl ChunkRef {
    /// The chunk's decoded length in bytes.
    pub fn raw_len(&self) -> usize {
        (self.raw & !VERBATIM) as usize
    }
    /// Whether it is stored as is (no LZO).
    pub fn is_verbatim(&self) -> bool {
        self.raw & VERBATIM != 0
    }
}

/// How a repository's chunks are stored: LZO1X-1 (the papers' choice: LPC and MWKD both
/// compress with LZO) or as is (MWKD's `lzo=false`: what §V-B's "hardly affected at all by
/// the compression" is measured against).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Compression {
    /// LZO1X-1.
    Lzo,
    /// Stored as is.
    None,
}

impl Compression {
    /// The bytes to store for `raw`.
    pub fn pack(self, raw: Vec<u8>) -> Vec<u8> {
        match self {
            Compression::Lzo => compress(&raw),
            Compression::None => raw,
        }
    }
}

/// A 64-bit checksum (four independent multiply–rotate lanes over 8-byte words, so the CPU
/// overlaps them; not cryptographic). Each lane step is a bijection of the lane state for a
/// fixed word, so any change confined to one word — in particular any single flipped byte —
/// always changes the result; other corruption goes undetected with probability ≈ 2⁻⁶⁴.
pub fn checksum(bytes: &[u8]) -> u64 {
    const K: u64 = 0x9E37_79B9_7F4A_7C15;
    let word = |w: &[u8]| {
        let mut b = [0u8; 8];
        b[..w.len()].copy_from_slice(w);
        u64::from_le_bytes(b)
    };
    let step = |h: u64, v: u64| (h ^ v).wrapping_mul(K).rotate_left(29);
    let mut lanes = [
        0x243F_6A88_85A3_08D3u64,
        0x1319_8A2E_0370_7344,
        0xA409_3822_299F_31D0,
        0x082E_FA98_EC4E_6C89,
    ];
    let mut blocks = bytes.chunks_exact(32);
    for b in &mut blocks {
        for (l, h) in lanes.iter_mut().enumerate() {
            *h = step(*h, word(&b[l * 8..l * 8 + 8]));
        }
    }
    let mut h = (bytes.len() as u64).wrapping_mul(K);
    for (l, w) in blocks.remainder().chunks(8).enumerate() {
        lanes[l] = step(lanes[l], word(w));
    }
    for lane in lanes {
        h = step(h, lane);
    }
    h ^ (h >> 32)
}

/// LZO1X-1 compression of one chunk.
pub fn compress(raw: &[u8]) -> Vec<u8> {
    lzo1x::compress(raw, lzo1x::CompressLevel::default())
}

/// Most bytes LZO1X can make of one stored byte, over a whole chunk: a run's length is
/// extended by 255 per zero byte of its instruction, and no instruction does better; the
/// constant covers the first instruction's fixed part. See [`max_raw_len`].
const LZO_MAX_RATIO: usize = 256;

/// The longest decompressed length `stored` bytes of LZO1X can have. A chunk reference
/// claiming more is corrupt: decompressing it would only allocate its claimed length (up to
/// 4 GiB, an abort when memory is short) before failing.
pub fn max_raw_len(stored: usize) -> usize {
    stored
        .saturating_mul(LZO_MAX_RATIO)
        .saturating_add(LZO_MAX_RATIO)
}

/// Decompresses `stored` into exactly `raw_len` bytes; `what` names the chunk in the error.
/// A `raw_len` more than LZO1X can make of `stored` ([`max_raw_len`]) is an error, checked
/// before anything is allocated.
pub fn decompress(stored: &[u8], raw_len: usize, what: &str) -> Result<Vec<u8>, String> {
    if raw_len > max_raw_len(stored.len()) {
        return Err(format!(
            "{what}: {raw_len} decompressed bytes claimed from {} stored bytes, more than \
             LZO can make of them (at most {})",
            stored.len(),
            max_raw_len(stored.len())
        ));
    }
    let mut out = vec![0u8; raw_len];
    lzo1x::decompress(stored, &mut out)
        .map_err(|e| format!("{what}: LZO decompression failed: {e:?}"))?;
    Ok(out)
}

/// Appends chunks to a new repository file. Written to `<path>.tmp` and renamed by
/// [`RepoWriter::finish`], so an interrupted build never leaves a repository that looks
/// complete; a writer dropped unfinished (a build that failed) removes the temporary file.
pub struct RepoWriter {
    out: BufWriter<File>,
    path: PathBuf,
    tmp: TempFile,
    offset: u64,
}

/// A temporary file removed on drop unless [`TempFile::keep`] was called.
struct TempFile(Option<PathBuf>);

impl TempFile {
    fn path(&self) -> &Path {
        self.0.as_deref().unwrap_or(Path::new(""))
    }
    /// The file is kept (it was renamed into place).
    fn keep(&mut self) {
        self.0 = None;
    }
}

impl Drop for TempFile {
    fn drop(&mut self) {
        if let Some(p) = &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

impl RepoWriter {
    /// Creates `<path>.tmp` and writes the magic.
    pub fn create(path: &Path) -> Result<Self, MethodError> {
        let tmp = scenes::colfile::temp_path(path);
        let file = File::create(&tmp).map_err(|e| MethodError::io(&tmp, e))?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        out.write_all(REPO_MAGIC)
            .map_err(|e| MethodError::io(&tmp, e))?;
        Ok(Self {
            out,
            path: path.to_owned(),
            tmp: TempFile(Some(tmp)),
            offset: REPO_MAGIC.len() as u64,
        })
    }
    /// Compresses `raw` and appends it.
    pub fn append(&mut self, raw: &[u8]) -> Result<ChunkRef, MethodError> {
        let stored = compress(raw);
        self.append_compressed(&stored, raw.len())
    }
    /// Appends `stored`, packed from `raw_len` bytes with `how` ([`Compression::pack`]).
    pub fn append_packed(
        &mut self,
        stored: &[u8],
        raw_len: usize,
        how: Compression,
    ) -> Result<ChunkRef, MethodError> {
        match how {
            Compression::Lzo => self.append_compressed(stored, raw_len),
            Compression::None if stored.len() != raw_len => Err(MethodError::Bug(format!(
                "{}: a chunk stored as is has {} bytes, not its {raw_len}",
                self.path.display(),
                stored.len()
            ))),
            Compression::None => {
                let mut r = self.append_compressed(stored, raw_len)?;
                r.raw |= VERBATIM;
                Ok(r)
            }
        }
    }
    /// Appends bytes already compressed with [`compress`] from `raw_len` bytes (lets a
    /// builder compress in parallel and write in order).
    pub fn append_compressed(
        &mut self,
        stored: &[u8],
        raw_len: usize,
    ) -> Result<ChunkRef, MethodError> {
        let too_big = |what: &str| {
            MethodError::Limit(format!(
                "{}: a chunk of {what} bytes exceeds the 2 GiB chunk limit",
                self.path.display()
            ))
        };
        let raw = u32::try_from(raw_len)
            .ok()
            .filter(|&n| n & VERBATIM == 0)
            .ok_or_else(|| too_big("raw"))?;
        let r = ChunkRef {
            offset: self.offset,
            stored: u32::try_from(stored.len()).map_err(|_| too_big("stored"))?,
            raw,
            checksum: checksum(stored),
        };
        self.out
            .write_all(stored)
            .map_err(|e| MethodError::io(self.tmp.path(), e))?;
        self.offset += stored.len() as u64;
        Ok(r)
    }
    /// Bytes written so far (magic included).
    pub fn bytes(&self) -> u64 {
        self.offset
    }
    /// Flushes, syncs and renames into place; returns the file size.
    pub fn finish(mut self) -> Result<u64, MethodError> {
        let file = self
            .out
            .into_inner()
            .map_err(|e| MethodError::io(self.tmp.path(), e.into_error()))?;
        file.sync_all()
            .map_err(|e| MethodError::io(self.tmp.path(), e))?;
        drop(file);
        std::fs::rename(self.tmp.path(), &self.path).map_err(|e| MethodError::io(&self.path, e))?;
        self.tmp.keep();
        Ok(self.offset)
    }
}

/// A repository file, memory-mapped read-only.
pub struct Repository {
    map: Mmap,
    path: PathBuf,
}

impl Repository {
    /// Maps `path` and checks its magic.
    pub fn open(path: &Path) -> Result<Self, MethodError> {
        let file = File::open(path).map_err(|e| MethodError::io(path, e))?;
        let map = scenes::os::map_readonly(&file).map_err(|e| MethodError::io(path, e))?;
        if map.len() < REPO_MAGIC.len() || &map[..REPO_MAGIC.len()] != REPO_MAGIC {
            return Err(MethodError::corrupt(
                path,
                "not a splatbench repository (bad magic)",
            ));
        }
        Ok(Self {
            map,
            path: path.to_owned(),
        })
    }
    /// The file.
    pub fn path(&self) -> &Path {
        &self.path
    }
    /// File size in bytes.
    pub fn len(&self) -> u64 {
        self.map.len() as u64
    }
    /// True if the file holds no chunk.
    pub fn is_empty(&self) -> bool {
        self.map.len() <= REPO_MAGIC.len()
    }
    /// Reads, verifies and decompresses chunk `r`; `what` names it in errors ("node 17").
    /// The mapped pages are released afterwards, so the resident set holds decoded chunks
    /// only, not the repository.
    pub fn read(&self, r: &ChunkRef, what: &str) -> Result<Vec<u8>, MethodError> {
        let span = chunk_span(r, Some(self.map.len() as u64), what)
            .map_err(|msg| MethodError::corrupt(&self.path, msg))?;
        let (start, end) = (span.start as usize, span.end as usize);
        let stored = &self.map[start..end];
        let out = unpack(stored, r, what).map_err(|msg| MethodError::corrupt(&self.path, msg));
        scenes::os::release_pages(&self.map, start, end);
        out
    }
}

/// The bytes of chunk `r` in a repository file of `len` bytes: after the magic and, when the
/// length is known, before the end (`None`: a remote file, whose range answers say where it
/// ends). The error names the chunk (`what`); the caller adds the file or URL.
pub fn chunk_span(
    r: &ChunkRef,
    len: Option<u64>,
    what: &str,
) -> Result<std::ops::Range<u64>, String> {
    let end = r.offset.checked_add(u64::from(r.stored));
    match end {
        Some(end) if r.offset >= REPO_MAGIC.len() as u64 && len.is_none_or(|l| end <= l) => {
            Ok(r.offset..end)
        }
        _ => Err(format!(
            "{what}: bytes {}..+{} lie outside the repository{}",
            r.offset,
            r.stored,
            len.map_or(String::new(), |l| format!(" ({l} bytes)"))
        )),
    }
}

/// Chunk `id`'s reference among `refs`, or [`MethodError::NoChunk`] (every source's first
/// step).
pub fn chunk_ref(refs: &[ChunkRef], id: u32) -> Result<&ChunkRef, MethodError> {
    refs.get(id as usize).ok_or(MethodError::NoChunk(id.into()))
}

/// Verifies the stored bytes of chunk `r` against its checksum and decompresses them (or,
/// for a chunk stored as is, checks their length); the error names the chunk (`what`), the
/// caller adds the file or URL.
pub fn unpack(stored: &[u8], r: &ChunkRef, what: &str) -> Result<Vec<u8>, String> {
    let sum = checksum(stored);
    if sum != r.checksum {
        return Err(format!(
            "{what}: checksum mismatch (stored {:016x}, computed {sum:016x})",
            r.checksum
        ));
    }
    if r.is_verbatim() {
        if stored.len() != r.raw_len() {
            return Err(format!(
                "{what}: stored as is in {} bytes, but {} claimed",
                stored.len(),
                r.raw_len()
            ));
        }
        return Ok(stored.to_vec());
    }
    decompress(stored, r.raw_len(), what)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checksum_sees_every_single_byte_flip() {
        let data: Vec<u8> = (0..1000u32).map(|i| (i * 7 + 3) as u8).collect();
        let h = checksum(&data);
        for i in 0..data.len() {
            for bit in [0x01u8, 0x80] {
                let mut d = data.clone();
                d[i] ^= bit;
                assert_ne!(checksum(&d), h, "flip at {i}");
            }
        }
        assert_ne!(checksum(&data[..999]), h);
    }

    /// A repository of LZO and verbatim chunks reads back every chunk exactly; a verbatim
    /// chunk's length is checked, and its flag does not count in its length.
    #[test]
    fn verbatim_and_compressed_chunks_round_trip() {
        let tmp = tempfile::tempdir().unwrap();
        let path = tmp.path().join("repo.bin");
        let chunks: Vec<Vec<u8>> = (0..6u32)
            .map(|k| (0..1000 * (k + 1)).map(|i| (i % (7 + k)) as u8).collect())
            .collect();
        let mut w = RepoWriter::create(&path).unwrap();
        let mut refs = Vec::new();
        for (k, c) in chunks.iter().enumerate() {
            let how = if k % 2 == 0 {
                Compression::Lzo
            } else {
                Compression::None
            };
            let stored = how.pack(c.clone());
            refs.push(w.append_packed(&stored, c.len(), how).unwrap());
        }
        assert!(matches!(
            w.append_packed(&[1, 2, 3], 4, Compression::None),
            Err(MethodError::Bug(_))
        ));
        w.finish().unwrap();
        let repo = Repository::open(&path).unwrap();
        for (k, (c, r)) in chunks.iter().zip(&refs).enumerate() {
            assert_eq!(r.is_verbatim(), k % 2 == 1);
            assert_eq!(r.raw_len(), c.len());
            if r.is_verbatim() {
                assert_eq!(r.stored as usize, c.len());
            } else {
                assert!((r.stored as usize) < c.len(), "these chunks compress");
            }
            assert_eq!(&repo.read(r, "chunk").unwrap(), c);
        }
        // A verbatim chunk whose stored length disagrees with its claim is an error.
        let mut bad = refs[1];
        bad.raw = (bad.raw_len() as u32 + 1) | VERBATIM;
        let e = repo.read(&bad, "node 1").unwrap_err().to_string();
        assert!(
            e.contains("node 1: stored as is in 2000 bytes, but 2001 claimed"),
            "{e}"
        );
    }

    #[test]
    fn raw_length_beyond_what_lzo_can_expand_is_an_error_before_allocating() {
        // The most compressible inputs stay within the bound.
        for n in [0usize, 1, 100, 4096, 1 << 22] {
            for fill in [0u8, 0xaa] {
                let raw = vec![fill; n];
                let stored = compress(&raw);
                assert!(
                    n <= max_raw_len(stored.len()),
                    "{n} bytes stored in {}",
                    stored.len()
                );
                assert_eq!(decompress(&stored, n, "chunk"), Ok(raw));
            }
        }
        // Found by the fuzzer (target mwkd, index.bin resealed): a reference claiming
        // ~4 GiB from a few hundred stored bytes made `vec![0; raw]` abort the process.
        let stored = compress(&[7u8; 5000]);
        let e = decompress(&stored, u32::MAX as usize, "node 3").unwrap_err();
        assert!(
            e.contains("node 3") && e.contains("more than LZO can make"),
            "{e}"
        );
    }

    #[test]
    fn repository_round_trip_and_corruption() -> Result<(), MethodError> {
        let dir = tempfile::tempdir().map_err(|e| MethodError::io("tempdir", e))?;
        let path = dir.path().join("repo.bin");
        let chunks: Vec<Vec<u8>> = (0..5u32)
            .map(|c| (0..(c * 997 + 10)).map(|i| ((i / 3) ^ c) as u8).collect())
            .collect();
        let mut w = RepoWriter::create(&path)?;
        let refs: Vec<ChunkRef> = chunks
            .iter()
            .map(|c| w.append(c))
            .collect::<Result<_, _>>()?;
        assert!(!path.exists(), "the repository appears only on finish");
        let size = w.finish()?;
        assert_eq!(
            size,
            std::fs::metadata(&path)
                .map_err(|e| MethodError::io(&path, e))?
                .len()
        );
        let repo = Repository::open(&path)?;
        for (i, (c, r)) in chunks.iter().zip(&refs).enumerate() {
            assert_eq!(&repo.read(r, &format!("chunk {i}"))?, c);
        }
        drop(repo);
        // Flip one stored byte of chunk 3: reading it names the chunk; the others still read.
        let mut bytes = std::fs::read(&path).map_err(|e| MethodError::io(&path, e))?;
        bytes[refs[3].offset as usize + 5] ^= 0x10;
        std::fs::write(&path, &bytes).map_err(|e| MethodError::io(&path, e))?;
        let repo = Repository::open(&path)?;
        let e = repo.read(&refs[3], "node 3").unwrap_err().to_string();
        assert!(e.contains("node 3") && e.contains("checksum"), "{e}");
        assert_eq!(&repo.read(&refs[2], "node 2")?, &chunks[2]);
        // A reference outside the file is an error, not a panic.
        let mut bad = refs[4];
        bad.offset = size;
        let e = repo.read(&bad, "node 4").unwrap_err().to_string();
        assert!(e.contains("outside"), "{e}");
        Ok(())
    }
}
