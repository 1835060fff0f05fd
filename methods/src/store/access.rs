//! The data-access layer (LPC §3 "Data layout and data access"): it hides whether chunks
//! come from a local memory-mapped repository or, later, from a remote one over HTTP range
//! requests. A method asks for a chunk asynchronously ([`DataAccess::request`]), tests
//! whether it is in core now ([`DataAccess::available`]) and takes it ([`DataAccess::get`]).
//!
//! Two layers:
//! - [`ChunkSource`]: verified, decompressed bytes of chunk `id` (blocking). [`LocalSource`]
//!   reads a [`Repository`]; an HTTP source implements the same trait.
//! - [`DataAccess`]: decoded chunks in core, filled by a loader thread from a source.

use std::sync::Arc;

use crate::store::{ChunkRef, Repository};
use crate::{MethodError, SplatBatch};

/// A decoded chunk, shared between the loader, the in-core cache and the caller.
pub type Decoded = Arc<SplatBatch>;

/// Turns a chunk's bytes into splats (the method's format); `id` names it in errors.
pub type Decoder = Arc<dyn Fn(u32, &[u8]) -> Result<SplatBatch, MethodError> + Send + Sync>;

/// Where the bytes of chunks come from (blocking reads).
pub trait ChunkSource: Send + Sync {
    /// Number of chunks.
    fn len(&self) -> usize;
    /// True if there are no chunks.
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    /// Verified, decompressed bytes of chunk `id`.
    fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError>;
}

/// Chunks of a local repository file.
pub struct LocalSource {
    repo: Repository,
    refs: Vec<ChunkRef>,
    noun: &'static str,
}

impl LocalSource {
    /// Chunks `refs` of `repo`; `noun` names a chunk in errors ("cloud", "node").
    pub fn new(repo: Repository, refs: Vec<ChunkRef>, noun: &'static str) -> Self {
        Self { repo, refs, noun }
    }
    /// The repository file.
    pub fn repository(&self) -> &Repository {
        &self.repo
    }
}

impl ChunkSource for LocalSource {
    fn len(&self) -> usize {
        self.refs.len()
    }
    fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError> {
        let r = self
            .refs
            .get(id as usize)
            .ok_or(MethodError::NoChunk(id as u64))?;
        self.repo.read(r, &format!("{} {id}", self.noun))
    }
}

/// The data-access layer seen by a method. Implementations are internally synchronised:
/// every call takes `&self`.
pub trait DataAccess: Send + Sync {
    /// Asks for chunk `id` to be brought in core; returns at once. Repeated requests for a
    /// chunk already queued, loading or in core are ignored.
    fn request(&self, id: u32);
    /// True if chunk `id` is in core now (a [`DataAccess::get`] will not block).
    fn available(&self, id: u32) -> bool;
    /// The decoded chunk: from core if available, else read and decoded now (blocking).
    fn get(&self, id: u32) -> Result<Decoded, MethodError>;
    /// Marks the start of a frame (ages delayed deliveries, advances the LRU clock).
    fn begin_frame(&self);
    /// Bytes of decoded chunks held in core.
    fn resident_bytes(&self) -> u64;
    /// Requests queued or in flight.
    fn pending(&self) -> usize;
}

/// Options of the local [`Loader`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoaderOptions {
    /// Bytes of decoded chunks kept in core (least recently used dropped beyond).
    pub core_bytes: u64,
    /// Frames ([`DataAccess::begin_frame`] calls) between a request and the moment its
    /// chunk counts as available: simulated latency; 0 = as soon as it is decoded.
    pub delay_frames: u32,
}

/// The local data-access layer (placeholder: synchronous until the loader thread lands).
pub struct Loader {
    source: Arc<dyn ChunkSource>,
    decode: Decoder,
    core: std::sync::Mutex<std::collections::HashMap<u32, Decoded>>,
}

impl Loader {
    /// Starts a loader over `source`.
    pub fn spawn(source: Arc<dyn ChunkSource>, decode: Decoder, options: LoaderOptions) -> Self {
        let _ = options;
        Self {
            source,
            decode,
            core: Default::default(),
        }
    }
    fn core(&self) -> std::sync::MutexGuard<'_, std::collections::HashMap<u32, Decoded>> {
        self.core.lock().unwrap_or_else(|e| e.into_inner())
    }
}

impl DataAccess for Loader {
    fn request(&self, id: u32) {
        let _ = self.get(id);
    }
    fn available(&self, id: u32) -> bool {
        self.core().contains_key(&id)
    }
    fn get(&self, id: u32) -> Result<Decoded, MethodError> {
        if let Some(d) = self.core().get(&id) {
            return Ok(d.clone());
        }
        let bytes = self.source.fetch(id)?;
        let d = Arc::new((self.decode)(id, &bytes)?);
        self.core().insert(id, d.clone());
        Ok(d)
    }
    fn begin_frame(&self) {}
    fn resident_bytes(&self) -> u64 {
        self.core().values().map(|b| b.byte_size()).sum()
    }
    fn pending(&self) -> usize {
        0
    }
}
