//! Procedural scenes. STUB — to be implemented.

use crate::{PointCloud, SceneError};

/// The generators.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Generator {
    /// Statue-like closed surface.
    Statue,
    /// Turbulent isosurface.
    Isosurface,
    /// LiDAR-like terrain.
    Terrain,
}

impl Generator {
    /// All generators.
    pub const ALL: &'static [Generator] = &[Generator::Statue, Generator::Isosurface, Generator::Terrain];
    /// Name.
    pub fn name(self) -> &'static str {
        match self {
            Generator::Statue => "statue",
            Generator::Isosurface => "isosurface",
            Generator::Terrain => "terrain",
        }
    }
    /// One-line description.
    pub fn describe(self) -> &'static str {
        ""
    }
    /// By name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|g| g.name() == name)
    }
    /// Generates `n` points with `seed`.
    pub fn generate(self, n: usize, seed: u64) -> Result<PointCloud, SceneError> {
        let _ = (n, seed);
        Err(SceneError::Path("not implemented".into()))
    }
    /// Streams to a column file (STUB).
    pub fn generate_to_file(self, n: usize, seed: u64, path: &std::path::Path, progress: &dyn crate::Progress) -> Result<PointCloud, SceneError> {
        let _ = (n, seed, path, progress);
        Err(SceneError::Path("not implemented".into()))
    }
}
