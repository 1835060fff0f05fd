//! The few things splatbench asks of the operating system beyond `std`, in one place, each
//! with a portable fallback.
//!
//! The fallbacks are compiled and tested on every platform (Linux CI included), not hidden
//! behind a `cfg` that only a Windows or macOS build would ever compile: the platform code
//! picks between the native call and the fallback, nothing else.
//!
//! - [`map_readonly`]: a read-only memory map of a file that is only ever replaced by a
//!   rename, never changed in place (column files, repositories, QSplat files).
//! - [`release_pages`]: drop the resident pages of a part of such a map (`MADV_DONTNEED`
//!   where the OS has it; elsewhere the pages stay until the OS reclaims them).
//! - [`read_exact_at`]: a positional read that needs no `&mut File` (`pread` on Unix,
//!   `seek_read` on Windows, a locked seek-and-read elsewhere).
//! - [`FileStamp`]: what tells one version of a file from another beyond its length and
//!   modification time, for caches keyed by a file.

use std::fs::{File, Metadata};
use std::io;

use memmap2::Mmap;

/// Maps `file` read-only.
///
/// Mapping is unsafe if another process truncates or rewrites the file while it is mapped:
/// every file splatbench maps is written once, to a temporary name, and renamed into place,
/// never changed in place; readers bounds-check every access against a length validated
/// when the file was opened.
#[expect(
    unsafe_code,
    reason = "memory-mapping a file is unsafe if another process truncates or rewrites it; \
              the files splatbench maps are written once through a temporary file and a \
              rename, never changed in place, and every read is bounds-checked"
)]
pub fn map_readonly(file: &File) -> io::Result<Mmap> {
    // SAFETY: see `reason` and the doc comment.
    unsafe { Mmap::map(file) }
}

/// The size of a memory page, bytes: the OS's where it says (`sysconf(_SC_PAGESIZE)`), else
/// 4096, the page of every platform splatbench runs on.
pub fn page_size() -> usize {
    #[cfg(unix)]
    {
        rustix::param::page_size()
    }
    #[cfg(not(unix))]
    {
        fallback::PAGE
    }
}

/// The page-aligned span that covers `start..end` of a map `len` bytes long, for pages of
/// `page` bytes: rounded *outwards* (the first page that holds `start`, up to the end of the
/// page that holds `end - 1`), clamped to the map. Outwards, so that after a release none of
/// the range is resident: a reader that releases what it has read holds nothing of it
/// afterwards, however small its pieces (rounded inwards, a piece smaller than a page would
/// release nothing and the whole file would stay resident). The cost is at most one page on
/// each side that a neighbour still reading must fault back from the page cache.
/// `None` when the span is empty.
pub fn page_span(start: usize, end: usize, len: usize, page: usize) -> Option<(usize, usize)> {
    let end = end.min(len);
    if end <= start {
        return None;
    }
    let first = start / page * page;
    let last = end.div_ceil(page).saturating_mul(page).min(len);
    (last > first).then_some((first, last - first))
}

/// Drops the resident pages of `start..end` of the read-only map `map` (rounded outwards to
/// whole pages: [`page_span`]). The next access reads the same bytes from the file. On a
/// platform without `madvise` the pages stay resident until the OS reclaims them; a failure
/// has the same effect and is ignored: releasing is an economy, never a correctness step.
pub fn release_pages(map: &Mmap, start: usize, end: usize) {
    let Some((offset, len)) = page_span(start, end, map.len(), page_size()) else {
        return;
    };
    #[cfg(unix)]
    unix::dont_need(map, offset, len);
    #[cfg(not(unix))]
    fallback::dont_need(map, offset, len);
}

/// Reads exactly `buf.len()` bytes of `file` at `offset`, without moving a cursor that other
/// threads share (the file is read by several threads at once).
pub fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> io::Result<()> {
    #[cfg(unix)]
    {
        std::os::unix::fs::FileExt::read_exact_at(file, buf, offset)
    }
    #[cfg(windows)]
    {
        windows::read_exact_at(file, buf, offset)
    }
    #[cfg(not(any(unix, windows)))]
    {
        fallback::read_exact_at(file, buf, offset)
    }
}

/// What a rewrite of a file cannot restore, beyond its length and modification time (which
/// `touch -d` or a copy with `-p` sets back, and which a file system may store to the second):
/// on Unix the device, the inode (a rewrite through a temporary file and a rename makes a new
/// one) and the inode's change time in nanoseconds (set by the kernel to "now" on every write
/// or metadata change, including the one that restores the mtime, and never settable by a
/// user). Elsewhere the creation time where the OS keeps it. Two stamps that are equal mean,
/// on Unix, that the file was not written between the two `stat`s, up to the clock's
/// resolution; a cache keyed by it serves stale data only if a same-length rewrite lands within
/// one tick of the file system's timestamp clock and keeps the inode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub struct FileStamp(pub [u64; 3]);

impl FileStamp {
    /// The stamp of `meta`.
    pub fn of(meta: &Metadata) -> Self {
        #[cfg(unix)]
        {
            unix::stamp(meta)
        }
        #[cfg(not(unix))]
        {
            fallback::stamp(meta)
        }
    }

    /// The stamp as bytes, for a hash.
    pub fn to_le_bytes(self) -> [u8; 24] {
        let mut out = [0u8; 24];
        for (chunk, v) in out.chunks_exact_mut(8).zip(self.0) {
            chunk.copy_from_slice(&v.to_le_bytes());
        }
        out
    }
}

#[cfg(unix)]
mod unix {
    use super::*;

    #[expect(
        unsafe_code,
        reason = "MADV_DONTNEED on a read-only shared file mapping only drops resident pages: \
                  the next access reads the same bytes from the file, so no slice borrowed \
                  from the map changes or dangles"
    )]
    pub(super) fn dont_need(map: &Mmap, offset: usize, len: usize) {
        // SAFETY: see `reason`; `page_span` keeps the span inside the map.
        let _ =
            unsafe { map.unchecked_advise_range(memmap2::UncheckedAdvice::DontNeed, offset, len) };
    }

    pub(super) fn stamp(meta: &Metadata) -> FileStamp {
        use std::os::unix::fs::MetadataExt;
        let ctime_ns = (meta.ctime() as u64)
            .wrapping_mul(1_000_000_000)
            .wrapping_add(meta.ctime_nsec() as u64);
        FileStamp([meta.dev(), meta.ino(), ctime_ns])
    }
}

#[cfg(windows)]
mod windows {
    use super::*;

    pub(super) fn read_exact_at(
        file: &File,
        mut buf: &mut [u8],
        mut offset: u64,
    ) -> io::Result<()> {
        use std::os::windows::fs::FileExt;
        while !buf.is_empty() {
            match file.seek_read(buf, offset) {
                Ok(0) => return Err(io::ErrorKind::UnexpectedEof.into()),
                Ok(n) => {
                    buf = &mut buf[n..];
                    offset += n as u64;
                }
                Err(e) if e.kind() == io::ErrorKind::Interrupted => {}
                Err(e) => return Err(e),
            }
        }
        Ok(())
    }
}

/// What a platform without the native calls gets; compiled everywhere, tested on Linux.
#[cfg_attr(unix, allow(dead_code))]
mod fallback {
    use super::*;

    /// The page size assumed where the OS is not asked.
    pub(super) const PAGE: usize = 4096;

    /// No advice: the pages stay resident until the OS reclaims them.
    pub(super) fn dont_need(_map: &Mmap, _offset: usize, _len: usize) {}

    /// A seek and a read under one process-wide lock, so that concurrent readers of one file
    /// do not move each other's cursor (`&File` shares its cursor with every clone).
    pub(super) fn read_exact_at(file: &File, buf: &mut [u8], offset: u64) -> io::Result<()> {
        use std::io::{Read, Seek, SeekFrom};
        static LOCK: std::sync::Mutex<()> = std::sync::Mutex::new(());
        let _guard = LOCK
            .lock()
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        let mut f = file;
        f.seek(SeekFrom::Start(offset))?;
        f.read_exact(buf)
    }

    /// The creation time in nanoseconds where the OS keeps it, else 0.
    pub(super) fn stamp(meta: &Metadata) -> FileStamp {
        let created = meta
            .created()
            .ok()
            .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
            .map_or(0, |d| d.as_nanos() as u64);
        FileStamp([0, 0, created])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    #[test]
    fn the_page_size_is_the_oss_and_a_power_of_two() {
        let page = page_size();
        assert!(page.is_power_of_two() && page >= 4096, "{page}");
    }

    /// Outwards to whole pages, clamped to the map; an empty or inverted range is nothing.
    #[test]
    fn a_span_covers_every_page_the_range_touches() {
        assert_eq!(page_span(0, 1, 100_000, 4096), Some((0, 4096)));
        assert_eq!(page_span(4095, 4097, 100_000, 4096), Some((0, 8192)));
        assert_eq!(page_span(4096, 8192, 100_000, 4096), Some((4096, 4096)));
        assert_eq!(page_span(5000, 5001, 100_000, 4096), Some((4096, 4096)));
        // The last page of the map is partial: the span stops at the map's end.
        assert_eq!(
            page_span(98_000, 200_000, 100_000, 4096),
            Some((94_208, 5_792))
        );
        assert_eq!(page_span(10, 10, 100_000, 4096), None);
        assert_eq!(page_span(20, 10, 100_000, 4096), None);
        assert_eq!(page_span(100_000, 100_010, 100_000, 4096), None);
        // Any page size: every byte of the range lies in the span, and the span starts and
        // ends on page boundaries (or the map's end).
        for page in [4096, 16_384, 65_536] {
            for (s, e) in [(1, 2), (4095, 70_000), (65_535, 65_537), (0, 99_999)] {
                let (o, l) = page_span(s, e, 100_000, page).unwrap();
                assert!(o <= s && o + l >= e.min(100_000), "{page} {s} {e}");
                assert!(o % page == 0 && ((o + l) % page == 0 || o + l == 100_000));
            }
        }
    }

    /// The native positional read and the fallback read the same bytes, and neither moves
    /// the other's position: interleaved reads at different offsets agree with the file.
    #[test]
    fn positional_reads_native_and_fallback_agree() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f");
        let data: Vec<u8> = (0..10_000u32).map(|i| (i * 7 % 251) as u8).collect();
        std::fs::File::create(&p).unwrap().write_all(&data).unwrap();
        let f = File::open(&p).unwrap();
        for (off, len) in [(0, 10), (9_990, 10), (1234, 4000), (5, 1)] {
            let mut a = vec![0u8; len];
            let mut b = vec![0u8; len];
            read_exact_at(&f, &mut a, off as u64).unwrap();
            fallback::read_exact_at(&f, &mut b, off as u64).unwrap();
            assert_eq!(a, data[off..off + len]);
            assert_eq!(b, data[off..off + len]);
        }
        let mut past = vec![0u8; 11];
        assert!(read_exact_at(&f, &mut past, 9_990).is_err());
        assert!(fallback::read_exact_at(&f, &mut past, 9_990).is_err());
    }

    /// Releasing pages keeps the bytes: the native release and the no-op fallback alike.
    #[test]
    fn released_pages_read_back_the_same_bytes() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f");
        let data: Vec<u8> = (0..100_000u32).map(|i| (i % 253) as u8).collect();
        std::fs::File::create(&p).unwrap().write_all(&data).unwrap();
        let map = map_readonly(&File::open(&p).unwrap()).unwrap();
        let sum: u64 = map.iter().map(|&b| b as u64).sum();
        release_pages(&map, 1000, 50_000);
        fallback::dont_need(&map, 0, 4096);
        release_pages(&map, 0, usize::MAX);
        assert_eq!(map.iter().map(|&b| b as u64).sum::<u64>(), sum);
        assert_eq!(&map[..], &data[..]);
    }

    /// A rewrite of the same length with the modification time set back changes the stamp:
    /// in place (the inode's change time moves, once the file system's timestamp clock has
    /// ticked: the test waits for the tick by watching a probe file's change time, not a
    /// clock) and through a temporary file and a rename (a new inode).
    #[test]
    fn a_same_size_rewrite_with_the_mtime_restored_changes_the_stamp() {
        let d = tempfile::tempdir().unwrap();
        let p = d.path().join("f");
        std::fs::write(&p, b"aaaa").unwrap();
        let before = std::fs::metadata(&p).unwrap();
        let mtime = before.modified().unwrap();
        let probe = d.path().join("probe");
        let ticked = (0..1_000_000).any(|_| {
            std::fs::write(&probe, b"p").unwrap();
            let m = std::fs::metadata(&probe).unwrap();
            FileStamp::of(&m).0[2] > FileStamp::of(&before).0[2]
        });
        assert!(ticked, "the file system's change time never moved");
        // In place, same length, mtime restored.
        std::fs::OpenOptions::new()
            .write(true)
            .open(&p)
            .unwrap()
            .write_all(b"bbbb")
            .unwrap();
        let f = std::fs::OpenOptions::new().write(true).open(&p).unwrap();
        f.set_modified(mtime).unwrap();
        drop(f);
        let after = std::fs::metadata(&p).unwrap();
        assert_eq!(after.len(), before.len());
        assert_eq!(after.modified().unwrap(), mtime);
        assert_ne!(FileStamp::of(&after), FileStamp::of(&before));
        // Unchanged file: the same stamp.
        assert_eq!(
            FileStamp::of(&std::fs::metadata(&p).unwrap()),
            FileStamp::of(&after)
        );
        // Through a temporary file and a rename, mtime restored: a new inode.
        let tmp = d.path().join("f.tmp");
        std::fs::write(&tmp, b"cccc").unwrap();
        let f = std::fs::OpenOptions::new().write(true).open(&tmp).unwrap();
        f.set_modified(mtime).unwrap();
        drop(f);
        std::fs::rename(&tmp, &p).unwrap();
        let renamed = std::fs::metadata(&p).unwrap();
        assert_eq!(renamed.modified().unwrap(), mtime);
        assert_ne!(FileStamp::of(&renamed).0[1], FileStamp::of(&after).0[1]);
        // The fallback's stamp: no device or inode, the creation time (or 0 where the file
        // system keeps none), the same for the same file read twice.
        let fb = fallback::stamp(&renamed);
        assert_eq!(fb.0[..2], [0, 0]);
        assert_eq!(fb, fallback::stamp(&std::fs::metadata(&p).unwrap()));
    }
}
