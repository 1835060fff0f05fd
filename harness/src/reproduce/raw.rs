//! Reproduction specs as written: the TOML tables, read with `deny_unknown_fields`, before
//! [`super::check`] resolves them for a profile. Field meanings are in [`super::spec`]'s
//! module docs.

use std::collections::BTreeMap;
use std::path::PathBuf;

use super::spec::{Format, MeasureKind, Profile};
use super::verdict::Rule;
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawSpec {
    pub(super) id: String,
    pub(super) paper: String,
    pub(super) title: String,
    pub(super) source: String,
    #[serde(default)]
    pub(super) notes: Option<String>,
    #[serde(default)]
    pub(super) profiles: Option<Vec<Profile>>,
    #[serde(default)]
    pub(super) reference: Option<toml::Value>,
    #[serde(default)]
    pub(super) scenes: BTreeMap<String, RawScene>,
    #[serde(default, rename = "measure")]
    pub(super) measures: Vec<RawMeasure>,
    #[serde(default, rename = "row")]
    pub(super) rows: Vec<RawRow>,
    #[serde(default, rename = "figure")]
    pub(super) figures: Vec<RawFigure>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawScene {
    pub(super) generator: Option<toml::Value>,
    pub(super) file: Option<PathBuf>,
    pub(super) points: Option<toml::Value>,
    pub(super) seed: Option<u64>,
    pub(super) sample: Option<toml::Value>,
    pub(super) sampling: Option<toml::Value>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawMeasure {
    pub(super) id: String,
    pub(super) kind: MeasureKind,
    pub(super) method: String,
    pub(super) scene: Option<String>,
    #[serde(default)]
    pub(super) params: toml::Table,
    pub(super) path: Option<String>,
    pub(super) frames: Option<toml::Value>,
    pub(super) skip: Option<toml::Value>,
    pub(super) eps: Option<toml::Value>,
    pub(super) budget: Option<toml::Value>,
    pub(super) width: Option<toml::Value>,
    pub(super) height: Option<toml::Value>,
    pub(super) kernel: Option<String>,
    pub(super) gpu_cache_mb: Option<u64>,
    pub(super) metrics: Option<bool>,
    pub(super) isolate: Option<bool>,
    pub(super) points: Option<toml::Value>,
    #[serde(default)]
    pub(super) profiles: Option<Vec<Profile>>,
    pub(super) reference_kernel: Option<String>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawRow {
    pub(super) what: String,
    pub(super) paper: Option<toml::Value>,
    pub(super) paper_text: Option<String>,
    pub(super) ours: toml::Value,
    pub(super) rule: Rule,
    pub(super) tolerance: Option<f64>,
    #[serde(default)]
    pub(super) format: Format,
    pub(super) reason: Option<String>,
    #[serde(default)]
    pub(super) needs_gpu: bool,
    pub(super) band: Option<[f64; 2]>,
    pub(super) band_reason: Option<String>,
    #[serde(default)]
    pub(super) judge_on_gpu: bool,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawFigure {
    pub(super) name: String,
    pub(super) title: String,
    pub(super) sweeps: Vec<String>,
}
