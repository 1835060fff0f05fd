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
//! needs nothing of a surface but samples of it — the same code serves every generator —
//! and is deterministic without any order dependence):
//! 1. `OVERSAMPLING · n` candidates: the generator's own random area-uniform samples with
//!    the same seed.
//! 2. Tiles: a grid of cubes whose side holds about [`TILE_CANDIDATES`] candidates of the
//!    surface (side from the mean spacing of a probe of candidates).
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
//! **Measured** (`scripts/sampling-measurements.sh`, `results/measurements/issue-35-sampling.md`;
//! `scenes/tests/even_sampling.rs` states the bounds), 240 k samples, nearest-neighbour CV /
//! bare fraction of discs of the area per sample: statue random 0.523 / 0.368 (the Poisson
//! values), even 0.126 / 0.173; isosurface random 0.518 / 0.392, even 0.129 / 0.189; the
//! Stanford bunny's mesh vertices (a real scan) 0.153 / 0.165. Even sampling is the closer
//! stand-in for the papers' scans.
//!
//! **Cost**: about 20 s per million samples on 2 cores (the elimination dominates; the
//! random candidates take 2 s), so even scenes of ≥ 2 M samples are cached like the others.
//!
//! **Memory**: the candidates are held in memory (24–27 bytes each, `OVERSAMPLING` per
//! sample), so even sampling is limited to [`EVEN_MAX_POINTS`] samples (an error beyond).

use std::collections::BinaryHeap;

use glam::Vec3;
use rayon::prelude::*;

use crate::{PointCloud, SceneError};

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
/// Most samples an even scene may have: its candidates are held in memory.
pub const EVEN_MAX_POINTS: usize = 40_000_000;
/// Exponent of Yuksel's weight function.
const ALPHA: i32 = 8;
/// Neighbour rank whose mean distance gives the candidates' density.
const DENSITY_K: usize = 6;
/// `√π · Γ(6) / Γ(6.5)`: `mean d₆ · C6 = 1/√λ` for uniformly random samples of density λ.
const C6: f32 = 0.738_795_6;
/// Candidates per tile measured for the density.
const DENSITY_PROBES: usize = 2048;

/// Checks that `n` samples can be sampled evenly.
pub fn check_count(n: usize) -> Result<(), SceneError> {
    if n > EVEN_MAX_POINTS {
        return Err(SceneError::InvalidCloud(format!(
            "even sampling holds {OVERSAMPLING} candidates per sample in memory: at most \
             {EVEN_MAX_POINTS} samples, asked for {n} (use random sampling, ':random')"
        )));
    }
    Ok(())
}

/// Keeps exactly `n` of `candidates` (which must hold at least `n`), evenly spaced; see the
/// module docs. The result has the candidates' attributes and origin.
pub fn thin(candidates: &PointCloud, n: usize) -> Result<PointCloud, SceneError> {
    let keep = select(candidates.positions(), n);
    let pos: Vec<[f32; 3]> = keep.iter().map(|&i| candidates.positions()[i]).collect();
    let nrm = candidates
        .normals()
        .map(|c| keep.iter().map(|&i| c[i]).collect::<Vec<_>>());
    let col = candidates
        .colors()
        .map(|c| keep.iter().map(|&i| c[i]).collect::<Vec<_>>());
    PointCloud::new(
        candidates.origin(),
        pos.into(),
        nrm.map(Into::into),
        col.map(Into::into),
        None,
    )
}

/// The indices of the `n` kept candidates, in output order (tiles in grid order, candidate
/// order inside a tile).
pub fn select(positions: &[[f32; 3]], n: usize) -> Vec<usize> {
    let c = positions.len();
    if n >= c {
        return (0..c).collect();
    }
    if n == 0 {
        return Vec::new();
    }
    let tiles = tiles(positions);
    let counts: Vec<usize> = tiles.iter().map(|t| t.len()).collect();
    let targets = allocate(&counts, n);
    let kept: Vec<Vec<usize>> = tiles
        .par_iter()
        .zip(targets.par_iter())
        .map(|(t, &nt)| eliminate(positions, t, nt))
        .collect();
    kept.into_iter().flatten().collect()
}

/// Candidate indices grouped by tile, tiles in grid order (z, then y, then x), candidate
/// order inside each.
fn tiles(positions: &[[f32; 3]]) -> Vec<Vec<usize>> {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in positions {
        lo = lo.min(Vec3::from(*p));
        hi = hi.max(Vec3::from(*p));
    }
    // Tile side: a patch of the surface holding TILE_CANDIDATES candidates, from the mean
    // spacing of an evenly strided probe (the candidates are in random order).
    let stride = positions.len().div_ceil(DENSITY_PROBES * 8).max(1);
    let probe: Vec<[f32; 3]> = positions.iter().step_by(stride).copied().collect();
    let spacing_probe = mean_spacing(&probe);
    let spacing = spacing_probe * (probe.len() as f32 / positions.len() as f32).sqrt();
    let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
    let side = if spacing.is_finite() && spacing > 0.0 {
        (spacing * (TILE_CANDIDATES as f32).sqrt()).min(extent)
    } else {
        extent
    };
    let dims = ((hi - lo) / side).floor().as_uvec3() + 1;
    let key = |p: &[f32; 3]| {
        let q = ((Vec3::from(*p) - lo) / side)
            .floor()
            .as_uvec3()
            .min(dims - 1);
        (q.z as u64 * dims.y as u64 + q.y as u64) * dims.x as u64 + q.x as u64
    };
    let mut order: Vec<(u64, usize)> = positions.iter().map(key).zip(0..).collect();
    order.par_sort_unstable();
    let mut out: Vec<Vec<usize>> = Vec::new();
    let mut last = None;
    for (k, i) in order {
        if last != Some(k) {
            out.push(Vec::new());
            last = Some(k);
        }
        if let Some(t) = out.last_mut() {
            t.push(i);
        }
    }
    out
}

/// `1/√λ` of uniformly random samples from their mean 6-th-neighbour distance (NaN when
/// there are too few).
fn mean_spacing(points: &[[f32; 3]]) -> f32 {
    if points.len() <= DENSITY_K {
        return f32::NAN;
    }
    let d = crate::spacing::knn_spacing(points, DENSITY_K);
    let mean = d.iter().map(|&x| x as f64).sum::<f64>() / d.len() as f64;
    C6 * mean as f32
}

/// `n` split over tiles of `counts` candidates in proportion, by largest remainder (ties by
/// tile order), never more than a tile has.
fn allocate(counts: &[usize], n: usize) -> Vec<usize> {
    let total: usize = counts.iter().sum();
    let mut out: Vec<usize> = Vec::with_capacity(counts.len());
    let mut rem: Vec<(u128, usize)> = Vec::with_capacity(counts.len());
    for (t, &c) in counts.iter().enumerate() {
        let exact = n as u128 * c as u128;
        out.push((exact / total as u128) as usize);
        rem.push((exact % total as u128, t));
    }
    let mut left = n - out.iter().sum::<usize>();
    rem.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    for &(_, t) in &rem {
        if left == 0 {
            break;
        }
        if out[t] < counts[t] {
            out[t] += 1;
            left -= 1;
        }
    }
    out
}

/// Yuksel's elimination of one tile's candidates `tile` down to `keep`; the kept indices in
/// candidate order.
fn eliminate(positions: &[[f32; 3]], tile: &[usize], keep: usize) -> Vec<usize> {
    let m = tile.len();
    if keep >= m {
        return tile.to_vec();
    }
    if keep == 0 {
        return Vec::new();
    }
    let pts: Vec<Vec3> = tile.iter().map(|&i| Vec3::from(positions[i])).collect();
    // Candidates' density in the tile, from a strided probe measured against all of them.
    let stride = m.div_ceil(DENSITY_PROBES).max(1);
    let spacing = local_spacing(&pts, stride);
    let c = m as f32 / keep as f32;
    let r_max = if spacing.is_finite() && spacing > 0.0 {
        // λ = 1/spacing²; r_max = √(c / (2√3 λ)).
        spacing * (c / (2.0 * 3f32.sqrt())).sqrt()
    } else {
        0.0
    };
    let reach = 2.0 * r_max;
    let neighbours = if reach > 0.0 {
        Neighbours::within(&pts, reach)
    } else {
        Neighbours::none(m)
    };
    let weight_of = |d: f32| (1.0 - d / reach).powi(ALPHA);
    let mut weight: Vec<f32> = (0..m)
        .map(|i| neighbours.of(i).iter().map(|&(_, d)| weight_of(d)).sum())
        .collect();
    let mut alive = vec![true; m];
    let mut heap: BinaryHeap<(OrdF32, std::cmp::Reverse<u32>)> = (0..m)
        .map(|i| (OrdF32(weight[i]), std::cmp::Reverse(i as u32)))
        .collect();
    let mut left = m;
    while left > keep {
        let Some((OrdF32(w), std::cmp::Reverse(i))) = heap.pop() else {
            break;
        };
        let i = i as usize;
        if !alive[i] || w.to_bits() != weight[i].to_bits() {
            continue; // stale entry
        }
        alive[i] = false;
        left -= 1;
        for &(j, d) in neighbours.of(i) {
            let j = j as usize;
            if alive[j] {
                weight[j] -= weight_of(d);
                heap.push((OrdF32(weight[j]), std::cmp::Reverse(j as u32)));
            }
        }
    }
    tile.iter()
        .zip(&alive)
        .filter_map(|(&i, &a)| a.then_some(i))
        .collect()
}

/// `1/√λ` of a tile's candidates: the mean 6-th-neighbour distance of every `stride`-th
/// candidate, measured against all of them, times [`C6`].
fn local_spacing(pts: &[Vec3], stride: usize) -> f32 {
    if pts.len() <= DENSITY_K {
        return f32::NAN;
    }
    let all: Vec<[f32; 3]> = pts.iter().map(|p| p.to_array()).collect();
    let probes: Vec<[f32; 3]> = all.iter().step_by(stride).copied().collect();
    let index = crate::spacing::KnnIndex::new(&all);
    // The probes are among the indexed points: the nearest (distance 0) is the probe itself.
    let lists = index.query_lists(&probes, DENSITY_K + 1);
    let mut sum = 0.0f64;
    let mut n = 0usize;
    for l in lists.chunks(DENSITY_K + 1) {
        let d2 = l[DENSITY_K];
        if d2.is_finite() {
            sum += (d2 as f64).sqrt();
            n += 1;
        }
    }
    if n == 0 {
        return f32::NAN;
    }
    C6 * (sum / n as f64) as f32
}

/// An `f32` with a total order (for the heap).
#[derive(Debug, Clone, Copy, PartialEq)]
struct OrdF32(f32);
impl Eq for OrdF32 {}
impl PartialOrd for OrdF32 {
    fn partial_cmp(&self, o: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for OrdF32 {
    fn cmp(&self, o: &Self) -> std::cmp::Ordering {
        self.0.total_cmp(&o.0)
    }
}

/// Every pair of a tile's candidates closer than a reach, as adjacency lists
/// (index, distance), from a hash grid of that cell size.
struct Neighbours {
    start: Vec<u32>,
    list: Vec<(u32, f32)>,
}

impl Neighbours {
    fn none(m: usize) -> Self {
        Self {
            start: vec![0; m + 1],
            list: Vec::new(),
        }
    }

    fn within(pts: &[Vec3], reach: f32) -> Self {
        let mut lo = Vec3::splat(f32::INFINITY);
        for p in pts {
            lo = lo.min(*p);
        }
        let cell = |p: Vec3| ((p - lo) / reach).floor().as_ivec3();
        let mut keyed: Vec<(glam::IVec3, u32)> = pts
            .iter()
            .enumerate()
            .map(|(i, &p)| (cell(p), i as u32))
            .collect();
        keyed.sort_unstable_by_key(|&(c, i)| (c.z, c.y, c.x, i));
        let find = |c: glam::IVec3| {
            let a = keyed.partition_point(|&(k, _)| (k.z, k.y, k.x) < (c.z, c.y, c.x));
            let b = keyed.partition_point(|&(k, _)| (k.z, k.y, k.x) <= (c.z, c.y, c.x));
            &keyed[a..b]
        };
        let r2 = reach * reach;
        let mut start = Vec::with_capacity(pts.len() + 1);
        let mut list = Vec::new();
        for (i, &p) in pts.iter().enumerate() {
            start.push(list.len() as u32);
            let c = cell(p);
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        for &(_, j) in find(c + glam::IVec3::new(dx, dy, dz)) {
                            if j as usize == i {
                                continue;
                            }
                            let d2 = p.distance_squared(pts[j as usize]);
                            if d2 < r2 {
                                list.push((j, d2.sqrt()));
                            }
                        }
                    }
                }
            }
        }
        start.push(list.len() as u32);
        Self { start, list }
    }

    fn of(&self, i: usize) -> &[(u32, f32)] {
        &self.list[self.start[i] as usize..self.start[i + 1] as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allocation_is_exact_and_proportional() {
        let counts = [10, 0, 7, 3, 100];
        for n in [0, 1, 5, 17, 60, 120] {
            let a = allocate(&counts, n);
            assert_eq!(a.iter().sum::<usize>(), n, "n = {n}");
            let total: usize = counts.iter().sum();
            for (t, &c) in counts.iter().enumerate() {
                let share = n as f64 * c as f64 / total as f64;
                assert!(
                    (a[t] as f64 - share).abs() < 1.0,
                    "tile {t}: {} vs {share}",
                    a[t]
                );
                assert!(a[t] <= c);
            }
        }
    }

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
}
