//! How regularly a cloud samples its surface: the spread of nearest-neighbour distances and
//! the bare fraction a splat of the average spacing leaves (`splatbench sampling`).
//!
//! - **Nearest-neighbour distance** `d₁` of every sample (exact, [`crate::spacing`]): its
//!   mean and its coefficient of variation `σ/μ`. Independent uniform samples (a Poisson
//!   process on a surface) have CV `√(4/π − 1) ≈ 0.52`; a square grid 0; mesh vertices of a
//!   merged scan and Poisson-disk sets ≈ 0.1–0.25.
//! - **Bare fraction at the average spacing**: each sample owns a disc of the area `A/N`
//!   (`A` the surface area); the fraction of the surface farther than that disc's radius
//!   `ρ = √(A/(πN))` from every sample. A Poisson process leaves exactly `e⁻¹ ≈ 0.368`
//!   bare (the Boolean model); a hexagonal lattice ≈ 0.1 of it. It is measured at *test
//!   points*: independent area-uniform points of the same surface (another seed of a
//!   generator, or a mesh resampled), whose own density also gives `A`: for `M` such points
//!   `A = M / λ` with `1/√λ = C6 · mean d₆` (exact for uniform random points, `πλd₆²` being
//!   Gamma(6)-distributed).

use crate::spacing::{KnnIndex, knn_spacing};

/// `√π · Γ(6) / Γ(6.5)`: `C6 · mean d₆ = 1/√λ` for uniform random points of density λ.
pub const C6: f64 = 0.738_795_6;

/// The regularity of a sampling.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct Regularity {
    /// Samples.
    pub samples: usize,
    /// Mean nearest-neighbour distance (local units).
    pub nn_mean: f64,
    /// Coefficient of variation of the nearest-neighbour distance.
    pub nn_cv: f64,
    /// Surface area from the test points (local units²); NaN without them.
    pub area: f64,
    /// Fraction of test points farther than `√(A/(πN))` from every sample; NaN without
    /// test points.
    pub bare_fraction: f64,
}

/// The regularity of `samples`; the area and bare fraction from `test` (independent
/// area-uniform points of the same surface, at least 7), NaN when `test` is empty.
pub fn regularity(samples: &[[f32; 3]], test: &[[f32; 3]]) -> Regularity {
    let nn = knn_spacing(samples, 1);
    let n = nn.len().max(1) as f64;
    let mean = nn.iter().map(|&d| d as f64).sum::<f64>() / n;
    let var = nn.iter().map(|&d| (d as f64 - mean).powi(2)).sum::<f64>() / n;
    let (area, bare) = if test.len() > 6 && !samples.is_empty() {
        let d6 = knn_spacing(test, 6);
        let m = d6.len() as f64;
        let s = C6 * d6.iter().map(|&d| d as f64).sum::<f64>() / m;
        let area = m * s * s;
        let rho = (area / (std::f64::consts::PI * samples.len() as f64)).sqrt();
        let nearest = KnnIndex::new(samples).query_lists(test, 1);
        let bare = nearest
            .iter()
            .filter(|&&d2| (d2 as f64).sqrt() > rho)
            .count() as f64
            / m;
        (area, bare)
    } else {
        (f64::NAN, f64::NAN)
    };
    Regularity {
        samples: samples.len(),
        nn_mean: mean,
        nn_cv: var.sqrt() / mean,
        area,
        bare_fraction: bare,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Pcg32;

    fn plane(n: usize, seed: u64) -> Vec<[f32; 3]> {
        let mut r = Pcg32::new(seed);
        (0..n).map(|_| [r.f32(), r.f32(), 0.0]).collect()
    }

    #[test]
    fn poisson_and_grid_have_their_known_values() {
        // Random points: CV √(4/π − 1) = 0.523, bare e⁻¹ = 0.368, area 1.
        let r = regularity(&plane(40_000, 1), &plane(40_000, 2));
        assert!((r.nn_cv - 0.523).abs() < 0.02, "{r:?}");
        assert!((r.bare_fraction - (-1f64).exp()).abs() < 0.02, "{r:?}");
        assert!((r.area - 1.0).abs() < 0.03, "{r:?}");
        // A square grid: CV 0 (up to f32 rounding); discs of area a² (radius a/√π = 0.564 a)
        // leave the corners of each cell bare: 1 − π·0.564²… measured against the exact
        // fraction of the unit cell farther than 0.564 a from all four corners: 0.0 < it < 0.1.
        let side = 200;
        let grid: Vec<[f32; 3]> = (0..side * side)
            .map(|i| {
                [
                    ((i % side) as f32 + 0.5) / side as f32,
                    ((i / side) as f32 + 0.5) / side as f32,
                    0.0,
                ]
            })
            .collect();
        let g = regularity(&grid, &plane(40_000, 3));
        assert!(g.nn_cv < 1e-3, "{g:?}");
        // Fraction of a unit square farther than ρ = 1/√π from its four corners: the
        // four quarter discs cover π ρ² = 1 but overlap (ρ > 1/2), so the bare part is
        // 1 − (area of the union) ≈ 0.0906.
        assert!((g.bare_fraction - 0.0906).abs() < 0.01, "{g:?}");
    }
}
