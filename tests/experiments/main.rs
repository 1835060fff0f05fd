//! The commands that run experiments and compare them, end to end through the binary:
//! `check` and the CI regression suite, `tune`, and `--emit-jobs` with `merge`. One test
//! binary for all of them (each links the whole wgpu stack, and linking is most of a clean
//! CI build's time).
#![allow(clippy::unwrap_used)]

#[path = "../common/mod.rs"]
mod common;

mod baselines;
mod check;
mod jobs;
mod tune;
