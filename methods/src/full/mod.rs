//! `full`: STUB.
use std::path::Path;
use scenes::{Attributes, PointCloud, Progress, View};
use crate::*;

/// Parameters.
#[derive(Debug, Clone, Default, serde::Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FullParams {}

/// Build.
pub fn build(_: &PointCloud, _: &Params, _: &str, _: &Path, _: &dyn Progress) -> Result<BuildStats, MethodError> { Err(MethodError::Limit("stub".into())) }

/// The method.
pub struct Full;
impl Full {
    /// Open.
    pub fn open(_: &Path, _: Manifest) -> Result<Self, MethodError> { Ok(Full) }
}
impl LodMethod for Full {
    fn attributes(&self) -> Attributes { Attributes::default() }
    fn input_points(&self) -> u64 { 0 }
    fn frame(&mut self, _: &View, _: Target, _: &Feedback) -> Result<DrawList, MethodError> { Ok(DrawList::default()) }
    fn chunk(&self, id: ChunkId) -> Result<SplatBatch, MethodError> { Err(MethodError::NoChunk(id)) }
    fn stats(&self) -> MethodStats { MethodStats::default() }
}
