//! Where the bytes of chunks come from: the one interface a local repository
//! (`access::LocalSource`) and a remote one (`remote::RemoteSource`) implement, under both and
//! the loader that reads through them.

use crate::MethodError;

/// The most requests a loader may have in flight (`in_flight`): each is a thread.
pub const MAX_IN_FLIGHT: u32 = 64;

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
    /// Stored (compressed) bytes read so far, over all fetches that returned their bytes.
    fn bytes_read(&self) -> u64 {
        0
    }
    /// Stored (compressed) bytes of chunk `id`: what one fetch of it reads (0 if unknown).
    fn stored_bytes(&self, id: u32) -> u64 {
        let _ = id;
        0
    }
}
