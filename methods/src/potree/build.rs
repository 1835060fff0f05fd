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

use scenes::{PointCloud, Progress};

use super::octree::{self, Quant};
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
    let p = PotreeParams::from_params(params)?;
    let format = Format::of(NAME, FORMAT_VERSION, INFO_FILE, &p);
    let mut extra = serde_json::Map::new();
    extra.insert(
        "sampling".into(),
        serde_json::to_value(p.sampling).unwrap_or_default(),
    );
    let fill = |quant: &Quant, _bytes_per_point: usize| octree::Subsample {
        spacing: quant.size / 128.0,
        params: &p,
    };
    let input = Input {
        cloud,
        params,
        scene,
        dir,
        hook,
    };
    build_format(input, &format, fill, extra, progress)
}

/// What a build in the Potree format is given.
pub struct Input<'a> {
    /// The scene's points.
    pub cloud: &'a PointCloud,
    /// The parameters as given (recorded in the manifest).
    pub params: &'a Params,
    /// The scene's description.
    pub scene: &'a str,
    /// The build directory.
    pub dir: &'a Path,
    /// Called with the units' spill files (tests damage them).
    pub hook: Option<crate::spill::SpillHook<'a>>,
}

/// How a method in the Potree format (`potree`, `voxel`) builds: its names and the
/// parameters the shared build reads.
pub struct Format {
    /// Registry name.
    pub name: &'static str,
    /// Version of the method's own files.
    pub format_version: u32,
    /// Its info file (an [`Info`]).
    pub info_file: &'static str,
    /// Leaf capacity.
    pub max_leaf: u32,
    /// Levels per hierarchy chunk.
    pub step: u32,
    /// Build memory, MiB.
    pub mem_mb: u64,
}

impl Format {
    /// The format of method `name` (its files' version, its info file) with the octree
    /// settings of `p` (leaf capacity, hierarchy step, build memory).
    pub fn of(
        name: &'static str,
        format_version: u32,
        info_file: &'static str,
        p: &PotreeParams,
    ) -> Self {
        Self {
            name,
            format_version,
            info_file,
            max_leaf: p.max_leaf,
            step: p.step,
            mem_mb: p.mem_mb,
        }
    }
}

/// The shared build of the methods in the Potree format: the cube and quantisation, the
/// octree in core or in units with the inner nodes filled by `fill(quant, bytes per
/// record)`, the files, the info file, `build.json`'s figures (`extra` first) and the
/// manifest last.
pub fn build_format<'a, F: octree::Fill>(
    input: Input<'a>,
    format: &Format,
    fill: impl FnOnce(&Quant, usize) -> F,
    mut extra: serde_json::Map<String, serde_json::Value>,
    progress: &dyn Progress,
) -> Result<BuildStats, MethodError> {
    let t0 = std::time::Instant::now();
    let Input {
        cloud,
        params,
        scene,
        dir,
        hook,
    } = input;
    let name = format.name;
    let n = cloud.len();
    if n == 0 || n > u32::MAX as usize {
        return Err(MethodError::Limit(format!(
            "method '{name}': {n} points; a build takes 1..=2³² − 1"
        )));
    }
    let quant = Quant::of(cloud);
    let meta = write::metadata(cloud, &quant, format.step, scene);
    let bytes_per_point = meta
        .layout(&dir.join(super::format::METADATA_FILE))?
        .bytes_per_point;
    let fill = fill(&quant, bytes_per_point);
    let budget = crate::spill::Budget {
        mem_bytes: format.mem_mb << 20,
        dir,
        hook,
    };
    let tree = ooc::Tree {
        cloud,
        quant,
        max_leaf: format.max_leaf,
        fill: &fill,
        meta,
    };
    let built = ooc::build_files(tree, budget, progress)?;
    let (written, units, largest) = (built.written, built.units, built.largest_unit);
    let nodes = written.nodes;
    crate::method::write_json(
        &dir.join(format.info_file),
        &Info {
            origin: cloud.origin().to_array(),
            nodes,
            levels: written.depth + 1,
        },
    )?;
    let mut put = |k: &str, v: serde_json::Value| {
        extra.insert(k.into(), v);
    };
    put("max_leaf", format.max_leaf.into());
    put("step", format.step.into());
    put("spacing", (quant.size / 128.0).into());
    put("scale", quant.scale.into());
    put("hierarchy_chunks", written.chunks.into());
    put("octree_bytes", written.octree_bytes.into());
    put("hierarchy_bytes", written.hierarchy_bytes.into());
    put("units", units.into());
    put("largest_unit", largest.into());
    if written.samples != n as u64 {
        // Records that are no input point (`voxel`'s voxels) besides the input points.
        put("samples", written.samples.into());
    }
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
        method: name.into(),
        format_version: format.format_version,
        params: params.clone(),
        attributes,
        points: n as u64,
        scene: scene.into(),
    }
    .write(dir)?;
    Ok(stats)
}
