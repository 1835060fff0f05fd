//! Index files of fixed-size records, shared by the out-of-core methods' indexes (LPC's
//! `index.bin`, MWKD's `index.bin`): an 8-byte magic, a `u64` record count, a `u64`
//! [`super::checksum`] of the record bytes, then the records (`#[repr(C)]` little-endian
//! `Pod`). Written through a temporary file and a rename; read whole, with the magic, the
//! length and the checksum checked and errors naming the file. What the records must satisfy
//! (a tree's shape) is the method's to check.

use std::path::Path;

use crate::MethodError;

/// Bytes before the records.
pub const HEADER_BYTES: usize = 24;

/// Writes `records` to `path` behind `magic`; returns the file's size in bytes.
pub fn write<T: bytemuck::Pod>(
    path: &Path,
    magic: &[u8; 8],
    records: &[T],
) -> Result<u64, MethodError> {
    let body: &[u8] = bytemuck::cast_slice(records);
    let mut bytes = Vec::with_capacity(HEADER_BYTES + body.len());
    bytes.extend_from_slice(magic);
    bytes.extend_from_slice(&(records.len() as u64).to_le_bytes());
    bytes.extend_from_slice(&super::checksum(body).to_le_bytes());
    bytes.extend_from_slice(body);
    let tmp = scenes::colfile::temp_path(path);
    std::fs::write(&tmp, &bytes).map_err(|e| MethodError::io(&tmp, e))?;
    std::fs::rename(&tmp, path).map_err(|e| MethodError::io(path, e))?;
    Ok(bytes.len() as u64)
}

/// Reads the records of `path`: a wrong magic is "not {what} (bad magic)", a count that does
/// not match the file's size or is 0 or above `max` an error saying so, a checksum mismatch
/// "index checksum mismatch"; every error names the file.
pub fn read<T: bytemuck::Pod>(
    path: &Path,
    magic: &[u8; 8],
    what: &str,
    max: u64,
) -> Result<Vec<T>, MethodError> {
    let bytes = std::fs::read(path).map_err(|e| MethodError::io(path, e))?;
    let bad = |msg: String| MethodError::corrupt(path, msg);
    if bytes.len() < HEADER_BYTES || &bytes[..8] != magic {
        return Err(bad(format!("not {what} (bad magic)")));
    }
    let word = |at: usize| {
        let mut w = [0u8; 8];
        w.copy_from_slice(&bytes[at..at + 8]);
        u64::from_le_bytes(w)
    };
    let count = word(8);
    let size = std::mem::size_of::<T>() as u64;
    if count == 0
        || count > max
        || count.checked_mul(size) != Some((bytes.len() - HEADER_BYTES) as u64)
    {
        return Err(bad(format!(
            "{count} nodes do not match the file size ({} bytes)",
            bytes.len()
        )));
    }
    let body = &bytes[HEADER_BYTES..];
    if super::checksum(body) != word(16) {
        return Err(bad("index checksum mismatch".into()));
    }
    Ok(body
        .chunks_exact(size as usize)
        .map(bytemuck::pod_read_unaligned)
        .collect())
}
