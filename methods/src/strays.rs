//! `--param strays=apart`: far stray samples held apart from a method's hierarchy.
//!
//! Every method builds its hierarchy over the bounds of its input (QSplat's root sphere,
//! LPC's root cube, MWKD's root box). On a real scan with a few far strays, such as a 1 km
//! aerial tile with two samples 6,260 km away (`append-bug-cpy.laz` in laspy's tests), that
//! box is thousands of times larger than the tile, and each paper's rule then degrades the
//! tile: QSplat's 13-bit child spheres can shrink by at most 13× a level, so the tile's
//! upper nodes and its shallow leaves keep radii of hundreds of metres (FLIP 0.73); LPC's
//! spacings of eqs. (1)–(2) follow the root cube down; MWKD quantises positions to 16 bits
//! of a node box that spans the strays (holes 0.88). The papers say nothing of strays; their
//! rule is the default (`strays=in`).
//!
//! `strays=apart` (a departure, any method) splits the samples by the camera framing's inlier
//! box ([`scenes::framing::inlier_box`]: the 0.1–99.9 % quantile box grown by half its
//! largest extent), builds the method over the inliers only, and keeps the strays beside it
//! in `strays.sbc`, each with the leaf radius the full-resolution reference gives it
//! ([`crate::leaf::leaf_radii`] over the whole cloud, isolated samples capped). Every frame
//! draws the method's selection plus every stray, as the reference draws them; they are
//! counted in `points_drawn`. Under a budget the method is given the budget less the strays,
//! so the budget stays a hard bound (a budget that does not cover the strays is an error).
//! A cloud without strays builds exactly as with `strays=in` (no `strays.sbc`; `strays.json`
//! and `build.json` say 0). A build that lost its `strays.sbc` fails to open.
//!
//! Cost: the build gathers the inliers into a copy of the cloud's columns (twice its
//! column bytes while it builds) and runs one k-NN pass over the whole cloud for the strays'
//! radii.

use std::path::Path;
use std::sync::Arc;

use scenes::{Attributes, PointCloud, Progress, View};

use crate::method::Manifest;
use crate::{
    BuildStats, ChunkId, DrawItem, DrawList, Feedback, LodMethod, MethodError, MethodKind,
    MethodStats, Params, SplatBatch, SplatSize, Target,
};

/// The parameter's key.
pub const PARAM: &str = "strays";
/// File of the strays in a build directory (absent when there are none).
pub const FILE: &str = "strays.sbc";
/// How many strays the build holds apart (`{"strays": N}`), written by every `strays=apart`
/// build, so that a missing [`FILE`] is an error, not a build without strays.
pub const COUNT_FILE: &str = "strays.json";

#[derive(serde::Serialize, serde::Deserialize)]
struct Count {
    strays: u64,
}
/// Chunk id of the strays' batch: no method numbers its chunks this high.
pub const CHUNK: ChunkId = u64::MAX;

/// Where far strays go.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Strays {
    /// In the method's hierarchy, as the papers do (default).
    In,
    /// Beside it, drawn whole every frame (see the module docs).
    Apart,
}

/// The strays rule of `params` and the method's own parameters (`params` without it).
pub fn split_params(params: &Params) -> Result<(Strays, Params), MethodError> {
    let mut own = params.clone();
    let rule = match own.0.remove(PARAM).as_deref() {
        None | Some("in") => Strays::In,
        Some("apart") => Strays::Apart,
        Some(v) => {
            return Err(MethodError::Param(format!(
                "{PARAM}={v}: expected 'in' (the paper's: strays in the hierarchy) or 'apart'"
            )));
        }
    };
    Ok((rule, own))
}

/// The samples of `cloud` at `idx`, with `radii` (one per sample of `cloud`) when given.
fn gather(
    cloud: &PointCloud,
    idx: &[usize],
    radii: Option<&[f32]>,
) -> Result<PointCloud, MethodError> {
    let pick = |c: &[[f32; 3]]| idx.iter().map(|&i| c[i]).collect::<Vec<_>>();
    PointCloud::new(
        cloud.origin(),
        pick(cloud.positions()).into(),
        cloud.normals().map(|c| pick(c).into()),
        cloud
            .colors()
            .map(|c| idx.iter().map(|&i| c[i]).collect::<Vec<_>>().into()),
        radii.map(|r| idx.iter().map(|&i| r[i]).collect::<Vec<_>>().into()),
    )
    .map_err(MethodError::from)
}

/// Builds `kind` over the inliers of `cloud` into `dir` and writes the strays beside it;
/// `params` are all the run's parameters (recorded in the manifest), `own` the method's.
pub fn build(
    kind: MethodKind,
    cloud: &PointCloud,
    params: &Params,
    own: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let Some(inlier) = scenes::framing::inlier_box(cloud) else {
        let mut stats = kind.build_method(cloud, own, scene, dir, progress)?;
        record(dir, params, 0, &mut stats)?;
        return Ok(stats);
    };
    let (mut inliers, mut strays) = (Vec::new(), Vec::new());
    for (i, &p) in cloud.positions().iter().enumerate() {
        if scenes::framing::is_inlier(&inlier, p) {
            inliers.push(i);
        } else {
            strays.push(i);
        }
    }
    progress.start("strays: leaf radii", cloud.len() as u64);
    let radii = crate::leaf::leaf_radii(cloud);
    progress.finish();
    let own_cloud = gather(cloud, &inliers, cloud.radii())?;
    drop(inliers);
    let mut stats = kind.build_method(&own_cloud, own, scene, dir, progress)?;
    drop(own_cloud);
    let path = dir.join(FILE);
    scenes::colfile::write(&path, &gather(cloud, &strays, Some(&radii))?)?;
    record(dir, params, strays.len() as u64, &mut stats)?;
    stats.points_in = cloud.len() as u64;
    stats.bytes_in = cloud.column_bytes();
    stats.bytes_out += std::fs::metadata(&path)
        .map_err(|e| MethodError::io(&path, e))?
        .len();
    Ok(stats.finish())
}

/// Records a `strays=apart` build of `strays` strays in `dir`: [`COUNT_FILE`], every
/// parameter in the manifest (so `open` knows to draw the strays, and a cache keyed on the
/// parameters never mistakes this build for the paper's), `strays_apart` in `stats`.
fn record(
    dir: &Path,
    params: &Params,
    strays: u64,
    stats: &mut BuildStats,
) -> Result<(), MethodError> {
    crate::method::write_json(&dir.join(COUNT_FILE), &Count { strays })?;
    let mut manifest = Manifest::read(dir)?;
    manifest.params = params.clone();
    manifest.write(dir)?;
    stats.extra.insert("strays_apart".into(), strays.into());
    Ok(())
}

/// An opened build with its strays held apart.
pub struct Apart {
    inner: Box<dyn LodMethod>,
    batch: Arc<SplatBatch>,
}

impl Apart {
    /// Wraps `inner`, opened from `dir`, with the strays of `dir` (when the build had none,
    /// `inner` alone is the build).
    pub fn open(dir: &Path, inner: Box<dyn LodMethod>) -> Result<Box<dyn LodMethod>, MethodError> {
        let count: Count = crate::method::read_json(&dir.join(COUNT_FILE))?;
        if count.strays == 0 {
            return Ok(inner);
        }
        let path = dir.join(FILE);
        let cloud = scenes::colfile::open(&path)?;
        if cloud.radii().is_none() || cloud.len() as u64 != count.strays {
            return Err(MethodError::corrupt(
                &path,
                format!(
                    "{} strays (with radii: {}); {COUNT_FILE} says {} with radii",
                    cloud.len(),
                    cloud.radii().is_some(),
                    count.strays
                ),
            ));
        }
        let mut batch = SplatBatch::from_cloud_range(&cloud, 0..cloud.len(), cloud.radii());
        // The strays carry what the method's splats carry (and their radii).
        let a = inner.attributes();
        if !a.normals {
            batch.normals = None;
        }
        if !a.colors {
            batch.colors = None;
        }
        Ok(Box::new(Apart {
            inner,
            batch: Arc::new(batch),
        }))
    }

    fn strays(&self) -> u64 {
        self.batch.len() as u64
    }
}

impl LodMethod for Apart {
    fn attributes(&self) -> Attributes {
        self.inner.attributes()
    }
    fn input_points(&self) -> u64 {
        self.inner.input_points() + self.strays()
    }
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let own = match target.validate()? {
            Target::Budget(b) if b <= self.strays() => {
                return Err(MethodError::Target(format!(
                    "budget {b} does not cover the {} strays drawn apart (strays=apart): \
                     the least is {}",
                    self.strays(),
                    self.strays() + 1
                )));
            }
            Target::Budget(b) => Target::Budget(b - self.strays()),
            t => t,
        };
        let mut list = self.inner.frame(view, own, feedback)?;
        list.items.push(DrawItem::Chunk {
            id: CHUNK,
            first: 0,
            points: self.batch.len() as u32,
            size: SplatSize::Radius {
                scale: 1.0,
                min_px: 1.0,
            },
        });
        Ok(list)
    }
    fn chunk(&self, id: ChunkId) -> Result<Arc<SplatBatch>, MethodError> {
        if id == CHUNK {
            Ok(self.batch.clone())
        } else {
            self.inner.chunk(id)
        }
    }
    fn stats(&self) -> MethodStats {
        self.inner.stats()
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        self.inner.extra_columns()
    }
    fn interval_tested(&self) -> bool {
        self.inner.interval_tested()
    }
    fn drawn_points(&self, view: &View, list: &DrawList) -> Result<u64, MethodError> {
        let is_stray = |i: &DrawItem| matches!(i, DrawItem::Chunk { id: CHUNK, .. });
        let strays: u64 = list
            .items
            .iter()
            .filter(|i| is_stray(i))
            .map(|i| i.points())
            .sum();
        let mut own = list.clone();
        own.items.retain(|i| !is_stray(i));
        Ok(self.inner.drawn_points(view, &own)? + strays)
    }
    fn occlusion_culled(&self) -> bool {
        self.inner.occlusion_culled()
    }
    fn gpu_resident_bytes(&self) -> Option<u64> {
        self.inner.gpu_resident_bytes()
    }
    fn chunk_level(&self, id: ChunkId) -> Option<u32> {
        // The strays' own chunk belongs to no level.
        (id != CHUNK).then(|| self.inner.chunk_level(id)).flatten()
    }
    fn failed_chunks(&self) -> Vec<(ChunkId, String)> {
        self.inner.failed_chunks()
    }
    fn loads_chunks(&self) -> bool {
        self.inner.loads_chunks()
    }
    fn traffic(&self) -> crate::store::access::Traffic {
        self.inner.traffic()
    }
    fn throughput(&self) -> Option<crate::store::access::Throughput> {
        self.inner.throughput()
    }
}
