//! Our converter: a scene into the Potree 2.0 format, following PotreeConverter 2.0
//! (Schütz et al. 2020, §4) in what the files hold:
//!
//! 1. The bounding **cube** of the points (the box's longest side on every axis); positions
//!    quantised to `int32` with `offset` = the cube's corner and `scale` = the smallest power
//!    of ten that fits the cube in 2³⁰ steps. The root's spacing is the cube's side / 128.
//! 2. The **octree**: a node with more than `max_leaf` points (10,000) is split into its
//!    octants, down to level [`super::format::MAX_LEVEL`] (deeper piles of duplicates stay in
//!    one leaf). Points are sorted by Morton code, so every node is a range ([`octree`]).
//! 3. **Subsampling**, bottom up: an inner node takes its points *from its children* (they
//!    are moved, not copied: every input point is stored exactly once), Poisson-disk with
//!    the level's spacing `spacing / 2^level`, or at random (see [`super::Sampling`]). A leaf
//!    left empty is dropped, as the converter does.
//! 4. **Files** ([`write`]): `octree.bin` node after node in breadth-first order (the
//!    converter writes them as they complete); `hierarchy.bin` in chunks of `step` levels,
//!    the root's first, nodes breadth first within a chunk, the chunk's last level as proxies.
//!
//! A cloud of more than `mem_mb·2²⁰ / 64` points is built in units ([`ooc`]), into the same
//! files byte for byte. Rayon splits the work by subtree; the output does not depend on the
//! number of threads either.

use std::path::Path;

use rayon::prelude::*;
use scenes::{PointCloud, Progress};

use super::octree::{self, Node, Quant, Sorted};
use super::{FORMAT_VERSION, INFO_FILE, Info, NAME, PotreeParams, ooc, write};
use crate::{BuildStats, Manifest, MethodError, Params};

/// Builds the Potree octree of `cloud` into `dir`: `octree.bin`, `hierarchy.bin`,
/// `metadata.json`, `potree.json`, then the manifest last.
pub fn build(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    build_with(cloud, params, scene, dir, None, progress)
}

/// [`build`] with a hook called with the units' spill files (tests damage them).
pub fn build_with(
    cloud: &PointCloud,
    params: &Params,
    scene: &str,
    dir: &Path,
    hook: Option<crate::spill::SpillHook<'_>>,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let t0 = std::time::Instant::now();
    let p = PotreeParams::from_params(params)?;
    let n = cloud.len();
    if n == 0 || n > u32::MAX as usize {
        return Err(MethodError::Limit(format!(
            "method '{NAME}': {n} points; a build takes 1..=2³² − 1"
        )));
    }
    let quant = Quant::of(cloud);
    let meta = write::metadata(cloud, &quant, &p, scene);
    let mem_bytes = p.mem_mb << 20;
    let (written, units, largest) = if n as u64 > ooc::unit_capacity(mem_bytes) {
        let budget = crate::spill::Budget {
            mem_bytes,
            dir,
            hook,
        };
        let b = ooc::build(cloud, quant, &p, meta, budget, progress)?;
        (b.written, b.units, b.largest_unit)
    } else {
        progress.start("potree: sort", n as u64);
        let origin = cloud.origin();
        let keyed: Vec<(u64, u32)> = cloud
            .positions()
            .par_iter()
            .enumerate()
            .map(|(i, &l)| (quant.morton(quant.of_local(origin, l)), i as u32))
            .collect();
        let sorted = Sorted::new(cloud, quant, 0, keyed);
        progress.finish();
        progress.start("potree: octree", n as u64);
        let at = Node::at(
            0,
            0,
            (quant.min, quant.min + glam::DVec3::splat(quant.size)),
        );
        let mut root = octree::split(&sorted, 0..n, at, p.max_leaf as usize);
        octree::sample(&mut root, &sorted, quant.size / 128.0, &p);
        progress.finish();
        let mut descs = Vec::new();
        write::describe(root, &mut descs);
        let w = write::write_files(cloud, meta, &mut descs, &sorted, &mut [], dir)?;
        (w, 1, n as u64)
    };
    let nodes = written.nodes;
    crate::method::write_json(
        &dir.join(INFO_FILE),
        &Info {
            origin: cloud.origin().to_array(),
            nodes,
            levels: written.depth + 1,
        },
    )?;
    let mut extra = serde_json::Map::new();
    let mut put = |k: &str, v: serde_json::Value| {
        extra.insert(k.into(), v);
    };
    put(
        "sampling",
        serde_json::to_value(p.sampling).unwrap_or_default(),
    );
    put("max_leaf", p.max_leaf.into());
    put("step", p.step.into());
    put("spacing", (quant.size / 128.0).into());
    put("scale", quant.scale.into());
    put("hierarchy_chunks", written.chunks.into());
    put("octree_bytes", written.octree_bytes.into());
    put("hierarchy_bytes", written.hierarchy_bytes.into());
    put("units", units.into());
    put("largest_unit", largest.into());
    let stats = BuildStats {
        points_in: n as u64,
        nodes,
        levels: written.depth + 1,
        bytes_in: cloud.column_bytes(),
        bytes_out: written.octree_bytes + written.hierarchy_bytes + written.metadata_bytes,
        bits_per_sample: 0.0,
        seconds: t0.elapsed().as_secs_f64(),
        points_per_s: 0.0,
        extra,
    }
    .finish();
    let attributes = written.layout.attributes();
    Manifest {
        method: NAME.into(),
        format_version: FORMAT_VERSION,
        params: params.clone(),
        attributes,
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    Ok(stats)
}
