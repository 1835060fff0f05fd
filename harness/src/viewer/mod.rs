//! `splatbench view` (issue 19): an interactive window onto any method, drawn by the same
//! renderer and draw lists as `run`, that records camera paths and screenshots `run` can
//! reproduce.
//!
//! The rules are plain functions with unit tests: input → camera ([`control`]), keys and
//! scripts ([`command`]), poses → camera-path files ([`record`]), the HUD's text ([`hud`]),
//! the hole mask ([`overlay`]). [`session`] is the viewer without its window (tests drive it
//! headless); [`window`] is winit around it and [`present`] the one pass that puts the
//! renderer's target (or an overlay image) and the HUD on the window.

pub mod command;
pub mod control;
pub mod hud;
pub mod overlay;
pub mod present;
pub mod record;
pub mod session;
pub mod window;
