//! Spill files: the temporary files of an out-of-core build, written once in blocks and read
//! back block by block, with every block's length and checksum kept in memory by the writer.
//!
//! Contract:
//! - [`SpillWriter::push`] appends one fixed-size record; a block is written when it holds
//!   the writer's block size (whole records), its [`crate::store::checksum`] kept in the returned
//!   [`Spill`]. Nothing about the contents is stored in the file itself.
//! - [`Spill::read`] checks the file's length first, then each block's checksum, and hands
//!   whole blocks (whole records) to the caller. A missing, short, long or altered file is
//!   [`MethodError::Corrupt`] naming the file and the block, never a panic and never wrong
//!   data passed on.
//! - Files live in a [`SpillDir`], a directory created inside the build's output directory
//!   (so they sit on the disk the user chose for the output) and removed with everything in
//!   it when the `SpillDir` is dropped, on success and on error alike.

pub mod samples;
pub mod split;

use std::fs::File;
use std::io::{Read, Write};
use std::path::{Path, PathBuf};

use crate::MethodError;
use crate::store::checksum;

/// Where and within how much memory a build in units works.
#[derive(Clone, Copy)]
pub struct Budget<'a> {
    /// Working memory in bytes.
    pub mem_bytes: u64,
    /// Where the spill directory is made (the build directory).
    pub dir: &'a Path,
    /// Called with the units' sample files once they are written, and by a build that
    /// writes more files per unit (QSplat's partitions) with those too (tests damage them to
    /// check the errors).
    pub hook: Option<SpillHook<'a>>,
}

/// Called with the units' sample files of a build in units.
pub type SpillHook<'a> = &'a dyn Fn(&[&Spill]);

/// Bytes per block (rounded down to whole records).
pub const BLOCK_BYTES: usize = 1 << 20;

/// A directory of spill files, removed on drop.
#[derive(Debug)]
pub struct SpillDir {
    path: PathBuf,
    next: std::sync::atomic::AtomicU64,
}

impl SpillDir {
    /// Creates `<parent>/<name>.tmp` (emptied first if a crashed build left it).
    pub fn create(parent: &Path, name: &str) -> Result<Self, MethodError> {
        let path = parent.join(format!("{name}.tmp"));
        if path.exists() {
            std::fs::remove_dir_all(&path).map_err(|e| MethodError::io(&path, e))?;
        }
        std::fs::create_dir_all(&path).map_err(|e| MethodError::io(&path, e))?;
        Ok(Self {
            path,
            next: std::sync::atomic::AtomicU64::new(0),
        })
    }

    /// The directory.
    pub fn path(&self) -> &Path {
        &self.path
    }

    /// A writer of a new file named `<stem>-<n>.bin` with records of `record` bytes, in
    /// blocks of about [`BLOCK_BYTES`].
    pub fn writer(&self, stem: &str, record: usize) -> Result<SpillWriter, MethodError> {
        self.writer_with_block(stem, record, BLOCK_BYTES)
    }

    /// [`Self::writer`] with blocks of about `block` bytes (whole records, at least one):
    /// smaller blocks for the many writers a build keeps open at once.
    pub fn writer_with_block(
        &self,
        stem: &str,
        record: usize,
        block: usize,
    ) -> Result<SpillWriter, MethodError> {
        let n = self.next.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        SpillWriter::create(&self.path.join(format!("{stem}-{n}.bin")), record, block)
    }
}

impl Drop for SpillDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.path);
    }
}

/// A spill file written: where it is and what it must hold.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Spill {
    /// The file.
    pub path: PathBuf,
    /// Bytes per record.
    pub record: usize,
    /// Records written.
    pub records: u64,
    /// Per block: length in bytes and checksum.
    pub blocks: Vec<(u32, u64)>,
}

impl Spill {
    /// Total bytes the file must hold.
    pub fn bytes(&self) -> u64 {
        self.records * self.record as u64
    }

    /// Reads the file block by block, checked, calling `f` with each block's bytes (a whole
    /// number of records).
    pub fn read(
        &self,
        mut f: impl FnMut(&[u8]) -> Result<(), MethodError>,
    ) -> Result<(), MethodError> {
        let mut r = self.reader()?;
        while let Some(block) = r.next_block()? {
            f(block)?;
        }
        Ok(())
    }

    /// A reader handing out one block or one record at a time (for merging several files);
    /// the file's length is checked here.
    pub fn reader(&self) -> Result<SpillReader<'_>, MethodError> {
        let file = File::open(&self.path).map_err(|e| MethodError::io(&self.path, e))?;
        let len = file
            .metadata()
            .map_err(|e| MethodError::io(&self.path, e))?
            .len();
        if len != self.bytes() {
            return Err(MethodError::corrupt(
                &self.path,
                format!(
                    "temporary file holds {len} bytes, {} were written",
                    self.bytes()
                ),
            ));
        }
        Ok(SpillReader {
            spill: self,
            file,
            block: 0,
            buf: Vec::new(),
            at: 0,
        })
    }

    /// Deletes the file (its space is needed no longer).
    pub fn remove(self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Reads a spill file record by record, each block checked as it is read.
pub struct SpillReader<'a> {
    spill: &'a Spill,
    file: File,
    block: usize,
    buf: Vec<u8>,
    at: usize,
}

impl SpillReader<'_> {
    /// Reads and checks the next block into the buffer; false at the end.
    fn fill(&mut self) -> Result<bool, MethodError> {
        let Some(&(n, sum)) = self.spill.blocks.get(self.block) else {
            return Ok(false);
        };
        let corrupt = |msg: String| MethodError::corrupt(&self.spill.path, msg);
        self.buf.resize(n as usize, 0);
        self.file
            .read_exact(&mut self.buf)
            .map_err(|e| corrupt(format!("temporary file, block {}: {e}", self.block)))?;
        if checksum(&self.buf) != sum {
            return Err(corrupt(format!(
                "temporary file, block {}: checksum mismatch (the file changed after it was \
                 written)",
                self.block
            )));
        }
        self.block += 1;
        self.at = 0;
        Ok(true)
    }

    /// The rest of the current block, or the next whole block; `None` at the end.
    pub fn next_block(&mut self) -> Result<Option<&[u8]>, MethodError> {
        if self.at == self.buf.len() && !self.fill()? {
            return Ok(None);
        }
        let b = &self.buf[self.at..];
        self.at = self.buf.len();
        Ok(Some(b))
    }

    /// The next record, or `None` at the end.
    pub fn next_record(&mut self) -> Result<Option<&[u8]>, MethodError> {
        if self.at == self.buf.len() && !self.fill()? {
            return Ok(None);
        }
        let r = &self.buf[self.at..self.at + self.spill.record];
        self.at += self.spill.record;
        Ok(Some(r))
    }
}

/// Appends fixed-size records to a spill file; each block is written with one `write`.
pub struct SpillWriter {
    out: File,
    spill: Spill,
    buf: Vec<u8>,
    block_bytes: usize,
}

impl SpillWriter {
    /// Creates `path` for records of `record` bytes in blocks of about `block` bytes.
    pub fn create(path: &Path, record: usize, block: usize) -> Result<Self, MethodError> {
        let out = File::create(path).map_err(|e| MethodError::io(path, e))?;
        let block_bytes = (block / record.max(1)).max(1) * record.max(1);
        Ok(Self {
            out,
            spill: Spill {
                path: path.to_owned(),
                record,
                records: 0,
                blocks: Vec::new(),
            },
            buf: Vec::with_capacity(block_bytes),
            block_bytes,
        })
    }

    /// Appends one record (exactly [`Spill::record`] bytes).
    pub fn push(&mut self, record: &[u8]) -> Result<(), MethodError> {
        debug_assert_eq!(record.len(), self.spill.record);
        self.buf.extend_from_slice(record);
        self.spill.records += 1;
        if self.buf.len() >= self.block_bytes {
            self.flush_block()?;
        }
        Ok(())
    }

    fn flush_block(&mut self) -> Result<(), MethodError> {
        if self.buf.is_empty() {
            return Ok(());
        }
        self.spill
            .blocks
            .push((self.buf.len() as u32, checksum(&self.buf)));
        self.out
            .write_all(&self.buf)
            .map_err(|e| MethodError::io(&self.spill.path, e))?;
        self.buf.clear();
        Ok(())
    }

    /// Writes the last block and closes the file.
    pub fn finish(mut self) -> Result<Spill, MethodError> {
        self.flush_block()?;
        Ok(self.spill)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn written(dir: &SpillDir, records: u32) -> Spill {
        let mut w = dir.writer("t", 12).unwrap();
        for i in 0..records {
            let mut r = [0u8; 12];
            r[..4].copy_from_slice(&i.to_le_bytes());
            w.push(&r).unwrap();
        }
        w.finish().unwrap()
    }

    #[test]
    fn round_trip_in_blocks_of_whole_records() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SpillDir::create(tmp.path(), "x").unwrap();
        let n = (BLOCK_BYTES / 12) as u32 * 2 + 5;
        let s = written(&dir, n);
        assert_eq!(s.blocks.len(), 3);
        let mut next = 0u32;
        s.read(|b| {
            assert_eq!(b.len() % 12, 0);
            for r in b.chunks_exact(12) {
                assert_eq!(u32::from_le_bytes(r[..4].try_into().unwrap()), next);
                next += 1;
            }
            Ok(())
        })
        .unwrap();
        assert_eq!(next, n);
        let path = dir.path().to_owned();
        drop(dir);
        assert!(!path.exists(), "the spill directory is removed on drop");
    }

    #[test]
    fn short_long_and_altered_files_are_errors_naming_them() {
        let tmp = tempfile::tempdir().unwrap();
        let dir = SpillDir::create(tmp.path(), "x").unwrap();
        let s = written(&dir, 1000);
        let name = s.path.display().to_string();
        let bytes = std::fs::read(&s.path).unwrap();
        let expect = |what: &str, e: MethodError| {
            let m = e.to_string();
            assert!(m.contains(&name) && m.contains(what), "{what}: {m}");
        };
        std::fs::write(&s.path, &bytes[..bytes.len() - 1]).unwrap();
        expect("11999 bytes, 12000", s.read(|_| Ok(())).unwrap_err());
        let mut long = bytes.clone();
        long.push(0);
        std::fs::write(&s.path, &long).unwrap();
        expect("12001 bytes", s.read(|_| Ok(())).unwrap_err());
        let mut flipped = bytes.clone();
        flipped[5000] ^= 0x10;
        std::fs::write(&s.path, &flipped).unwrap();
        expect(
            "block 0: checksum mismatch",
            s.read(|_| Ok(())).unwrap_err(),
        );
        std::fs::remove_file(&s.path).unwrap();
        assert!(matches!(s.read(|_| Ok(())), Err(MethodError::Io { .. })));
    }
}
