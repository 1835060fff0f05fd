//! Leaf radii shared by every method: the splat radius of an input sample drawn alone.
//!
//! If the scene carries radii (from mesh faces or the file), those are used. Otherwise the
//! radius is the distance to the [`LEAF_K`]-th nearest neighbour: on a uniformly sampled
//! surface, discs of that radius overlap their neighbours with margin, so a full-resolution
//! rendering has no holes even where random sampling leaves gaps (the mean nearest-neighbour
//! distance would leave many). QSplat's paper uses the same idea ("neighbouring leaf spheres
//! touch"); the value of `k` is our choice, measured on `statue` to give < 1 % holes at 1 px.
//!
//! **Exact, and kept exact for build speed too** (decided in issue 16). The search is exact
//! (`scenes::spacing::knn_spacing`, and out of core [`crate::unit_knn`] with the same
//! values bit for bit). At 10 M and 50 M terrain points on 2 cores it alone takes ≈ 73 % of
//! PotreeConverter 2.0's whole default build, while it is 4–6× faster than nanoflann and
//! 9–13× faster than SciPy's cKDTree on the same points (`scripts/knn-peers.sh`,
//! `results/measurements/issue-16-builds.md`). A cheaper, approximate spacing would move
//! every leaf sphere, every image and every image-error figure to win a build-time
//! benchmark, and could save at most that one phase: QSplat's other phases alone take
//! longer than PotreeConverter's whole build at 10 M. So no departure is offered; the
//! radii stay this exact search.
//!
//! **Isolated samples.** The k-NN distance of a stray sample far from the rest (a scanner's
//! multipath return, a bird, a bad GPS fix) is not a spacing of any surface: one point
//! 6,000 km from a 1 km tile gets a 6,000 km splat that covers the whole image of the
//! reference, and every method then scores a hole ratio near 1. So a k-NN radius is capped at
//! [`OUTLIER_CAP`] × the [`OUTLIER_QUANTILE`] quantile of all k-NN radii. The quantile is
//! taken high so that a sparse region that is part of the scan (aerial LiDAR varies 100× in
//! density: 10× in spacing) sits below it as long as it holds more than 0.1 % of the
//! samples, and the factor 4 leaves the sparsest tail of that region its own spacing; only
//! samples that are isolated by a margin get capped. On the generators no sample is capped
//! (`tests/leaf.rs` checks statue, isosurface and terrain), so the figures measured on them
//! do not move. Radii given by the scene are its own and never capped.

use std::borrow::Cow;
use std::ops::Deref;

use scenes::PointCloud;

/// Which neighbour's distance is the leaf radius when the scene has no radii.
pub const LEAF_K: usize = 6;

/// The quantile of the k-NN radii that [`OUTLIER_CAP`] multiplies.
pub const OUTLIER_QUANTILE: f64 = 0.999;

/// The largest k-NN leaf radius, as a multiple of their [`OUTLIER_QUANTILE`] quantile.
pub const OUTLIER_CAP: f32 = 4.0;

/// At most this many radii (a stride through the cloud) estimate the quantile, so a 100 M
/// sample cloud does not copy its radii to sort them.
const QUANTILE_SAMPLES: usize = 1 << 20;

/// The leaf radius of every sample, and how many k-NN radii were capped as isolated.
/// Dereferences to the radii.
#[derive(Debug, Clone)]
pub struct LeafRadii<'a> {
    /// One radius per sample (borrowed when the scene has radii).
    pub radii: Cow<'a, [f32]>,
    /// Samples whose k-NN radius exceeded the cap (0 when the scene has radii).
    pub capped: u64,
}

impl Deref for LeafRadii<'_> {
    type Target = [f32];
    fn deref(&self) -> &[f32] {
        &self.radii
    }
}

/// The leaf radius of every sample (see the module docs for the cap on isolated samples).
pub fn leaf_radii(cloud: &PointCloud) -> LeafRadii<'_> {
    match cloud.radii() {
        Some(r) => LeafRadii {
            radii: Cow::Borrowed(r),
            capped: 0,
        },
        None => {
            let mut r = scenes::spacing::knn_spacing(cloud.positions(), LEAF_K);
            let capped = cap_isolated(&mut r);
            LeafRadii {
                radii: Cow::Owned(r),
                capped,
            }
        }
    }
}

/// Caps `radii` at [`OUTLIER_CAP`] × their [`OUTLIER_QUANTILE`] quantile (estimated from at
/// most [`QUANTILE_SAMPLES`] evenly strided values); returns how many were capped.
pub fn cap_isolated(radii: &mut [f32]) -> u64 {
    if radii.len() < 2 {
        return 0;
    }
    let stride = quantile_stride(radii.len());
    let cap = isolation_cap(radii.iter().step_by(stride).copied().collect());
    let mut capped = 0;
    for r in radii.iter_mut().filter(|r| **r > cap) {
        *r = cap;
        capped += 1;
    }
    capped
}

/// The stride of the samples that estimate the quantile of `n` radii: the radii of samples
/// `0, s, 2s, …` (an out-of-core build gathers them by sample index).
pub fn quantile_stride(n: usize) -> usize {
    n.div_ceil(QUANTILE_SAMPLES).max(1)
}

/// The cap on k-NN radii given the strided `sample` of them ([`quantile_stride`]; not
/// empty).
pub fn isolation_cap(mut sample: Vec<f32>) -> f32 {
    let at = ((sample.len() - 1) as f64 * OUTLIER_QUANTILE).floor() as usize;
    let (_, q, _) = sample.select_nth_unstable_by(at, f32::total_cmp);
    *q * OUTLIER_CAP
}
