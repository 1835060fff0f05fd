//! LOD methods, GPU-free.
//!
//! Contract: a method *builds* an on-disk representation from a [`scenes::PointCloud`],
//! *opens* it, and per frame answers "what to draw for this view" as a plain-data
//! [`DrawList`]. It never touches a GPU: the harness turns draw lists into GPU work, so every
//! method is testable without one and one renderer serves all of them.
//!
//! - [`method`]: the [`LodMethod`] trait, build/open statistics, the `method.json` manifest.
//! - [`draw`]: draw lists, splat batches (what a chunk decodes to), targets, feedback.
//! - [`params`]: `--param key=value` pairs into a method's typed, `deny_unknown_fields` params.
//! - [`registry`]: [`MethodKind`], the one explicit list of methods.
//! - [`cull`]: normal cones and back-face tests shared by the methods.
//! - [`store`]: the LZO chunk store with per-chunk checksums and the data-access layer
//!   (loader thread) shared by the out-of-core methods.
//! - one module per method: [`full`] (no LOD, the reference), then the four papers' methods
//!   ([`qsplat`], [`spt`], [`lpc`], [`mwkd`]), [`potree`], today's practice (Potree 2.0), and [`clod`], continuous LOD (2019).

pub mod cellmap;
pub mod clod;
pub mod cull;
pub mod draw;
pub mod error;
pub mod full;
pub mod jsonfile;
pub mod leaf;
pub mod lpc;
pub mod method;
pub mod morton;
pub mod mwkd;
pub mod octnormal;
pub mod overlap;
pub mod params;
pub mod potree;
pub mod qsplat;
pub mod registry;
pub mod sortkey;
pub mod spill;
pub mod spt;
pub mod store;
pub mod strays;
pub mod unit_knn;
pub mod voxel;

pub use draw::{
    Cached, ChunkId, ClodTest, DrawItem, DrawList, Feedback, IntervalTest, OcclusionCandidate,
    OcclusionPass, SplatBatch, SplatShape, SplatSize, SplatTest, Target,
};
pub use error::{MethodError, UnknownName};
pub use method::{BuildStats, KnownEffect, LodMethod, Manifest, MethodStats, Observed};
pub use params::Params;
pub use registry::MethodKind;
