//! `clod`: continuous level of detail (Schütz, Krösl, Wimmer, "Real-Time Continuous Level of
//! Detail Rendering of Point Clouds", IEEE VR 2019), a modern baseline aimed at what the
//! layered methods do worst: popping.
//!
//! **Structure** (the paper's §3–4): a flattened layered point cloud. The points are
//! organised into Potree's octree ([`crate::potree::octree`], in core: Poisson-disk subsamples
//! whose spacing halves per level, from a root spacing of the bounding cube's side / 128),
//! then the octree is dropped: every point keeps only its level, as an attribute of one large
//! unordered buffer. Each point's level gets a fixed random offset `u ∈ [0, 1)`, and what a
//! point stores is its spacing `spacing₀ / 2^(level + u)` ([`select`]).
//!
//! **Per frame**: every point is tested — there is no hierarchy to cull with — by a pass on the
//! GPU that keeps the points whose spacing is at least the *target spacing* at their distance
//! (ε pixels there; more away from the screen's centre); a kept point's size follows the target
//! spacing and fades in over the last 20 % before its cut-off, so a level comes in point by
//! point instead of node by node. The pass is the renderer's per-splat test
//! ([`crate::SplatTest::Clod`]), evaluated in the vertex stage of the quads, in the compute
//! rasteriser and in the counting pass; [`select`] is its CPU mirror.
//!
//! **Targets**: a tolerance ε sets the target spacing to the size of ε pixels; a budget `B`
//! takes the smallest ε at which at most `B` points pass (chosen on the CPU from every point's
//! limit, then checked with the filter itself).
//!
//! See `README.md` beside this file for what is faithful and what is simplified.

pub mod select;

use std::path::Path;
use std::sync::{Arc, Mutex};
use std::time::Instant;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use scenes::{Attributes, PointCloud, Progress, View};

use crate::potree::octree::{self, Node, Quant, Sorted};
use crate::potree::{PotreeParams, Sampling};
use crate::{
    BuildStats, ChunkId, ClodTest, DrawItem, DrawList, Feedback, LodMethod, Manifest, MethodError,
    MethodStats, Params, SplatBatch, SplatSize, SplatTest, Target,
};

/// Registry name.
pub const NAME: &str = "clod";
/// Version of the files [`build`] writes.
pub const FORMAT_VERSION: u32 = 1;
/// Points per chunk (one GPU buffer each; the filter runs over all of them every frame).
pub const CHUNK_POINTS: usize = 1 << 20;
/// The points, in octree order (root first, depth first), with their spacing in the radius
/// column.
const POINTS_FILE: &str = "points.sbc";
/// `clod.json`.
pub const INFO_FILE: &str = "clod.json";
/// Parameters read at `open` only.
pub const RUNTIME_PARAMS: &[&str] = &["fovea", "point_size"];
/// Extra CSV columns: the ε (pixels) the frame's filter used — the tolerance, or what the
/// budget chose.
pub const COLUMNS: &[&str] = &["target_px"];

/// Parameters of `clod`.
#[derive(Debug, Clone, PartialEq, serde::Deserialize, serde::Serialize)]
#[serde(deny_unknown_fields, default)]
pub struct ClodParams {
    /// Largest node of the octree the levels come from (Potree's 10,000).
    pub max_leaf: u32,
    /// Seed of the per-point level offsets (the paper hashes the position; ours is a seeded
    /// hash of the point's index, reproducible and uncorrelated with the geometry).
    pub seed: u64,
    /// How fast density falls away from the screen's centre: target spacing divided by
    /// `max(1 − fovea·|ndc|, 0.3)` (the paper's 0.7; 0 = the same density everywhere).
    pub fovea: f32,
    /// Point size factor (the shader's `pointSize`, 1).
    pub point_size: f32,
}

impl Default for ClodParams {
    fn default() -> Self {
        Self {
            max_leaf: 10_000,
            seed: 0,
            fovea: 0.7,
            point_size: 1.0,
        }
    }
}

impl ClodParams {
    /// Parses and validates `--param` pairs (errors name the parameter).
    pub fn from_params(params: &Params) -> Result<Self, MethodError> {
        let p: ClodParams = params.to_typed(NAME)?;
        let bad = |msg: String| Err(MethodError::Param(format!("method '{NAME}': {msg}")));
        if p.max_leaf < 1 {
            return bad(format!("max_leaf must be ≥ 1, got {}", p.max_leaf));
        }
        if !(0.0..=1.0).contains(&p.fovea) {
            return bad(format!("fovea must be in 0..=1, got {}", p.fovea));
        }
        if !p.point_size.is_finite() || p.point_size <= 0.0 {
            return bad(format!(
                "point_size must be a finite number > 0, got {}",
                p.point_size
            ));
        }
        Ok(p)
    }
}

/// `clod.json`: what the points' spacings were made from.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Info {
    /// The octree's root spacing (`spacing₀`, the bounding cube's side / 128).
    pub spacing: f64,
    /// Levels of the octree (deepest + 1).
    pub levels: u32,
    /// Nodes of the octree.
    pub nodes: u64,
    /// Points per level, root first.
    pub per_level: Vec<u64>,
}

/// The offset `u ∈ [0, 1)` of point `index`'s level: 24 bits of a seeded SplitMix64 hash.
pub fn level_offset(seed: u64, index: u64) -> f32 {
    let mut x = seed ^ index.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    (scenes::rng::splitmix64(&mut x) >> 40) as f32 / (1u64 << 24) as f32
}

/// The spacing a point of `level` with offset `u` stores: `spacing₀ / 2^(level + u)`.
pub fn point_spacing(spacing0: f64, level: u32, u: f32) -> f32 {
    (spacing0 / (f64::from(level) + f64::from(u)).exp2()) as f32
}

/// The octree's points in depth-first order (root first), with their levels.
fn flatten(node: &Node, sorted: &Sorted, out: &mut Vec<(u32, u8)>) {
    let level = node.level.min(u32::from(u8::MAX)) as u8;
    out.extend(
        node.points
            .iter()
            .map(|&r| (sorted.order[r as usize], level)),
    );
    for c in node.children.iter().flatten() {
        flatten(c, sorted, out);
    }
}

fn count_nodes(node: &Node) -> u64 {
    1 + node
        .children
        .iter()
        .flatten()
        .map(|c| count_nodes(c))
        .sum::<u64>()
}

/// Builds `cloud` into `dir`: `points.sbc` (the points in octree order, their spacing in the
/// radius column), `clod.json`, then the manifest last.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let t0 = Instant::now();
    let p = ClodParams::from_params(params)?;
    let n = cloud.len();
    if n == 0 || n > u32::MAX as usize {
        return Err(MethodError::Limit(format!(
            "method '{NAME}': {n} points; a build takes 1..=2³² − 1"
        )));
    }
    progress.start("clod: octree", n as u64);
    let quant = Quant::of(cloud);
    let origin = cloud.origin();
    let sorted = Sorted::of_cloud(cloud, quant);
    let at = Node::at(0, 0, (quant.min, quant.min + DVec3::splat(quant.size)));
    let mut root = octree::split(&sorted, 0..n, at, p.max_leaf as usize, false);
    let spacing = quant.size / 128.0;
    let tree = PotreeParams {
        sampling: Sampling::Poisson,
        max_leaf: p.max_leaf,
        ..PotreeParams::default()
    };
    octree::sample(&mut root, &sorted, spacing, &tree);
    let mut flat = Vec::with_capacity(n);
    flatten(&root, &sorted, &mut flat);
    let nodes = count_nodes(&root);
    drop(root);
    drop(sorted);
    progress.finish();
    if flat.len() != n {
        return Err(MethodError::Limit(format!(
            "method '{NAME}': the octree holds {} of {n} points (a bug)",
            flat.len()
        )));
    }
    let levels = flat
        .iter()
        .map(|&(_, l)| u32::from(l) + 1)
        .max()
        .unwrap_or(1);
    let mut per_level = vec![0u64; levels as usize];
    for &(_, l) in &flat {
        per_level[usize::from(l)] += 1;
    }
    progress.start("clod: writing", n as u64);
    let path = dir.join(POINTS_FILE);
    let mut attrs = cloud.attributes();
    attrs.radii = true;
    let mut w = scenes::colfile::ColumnWriter::create(&path, attrs, origin, n as u64)?;
    for block in flat.chunks(1 << 16) {
        let pos: Vec<_> = block
            .iter()
            .map(|&(i, _)| cloud.positions()[i as usize])
            .collect();
        let nrm: Option<Vec<_>> = cloud
            .normals()
            .map(|c| block.iter().map(|&(i, _)| c[i as usize]).collect());
        let col: Option<Vec<_>> = cloud
            .colors()
            .map(|c| block.iter().map(|&(i, _)| c[i as usize]).collect());
        let sp: Vec<f32> = block
            .iter()
            .map(|&(i, l)| point_spacing(spacing, u32::from(l), level_offset(p.seed, u64::from(i))))
            .collect();
        w.push(&pos, nrm.as_deref(), col.as_deref(), Some(&sp))?;
        progress.inc(block.len() as u64);
    }
    w.finish()?;
    progress.finish();
    let info = Info {
        spacing,
        levels,
        nodes,
        per_level,
    };
    crate::method::write_json(&dir.join(INFO_FILE), &info)?;
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes: cloud.attributes(),
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    let bytes_out = std::fs::metadata(&path)
        .map_err(|e| MethodError::io(&path, e))?
        .len();
    let mut extra = serde_json::Map::new();
    extra.insert("spacing".into(), spacing.into());
    extra.insert("octree_nodes".into(), nodes.into());
    Ok(BuildStats {
        points_in: n as u64,
        nodes: n.div_ceil(CHUNK_POINTS) as u64,
        levels,
        bytes_in: cloud.column_bytes(),
        bytes_out,
        seconds: t0.elapsed().as_secs_f64(),
        extra,
        ..Default::default()
    }
    .finish())
}

/// An opened `clod` build: every point in core, in chunks ready to upload.
pub struct Clod {
    chunks: Vec<Arc<SplatBatch>>,
    attrs: Attributes,
    info: Info,
    params: ClodParams,
    points: u64,
    /// The last [`Clod::count_kept`], by its inputs' bits: a budget's frame counts at its
    /// scale to confirm it, and the runner's [`LodMethod::drawn_points`] asks the same count
    /// of the same frame; each is a pass over every point.
    last_count: Mutex<Option<(CountKey, u64)>>,
}

/// The inputs of a count, bit for bit: the view-projection, the eye, the scale (the fovea
/// is fixed when the build is opened, the points when it is read).
type CountKey = [u32; 20];

fn count_key(vp: &glam::Mat4, eye: Vec3, scale: f32) -> CountKey {
    let mut k = [0u32; 20];
    for (d, v) in k.iter_mut().zip(
        vp.to_cols_array()
            .into_iter()
            .chain(eye.to_array())
            .chain([scale]),
    ) {
        *d = v.to_bits();
    }
    k
}

impl Clod {
    /// Opens the build in `dir` (runtime parameters merged into `manifest.params`).
    pub fn open(dir: &Path, manifest: Manifest) -> Result<Self, MethodError> {
        manifest.expect_version(dir, FORMAT_VERSION)?;
        let params = ClodParams::from_params(&manifest.params)?;
        let info: Info = crate::method::read_json(&dir.join(INFO_FILE))?;
        let path = dir.join(POINTS_FILE);
        let cloud = scenes::colfile::open(&path)?;
        let Some(spacings) = cloud.radii() else {
            return Err(MethodError::corrupt(&path, "no spacing column (radii)"));
        };
        if cloud.len() as u64 != manifest.points {
            return Err(MethodError::corrupt(
                &path,
                format!(
                    "{} points (the manifest says {})",
                    cloud.len(),
                    manifest.points
                ),
            ));
        }
        if let Some(i) = spacings.iter().position(|s| !(s.is_finite() && *s > 0.0)) {
            return Err(MethodError::corrupt(
                &path,
                format!(
                    "point {i}: spacing {} (must be finite and > 0)",
                    spacings[i]
                ),
            ));
        }
        let chunks = (0..cloud.len())
            .step_by(CHUNK_POINTS)
            .map(|start| {
                let range = start..(start + CHUNK_POINTS).min(cloud.len());
                let mut b = SplatBatch::from_cloud_range(&cloud, range.clone(), None);
                b.lod = Some(
                    spacings[range]
                        .iter()
                        .map(|&s| [s, 0.0, 0.0, 0.0])
                        .collect(),
                );
                Arc::new(b)
            })
            .collect();
        Ok(Self {
            chunks,
            attrs: manifest.attributes,
            info,
            params,
            points: manifest.points,
            last_count: Mutex::new(None),
        })
    }

    /// The scale (ε/k) of a budget: the smallest at which at most `budget` points pass the
    /// filter for `view`; when every point in the extended frustum fits, the largest at which
    /// all of them pass at full size (`BLEND` × the smallest limit: the coarsest target that
    /// still draws everything, where scale 0 would draw every point at 1 px).
    pub fn budget_scale(&self, view: &View, budget: u64) -> f32 {
        let vp = view.view_proj();
        let eye = view.camera.position;
        let fovea = self.params.fovea;
        let mut limits: Vec<f32> = self
            .chunks
            .par_iter()
            .flat_map_iter(|c| {
                let lod = c.lod.as_deref().unwrap_or(&[]);
                c.positions.iter().zip(lod).filter_map(move |(p, l)| {
                    select::scale_limit(Vec3::from(*p), l[0], &vp, eye, fovea)
                })
            })
            .collect();
        if limits.len() as u64 <= budget {
            let least = limits.iter().copied().fold(f32::INFINITY, f32::min);
            return if least.is_finite() {
                select::BLEND * least
            } else {
                0.0
            };
        }
        // The (budget + 1)-th largest limit: just above it, at most `budget` limits remain.
        let b = budget as usize;
        let (_, v, _) = limits.select_nth_unstable_by(b, |a, b| b.total_cmp(a));
        if !v.is_finite() {
            // More than `budget` points at the eye itself: no scale excludes them.
            return f32::MAX;
        }
        // The filter compares spacing with the target spacing, not limits with the scale:
        // rounding may keep a few more; raise the scale by f32 steps (doubling) until the
        // filter itself agrees, or the scale is the largest finite one.
        let mut scale = v.next_up();
        let mut step = 1u32;
        while self.count_kept(view, scale) > budget && scale < f32::MAX {
            scale = f32::from_bits(scale.to_bits().saturating_add(step)).min(f32::MAX);
            step = step.saturating_mul(2);
        }
        scale
    }

    /// Points the filter keeps for `view` at `scale` (the CPU mirror, in parallel; the last
    /// count is remembered, so the same question twice is one pass).
    pub fn count_kept(&self, view: &View, scale: f32) -> u64 {
        let vp = view.view_proj();
        let eye = view.camera.position;
        let key = count_key(&vp, eye, scale);
        // A poisoned lock holds a whole entry or none: its value is still good.
        let last = *self.last_count.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((k, n)) = last
            && k == key
        {
            return n;
        }
        let fovea = self.params.fovea;
        let n = self
            .chunks
            .par_iter()
            .map(|c| {
                let lod = c.lod.as_deref().unwrap_or(&[]);
                c.positions
                    .iter()
                    .zip(lod)
                    .filter(|(p, l)| select::keeps(Vec3::from(**p), l[0], &vp, eye, scale, fovea))
                    .count() as u64
            })
            .sum();
        *self.last_count.lock().unwrap_or_else(|e| e.into_inner()) = Some((key, n));
        n
    }

    /// The octree the levels came from.
    pub fn info(&self) -> &Info {
        &self.info
    }

    /// The test of a frame at `scale`.
    pub fn test(&self, view: &View, scale: f32) -> ClodTest {
        ClodTest {
            scale,
            fovea: self.params.fovea,
            view_proj: view.view_proj().to_cols_array_2d(),
        }
    }
}

impl LodMethod for Clod {
    fn attributes(&self) -> Attributes {
        self.attrs
    }
    fn input_points(&self) -> u64 {
        self.points
    }
    fn frame(
        &mut self,
        view: &View,
        target: Target,
        _feedback: &Feedback,
    ) -> Result<DrawList, MethodError> {
        let k = view.proj_scale();
        let scale = match target.validate()? {
            Target::Tolerance(eps) => eps / k,
            Target::Budget(b) => self.budget_scale(view, b),
        };
        let test = SplatTest::Clod(self.test(view, scale));
        let size = SplatSize::Clod {
            point_size: self.params.point_size,
        };
        let items = self
            .chunks
            .iter()
            .enumerate()
            .map(|(i, c)| DrawItem::Sequential {
                id: i as ChunkId,
                prefix: c.len() as u32,
                test,
                size,
            })
            .collect();
        Ok(DrawList {
            items,
            counters: vec![f64::from(scale * k)],
            ..Default::default()
        })
    }
    fn chunk(&self, id: ChunkId) -> Result<Arc<SplatBatch>, MethodError> {
        usize::try_from(id)
            .ok()
            .and_then(|i| self.chunks.get(i))
            .cloned()
            .ok_or(MethodError::NoChunk(id))
    }
    fn stats(&self) -> MethodStats {
        MethodStats {
            resident_bytes: self.chunks.iter().map(|c| c.byte_size()).sum(),
            nodes: self.chunks.len() as u64,
            levels: self.info.levels,
        }
    }
    fn extra_columns(&self) -> &'static [&'static str] {
        COLUMNS
    }
    fn interval_tested(&self) -> bool {
        true
    }
    fn gpu_resident_bytes(&self) -> Option<u64> {
        Some(self.chunks.iter().map(|c| c.byte_size()).sum())
    }
    /// The points its filter keeps, counted in parallel by [`Clod::count_kept`] (the same
    /// predicate as [`crate::method::count_drawn`]'s, without decoding every normal it ignores), when
    /// every item carries one CLOD test for this view; otherwise the default count.
    fn drawn_points(&self, view: &View, list: &DrawList) -> Result<u64, MethodError> {
        let vp = view.view_proj().to_cols_array_2d();
        let mut tests = list.items.iter().map(|i| match i {
            DrawItem::Sequential {
                test: SplatTest::Clod(t),
                prefix,
                id,
                ..
            } if t.view_proj == vp
                && t.fovea == self.params.fovea
                && self
                    .chunks
                    .get(*id as usize)
                    .is_some_and(|c| c.len() == *prefix as usize) =>
            {
                Some(t.scale)
            }
            _ => None,
        });
        let first = tests.next().flatten();
        match first {
            Some(scale)
                if list.items.len() == self.chunks.len() && tests.all(|t| t == Some(scale)) =>
            {
                Ok(self.count_kept(view, scale))
            }
            _ => crate::method::count_drawn(self, view, list),
        }
    }
}

/// Median hole ratio above which a run's holes are taken as the foveated rule's: 2 % (LPC's
/// threshold for its spacing rule); measured on the 40 K statue orbit at
/// 256², ε = 1: 32 % with the paper's fovea 0.7, 0.04 % with `fovea=0`.
pub const FOVEA_HOLES: f64 = 0.02;

/// The effect on a run with `params` in force that measured `observed`: the paper's
/// foveation (`fovea > 0`) with median holes above [`FOVEA_HOLES`].
pub fn known_effect(params: &Params, observed: &crate::Observed) -> Option<crate::KnownEffect> {
    let p = ClodParams::from_params(params).ok()?;
    let holes = observed.hole_ratio?;
    (p.fovea > 0.0 && holes > FOVEA_HOLES).then(|| crate::KnownEffect {
        effect: format!(
            "holes {:.1} % (median): the paper's rule keeps no point whose spacing is below \
             the target spacing, ε px at the screen's centre and up to ε/{} at its edges \
             (foveation {}), and has no floor: where even the root's spacing (the bounding \
             cube's side / 128) projects below it, nothing is drawn",
            holes * 100.0,
            select::FOVEA_FLOOR,
            p.fovea
        ),
        param: "fovea=0".into(),
        cost: "a departure: the same target spacing everywhere on screen; on the 40 K statue \
               orbit at 256², ε = 1: holes 32 % → 0.04 %, 2.7× the points"
            .into(),
        doc: "methods/src/clod/README.md".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observed(h: f64) -> crate::Observed {
        crate::Observed {
            hole_ratio: Some(h),
        }
    }

    #[test]
    fn foveated_runs_with_holes_name_fovea_zero_and_others_nothing() {
        let e = known_effect(&Params::default(), &observed(0.321)).expect("an effect");
        assert!(
            e.effect.starts_with("holes 32.1 % (median)"),
            "{}",
            e.effect
        );
        assert_eq!(e.param, "fovea=0");
        assert!(known_effect(&Params::default(), &observed(0.02)).is_none());
        let flat = Params::parse(&["fovea=0"]).unwrap();
        assert!(known_effect(&flat, &observed(0.5)).is_none());
        assert!(known_effect(&Params::default(), &crate::Observed::default()).is_none());
    }

    #[test]
    fn level_offsets_are_in_the_unit_interval_and_seeded() {
        let u: Vec<f32> = (0..10_000).map(|i| level_offset(0, i)).collect();
        assert!(u.iter().all(|&x| (0.0..1.0).contains(&x)));
        assert_ne!(level_offset(0, 5), level_offset(1, 5));
        assert_eq!(point_spacing(8.0, 1, 0.0), 4.0);
        assert_eq!(point_spacing(8.0, 2, 0.5), (8.0 / 2f64.powf(2.5)) as f32);
    }
}
