//! Harness: the headless wgpu renderer, the camera-path runner, image metrics, results
//! export and plots.
//!
//! Arrows point one way: `harness → methods → scenes`. Methods hand over plain-data draw
//! lists; everything GPU lives here.

pub mod cache;
pub mod check;
pub mod gpu;
pub mod image;
pub mod memory;
pub mod metrics;
pub mod plot;
pub mod progress;
pub mod remote;
pub mod render;
pub mod reproduce;
pub mod results;
pub mod rss;
pub mod runner;
pub mod serve;
pub mod sweep;
pub mod tune;
pub mod viewer;
