//! A repository read from somewhere else by byte ranges (LPC §3: "over HTTP/1.1 range
//! requests with persistent connections"): [`RemoteFile`] is a file that can be fetched
//! whole (an index, a manifest) or by one byte range; [`RemoteSource`] is the
//! [`ChunkSource`] of a remote repository file, each chunk one range, verified by the same
//! checksum and decompression as a local read ([`super::unpack`]).
//!
//! The methods crate holds no network client: the HTTP one (keep-alive agent, status and
//! `Content-Range` checks, timeouts) is `harness::remote::HttpFile`, which implements
//! [`RemoteFile`]. Its contract: a range comes back with exactly the bytes asked for, or a
//! [`MethodError::Remote`] naming the URL; a checksum mismatch is [`MethodError::Corrupt`]
//! naming the URL and the chunk (this module's). Retrying is the loader's business, not this
//! layer's.

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use super::source::ChunkSource;
use super::{ChunkRef, REPO_MAGIC, unpack};
use crate::MethodError;

/// One file at a URL, read whole or by byte range (blocking).
pub trait RemoteFile: Send + Sync {
    /// The URL (errors name it).
    fn url(&self) -> &str;
    /// The whole file.
    fn get(&self) -> Result<Vec<u8>, MethodError>;
    /// Bytes `start..start + len`, exactly `len` of them (`len = 0`: none).
    fn get_range(&self, start: u64, len: u64) -> Result<Vec<u8>, MethodError>;
}

/// Opens the file at a URL (a client's agent, shared by the files it opens).
pub type RemoteOpener<'a> = &'a dyn Fn(&str) -> Arc<dyn RemoteFile>;

/// The chunks of a remote repository file.
pub struct RemoteSource {
    file: Arc<dyn RemoteFile>,
    refs: Vec<ChunkRef>,
    noun: &'static str,
    read: AtomicU64,
}

impl RemoteSource {
    /// Chunks `refs` of the repository file `file`, whose magic is checked now; `noun` names
    /// a chunk in errors ("cloud", "node").
    pub fn open(
        file: Arc<dyn RemoteFile>,
        refs: Vec<ChunkRef>,
        noun: &'static str,
    ) -> Result<Self, MethodError> {
        let magic = file.get_range(0, REPO_MAGIC.len() as u64)?;
        if magic != REPO_MAGIC {
            return Err(MethodError::corrupt(
                file.url(),
                "not a splatbench repository (bad magic)",
            ));
        }
        Ok(Self {
            file,
            refs,
            noun,
            read: AtomicU64::new(0),
        })
    }

    /// The repository's URL.
    pub fn url(&self) -> &str {
        self.file.url()
    }
}

impl ChunkSource for RemoteSource {
    fn len(&self) -> usize {
        self.refs.len()
    }

    fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError> {
        let r = crate::store::chunk_ref(&self.refs, id)?;
        let what = format!("{} {id}", self.noun);
        let span = super::chunk_span(r, None, &what)
            .map_err(|msg| MethodError::corrupt(self.file.url(), msg))?;
        let stored = self.file.get_range(span.start, span.end - span.start)?;
        self.read.fetch_add(stored.len() as u64, Ordering::Relaxed);
        unpack(&stored, r, &what).map_err(|msg| MethodError::corrupt(self.file.url(), msg))
    }

    fn bytes_read(&self) -> u64 {
        self.read.load(Ordering::Relaxed)
    }

    fn stored_bytes(&self, id: u32) -> u64 {
        crate::store::chunk_ref(&self.refs, id).map_or(0, |r| u64::from(r.stored))
    }
}
