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

/// Streaming writer (STUB).
pub struct ColumnWriter;
impl ColumnWriter {
    /// Create.
    pub fn create(path: &Path, attrs: crate::Attributes, origin: glam::DVec3, count: u64) -> Result<Self, SceneError> {
        let _ = (attrs, origin, count);
        Err(SceneError::format(path, "stub"))
    }
    /// Push.
    pub fn push(&mut self, positions: &[[f32; 3]], normals: Option<&[[f32; 3]]>, colors: Option<&[[u8; 3]]>, radii: Option<&[f32]>) -> Result<(), SceneError> {
        let _ = (positions, normals, colors, radii);
        Ok(())
    }
    /// Finish.
    pub fn finish(self) -> Result<PointCloud, SceneError> {
        Err(SceneError::Path("stub".into()))
    }
}
