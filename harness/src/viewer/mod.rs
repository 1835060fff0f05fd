//! The interactive viewer's logic, free of any window (issue 19): how input moves the camera
//! ([`control`]), and how poses become camera-path files that `run --path` reads
//! ([`record`]). The window (winit + the same renderer) drives these; every rule here is a
//! plain function with unit tests.

pub mod control;
pub mod record;
