//! Buffered input: the file streamed through one large buffer.

use std::fs::File;
use std::io::{self, Read, Seek, SeekFrom};

/// Size of the read buffer.
const READ_BUFFER: usize = 4 << 20;

// ---------------------------------------------------------------------------------------------
// Buffered input
// ---------------------------------------------------------------------------------------------

/// A file streamed through one large buffer, handing out slices of it.
pub(super) struct Input {
    file: File,
    pub(super) buf: Vec<u8>,
    /// Start of the unread bytes in `buf`.
    pos: usize,
    /// End of the valid bytes in `buf`.
    end: usize,
    /// File offset of `buf[end]`.
    file_pos: u64,
    /// File length when opened.
    file_len: u64,
}

pub(super) enum LineRead<T> {
    Line(T),
    Eof,
    TooLong,
}

impl Input {
    pub(super) fn new(file: File, file_len: u64) -> Input {
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
    pub(super) fn position(&self) -> u64 {
        self.file_pos - (self.end - self.pos) as u64
    }
    /// Bytes between the next unread byte and the end of the file.
    pub(super) fn remaining(&self) -> u64 {
        self.file_len.saturating_sub(self.position())
    }
    pub(super) fn avail(&self) -> &[u8] {
        &self.buf[self.pos..self.end]
    }
    pub(super) fn consume(&mut self, n: usize) {
        self.pos = (self.pos + n).min(self.end);
    }
    /// Makes at least `need` unread bytes available; false if the file ends first (everything
    /// left is then in the buffer). Never allocates more than the file can fill.
    pub(super) fn fill(&mut self, need: usize) -> io::Result<bool> {
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
    pub(super) fn take(&mut self, n: usize) -> io::Result<Option<&[u8]>> {
        if !self.fill(n)? {
            return Ok(None);
        }
        let start = self.pos;
        self.pos += n;
        Ok(Some(&self.buf[start..start + n]))
    }
    /// Skips `n` bytes; false if the file is shorter.
    pub(super) fn skip(&mut self, n: u64) -> io::Result<bool> {
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
    pub(super) fn next_line_range(
        &mut self,
        max: usize,
    ) -> io::Result<LineRead<std::ops::Range<usize>>> {
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
