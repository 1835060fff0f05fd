//! A mutation fuzzer for splatbench's decoders, on stable Rust (see `fuzz/README.md`).
//!
//! Contract:
//! - [`targets`]: each target is a decoder (a scenes reader, a method's repository files)
//!   with seed files ([`seeds`]: small real files, files the writers and method builders
//!   produce from a tiny generated scene, held in a [`corpus::Corpus`]) and a way to drive it
//!   with an input ([`execute`]).
//! - [`inputs`] with [`mutate`]: input `i` of a run is a seed file with 1–4 stacked mutations drawn from
//!   `Pcg32::stream(seed, i)`: byte flips, random and interesting bytes and integers,
//!   truncation, extension, splices, and header-field edits that know PLY, LAS/LAZ, PCD and
//!   TOML/JSON.
//!   The same `(seed, i)` always gives the same input, which is how a crash is reproduced.
//! - [`run`]: iterations run in a child process under an address-space limit; a panic, an
//!   abort (signal), an out-of-memory or a hang is a finding, saved as
//!   `fuzz/crashes/TARGET-<hash>.bin` with a `.txt` note. A decoder returning an error is the
//!   expected outcome for most inputs, not a finding.

pub mod corpus;
pub mod execute;
pub mod http;
pub mod inputs;
pub mod mutate;
pub mod run;
pub mod seeds;
pub mod targets;
