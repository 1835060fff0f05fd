//! Procedural scenes: seeded, deterministic, any size.
//!
//! Contract (all generators):
//! - exactly `n` points for any `n ≥ 1` (`n = 0` is an error, never a panic);
//! - same `(n, seed)` ⇒ byte-identical columns, whatever the number of rayon threads, and
//!   [`Generator::generate_to_file`] writes the same bytes [`Generator::generate`] returns;
//! - **+Z is up** in every scene;
//! - normals are analytic (gradients of the defining functions, never finite differences),
//!   unit length, and only the attributes listed in [`Generator::attributes`] are produced.
//!
//! How determinism is achieved: the points are produced in fixed blocks of [`BLOCK`] points;
//! block `b` draws only from [`Pcg32::stream`]`(seed, b)`, and the scene's own random
//! parameters (waves, density grid) from a reserved stream. Blocks run in parallel and are
//! stored in block order, so the thread count cannot change a byte. Trigonometry goes through
//! the portable [`waves::sincos`]; a few `exp`/`powf` calls still use the platform's libm, so
//! identical bytes are guaranteed on one platform and toolchain, not across operating systems
//! (bump the scene cache's generator version if a result ever changes).
//!
//! `generate_to_file` fills [`BATCH_BLOCKS`] blocks at a time in parallel and pushes them in
//! order through a [`ColumnWriter`], so a 100 M-point scene never sits in memory.
//!
//! The scenes ([`statue`], [`isosurface`], [`terrain`]) stand in for the papers' St. Matthew
//! statue, the Richtmyer–Meshkov isosurface and LiDAR surveys; each module documents its
//! construction.

pub mod even;
pub mod isosurface;
pub mod statue;
pub mod terrain;
pub mod waves;

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use crate::colfile::ColumnWriter;
use crate::rng::Pcg32;
use crate::{Attributes, PointCloud, Progress, SceneError};
use even::Candidates as _;
pub use even::Sampling;

/// Points per block: the unit of seeding and of parallel work.
pub const BLOCK: usize = 4096;
/// Blocks generated in parallel per batch in [`Generator::generate_to_file`].
pub const BATCH_BLOCKS: usize = 64;
/// The stream index (of the user's seed) that scene parameters are drawn from; blocks use
/// streams `0, 1, 2, …`, far below it.
pub(crate) const PARAM_STREAM: u64 = u64::MAX;

/// The generators.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Generator {
    /// Statue-like closed surface.
    Statue,
    /// Turbulent isosurface.
    Isosurface,
    /// The turbulent isosurface at three times the wave number: the papers' depth
    /// complexity (> 100) for scenes of ≥ 100 M samples.
    IsosurfaceDeep,
    /// LiDAR-like terrain.
    Terrain,
}

impl Generator {
    /// All generators.
    pub const ALL: &'static [Generator] = &[
        Generator::Statue,
        Generator::Isosurface,
        Generator::IsosurfaceDeep,
        Generator::Terrain,
    ];

    /// Name.
    pub fn name(self) -> &'static str {
        match self {
            Generator::Statue => "statue",
            Generator::Isosurface => "isosurface",
            Generator::IsosurfaceDeep => "isosurface-deep",
            Generator::Terrain => "terrain",
        }
    }

    /// One-line description.
    pub fn describe(self) -> &'static str {
        match self {
            Generator::Statue => {
                "closed 2 m standing figure with fractal relief (48 waves, 1.6 cm–2 m), area-uniform, normals"
            }
            Generator::Isosurface => {
                "turbulent mixing-layer isosurface in a 2×2×1.2 box, depth complexity > 20, normals"
            }
            Generator::IsosurfaceDeep => {
                "the isosurface at 3× the wave number (2.1 cm): depth complexity > 100, the papers'; for ≥ 100 M samples"
            }
            Generator::Terrain => {
                "2 km LiDAR-like terrain at UTM (500000, 4100000), density varying > 300×, normals + colours"
            }
        }
    }

    /// By name.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.iter().copied().find(|g| g.name() == name)
    }

    /// The sampling `generator:points:seed` means when none is named: [`Sampling::Even`] for
    /// `statue` and `isosurface`, which stand in for the papers' scanned and extracted
    /// surfaces (mesh vertices: measured nearest-neighbour CV 0.15 on the Stanford bunny,
    /// 0.13 for even samples, 0.52 for random ones: [`even`]); [`Sampling::Random`] for
    /// `terrain`, as aerial LiDAR is closer to it. `:random` still asks for random samples.
    pub fn default_sampling(self) -> Sampling {
        match self {
            Generator::Statue | Generator::Isosurface | Generator::IsosurfaceDeep => Sampling::Even,
            Generator::Terrain => Sampling::Random,
        }
    }

    /// The attributes this generator produces.
    pub fn attributes(self) -> Attributes {
        Attributes {
            normals: true,
            colors: self == Generator::Terrain,
            radii: false,
        }
    }

    /// Generates `n` points with `seed`, in memory.
    pub fn generate(self, n: usize, seed: u64) -> Result<PointCloud, SceneError> {
        check_n(self, n)?;
        generate_from(self.sampler(seed).as_ref(), n, seed, 0)
    }

    /// `n` independent area-uniform points of the same surface as `seed`'s scene, from
    /// random streams no scene uses (blocks from [`TEST_POINT_BLOCK`] on): test points that
    /// share no sample with any scene of this seed ([`crate::regularity`]).
    pub fn test_points(self, n: usize, seed: u64) -> Result<PointCloud, SceneError> {
        check_n(self, n)?;
        generate_from(self.sampler(seed).as_ref(), n, seed, TEST_POINT_BLOCK)
    }

    /// The scene of `seed`.
    fn sampler(self, seed: u64) -> Box<dyn BlockSampler> {
        match self {
            Generator::Statue => Box::new(statue::Statue::new(seed)),
            Generator::Isosurface => Box::new(isosurface::Isosurface::new(seed)),
            Generator::IsosurfaceDeep => Box::new(isosurface::Isosurface::deep(seed)),
            Generator::Terrain => Box::new(terrain::Terrain::new(seed)),
        }
    }

    /// Generates `n` points with `seed` and `sampling`, in memory ([`Sampling::Even`]: from
    /// [`even::OVERSAMPLING`]` · n` random candidates of the same seed, [`even`]; at most
    /// [`even::EVEN_MAX_IN_MEMORY`]).
    pub fn generate_sampled(
        self,
        n: usize,
        seed: u64,
        sampling: Sampling,
    ) -> Result<PointCloud, SceneError> {
        match sampling {
            Sampling::Random => self.generate(n, seed),
            Sampling::Even => {
                check_n(self, n)?;
                even::check_count(n, true)?;
                let candidates = self.generate(n * even::OVERSAMPLING, seed)?;
                even::thin(&candidates, n)
            }
        }
    }

    /// [`generate_to_file`](Self::generate_to_file) with `sampling`; the bytes equal
    /// [`generate_sampled`](Self::generate_sampled)'s. Even samples are made out of core
    /// (the candidates are generated twice and spilled beside `path`: [`even`]).
    pub fn generate_to_file_sampled(
        self,
        n: usize,
        seed: u64,
        sampling: Sampling,
        path: &Path,
        progress: &dyn Progress,
    ) -> Result<PointCloud, SceneError> {
        match sampling {
            Sampling::Random => self.generate_to_file(n, seed, path, progress),
            Sampling::Even => {
                check_n(self, n)?;
                even::check_count(n, false)?;
                let s = self.sampler(seed);
                let src = Generated {
                    s: s.as_ref(),
                    seed,
                    n: n * even::OVERSAMPLING,
                };
                even::sample_to_file(&src, n, path, &even::Options::beside(path), progress)
            }
        }
    }

    /// Generates `n` points with `seed` straight into the column file `path` (written through
    /// `<path>.tmp` and renamed when complete) and returns it memory-mapped. Holds at most
    /// [`BATCH_BLOCKS`] × [`BLOCK`] points in memory; the bytes equal [`generate`](Self::generate)'s.
    pub fn generate_to_file(
        self,
        n: usize,
        seed: u64,
        path: &Path,
        progress: &dyn Progress,
    ) -> Result<PointCloud, SceneError> {
        check_n(self, n)?;
        let s = self.sampler(seed);
        let src = Generated {
            s: s.as_ref(),
            seed,
            n,
        };
        let mut w = ColumnWriter::create(path, src.attributes(), s.origin(), n as u64)?;
        progress.start(
            &format!("generating {n} points of {}", self.name()),
            n as u64,
        );
        src.each_batch(&mut |b| {
            w.push(b.pos, b.nrm, b.col, None)?;
            progress.inc(b.pos.len() as u64);
            Ok(())
        })?;
        progress.finish();
        w.finish()
    }
}

fn check_n(g: Generator, n: usize) -> Result<(), SceneError> {
    if n == 0 {
        return Err(SceneError::Spec {
            spec: format!("{}:0", g.name()),
            msg: "a generated scene needs at least one point".into(),
        });
    }
    Ok(())
}

/// A scene that fills blocks of points (internal to the generators).
pub(crate) trait BlockSampler: Sync {
    /// World origin of the scene (added to the local `f32` positions).
    fn origin(&self) -> DVec3;
    /// Whether the scene has colours (all scenes have normals).
    fn has_colors(&self) -> bool;
    /// Fills one block: `pos.len() == nrm.len()` points, and colours when the scene has them
    /// (then `col.len() == pos.len()`), drawing randomness from `rng` only.
    fn fill(
        &self,
        rng: &mut Pcg32,
        pos: &mut [[f32; 3]],
        nrm: &mut [[f32; 3]],
        col: Option<&mut [[u8; 3]]>,
    );
}

/// Fills the blocks `first_block, first_block + 1, …` covering the given buffers, in parallel.
fn fill_blocks<S: BlockSampler + ?Sized>(
    s: &S,
    seed: u64,
    first_block: u64,
    pos: &mut [[f32; 3]],
    nrm: &mut [[f32; 3]],
    col: Option<&mut [[u8; 3]]>,
) {
    let mut col_chunks = col.map(|c| c.chunks_mut(BLOCK));
    let jobs: Vec<_> = pos
        .chunks_mut(BLOCK)
        .zip(nrm.chunks_mut(BLOCK))
        .enumerate()
        .map(|(i, (p, n))| (i, p, n, col_chunks.as_mut().and_then(Iterator::next)))
        .collect();
    jobs.into_par_iter().for_each(|(i, p, n, c)| {
        let mut rng = Pcg32::stream(seed, first_block + i as u64);
        s.fill(&mut rng, p, n, c);
    });
}

/// `vec![value; n]`, but an error instead of an abort when the memory cannot be had.
fn try_vec<T: Clone>(n: usize, value: T, what: &str) -> Result<Vec<T>, SceneError> {
    let mut v = Vec::new();
    v.try_reserve_exact(n).map_err(|e| {
        SceneError::InvalidCloud(format!(
            "cannot allocate {what} for {n} points ({e}); generate large scenes to a column file"
        ))
    })?;
    v.resize(n, value);
    Ok(v)
}

/// The first block of [`Generator::test_points`]: far above any scene's blocks (a scene of
/// 2⁴⁰ blocks would have 4.5 · 10¹⁵ points) and below [`PARAM_STREAM`].
pub const TEST_POINT_BLOCK: u64 = 1 << 40;

fn generate_from<S: BlockSampler + ?Sized>(
    s: &S,
    n: usize,
    seed: u64,
    first_block: u64,
) -> Result<PointCloud, SceneError> {
    let mut pos = try_vec(n, [0.0f32; 3], "positions")?;
    let mut nrm = try_vec(n, [0.0f32; 3], "normals")?;
    let mut col = match s.has_colors() {
        true => Some(try_vec(n, [0u8; 3], "colours")?),
        false => None,
    };
    fill_blocks(s, seed, first_block, &mut pos, &mut nrm, col.as_deref_mut());
    PointCloud::new(
        s.origin(),
        pos.into(),
        Some(nrm.into()),
        col.map(Into::into),
        None,
    )
}

/// A generator's first `n` points as the candidates of even sampling (and the batches of
/// [`Generator::generate_to_file`]): blocks `0, 1, …`, [`BATCH_BLOCKS`] at a time.
struct Generated<'a> {
    s: &'a dyn BlockSampler,
    seed: u64,
    n: usize,
}

impl even::Candidates for Generated<'_> {
    fn len(&self) -> usize {
        self.n
    }

    fn attributes(&self) -> Attributes {
        Attributes {
            normals: true,
            colors: self.s.has_colors(),
            radii: false,
        }
    }

    fn origin(&self) -> DVec3 {
        self.s.origin()
    }

    fn head(&self, m: usize) -> Result<Vec<[f32; 3]>, SceneError> {
        let m = m.min(self.n);
        if m == 0 {
            return Ok(Vec::new());
        }
        Ok(generate_from(self.s, m, self.seed, 0)?.positions().to_vec())
    }

    fn each_batch(
        &self,
        f: &mut dyn FnMut(even::Batch<'_>) -> Result<(), SceneError>,
    ) -> Result<(), SceneError> {
        let batch = BLOCK * BATCH_BLOCKS;
        let cap = batch.min(self.n);
        let mut pos = vec![[0.0f32; 3]; cap];
        let mut nrm = vec![[0.0f32; 3]; cap];
        let mut col = self.s.has_colors().then(|| vec![[0u8; 3]; cap]);
        let mut start = 0usize;
        while start < self.n {
            let m = batch.min(self.n - start);
            fill_blocks(
                self.s,
                self.seed,
                (start / BLOCK) as u64,
                &mut pos[..m],
                &mut nrm[..m],
                col.as_mut().map(|c| &mut c[..m]),
            );
            f(even::Batch {
                first: start,
                pos: &pos[..m],
                nrm: Some(&nrm[..m]),
                col: col.as_ref().map(|c| &c[..m]),
            })?;
            start += m;
        }
        Ok(())
    }
}
