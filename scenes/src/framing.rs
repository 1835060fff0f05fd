//! The extent a camera frames: the cloud's bounds without its far outliers.
//!
//! Camera paths are defined relative to a bounding box ([`crate::paths`]). The plain bounds
//! of a real scan are set by its strays: one point 6,000 km from a 1 km tile makes the box
//! thousands of times too large, and every path then looks at an empty sky. [`framing`]
//! returns the bounds of the *inliers*, the samples inside the box
//!
//! `[q₀.₁ − m, q₉₉.₉ + m]` per axis, with `m = ½ · max over axes of (q₉₉.₉ − q₀.₁)`,
//!
//! where `q₀.₁`, `q₉₉.₉` are the 0.1 % and 99.9 % quantiles of each coordinate (estimated
//! from at most 2²⁰ evenly strided samples). The margin is half the largest robust extent,
//! the same on every axis, so a flat terrain's trees and towers (far outside the quantiles of
//! its thin z range, but not far from the tile) stay inliers, and a cloud without strays keeps
//! exactly its bounds: every sample is within its own extent of the quantile box. The
//! outliers are still drawn, by every method and by the reference; they are only not framed.

use crate::{Aabb, PointCloud};

/// Quantiles that bound the robust extent.
pub const QUANTILES: (f64, f64) = (0.001, 0.999);

/// The margin around the quantile box, as a fraction of its largest extent.
pub const MARGIN: f32 = 0.5;

/// At most this many samples estimate the quantiles.
const QUANTILE_SAMPLES: usize = 1 << 20;

/// What the camera frames.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Framing {
    /// Bounds of the inliers (the cloud's bounds when it has no outlier).
    pub framed: Aabb,
    /// Samples outside the inlier box.
    pub outside: u64,
}

/// The stride that keeps at most [`QUANTILE_SAMPLES`] of `len` samples.
fn quantile_stride(len: usize) -> usize {
    len.div_ceil(QUANTILE_SAMPLES).max(1)
}

/// The [`QUANTILES`] of each coordinate of `sample` (at least one point, every
/// [`quantile_stride`]-th of a cloud): the per-axis low and high corners.
fn quantile_box<T: Copy + Default>(
    sample: &[[T; 3]],
    cmp: fn(&T, &T) -> std::cmp::Ordering,
) -> ([T; 3], [T; 3]) {
    let (mut lo, mut hi) = ([T::default(); 3], [T::default(); 3]);
    let mut axis: Vec<T> = Vec::with_capacity(sample.len());
    for a in 0..3 {
        axis.clear();
        axis.extend(sample.iter().map(|v| v[a]));
        let last = (axis.len() - 1) as f64;
        let i_lo = (last * QUANTILES.0).floor() as usize;
        let i_hi = (last * QUANTILES.1).ceil() as usize;
        lo[a] = *axis.select_nth_unstable_by(i_lo, cmp).1;
        hi[a] = *axis.select_nth_unstable_by(i_hi, cmp).1;
    }
    (lo, hi)
}

/// The origin a reader should store `f32` positions against, when `world` (all positions, or
/// an even stride through them, in `f64`) has far outliers beyond `lo`..`hi`'s inliers: the
/// centre of the quantile box, so the inliers keep the precision of their own extent. `None`
/// when every sample within `lo`..`hi` is an inlier (the centre of the bounds is then as
/// good). Without it, two stray points at (0, 0, 0) beside a UTM tile put the origin half
/// way, 3,000 km from the tile, where `f32` keeps 0.25 m.
pub fn inlier_origin(world: &[[f64; 3]], lo: glam::DVec3, hi: glam::DVec3) -> Option<glam::DVec3> {
    if world.len() < 3 {
        return None;
    }
    let stride = quantile_stride(world.len());
    let sample: Vec<[f64; 3]> = world.iter().step_by(stride).copied().collect();
    let (qlo, qhi) = quantile_box(&sample, f64::total_cmp);
    let (qlo, qhi) = (glam::DVec3::from(qlo), glam::DVec3::from(qhi));
    let m = (qhi - qlo).max_element() * f64::from(MARGIN);
    let inside = (qlo - m).cmple(lo).all() && (qhi + m).cmpge(hi).all();
    (!inside).then(|| (qlo + qhi) * 0.5)
}

/// The inlier box of `cloud` (the quantile box grown by the margin, see the module docs):
/// a sample is an inlier when it lies inside it (bounds included). `None` when every sample
/// does, or the cloud has fewer than 3 samples.
pub fn inlier_box(cloud: &PointCloud) -> Option<Aabb> {
    if cloud.len() < 3 {
        return None;
    }
    let sample = strided_sample(cloud);
    let (lo, hi) = quantile_box(&sample, f32::total_cmp);
    let (lo, hi) = (glam::Vec3::from(lo), glam::Vec3::from(hi));
    let m = (hi - lo).max_element() * MARGIN;
    let inlier = Aabb {
        min: lo - m,
        max: hi + m,
    };
    let b = cloud.bounds();
    (!(inlier.min.cmple(b.min).all() && inlier.max.cmpge(b.max).all())).then_some(inlier)
}

/// Every [`quantile_stride`]-th sample of `cloud` (at most [`QUANTILE_SAMPLES`]). Gathered a
/// block at a time and the block's pages of a mapped cloud released behind it: a stride of
/// a few dozen samples touches every page, and a run that opens a build (and draws nothing
/// from the scene) kept the whole position column of a cloud without strays resident (1.1
/// GB of the 100 M walkthrough's peak, issue 35; [`framing`] releases the pages it reads,
/// but returns early on such a cloud).
fn strided_sample(cloud: &PointCloud) -> Vec<[f32; 3]> {
    let p = cloud.positions();
    let stride = quantile_stride(p.len());
    let block = stride * 4096;
    let mut sample: Vec<[f32; 3]> = Vec::with_capacity(p.len().div_ceil(stride));
    for start in (0..p.len()).step_by(block) {
        let r = start..(start + block).min(p.len());
        sample.extend(p[r.clone()].iter().step_by(stride));
        cloud.release_pages(r);
    }
    sample
}

/// The flat base ([`crate::axis::flat_base`]) of `cloud`'s samples inside `framed` (the
/// [`framing`]'s bounds, so strays neither stretch the box nor count), estimated from the
/// same strided sample as the quantiles: a hint that a file is not Z-up.
pub fn flat_base(cloud: &PointCloud, framed: &Aabb) -> Option<crate::axis::FlatBase> {
    crate::axis::flat_base(strided_sample(cloud).iter(), (framed.min, framed.max))
}

/// True if `v` is an inlier of `inlier` ([`inlier_box`]).
#[inline]
pub fn is_inlier(inlier: &Aabb, v: [f32; 3]) -> bool {
    let v = glam::Vec3::from(v);
    v.cmpge(inlier.min).all() && v.cmple(inlier.max).all()
}

/// The inlier bounds of `cloud` (see the module docs).
pub fn framing(cloud: &PointCloud) -> Framing {
    let p = cloud.positions();
    let Some(inlier) = inlier_box(cloud) else {
        return Framing {
            framed: cloud.bounds(),
            outside: 0,
        };
    };
    use rayon::prelude::*;
    const BLOCK: usize = 1 << 20;
    let (framed, outside) = (0..p.len().div_ceil(BLOCK))
        .into_par_iter()
        .map(|k| {
            let r = k * BLOCK..((k + 1) * BLOCK).min(p.len());
            let mut acc = (Aabb::EMPTY, 0u64);
            for &v in &p[r.clone()] {
                if is_inlier(&inlier, v) {
                    acc.0 = acc.0.grow(glam::Vec3::from(v));
                } else {
                    acc.1 += 1;
                }
            }
            cloud.release_pages(r);
            acc
        })
        .reduce(|| (Aabb::EMPTY, 0), |a, b| (a.0.union(b.0), a.1 + b.1));
    Framing { framed, outside }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn cloud(p: Vec<[f32; 3]>) -> PointCloud {
        PointCloud::new(DVec3::ZERO, p.into(), None, None, None).unwrap()
    }

    fn grid(n: usize) -> Vec<[f32; 3]> {
        (0..n)
            .map(|i| [(i % 50) as f32, (i / 50) as f32, 0.01 * (i % 3) as f32])
            .collect()
    }

    #[test]
    fn a_far_stray_is_not_framed() {
        let mut p = grid(5000);
        let clean = framing(&cloud(p.clone()));
        assert_eq!(clean.outside, 0);
        assert_eq!(clean.framed, cloud(p.clone()).bounds());
        p.push([6.0e6, -3.0e6, 1.0e5]);
        let f = framing(&cloud(p));
        assert_eq!(f.outside, 1);
        assert_eq!(f.framed, clean.framed);
    }

    #[test]
    fn every_generator_is_framed_whole() {
        // Paths over generated scenes must not move: every figure in paper/ depends on them.
        for g in crate::generators::Generator::ALL {
            let c = g.generate(100_000, 1).unwrap();
            let f = framing(&c);
            assert_eq!((f.outside, f.framed), (0, c.bounds()), "{}", g.name());
        }
    }

    #[test]
    fn a_terrain_s_towers_stay_framed() {
        // A flat tile 50 × 100 with 1 % of its samples on 30-unit towers: far beyond the
        // z quantiles, within the margin (half the largest robust extent).
        let mut p = grid(10_000);
        for (i, v) in p.iter_mut().enumerate().filter(|(i, _)| i % 100 == 0) {
            v[2] = 30.0 + (i % 7) as f32;
        }
        let c = cloud(p);
        let f = framing(&c);
        assert_eq!((f.outside, f.framed), (0, c.bounds()));
    }
}
