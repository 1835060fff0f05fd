//! LAS/LAZ reader/writer. STUB — to be implemented.

use std::path::Path;

use crate::{PointCloud, SceneError};

/// Reads a LAS or LAZ file.
pub fn read(path: &Path) -> Result<PointCloud, SceneError> {
    Err(SceneError::format(path, "not implemented"))
}
