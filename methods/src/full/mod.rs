//! `full`: no level of detail. Every input sample is drawn as a splat of its own leaf radius
//! ([`crate::leaf`]), never smaller than 1 px. This is the full-resolution reference the image
//! metrics compare against, and the baseline "what does no LOD cost".
//!
//! Build: the samples are written, in a seeded random order, with their leaf radii, to one
//! memory-mapped column file; chunks are consecutive ranges of [`CHUNK_POINTS`]. Because the
//! order is random, any prefix is a uniform random subsample: under a budget `B < N`, `full`
//! draws the first `B` samples with radii scaled by `sqrt(N/B)` (same expected coverage) — the
//! "random subsampling" baseline. With a tolerance it draws everything (the tolerance does not
//! apply to a method without LOD).

use std::path::Path;
use std::time::Instant;

use scenes::{Attributes, PointCloud, Progress, View};

use crate::{
    BuildStats, ChunkId, DrawItem, DrawList, Feedback, LodMethod, Manifest, MethodError,
    MethodStats, Params, SplatBatch, SplatSize, Target,
};

/// Samples per chunk (3 MiB of positions: well inside every adapter's storage binding limit).
pub const CHUNK_POINTS: usize = 1 << 18;
/// Version of the on-disk layout.
pub const FORMAT_VERSION: u32 = 1;
const POINTS_FILE: &str = "points.sbc";

/// Parameters of `full`.
#[derive(Debug, Clone, Default, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct FullParams {
    /// Seed of the sample order.
    pub seed: u64,
}

/// Writes the build directory.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let p: FullParams = params.to_typed("full")?;
    let t0 = Instant::now();
    let n = cloud.len();
    progress.start("full: leaf radii", n as u64);
    let radii = crate::leaf::leaf_radii(cloud);
    progress.finish();
    let order = permutation(n, p.seed);
    let path = dir.join(POINTS_FILE);
    let mut attrs = cloud.attributes();
    attrs.radii = true;
    let mut w = scenes::colfile::ColumnWriter::create(&path, attrs, cloud.origin(), n as u64)?;
    progress.start("full: writing", n as u64);
    for block in order.chunks(1 << 16) {
        let pos: Vec<_> = block
            .iter()
            .map(|&i| cloud.positions()[i as usize])
            .collect();
        let nrm: Option<Vec<_>> = cloud
            .normals()
            .map(|c| block.iter().map(|&i| c[i as usize]).collect());
        let col: Option<Vec<_>> = cloud
            .colors()
            .map(|c| block.iter().map(|&i| c[i as usize]).collect());
        let rad: Vec<_> = block.iter().map(|&i| radii[i as usize]).collect();
        w.push(&pos, nrm.as_deref(), col.as_deref(), Some(&rad))?;
        progress.inc(block.len() as u64);
    }
    w.finish()?;
    progress.finish();
    Manifest {
        method: "full".into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: attrs,
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    let bytes_out = std::fs::metadata(&path)
        .map_err(|e| MethodError::io(&path, e))?
        .len();
    Ok(BuildStats {
        points_in: n as u64,
        nodes: n.div_ceil(CHUNK_POINTS) as u64,
        levels: 1,
        bytes_in: cloud.column_bytes(),
        bytes_out,
        seconds: t0.elapsed().as_secs_f64(),
        extra: [("leaf_radii_capped".to_string(), radii.capped.into())]
            .into_iter()
            .collect(),
        ..Default::default()
    }
    .finish())
}

/// Seeded Fisher–Yates permutation of `0..n`.
fn permutation(n: usize, seed: u64) -> Vec<u32> {
    let mut v: Vec<u32> = (0..n as u32).collect();
    let mut rng = scenes::rng::Pcg32::new(seed ^ 0xF0_11);
    for i in (1..n).rev() {
        let j = rng.below(i as u32 + 1) as usize;
        v.swap(i, j);
    }
    v
}

/// An opened `full` build.
pub struct Full {
    cloud: PointCloud,
    attrs: Attributes,
}

impl Full {
    /// Opens a build directory (the column file is memory-mapped).
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        manifest.expect_version(dir, FORMAT_VERSION)?;
        let path = dir.join(POINTS_FILE);
        let cloud = scenes::colfile::open(&path)?;
        if cloud.len() as u64 != manifest.points || cloud.radii().is_none() {
            return Err(MethodError::corrupt(
                &path,
                format!(
                    "{} samples (manifest says {}), radii {}",
                    cloud.len(),
                    manifest.points,
                    if cloud.radii().is_some() {
                        "present"
                    } else {
                        "missing"
                    }
                ),
            ));
        }
        Ok(Self {
            attrs: cloud.attributes(),
            cloud,
        })
    }
}

impl LodMethod for Full {
    fn attributes(&self) -> Attributes {
        self.attrs
    }
    fn input_points(&self) -> u64 {
        self.cloud.len() as u64
    }
    fn frame(
        &mut self,
        _view: &View,
        target: Target,
        _feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let n = self.cloud.len();
        let (draw, scale) = match target.validate()? {
            Target::Tolerance(_) => (n, 1.0),
            Target::Budget(b) => {
                let d = (b as usize).min(n);
                (d, (n as f32 / d as f32).sqrt())
            }
        };
        let size = SplatSize::Radius { scale, min_px: 1.0 };
        let items = (0..draw.div_ceil(CHUNK_POINTS))
            .map(|c| DrawItem::Chunk {
                id: c as ChunkId,
                first: 0,
                points: (draw - c * CHUNK_POINTS).min(CHUNK_POINTS) as u32,
                size,
            })
            .collect();
        Ok(DrawList {
            items,
            ..Default::default()
        })
    }
    fn chunk(&self, id: ChunkId) -> Result<std::sync::Arc<SplatBatch>, MethodError> {
        let n = self.cloud.len();
        let start = usize::try_from(id)
            .ok()
            .and_then(|i| i.checked_mul(CHUNK_POINTS))
            .filter(|&s| s < n)
            .ok_or(MethodError::NoChunk(id))?;
        let range = start..(start + CHUNK_POINTS).min(n);
        Ok(std::sync::Arc::new(SplatBatch::from_cloud_range(
            &self.cloud,
            range,
            self.cloud.radii(),
        )))
    }
    fn stats(&self) -> MethodStats {
        MethodStats {
            resident_bytes: 0,
            nodes: self.cloud.len().div_ceil(CHUNK_POINTS) as u64,
            levels: 1,
        }
    }
}
