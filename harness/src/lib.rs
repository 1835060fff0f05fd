//! Harness: the headless wgpu renderer, the camera-path runner, image metrics, results
//! export and plots.

pub mod image;
pub mod metrics;
pub mod plot;
