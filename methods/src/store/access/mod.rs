//! The data-access layer (LPC §3 "Data layout and data access"): it hides whether chunks
//! come from a local memory-mapped repository or, later, from a remote one over HTTP range
//! requests. A method asks for a chunk asynchronously ([`DataAccess::request`]), tests
//! whether it is in core now ([`DataAccess::available`]) and takes it ([`DataAccess::get`]).
//!
//! Two layers:
//! - [`ChunkSource`]: verified, decompressed bytes of chunk `id` (blocking). [`LocalSource`]
//!   reads a [`Repository`]; an HTTP source implements the same trait.
//! - [`DataAccess`]: decoded chunks in core, filled by a loader thread from a source.
//!   [`Loader`] (`loader.rs`) is the implementation; its documentation gives the design, the
//!   delay semantics, the core budget and the error handling.

mod clock;
mod loader;
mod meter;
mod options;

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};

use crate::store::{ChunkRef, Repository};
use crate::{MethodError, SplatBatch};

pub use super::source::{ChunkSource, MAX_IN_FLIGHT};
pub use clock::{Clock, ManualClock};
pub use loader::Loader;
pub use meter::METER_WINDOW;
pub use options::{DUE_WAIT, LoaderOptions, Retry};

/// A decoded chunk, shared between the loader, the in-core cache and the caller.
pub type Decoded = Arc<SplatBatch>;

/// Turns a chunk's bytes into splats (the method's format); `id` names it in errors.
pub type Decoder = Arc<dyn Fn(u32, &[u8]) -> Result<SplatBatch, MethodError> + Send + Sync>;

/// Chunks of a local repository file.
pub struct LocalSource {
    repo: Repository,
    refs: Vec<ChunkRef>,
    noun: &'static str,
    read: AtomicU64,
}

impl LocalSource {
    /// Chunks `refs` of `repo`; `noun` names a chunk in errors ("cloud", "node").
    pub fn new(repo: Repository, refs: Vec<ChunkRef>, noun: &'static str) -> Self {
        Self {
            repo,
            refs,
            noun,
            read: AtomicU64::new(0),
        }
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
        let r = crate::store::chunk_ref(&self.refs, id)?;
        let bytes = self.repo.read(r, &format!("{} {id}", self.noun))?;
        self.read.fetch_add(u64::from(r.stored), Ordering::Relaxed);
        Ok(bytes)
    }
    fn bytes_read(&self) -> u64 {
        self.read.load(Ordering::Relaxed)
    }
    fn stored_bytes(&self, id: u32) -> u64 {
        crate::store::chunk_ref(&self.refs, id).map_or(0, |r| u64::from(r.stored))
    }
}

/// The [`crate::LodMethod`] methods of a method that loads its chunks through the
/// [`DataAccess`] in its field `$field` (LPC, MWKD, Potree): `loads_chunks` true, and
/// `traffic`, `throughput` and `failed_chunks` as the access layer reports them. Used
/// inside the `impl LodMethod` block.
#[macro_export]
macro_rules! loads_through_access {
    ($field:ident) => {
        fn loads_chunks(&self) -> bool {
            true
        }
        fn traffic(&self) -> $crate::store::access::Traffic {
            self.$field.traffic()
        }
        fn throughput(&self) -> Option<$crate::store::access::Throughput> {
            self.$field.throughput()
        }
        fn failed_chunks(&self) -> Vec<($crate::ChunkId, String)> {
            self.$field
                .failures()
                .into_iter()
                .map(|(id, e)| ($crate::ChunkId::from(id), e))
                .collect()
        }
    };
}

/// Requests a remote repository has in flight unless told otherwise: as many as Potree's
/// viewer loads at once (`Potree.maxNodesLoading`, 4), so that a link's latency is paid once
/// per four chunks rather than once per chunk.
pub const REMOTE_IN_FLIGHT: u32 = 4;

/// Where a build's repository file is read from.
#[derive(Clone)]
pub enum RepoAt {
    /// A local file, memory-mapped.
    Local(std::path::PathBuf),
    /// A file served elsewhere (over HTTP: `harness::remote`), read by range requests
    /// ([`super::remote`]).
    Remote(std::sync::Arc<dyn super::remote::RemoteFile>),
}

impl RepoAt {
    /// Requests in flight: `asked`, else one for a local file (the paper's one loader
    /// thread; reads from a page cache gain nothing from more, and the renderer needs the
    /// cores) and [`REMOTE_IN_FLIGHT`] for a remote one.
    pub fn in_flight(&self, asked: Option<u32>) -> u32 {
        asked.unwrap_or(match self {
            RepoAt::Local(_) => 1,
            RepoAt::Remote(_) => REMOTE_IN_FLIGHT,
        })
    }
}

/// Checks a method's `in_flight` parameter (1..=[`MAX_IN_FLIGHT`]); `method` names it.
pub fn check_in_flight(method: &str, in_flight: Option<u32>) -> Result<(), MethodError> {
    match in_flight {
        Some(n) if !(1..=MAX_IN_FLIGHT).contains(&n) => Err(MethodError::Param(format!(
            "method '{method}': in_flight must be in 1..={MAX_IN_FLIGHT}, got {n}"
        ))),
        _ => Ok(()),
    }
}

/// What a chunked build's figures (LPC's `lpc.json`, MWKD's `mwkd.json`) say of its size,
/// checked at `open` against its index and manifest ([`open_figures`]).
pub trait BuildFigures: serde::de::DeserializeOwned {
    /// Nodes (chunks) in the index.
    fn nodes(&self) -> u64;
    /// Input points.
    fn points(&self) -> u64;
}

/// Opens a chunked build's figures (LPC, MWKD): reads them from `path`, checks their node
/// and point counts against the index — `index_nodes` nodes and, where the index records it
/// (MWKD), the `root_samples` under its root — and the manifest's `manifest_points`, then
/// reads the root chunk through `access` now: it is the coarsest representation, without it
/// there is nothing to draw, and reading it verifies it.
pub fn open_figures<F: BuildFigures>(
    path: &std::path::Path,
    index_nodes: usize,
    root_samples: Option<u64>,
    manifest_points: u64,
    access: &dyn DataAccess,
) -> Result<F, MethodError> {
    let info: F = crate::jsonfile::read_json(path)?;
    if info.nodes() != index_nodes as u64
        || info.points() != manifest_points
        || root_samples.is_some_and(|s| s != info.points())
    {
        return Err(MethodError::corrupt(
            path,
            format!(
                "{} nodes / {} points disagree with the index ({index_nodes} nodes{}) and the \
                 manifest ({manifest_points} points)",
                info.nodes(),
                info.points(),
                root_samples.map_or(String::new(), |s| format!(", {s} samples")),
            ),
        ));
    }
    access.get(0)?;
    Ok(info)
}

/// The data-access layer seen by a method. Implementations are internally synchronised:
/// every call takes `&self`.
pub trait DataAccess: Send + Sync {
    /// Asks for chunk `id` to be brought in core; returns at once. A method asks each frame,
    /// best first, for what it still wants: a chunk still queued from an earlier frame is
    /// moved up among this frame's requests; one loading or in core is not fetched again.
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
    /// Chunks that failed to load (read or decode), by id, each with its error naming the
    /// source and the chunk; none by default.
    fn failures(&self) -> Vec<(u32, String)> {
        Vec::new()
    }
    /// What has travelled so far (see [`Traffic`]); zeros by default.
    fn traffic(&self) -> Traffic {
        Traffic::default()
    }
    /// The rate the source delivered at over its recent responses; `None` before the first
    /// response, or by default.
    fn throughput(&self) -> Option<Throughput> {
        None
    }
}

/// The measured rate of a source: stored bytes and chunks over the time during which at
/// least one fetch was in flight, over the last [`METER_WINDOW`] responses (failed ones
/// count their time, no bytes). LPC issues as many requests per frame as this rate
/// delivers in a frame (the paper's "estimated bandwidth").
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Throughput {
    /// Stored bytes per second.
    pub bytes_per_s: f64,
    /// Chunks delivered per second.
    pub chunks_per_s: f64,
    /// Responses it was measured over (≤ [`METER_WINDOW`]).
    pub responses: usize,
}

/// A loader's traffic since it was opened.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Traffic {
    /// Requests queued (a re-request of a queued chunk re-prioritises it, not counted).
    pub issued: u64,
    /// Queued requests dropped unserved because no frame asked for them any more.
    pub cancelled: u64,
    /// Chunks delivered after every frame that wanted them had passed.
    pub stale: u64,
    /// Fetches or decodes that failed, every try counted (a chunk given up on after 4
    /// tries counts 4).
    pub failed: u64,
    /// Stored (compressed) bytes the source read ([`ChunkSource::bytes_read`]).
    pub bytes: u64,
}

impl Traffic {
    /// What happened since `earlier` (a reading of the same loader).
    pub fn since(&self, earlier: &Traffic) -> Traffic {
        Traffic {
            issued: self.issued.saturating_sub(earlier.issued),
            cancelled: self.cancelled.saturating_sub(earlier.cancelled),
            stale: self.stale.saturating_sub(earlier.stale),
            failed: self.failed.saturating_sub(earlier.failed),
            bytes: self.bytes.saturating_sub(earlier.bytes),
        }
    }
}
