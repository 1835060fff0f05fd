//! Scenes: everything splatbench knows about the input, and nothing about LOD or GPUs.
//!
//! Contract:
//! - [`PointCloud`] is columnar. Positions are `f32` *relative to an `f64` origin*, so
//!   georeferenced coordinates (UTM, ECEF) keep sub-millimetre precision. Normals, colours and
//!   radii are optional columns; [`Attributes`] says which a cloud has, and nothing downstream
//!   stores, uploads or shades a column the cloud lacks.
//! - Columns are either owned vectors or views into a memory-mapped column file
//!   ([`colfile`]), so a cloud larger than RAM streams through the page cache.
//! - Generators ([`generators`]) are seeded and deterministic: same seed and count ⇒ identical bytes.
//! - Readers ([`ply`], [`las`], [`e57`], [`pcd`]) return a clear [`SceneError`] naming the file and the field for
//!   malformed input, never a panic.
//! - [`camera`] holds `Camera`/`View` (frustum planes, projection scale) and [`paths`] the
//!   scripted camera paths.

pub mod atomic;
pub mod axis;
pub mod camera;
pub mod cloud;
pub mod colfile;
pub mod e57;
pub mod error;
pub mod framing;
pub mod generators;
pub mod hash;
pub mod las;
mod las_check;
pub mod os;
pub mod paths;
pub mod pcd;
pub mod ply;
pub mod progress;
pub mod regularity;
pub mod rng;
pub mod scalar;
pub mod screen;
pub mod sniff;
pub mod spacing;
pub mod spec;

pub use axis::Up;
pub use camera::{Camera, Containment, Frustum, View};
pub use cloud::{Aabb, Attributes, Column, PointCloud};
pub use error::SceneError;
pub use progress::{NoProgress, Progress};
pub use scalar::Scalar;
pub use spec::{Loaded, SceneSpec};
