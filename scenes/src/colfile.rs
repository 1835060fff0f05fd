//! Memory-mapped column files (`.sbc`). STUB — to be implemented.

use std::path::Path;

use crate::{PointCloud, SceneError};

/// Writes `cloud` to `path`; returns bytes written.
pub fn write(path: &Path, cloud: &PointCloud) -> Result<u64, SceneError> {
    let _ = (path, cloud);
    Err(SceneError::Path("colfile::write not implemented".into()))
}

/// Opens a column file as a memory-mapped cloud.
pub fn open(path: &Path) -> Result<PointCloud, SceneError> {
    Err(SceneError::format(path, "colfile::open not implemented"))
}
