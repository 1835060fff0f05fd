//! PLY reader/writer. STUB — to be implemented.

use std::path::Path;

use crate::{PointCloud, SceneError};

/// Reading options.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlyOptions {
    /// Resample the mesh surface to this many points (area-weighted, seeded).
    pub sample: Option<usize>,
    /// Seed for resampling.
    pub seed: u64,
}

/// Reads a PLY file.
pub fn read(path: &Path, opts: &PlyOptions) -> Result<PointCloud, SceneError> {
    let _ = opts;
    Err(SceneError::format(path, "not implemented"))
}
