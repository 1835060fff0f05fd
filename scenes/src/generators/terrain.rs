//! `terrain`: a georeferenced LiDAR-like survey of a 2 km × 2 km height field with strongly
//! non-uniform density — the stand-in for airborne + terrestrial laser scans.
//!
//! **Frame.** World origin `(500000, 4100000, 0)` (UTM-like metres, so the `f64` origin
//! matters: in `f32`, raw coordinates would keep only ≈ 0.5 m); local `x, y ∈ [0, 2000]` m,
//! `z` = elevation, +Z up.
//!
//! **Height** `z = h(x, y)`, all terms analytic with analytic gradients:
//! - hills: 9 octaves × 5 plane waves, wavelengths 1800 m … 7 m, random directions,
//!   amplitude `∝ λ^0.9` (fractal, rougher at small scale than a Brownian surface would be);
//! - ridges: 4 octaves × 2 ridged waves `a (1 − |sin θ|)²` (sharp crests), multiplied by a
//!   3 km mask wave so that one side of the map is mountainous and the other rolling;
//! - scaled so the sampled relief spans 200 m … 550 m;
//! - a lake: an ellipse with semi-axes 320 m × 210 m at a random orientation around the
//!   lowest interior point, flattened to the lowest elevation found within its shore, blended
//!   into the terrain over a 140 m shore (smoothstep of the elliptical radius).
//!
//! **Density**: a piecewise-constant grid of 256 × 256 cells (7.8 m), sampled by its CDF
//! (binary search) and uniformly inside a cell:
//! - airborne flight strips: parallel 460 m wide strips every 380 m along a random heading
//!   (80 m overlaps get double density) plus two cross strips: 1–4 returns per unit;
//! - a terrestrial scan station: `600 · (8 m / max(r, 8 m))²` within 600 m — 600× the airborne
//!   density at the station, falling with the square of the distance;
//! - water: × 0.02 inside the lake (laser returns from water are sparse; the lake always
//!   contains a disc of radius 210 m, hence whole cells of any grid coarser than 125 m);
//! - per-cell noise × [0.75, 1.33].
//!
//! By construction the grid's max/min ratio is ≥ 601 · 0.75 / (0.02 · 4 · 1.33) > 4000 (the
//! station's cell against the sparsest water cell); measured ≈ 37 000–50 000.
//!
//! **Colour** (sRGB): grass (green to dry by a noise field), forest patches, rock on steep
//! slopes, snow above ≈ 80 % of the relief on gentle slopes, a sinuous gravel road, blue-grey
//! water, plus per-point jitter. **Normals**: `(−∂h/∂x, −∂h/∂y, 1)`, normalised. No radii.

use glam::{DVec3, Vec2, Vec3};

use super::waves::{WaveSum, sincos, unit_vector};
use super::{BlockSampler, PARAM_STREAM};
use crate::rng::Pcg32;

/// World origin of the local coordinates.
pub const ORIGIN: DVec3 = DVec3::new(500_000.0, 4_100_000.0, 0.0);
/// Edge length of the square scene, metres.
pub const SIZE: f32 = 2000.0;
/// Density grid resolution (cells per edge).
pub const GRID: usize = 256;
/// Lowest sampled elevation, metres.
pub const BASE_ELEVATION: f32 = 200.0;
/// Sampled relief (max − min elevation on a 129² grid), metres.
pub const RELIEF: f32 = 350.0;
/// Lake semi-axes and shore width (along the minor axis), metres.
pub const LAKE: (f32, f32, f32) = (320.0, 210.0, 140.0);
/// Scan station: peak relative density, inner radius (m), range (m).
pub const STATION: (f32, f32, f32) = (600.0, 8.0, 600.0);

const CELL: f32 = SIZE / GRID as f32;
const WATER_DENSITY: f32 = 0.02;
const STRIP_WIDTH: f32 = 460.0;
const STRIP_SPACING: f32 = 380.0;

/// The terrain for one seed.
#[derive(Debug, Clone)]
pub struct Terrain {
    hills: WaveSum,
    ridges: WaveSum,
    /// Mask wave for the ridges: (k, phase).
    mask: (Vec2, f32),
    scale: f32,
    offset: f32,
    lake: Vec2,
    /// Unit major axis of the lake.
    lake_axis: Vec2,
    water: f32,
    station: Vec2,
    road: Road,
    colour_noise: WaveSum,
    density: Vec<f32>,
    cdf: Vec<f64>,
}

/// A sinuous road: `v = v0 + A sin(2π u / L + φ)` in a rotated frame.
#[derive(Debug, Clone, Copy)]
struct Road {
    dir: Vec2,
    v0: f32,
    amp: f32,
    k: f32,
    phase: f32,
}

impl Terrain {
    /// The terrain for `seed`.
    pub fn new(seed: u64) -> Terrain {
        let mut rng = Pcg32::stream(seed, PARAM_STREAM);
        let tau = std::f32::consts::TAU;
        let dir2 = |rng: &mut Pcg32| {
            let (s, c) = sincos(rng.range_f32(0.0, tau));
            Vec3::new(c, s, 0.0)
        };
        let mut hills = WaveSum::new();
        for o in 0..9 {
            let lambda = 1800.0 / 2f32.powi(o);
            for _ in 0..5 {
                let k = tau / lambda * rng.range_f32(0.85, 1.15);
                let amp = lambda.powf(0.9) * rng.range_f32(0.7, 1.3) / 5f32.sqrt();
                hills.push(dir2(&mut rng) * k, rng.range_f32(0.0, tau), amp);
            }
        }
        let mut ridges = WaveSum::new();
        for o in 0..4 {
            let lambda = 1100.0 / 2f32.powi(o);
            for _ in 0..2 {
                let k = tau / lambda * rng.range_f32(0.85, 1.15);
                let amp = 1.6 * lambda.powf(0.9) * rng.range_f32(0.7, 1.3);
                ridges.push(dir2(&mut rng) * k, rng.range_f32(0.0, tau), amp);
            }
        }
        let md = dir2(&mut rng);
        let mask = (
            Vec2::new(md.x, md.y) * (tau / 3000.0),
            rng.range_f32(0.0, tau),
        );
        let mut colour_noise = WaveSum::new();
        for i in 0..8 {
            let lambda = 240.0 / 1.5f32.powi(i);
            colour_noise.push(
                dir2(&mut rng) * (tau / lambda),
                rng.range_f32(0.0, tau),
                0.35,
            );
        }
        let road = Road {
            dir: {
                let d = dir2(&mut rng);
                Vec2::new(d.x, d.y)
            },
            v0: rng.range_f32(-400.0, 400.0),
            amp: rng.range_f32(60.0, 140.0),
            k: tau / rng.range_f32(700.0, 1100.0),
            phase: rng.range_f32(0.0, tau),
        };
        let mut t = Terrain {
            hills,
            ridges,
            mask,
            scale: 1.0,
            offset: 0.0,
            lake: Vec2::splat(SIZE / 2.0),
            lake_axis: Vec2::X,
            water: f32::NEG_INFINITY,
            station: Vec2::splat(SIZE / 2.0),
            road,
            colour_noise,
            density: Vec::new(),
            cdf: Vec::new(),
        };
        // Normalise the relief on a coarse grid and put the lake at the lowest interior point.
        const N: usize = 129;
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        let mut lowest = (f32::INFINITY, Vec2::splat(SIZE / 2.0));
        for j in 0..N {
            for i in 0..N {
                let p = Vec2::new(i as f32, j as f32) * (SIZE / (N - 1) as f32);
                let h = t.raw_height(p).0;
                lo = lo.min(h);
                hi = hi.max(h);
                let interior = p.min_element() >= 450.0 && p.max_element() <= SIZE - 450.0;
                if interior && h < lowest.0 {
                    lowest = (h, p);
                }
            }
        }
        t.scale = if hi > lo { RELIEF / (hi - lo) } else { 1.0 };
        t.offset = BASE_ELEVATION - lo * t.scale;
        t.lake = lowest.1;
        let (sa, ca) = sincos(rng.range_f32(0.0, std::f32::consts::PI));
        t.lake_axis = Vec2::new(ca, sa);
        let mut water = f32::INFINITY;
        for j in 0..N {
            for i in 0..N {
                let p = Vec2::new(i as f32, j as f32) * (SIZE / (N - 1) as f32);
                if t.lake_radius(p).0 <= 1.0 + LAKE.2 / LAKE.1 {
                    water = water.min(t.terrain_height(p).0);
                }
            }
        }
        t.water = if water.is_finite() {
            water
        } else {
            t.terrain_height(t.lake).0
        };
        // The station: somewhere ≥ 700 m from the lake, not too close to the edge.
        t.station = Vec2::new(SIZE - t.lake.x, SIZE - t.lake.y);
        for _ in 0..64 {
            let p = Vec2::new(
                rng.range_f32(300.0, SIZE - 300.0),
                rng.range_f32(300.0, SIZE - 300.0),
            );
            if p.distance(t.lake) >= 700.0 {
                t.station = p;
                break;
            }
        }
        t.build_density(&mut rng);
        t
    }

    /// The un-normalised hills + ridges and their gradient.
    fn raw_height(&self, p: Vec2) -> (f32, Vec2) {
        let p3 = Vec3::new(p.x, p.y, 0.0);
        let (h, gh) = self.hills.value_gradient(p3);
        let (r, gr) = self.ridges.ridged_value_gradient(p3);
        let (ms, mc) = sincos(self.mask.0.dot(p) + self.mask.1);
        let m = 0.5 + 0.5 * ms;
        let gm = self.mask.0 * (0.5 * mc);
        (
            h + r * m,
            Vec2::new(gh.x, gh.y) + Vec2::new(gr.x, gr.y) * m + gm * r,
        )
    }

    /// Normalised terrain height without the lake.
    fn terrain_height(&self, p: Vec2) -> (f32, Vec2) {
        let (h, g) = self.raw_height(p);
        (self.offset + self.scale * h, g * self.scale)
    }

    /// The elliptical radius of `p` around the lake (1 on the waterline) and its gradient.
    fn lake_radius(&self, p: Vec2) -> (f32, Vec2) {
        let d = p - self.lake;
        let (a, b, _) = LAKE;
        let (u, v) = (d.dot(self.lake_axis), d.dot(self.lake_axis.perp()));
        let r = ((u / a).powi(2) + (v / b).powi(2)).sqrt();
        let g =
            (self.lake_axis * (u / (a * a)) + self.lake_axis.perp() * (v / (b * b))) / r.max(1e-6);
        (r, g)
    }

    /// Elevation `h(x, y)` (local metres) and its analytic gradient `(∂h/∂x, ∂h/∂y)`.
    pub fn height(&self, x: f32, y: f32) -> (f32, Vec2) {
        let p = Vec2::new(x, y);
        let (r, gr) = self.lake_radius(p);
        if r < 1.0 {
            return (self.water, Vec2::ZERO);
        }
        let (h, g) = self.terrain_height(p);
        // Shore parameter: 0 on the waterline, 1 at the outer edge of the shore.
        let k = LAKE.1 / LAKE.2;
        let t = (r - 1.0) * k;
        if t >= 1.0 {
            return (h, g);
        }
        // s = 1 at the water's edge, 0 at the outer shore; smoothstep in between.
        let s = 1.0 - t * t * (3.0 - 2.0 * t);
        let grad_s = gr * (-6.0 * t * (1.0 - t) * k);
        (
            h + s * (self.water - h),
            g * (1.0 - s) + grad_s * (self.water - h),
        )
    }

    /// True inside the lake.
    pub fn is_water(&self, x: f32, y: f32) -> bool {
        self.lake_radius(Vec2::new(x, y)).0 < 1.0
    }

    /// The density grid, `GRID × GRID` cells, row-major from (0, 0), relative units.
    pub fn density_grid(&self) -> &[f32] {
        &self.density
    }

    fn build_density(&mut self, rng: &mut Pcg32) {
        let heading = unit_vector(rng);
        let along = Vec2::new(heading.x, heading.y).normalize_or(Vec2::X);
        let across = along.perp();
        let strip_phase = rng.range_f32(0.0, STRIP_SPACING);
        let cross_offsets = [rng.range_f32(-700.0, 0.0), rng.range_f32(0.0, 700.0)];
        let centre = Vec2::splat(SIZE / 2.0);
        let (peak, r0, range) = STATION;
        let mut density = Vec::with_capacity(GRID * GRID);
        for j in 0..GRID {
            for i in 0..GRID {
                let p = (Vec2::new(i as f32, j as f32) + 0.5) * CELL;
                // Parallel strips: count the strips whose swath covers p.
                let a = (p - centre).dot(across) + strip_phase;
                let first = ((a - STRIP_WIDTH / 2.0) / STRIP_SPACING).ceil() as i32;
                let last = ((a + STRIP_WIDTH / 2.0) / STRIP_SPACING).floor() as i32;
                let mut d = (last - first + 1).max(1) as f32;
                // Two cross strips.
                let b = (p - centre).dot(along);
                d += cross_offsets
                    .iter()
                    .filter(|&&o| (b - o).abs() <= STRIP_WIDTH / 2.0)
                    .count() as f32;
                if self.is_water(p.x, p.y) {
                    d *= WATER_DENSITY;
                }
                let r = p.distance(self.station);
                if r < range {
                    d += peak * (r0 / r.max(r0)).powi(2);
                }
                d *= 0.75 * (1.33f32 / 0.75).powf(rng.f32());
                density.push(d);
            }
        }
        let mut cdf = Vec::with_capacity(density.len());
        let mut acc = 0.0f64;
        for &d in &density {
            acc += d as f64;
            cdf.push(acc);
        }
        for c in &mut cdf {
            *c /= acc;
        }
        self.density = density;
        self.cdf = cdf;
    }

    fn colour(&self, p: Vec2, h: f32, g: Vec2, rng: &mut Pcg32) -> [u8; 3] {
        let jitter = (rng.f32() - 0.5) * 14.0;
        let mut c = if self.is_water(p.x, p.y) {
            Vec3::new(38.0, 64.0, 84.0)
        } else {
            let n = self
                .colour_noise
                .value(Vec3::new(p.x, p.y, 0.0))
                .clamp(-1.0, 1.0);
            let slope = g.length();
            let e = (h - BASE_ELEVATION) / RELIEF;
            let grass =
                Vec3::new(72.0, 108.0, 46.0).lerp(Vec3::new(128.0, 124.0, 70.0), 0.5 + 0.5 * n);
            let forest = Vec3::new(40.0, 66.0, 38.0);
            let rock = Vec3::new(120.0, 113.0, 104.0);
            let snow = Vec3::new(236.0, 238.0, 242.0);
            let mut c = grass.lerp(
                forest,
                smoothstep(0.25, 0.45, n) * (1.0 - smoothstep(0.55, 0.8, e)),
            );
            c = c.lerp(rock, smoothstep(0.5, 0.95, slope + 0.2 * n));
            c = c.lerp(
                snow,
                smoothstep(0.76, 0.86, e + 0.04 * n) * (1.0 - smoothstep(0.7, 1.1, slope)),
            );
            let road = self.road.distance(p);
            c.lerp(
                Vec3::new(112.0, 104.0, 92.0),
                1.0 - smoothstep(3.0, 5.5, road),
            )
        };
        c += Vec3::splat(jitter) + Vec3::new(rng.f32(), rng.f32(), rng.f32()) * 6.0 - 3.0;
        let c = c.clamp(Vec3::ZERO, Vec3::splat(255.0)).round();
        [c.x as u8, c.y as u8, c.z as u8]
    }
}

impl Road {
    /// Approximate distance to the road's centre line (vertical offset in the road frame,
    /// corrected by the local slope of the curve).
    fn distance(&self, p: Vec2) -> f32 {
        let q = p - Vec2::splat(SIZE / 2.0);
        let u = q.dot(self.dir);
        let v = q.dot(self.dir.perp());
        let (s, c) = sincos(self.k * u + self.phase);
        let dv = v - (self.v0 + self.amp * s);
        let slope = self.amp * self.k * c;
        dv.abs() / (1.0 + slope * slope).sqrt()
    }
}

fn smoothstep(e0: f32, e1: f32, x: f32) -> f32 {
    let t = ((x - e0) / (e1 - e0)).clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

impl BlockSampler for Terrain {
    fn origin(&self) -> DVec3 {
        ORIGIN
    }
    fn has_colors(&self) -> bool {
        true
    }
    fn fill(
        &self,
        rng: &mut Pcg32,
        pos: &mut [[f32; 3]],
        nrm: &mut [[f32; 3]],
        col: Option<&mut [[u8; 3]]>,
    ) {
        let last = self.cdf.len().saturating_sub(1);
        let mut col = col;
        for i in 0..pos.len() {
            let u = rng.f64();
            let cell = self.cdf.partition_point(|&c| c <= u).min(last);
            let (ci, cj) = ((cell % GRID) as f32, (cell / GRID) as f32);
            let x = ((ci + rng.f32()) * CELL).min(SIZE);
            let y = ((cj + rng.f32()) * CELL).min(SIZE);
            let (h, g) = self.height(x, y);
            pos[i] = [x, y, h];
            nrm[i] = Vec3::new(-g.x, -g.y, 1.0).normalize().to_array();
            if let Some(col) = col.as_deref_mut() {
                col[i] = self.colour(Vec2::new(x, y), h, g, rng);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn gradient_is_consistent_and_grid_ratio_large() {
        let t = Terrain::new(3);
        for &(x, y) in &[(300.0f32, 700.0f32), (1234.0, 456.0), (1800.0, 1500.0)] {
            let (_, g) = t.height(x, y);
            let e = 0.01;
            let gx = (t.height(x + e, y).0 - t.height(x - e, y).0) / (2.0 * e);
            let gy = (t.height(x, y + e).0 - t.height(x, y - e).0) / (2.0 * e);
            assert!(
                (gx - g.x).abs() < 0.05 + 0.05 * g.length(),
                "{gx} vs {}",
                g.x
            );
            assert!(
                (gy - g.y).abs() < 0.05 + 0.05 * g.length(),
                "{gy} vs {}",
                g.y
            );
        }
        let d = t.density_grid();
        let max = d.iter().copied().fold(0.0, f32::max);
        let min = d.iter().copied().fold(f32::INFINITY, f32::min);
        assert!(min > 0.0 && max / min >= 300.0, "{max} / {min}");
    }
}
