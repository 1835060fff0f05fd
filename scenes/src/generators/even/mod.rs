//! Even ("scan-like") sampling: near-uniform spacing, as the vertices of a merged range scan
//! have, instead of the independent area-uniform samples of [`Sampling::Random`].
//!
//! **Why.** The papers' models are mesh vertices of merged scans (QSplat's and LPC's
//! St. Matthew, David, Lucy; MWKD's the same and Pisa) or vertices of an extracted
//! isosurface: their nearest-neighbour distances vary little. Independent random samples
//! (a Poisson process) leave gaps: splats of the average spacing `√(A/N)` placed at random
//! leave `e⁻¹ ≈ 37 %` of the surface bare (the Boolean model), where the same splats on a
//! regular sampling leave none. The layered methods size their splats from the average
//! spacing (LPC's `r`, Potree's level spacing), so which sampling a scene has decides
//! whether they show holes.
//!
//! **Construction** (decision: sample elimination, because it gives exactly `n` samples,
//! needs nothing of a surface but samples of it — the same code serves every generator and
//! any cloud — and is deterministic without any order dependence):
//! 1. `OVERSAMPLING · n` candidates: the generator's own random area-uniform samples with
//!    the same seed (the candidates of [`Generator::generate`](super::Generator::generate)
//!    `(OVERSAMPLING · n, seed)`, in that order).
//! 2. Tiles: a grid of cubes whose side holds about [`TILE_CANDIDATES`] candidates of the
//!    surface. The grid is laid over the bounding box of the first [`HEAD`] candidates (the
//!    candidates are independent and uniform, so these are a uniform sample of the surface;
//!    a candidate outside that box falls into the nearest boundary tile), its side from the
//!    mean spacing of the first [`PROBE`] of them. Using the first candidates, not all of
//!    them, is what lets a scene larger than memory be tiled before it has been seen whole.
//! 3. Each tile keeps `n_t` samples, `n · C_t / C` rounded by largest remainder (ties by
//!    tile order), so the total is exactly `n` and density follows the candidates' (a
//!    terrain keeps its density variation between tiles).
//! 4. In each tile, Yuksel's *sample elimination* (Yuksel 2015, "Sample Elimination for
//!    Generating Poisson Disk Sample Sets", EG): every candidate weighs
//!    `Σ_j (1 − d_ij / 2r_max)^8` over the candidates within `2r_max`, `r_max` the radius of
//!    `n_t` discs packed hexagonally on the tile's surface; the heaviest is removed and its
//!    neighbours' weights lowered, until `n_t` remain (ties by candidate index).
//!    `r_max = √(c / (2√3 λ_t))`, `λ_t` the candidates' density in the tile (from the mean
//!    6-th-neighbour distance of a probe, exact for uniform random samples: `πλd₆²` is
//!    Gamma(6)), so only local density is used.
//! 5. Output: tiles in grid order (z, y, x), each tile's kept samples in candidate order —
//!    spatially coherent, as a scan's vertex order is.
//!
//! Tiles do not see each other: along a tile's faces two samples of neighbouring tiles may
//! be closer than inside a tile (a seam slightly denser, never a gap). With tiles of ≈ 2¹⁶
//! candidates (16 k samples), about 3 % of the samples lie within one spacing of a face.
//!
//! **Out of core** ([`Generator::generate_to_file_sampled`](super::Generator::generate_to_file_sampled)):
//! the tiles are grouped into partitions of about [`PART_CANDIDATES`] candidates (contiguous
//! runs of tiles in grid order, cut at quantiles of the first candidates' tiles). One pass
//! over the candidates counts every tile and spills each candidate to its partition's file;
//! each partition is then read back, eliminated tile by tile, written out and deleted. Where
//! the output's file system has room for 32 bytes a candidate (128 a sample: position,
//! normal, colour, index) that is all — one pass over the candidates. Otherwise the spill
//! holds positions and indices only (16 bytes a candidate), and a second pass over the
//! candidates writes the kept ones in candidate order to a staged column file, finally
//! permuted into tile order (that permutation reads the staged file in random order: fast
//! while it fits the page cache, 24 bytes a sample). Memory: one partition (≈ 0.5 GB). The
//! partitioning and the path change nothing in the result: the in-memory, one-pass and
//! two-pass paths give the same bytes (unit-tested with partitions of a few tiles).
//!
//! **Measured** (`scripts/sampling-measurements.sh`, `results/measurements/issue-35-sampling.md`;
//! `scenes/tests/even_sampling.rs` states the bounds), 240 k samples, nearest-neighbour CV /
//! bare fraction of discs of the area per sample: statue random 0.523 / 0.368 (the Poisson
//! values), even 0.126 / 0.173; isosurface random 0.518 / 0.392, even 0.129 / 0.189; the
//! Stanford bunny's mesh vertices (a real scan) 0.153 / 0.165. Even sampling is the closer
//! stand-in for the papers' scans.
//!
//! **Cost**: ≈ 6 s per million samples on 2 cores in one pass, ≈ 8.6 in two
//! (`results/measurements/issue-35-reproduction.md`): generating the candidates and the
//! elimination.
//!
//! **Limits**: candidates are indexed by `u32`, so at most [`EVEN_MAX_POINTS`] samples; in
//! memory ([`Generator::generate_sampled`](super::Generator::generate_sampled), which holds
//! every candidate) at most [`EVEN_MAX_IN_MEMORY`].

mod eliminate;
mod spill;

use std::path::{Path, PathBuf};

use glam::{DVec3, U64Vec3, Vec3};
use rayon::prelude::*;

use crate::colfile::ColumnWriter;
use crate::{Attributes, PointCloud, Progress, SceneError};
use eliminate::{KeyMap, allocate, eliminate, mean_spacing};
use spill::Spill;

/// How a generator places its samples on its surface.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Hash)]
pub enum Sampling {
    /// Independent area-uniform samples (a Poisson process): the generators' first
    /// sampling; aerial LiDAR is closer to it.
    #[default]
    Random,
    /// Near-uniform spacing by sample elimination ([`even`](self)): like mesh vertices of a
    /// merged scan.
    Even,
}

impl Sampling {
    /// `random` or `even`.
    pub fn name(self) -> &'static str {
        match self {
            Sampling::Random => "random",
            Sampling::Even => "even",
        }
    }

    /// By name (`random`, `even`).
    pub fn from_name(name: &str) -> Option<Self> {
        match name {
            "random" => Some(Sampling::Random),
            "even" => Some(Sampling::Even),
            _ => None,
        }
    }
}

/// Candidates per kept sample (Yuksel's paper uses 3–5; the spacing's spread shrinks with
/// more, the cost grows linearly).
pub const OVERSAMPLING: usize = 4;
/// Candidates per tile, about.
pub const TILE_CANDIDATES: usize = 1 << 16;
/// Most samples an even scene may have: its candidates are indexed by `u32`.
pub const EVEN_MAX_POINTS: usize = (u32::MAX as usize) / OVERSAMPLING;
/// Most samples [`Generator::generate_sampled`](super::Generator::generate_sampled) makes in
/// memory (it holds every candidate, 24–27 bytes each); a column file has no such limit.
pub const EVEN_MAX_IN_MEMORY: usize = 40_000_000;
/// The first candidates whose bounding box the tile grid covers.
pub const HEAD: usize = super::BLOCK * super::BATCH_BLOCKS;
/// The first candidates whose mean spacing sizes the tiles.
pub const PROBE: usize = 16_384;
/// Candidates per partition, about (out of core: one partition is in memory at a time).
pub const PART_CANDIDATES: usize = 1 << 24;

/// Checks that `n` samples can be sampled evenly, in memory when `in_memory`.
pub fn check_count(n: usize, in_memory: bool) -> Result<(), SceneError> {
    let (max, why) = match in_memory {
        true => (
            EVEN_MAX_IN_MEMORY,
            "in memory even sampling holds {OVERSAMPLING} candidates per sample (write a column \
             file, or use random sampling, ':random')",
        ),
        false => (
            EVEN_MAX_POINTS,
            "even sampling indexes its candidates by 32 bits (use random sampling, ':random')",
        ),
    };
    if n > max {
        let why = why.replace("{OVERSAMPLING}", &OVERSAMPLING.to_string());
        return Err(SceneError::InvalidCloud(format!(
            "even sampling: at most {max} samples, asked for {n}: {why}"
        )));
    }
    Ok(())
}

/// One batch of candidates: the index of its first, its positions and attributes.
pub(crate) struct Batch<'a> {
    pub first: usize,
    pub pos: &'a [[f32; 3]],
    pub nrm: Option<&'a [[f32; 3]]>,
    pub col: Option<&'a [[u8; 3]]>,
}

/// Candidates in a fixed order, read batch by batch: every read gives the same candidates.
pub(crate) trait Candidates: Sync {
    /// How many.
    fn len(&self) -> usize;
    /// Their columns (radii are never carried over).
    fn attributes(&self) -> Attributes;
    /// World origin of their positions.
    fn origin(&self) -> DVec3;
    /// Positions of the first `m` (at most [`len`](Self::len)).
    fn head(&self, m: usize) -> Result<Vec<[f32; 3]>, SceneError>;
    /// Calls `f` on consecutive batches covering every candidate, in order.
    fn each_batch(
        &self,
        f: &mut dyn FnMut(Batch<'_>) -> Result<(), SceneError>,
    ) -> Result<(), SceneError>;
}

/// A cloud's columns as candidates.
struct Columns<'a> {
    pos: &'a [[f32; 3]],
    nrm: Option<&'a [[f32; 3]]>,
    col: Option<&'a [[u8; 3]]>,
    origin: DVec3,
}

impl Candidates for Columns<'_> {
    fn len(&self) -> usize {
        self.pos.len()
    }
    fn attributes(&self) -> Attributes {
        Attributes {
            normals: self.nrm.is_some(),
            colors: self.col.is_some(),
            radii: false,
        }
    }
    fn origin(&self) -> DVec3 {
        self.origin
    }
    fn head(&self, m: usize) -> Result<Vec<[f32; 3]>, SceneError> {
        Ok(self.pos[..m.min(self.pos.len())].to_vec())
    }
    fn each_batch(
        &self,
        f: &mut dyn FnMut(Batch<'_>) -> Result<(), SceneError>,
    ) -> Result<(), SceneError> {
        for first in (0..self.pos.len()).step_by(HEAD) {
            let end = (first + HEAD).min(self.pos.len());
            f(Batch {
                first,
                pos: &self.pos[first..end],
                nrm: self.nrm.map(|c| &c[first..end]),
                col: self.col.map(|c| &c[first..end]),
            })?;
        }
        Ok(())
    }
}

/// Keeps exactly `n` of `candidates` (which must hold at least `n`), evenly spaced, in
/// memory; see the module docs. The result has the candidates' normals, colours and origin.
pub fn thin(candidates: &PointCloud, n: usize) -> Result<PointCloud, SceneError> {
    let src = Columns {
        pos: candidates.positions(),
        nrm: candidates.normals(),
        col: candidates.colors(),
        origin: candidates.origin(),
    };
    let order = select_order(&src, n, &Options::in_memory(), &crate::NoProgress)?;
    PointCloud::new(
        candidates.origin(),
        gather(candidates.positions(), &order).into(),
        candidates.normals().map(|c| gather(c, &order).into()),
        candidates.colors().map(|c| gather(c, &order).into()),
        None,
    )
}

/// `column[i]` for each `i` of `idx`.
fn gather<T: Copy>(column: &[T], idx: &[u32]) -> Vec<T> {
    idx.iter().map(|&i| column[i as usize]).collect()
}

/// The indices of the `n` kept candidates of `positions`, in output order (tiles in grid
/// order, candidate order inside a tile).
pub fn select(positions: &[[f32; 3]], n: usize) -> Vec<usize> {
    let src = Columns {
        pos: positions,
        nrm: None,
        col: None,
        origin: DVec3::ZERO,
    };
    select_order(&src, n, &Options::in_memory(), &crate::NoProgress)
        .map(|o| o.into_iter().map(|i| i as usize).collect())
        .unwrap_or_default() // in memory nothing can fail
}

/// How the selection holds its candidates (the result does not depend on it).
#[derive(Debug, Clone)]
pub(crate) struct Options {
    /// Candidates per partition, about.
    pub part_candidates: usize,
    /// Where partitions spill when there are several (`None`: in memory).
    pub spill_dir: Option<PathBuf>,
    /// Writing a file: one pass (attributes spilled) or two; `None`: one where the disk
    /// has room.
    pub one_pass: Option<bool>,
}

impl Options {
    fn in_memory() -> Self {
        Self {
            part_candidates: PART_CANDIDATES,
            spill_dir: None,
            one_pass: None,
        }
    }

    /// Out of core beside the column file `path`.
    pub fn beside(path: &Path) -> Self {
        let mut dir = path.as_os_str().to_owned();
        dir.push(format!(".even-spill.{}", std::process::id()));
        Self {
            part_candidates: PART_CANDIDATES,
            spill_dir: Some(dir.into()),
            one_pass: None,
        }
    }
}

/// The tile grid (module docs, step 2).
struct Grid {
    lo: Vec3,
    side: f32,
    dims: U64Vec3,
}

impl Grid {
    /// Over the bounding box of `head`, tiles sized from the spacing of its first [`PROBE`],
    /// scaled to `total` candidates.
    fn new(head: &[[f32; 3]], total: usize) -> Self {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in head {
            lo = lo.min(Vec3::from(*p));
            hi = hi.max(Vec3::from(*p));
        }
        let probe = &head[..head.len().min(PROBE)];
        let spacing = mean_spacing(probe) * (probe.len() as f32 / total as f32).sqrt();
        let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
        let side = if spacing.is_finite() && spacing > 0.0 {
            (spacing * (TILE_CANDIDATES as f32).sqrt()).min(extent)
        } else {
            extent
        };
        let dims = ((hi - lo) / side).floor().as_u64vec3() + 1;
        Self { lo, side, dims }
    }

    /// The tile of `p`, in grid order (z, then y, then x); outside the box, the nearest.
    fn key(&self, p: &[f32; 3]) -> u64 {
        // `as` saturates: below the box (and NaN) → 0.
        let q = ((Vec3::from(*p) - self.lo) / self.side)
            .floor()
            .as_u64vec3()
            .min(self.dims - 1);
        (q.z * self.dims.y + q.y) * self.dims.x + q.x
    }
}

/// What a spilled candidate carries: at least its position and its index in candidate order.
trait SpillRec: bytemuck::Pod + Send + Sync {
    /// Candidate `i` of batch `b`.
    fn of(b: &Batch<'_>, i: usize) -> Self;
    fn pos(&self) -> [f32; 3];
    fn idx(&self) -> u32;
}

/// Position and index (16 bytes): the two-pass path's record.
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
struct Rec {
    pos: [f32; 3],
    idx: u32,
}

impl SpillRec for Rec {
    fn of(b: &Batch<'_>, i: usize) -> Self {
        Rec {
            pos: b.pos[i],
            idx: (b.first + i) as u32,
        }
    }
    fn pos(&self) -> [f32; 3] {
        self.pos
    }
    fn idx(&self) -> u32 {
        self.idx
    }
}

/// Position, normal, colour and index (32 bytes): the one-pass path's record, which is
/// written out as it is kept.
#[derive(Debug, Clone, Copy, PartialEq, bytemuck::Pod, bytemuck::Zeroable)]
#[repr(C)]
struct FullRec {
    pos: [f32; 3],
    nrm: [f32; 3],
    idx: u32,
    col: [u8; 4],
}

impl SpillRec for FullRec {
    fn of(b: &Batch<'_>, i: usize) -> Self {
        let c = b.col.map_or([0; 3], |c| c[i]);
        FullRec {
            pos: b.pos[i],
            nrm: b.nrm.map_or([0.0; 3], |c| c[i]),
            idx: (b.first + i) as u32,
            col: [c[0], c[1], c[2], 0],
        }
    }
    fn pos(&self) -> [f32; 3] {
        self.pos
    }
    fn idx(&self) -> u32 {
        self.idx
    }
}

/// The candidate indices kept, in output order: steps 2–5 of the module docs.
fn select_order(
    src: &dyn Candidates,
    n: usize,
    opts: &Options,
    progress: &dyn Progress,
) -> Result<Vec<u32>, SceneError> {
    let mut order: Vec<u32> = Vec::with_capacity(n.min(src.len()));
    select_kept::<Rec>(src, n, opts, progress, &mut |kept| {
        order.extend(kept.iter().map(|r| r.idx));
        Ok(())
    })?;
    Ok(order)
}

/// Steps 2–5 of the module docs: `emit` receives the kept candidates' records in output
/// order, a partition at a time.
fn select_kept<R: SpillRec>(
    src: &dyn Candidates,
    n: usize,
    opts: &Options,
    progress: &dyn Progress,
    emit: &mut dyn FnMut(&[R]) -> Result<(), SceneError>,
) -> Result<(), SceneError> {
    let total = src.len();
    if total > u32::MAX as usize {
        return Err(SceneError::InvalidCloud(format!(
            "even sampling indexes candidates by 32 bits: {total} candidates"
        )));
    }
    if n == 0 {
        return Ok(());
    }
    if n >= total {
        return src.each_batch(&mut |b| {
            let recs: Vec<R> = (0..b.pos.len()).map(|i| R::of(&b, i)).collect();
            emit(&recs)
        });
    }
    let head = src.head(HEAD)?;
    let grid = Grid::new(&head, total);
    // Partitions: runs of tiles cut at quantiles of the head's tiles.
    let mut head_keys: Vec<u64> = head.iter().map(|p| grid.key(p)).collect();
    head_keys.sort_unstable();
    let parts = total.div_ceil(opts.part_candidates.max(1)).max(1);
    let mut cuts: Vec<u64> = (1..parts)
        .map(|k| head_keys[k * head_keys.len() / parts])
        .collect();
    cuts.dedup();
    let part_of = |key: u64| cuts.partition_point(|&c| c <= key);
    let mut spill: Spill<R> = match &opts.spill_dir {
        Some(dir) if cuts.len() + 1 > 1 => {
            let bytes = total as u64 * std::mem::size_of::<R>() as u64;
            crate::colfile::check_free_space(dir, bytes)?;
            Spill::files(dir.clone(), cuts.len() + 1)?
        }
        _ => Spill::memory(cuts.len() + 1),
    };
    progress.start(
        &format!("even sampling: {total} candidates into tiles"),
        total as u64,
    );
    let mut counts: KeyMap<u64> = KeyMap::default();
    src.each_batch(&mut |b| {
        let keys: Vec<u64> = b.pos.par_iter().map(|p| grid.key(p)).collect();
        for (i, &k) in keys.iter().enumerate() {
            *counts.entry(k).or_insert(0) += 1;
            spill.push(part_of(k), R::of(&b, i))?;
        }
        progress.inc(b.pos.len() as u64);
        Ok(())
    })?;
    progress.finish();
    let mut tiles: Vec<(u64, u64)> = counts.into_iter().collect();
    tiles.sort_unstable();
    let counts: Vec<u64> = tiles.iter().map(|t| t.1).collect();
    let targets: KeyMap<u64> = tiles
        .iter()
        .map(|t| t.0)
        .zip(allocate(&counts, n as u64))
        .collect();
    progress.start(
        &format!("even sampling: eliminating down to {n}"),
        (cuts.len() + 1) as u64,
    );
    for part in 0..=cuts.len() {
        let mut recs: Vec<(u64, R)> = spill
            .take(part)?
            .into_par_iter()
            .map(|r| (grid.key(&r.pos()), r))
            .collect();
        recs.par_sort_unstable_by_key(|r| (r.0, r.1.idx()));
        let mut runs: Vec<&[(u64, R)]> = Vec::new();
        let mut rest = &recs[..];
        while let Some(first) = rest.first() {
            let len = rest.partition_point(|r| r.0 == first.0);
            runs.push(&rest[..len]);
            rest = &rest[len..];
        }
        let kept: Vec<Vec<R>> = runs
            .par_iter()
            .map(|t| {
                let pts: Vec<Vec3> = t.iter().map(|r| Vec3::from(r.1.pos())).collect();
                let keep = targets.get(&t[0].0).copied().unwrap_or(0) as usize;
                let alive = eliminate(&pts, keep);
                t.iter()
                    .zip(alive)
                    .filter_map(|(r, a)| a.then_some(r.1))
                    .collect()
            })
            .collect();
        drop(runs);
        drop(recs);
        for k in &kept {
            emit(k)?;
        }
        progress.inc(1);
    }
    progress.finish();
    Ok(())
}

/// Keeps `n` of `src`'s candidates, evenly spaced, straight into the column file `path`
/// (out of core: see the module docs): in one pass over the candidates where the disk holds
/// their attributes (32 bytes each), else in two.
pub(crate) fn sample_to_file(
    src: &dyn Candidates,
    n: usize,
    path: &Path,
    opts: &Options,
    progress: &dyn Progress,
) -> Result<PointCloud, SceneError> {
    let one_pass = opts.one_pass.unwrap_or_else(|| {
        let need = src.len() as u64 * std::mem::size_of::<FullRec>() as u64 + n as u64 * 27;
        match &opts.spill_dir {
            Some(dir) => crate::colfile::check_free_space(dir, need).is_ok(),
            None => true,
        }
    });
    if one_pass {
        one_pass_to_file(src, n, path, opts, progress)
    } else {
        two_pass_to_file(src, n, path, opts, progress)
    }
}

/// The kept candidates' records carry their attributes: written out as each partition is
/// eliminated, in output order.
fn one_pass_to_file(
    src: &dyn Candidates,
    n: usize,
    path: &Path,
    opts: &Options,
    progress: &dyn Progress,
) -> Result<PointCloud, SceneError> {
    let attrs = src.attributes();
    let mut w = ColumnWriter::create(path, attrs, src.origin(), n.min(src.len()) as u64)?;
    select_kept::<FullRec>(src, n, opts, progress, &mut |kept| {
        let pos: Vec<[f32; 3]> = kept.iter().map(|r| r.pos).collect();
        let nrm: Vec<[f32; 3]> = kept.iter().map(|r| r.nrm).collect();
        let col: Vec<[u8; 3]> = kept
            .iter()
            .map(|r| [r.col[0], r.col[1], r.col[2]])
            .collect();
        w.push(
            &pos,
            attrs.normals.then_some(&nrm[..]),
            attrs.colors.then_some(&col[..]),
            None,
        )
    })?;
    w.finish()
}

/// Positions only in the spill (16 bytes a candidate); a second pass over the candidates
/// gathers the kept ones' attributes into a staged file, permuted into output order.
fn two_pass_to_file(
    src: &dyn Candidates,
    n: usize,
    path: &Path,
    opts: &Options,
    progress: &dyn Progress,
) -> Result<PointCloud, SceneError> {
    let order = select_order(src, n, opts, progress)?;
    let n = order.len();
    // Kept candidates in candidate order, each with its output slot.
    let mut kept: Vec<(u32, u32)> = order
        .iter()
        .enumerate()
        .map(|(slot, &i)| (i, slot as u32))
        .collect();
    drop(order);
    kept.par_sort_unstable();
    let attrs = src.attributes();
    let mut staged = path.as_os_str().to_owned();
    staged.push(format!(".even-staged.{}", std::process::id()));
    let staged = RemoveOnDrop(staged.into());
    let mut w = ColumnWriter::create(&staged.0, attrs, src.origin(), n as u64)?;
    progress.start(&format!("even sampling: writing {n} samples"), n as u64);
    let mut at = 0usize;
    let (mut pos, mut nrm, mut col) = (Vec::new(), Vec::new(), Vec::new());
    src.each_batch(&mut |b| {
        let end = b.first + b.pos.len();
        pos.clear();
        nrm.clear();
        col.clear();
        while at < kept.len() && (kept[at].0 as usize) < end {
            let i = kept[at].0 as usize - b.first;
            pos.push(b.pos[i]);
            if let Some(c) = b.nrm {
                nrm.push(c[i]);
            }
            if let Some(c) = b.col {
                col.push(c[i]);
            }
            at += 1;
        }
        w.push(
            &pos,
            attrs.normals.then_some(&nrm[..]),
            attrs.colors.then_some(&col[..]),
            None,
        )
    })?;
    let staged_cloud = w.finish()?;
    // Slot → rank in candidate order, then the staged file read in slot order.
    let mut rank = vec![0u32; n];
    for (j, &(_, slot)) in kept.iter().enumerate() {
        rank[slot as usize] = j as u32;
    }
    drop(kept);
    let mut w = ColumnWriter::create(path, attrs, src.origin(), n as u64)?;
    for chunk in rank.chunks(HEAD) {
        let pos = gather(staged_cloud.positions(), chunk);
        let nrm = staged_cloud.normals().map(|c| gather(c, chunk));
        let col = staged_cloud.colors().map(|c| gather(c, chunk));
        w.push(&pos, nrm.as_deref(), col.as_deref(), None)?;
        progress.inc(chunk.len() as u64);
    }
    drop(staged_cloud);
    let cloud = w.finish();
    progress.finish();
    cloud
}

/// A file removed when dropped (a staging file, also on error).
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.0);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn elimination_keeps_exactly_and_spreads_a_plane() {
        // 4 000 random candidates on the unit square, 1 000 kept: the kept set's smallest
        // nearest-neighbour distance is far above the candidates'.
        let mut rng = crate::rng::Pcg32::new(5);
        let pts: Vec<[f32; 3]> = (0..4000).map(|_| [rng.f32(), rng.f32(), 0.0]).collect();
        let keep = select(&pts, 1000);
        assert_eq!(keep.len(), 1000);
        let mut sorted = keep.clone();
        sorted.sort_unstable();
        sorted.dedup();
        assert_eq!(sorted.len(), 1000, "no candidate twice");
        let kept: Vec<[f32; 3]> = keep.iter().map(|&i| pts[i]).collect();
        let nn = crate::spacing::knn_spacing(&kept, 1);
        let min = nn.iter().copied().fold(f32::INFINITY, f32::min);
        // Hexagonal packing radius of 1 000 discs on the unit square: r_max ≈ 0.0170; a
        // Poisson-disk set reaches ≳ 0.6 r_max as its smallest distance (Yuksel: ~0.75 in
        // the interior), random points reach ≈ 0.
        assert!(min > 0.5 * 0.0170, "min nn {min}");
        assert_eq!(select(&pts, 1000), keep, "deterministic");
    }

    #[test]
    fn out_of_core_partitions_give_the_in_memory_bytes() {
        // 200 k statue candidates in partitions of ≈ 20 k (a few tiles each) spilled to
        // files, and written in one pass or through the staged permutation: the same
        // samples, in the same order, as the in-memory path with one partition; the same
        // for a terrain's (colours too).
        use super::super::Generator;
        for (g, n, part) in [
            (Generator::Statue, 50_000, 20_000),
            (Generator::Terrain, 30_000, 15_000),
        ] {
            out_of_core_equals_in_memory(g, n, part);
        }
    }

    /// Records each phase's name and total.
    #[derive(Default)]
    struct Phases(std::sync::Mutex<Vec<(String, u64)>>);

    impl Phases {
        fn total_of(&self, prefix: &str) -> u64 {
            let p = self.0.lock().unwrap();
            p.iter()
                .find(|(w, _)| w.starts_with(prefix))
                .map_or(0, |(_, t)| *t)
        }
    }

    impl Progress for Phases {
        fn start(&self, what: &str, total: u64) {
            self.0.lock().unwrap().push((what.to_owned(), total));
        }
        fn inc(&self, _: u64) {}
        fn finish(&self) {}
    }

    fn out_of_core_equals_in_memory(g: super::super::Generator, n: usize, part: usize) {
        let cand = g.generate(n * OVERSAMPLING, 7).unwrap();
        let want = thin(&cand, n).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("even.sbc");
        let src = Columns {
            pos: cand.positions(),
            nrm: cand.normals(),
            col: cand.colors(),
            origin: cand.origin(),
        };
        for one_pass in [false, true] {
            let opts = Options {
                part_candidates: part,
                spill_dir: Some(dir.path().join("spill")),
                one_pass: Some(one_pass),
            };
            let phases = Phases::default();
            let got = sample_to_file(&src, n, &path, &opts, &phases).unwrap();
            // The run really was out of core: several partitions were eliminated in turn.
            let parts = phases.total_of("even sampling: eliminating");
            assert!(parts > 1, "{:?}: one partition", g.name());
            assert_eq!(got.positions(), want.positions(), "one pass: {one_pass}");
            assert_eq!(got.normals(), want.normals(), "one pass: {one_pass}");
            assert_eq!(got.colors(), want.colors(), "one pass: {one_pass}");
            assert_eq!(got.origin(), want.origin());
            drop(got);
            let left: Vec<_> = std::fs::read_dir(dir.path())
                .unwrap()
                .map(|e| e.unwrap().file_name())
                .collect();
            assert_eq!(
                left,
                vec![std::ffi::OsString::from("even.sbc")],
                "spill and staging removed"
            );
            std::fs::remove_file(&path).unwrap();
        }
    }
}
