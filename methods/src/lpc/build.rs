//! Out-of-core LPC build (placeholder: being written).

use std::path::Path;

use scenes::{PointCloud, Progress};

use super::LpcParams;
use crate::{BuildStats, MethodError};

/// Builds the index tree and the repository of `cloud` into `dir`.
pub fn build(
    cloud: &PointCloud,
    params: &LpcParams,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let _ = (cloud, params, scene, dir, progress);
    Err(MethodError::Limit("lpc build: not yet implemented".into()))
}
