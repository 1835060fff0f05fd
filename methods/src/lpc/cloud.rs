//! The LPC cloud codec (placeholder: being written).

use crate::{MethodError, SplatBatch};

/// Decodes the bytes of cloud `id` (already decompressed and checksummed).
pub fn decode(id: u32, bytes: &[u8]) -> Result<SplatBatch, MethodError> {
    let _ = bytes;
    Err(MethodError::Limit(format!(
        "cloud {id}: codec not yet implemented"
    )))
}
