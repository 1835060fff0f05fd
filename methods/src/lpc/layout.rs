//! The build's shared constants: the sample record's size, the I/O block and buffer sizes,
//! the spacing probe. Below every file of the build (`build`, `partition`, `multilevel`,
//! `source`, `spacing`), which all read them.

use super::cloud::Sample;

/// Flag of a probe sample (spacing estimate).
pub const PROBE: u16 = 1;
/// Expected number of probe samples of the spacing estimate.
pub const PROBES: u64 = 16_384;
/// Bytes of one sample record.
pub const RECORD_BYTES: u64 = std::mem::size_of::<Sample>() as u64;
/// Bytes per sample of a subtree partitioned in memory (source and destination buffers).
pub const IN_CORE_BYTES_PER_SAMPLE: u64 = 2 * RECORD_BYTES;
/// Samples per block when reading the scene or a temporary file.
pub const BLOCK: usize = 1 << 16;
/// Samples per parallel chunk when converting the scene's columns.
pub const CONVERT_CHUNK: usize = 1 << 13;
/// Capacity of each buffered reader / writer.
pub const IO_BUF: usize = 1 << 20;
/// Added to every cone half-angle (radians): covers `f32` rounding of the dot products.
pub const CONE_MARGIN: f32 = 1e-3;
