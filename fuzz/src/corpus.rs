//! A target's corpus: its seed files, what its decoder needs beside an input, and one input.

use std::path::PathBuf;

use methods::store::ChunkRef;
use scenes::Aabb;

/// One seed file.
#[derive(Debug, Clone)]
pub struct Seed {
    /// Its name (the file's name in a build directory; the extension matters elsewhere).
    pub name: String,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// A target's seeds and what its decoder needs beside the input.
pub struct Corpus {
    /// The seed files.
    pub seeds: Vec<Seed>,
    /// Method targets: the build directory the seeds were read from.
    pub dir: Option<PathBuf>,
    /// `repo`: each seed repository's chunk references, and whether it is MWKD's.
    pub refs: Vec<(Vec<ChunkRef>, bool)>,
    /// Bounds of the scene, for views (method and path targets).
    pub bounds: Aabb,
}

/// One input: the seed it came from and its (mutated) bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Input {
    /// Index into [`Corpus::seeds`].
    pub seed: usize,
    /// The bytes to decode.
    pub bytes: Vec<u8>,
}
