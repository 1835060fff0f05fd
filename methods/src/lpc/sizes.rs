//! §4's splat sizes against the samples they cover: "The technique does not ensure that
//! splat size is constant per cloud, but maintains it reasonably close to the average value
//! for complex models."
//!
//! A cloud `j` is drawn with its ancestors' clouds (they are above it in the traversal), and
//! eq. (2) gives `r_j` as the average spacing of that union. [`cloud_spacing`] measures it: for
//! up to [`CLOUDS`] inner clouds (exactly `M` samples, at least two levels below the root,
//! evenly spread in processing order), up to [`PROBES`] evenly strided samples of the cloud
//! each find their `LEAF_K`-th nearest neighbour among the cloud and all its ancestors'
//! samples (brute force), and the cloud's measured spacing is `MEAN_SPACING_FACTOR × mean
//! d₆` (the same estimator as the input spacing `r`, [`super::spacing`]). Reported: the
//! median and the 10th and 90th percentiles over the clouds of measured ÷ `r_j`, and the
//! median over the clouds of the coefficient of variation of `d₆` within a cloud (how far
//! from constant a splat size would have to be to fit each sample). Siblings' samples are
//! not searched: a probe near its cloud's border may find a neighbour farther away than the
//! drawn image has, so the measured spacing errs high there.

use super::cloud::Sample;
use super::partition::PNode;
use super::spacing::MEAN_SPACING_FACTOR;
use crate::MethodError;

/// At most this many clouds are measured.
pub const CLOUDS: usize = 64;
/// At most this many samples of a cloud probe it.
pub const PROBES: usize = 64;

/// The figures of [`cloud_spacing`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SizeCheck {
    /// Clouds measured.
    pub clouds: u64,
    /// Median over the clouds of measured spacing ÷ `r_j`.
    pub ratio_median: f64,
    /// 10th percentile of that ratio.
    pub ratio_p10: f64,
    /// 90th percentile.
    pub ratio_p90: f64,
    /// Median over the clouds of the coefficient of variation of `d₆` within the cloud.
    pub cv_median: f64,
}

/// Measures the clouds of `nodes` (phase 1's nodes, by processing order; `spacing(i)` is node
/// `i`'s `r_j`; `read(i)` its samples). `None` when no cloud qualifies.
pub(super) fn cloud_spacing(
    nodes: &[PNode],
    m: u32,
    spacing: impl Fn(usize) -> f64,
    mut read: impl FnMut(usize) -> Result<Vec<Sample>, MethodError>,
) -> Result<Option<SizeCheck>, MethodError> {
    let k = crate::leaf::LEAF_K;
    let candidates: Vec<usize> = (0..nodes.len())
        .filter(|&i| nodes[i].level >= 2 && nodes[i].m == m && m as usize > k)
        .collect();
    if candidates.is_empty() {
        return Ok(None);
    }
    let stride = candidates.len().div_ceil(CLOUDS);
    let (mut ratios, mut cvs) = (Vec::new(), Vec::new());
    for &j in candidates.iter().step_by(stride) {
        let own = read(j)?;
        let mut all: Vec<[f32; 3]> = own.iter().map(|s| s.p).collect();
        let mut p = nodes[j].parent;
        while p != super::index::NONE {
            all.extend(read(p as usize)?.iter().map(|s| s.p));
            p = nodes[p as usize].parent;
        }
        let step = own.len().div_ceil(PROBES);
        let mut d: Vec<f64> = Vec::with_capacity(PROBES);
        let mut dist = Vec::with_capacity(all.len());
        for (i, s) in own.iter().enumerate().step_by(step) {
            dist.clear();
            let q = glam::Vec3::from(s.p);
            // The probe itself is `all[i]`: left out by index, not by distance (a duplicate
            // sample elsewhere is a neighbour at 0).
            dist.extend(
                all.iter()
                    .enumerate()
                    .filter(|&(t, _)| t != i)
                    .map(|(_, v)| q.distance(glam::Vec3::from(*v))),
            );
            let (_, kth, _) = dist.select_nth_unstable_by(k - 1, f32::total_cmp);
            d.push(f64::from(*kth));
        }
        let mean = d.iter().sum::<f64>() / d.len() as f64;
        let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f64>() / d.len() as f64;
        let r_j = spacing(j);
        if r_j > 0.0 && mean > 0.0 {
            ratios.push(MEAN_SPACING_FACTOR * mean / r_j);
            cvs.push(var.sqrt() / mean);
        }
    }
    if ratios.is_empty() {
        return Ok(None);
    }
    let q = |v: &mut Vec<f64>, f: f64| {
        v.sort_unstable_by(f64::total_cmp);
        v[((v.len() - 1) as f64 * f).round() as usize]
    };
    Ok(Some(SizeCheck {
        clouds: ratios.len() as u64,
        ratio_median: q(&mut ratios, 0.5),
        ratio_p10: q(&mut ratios, 0.1),
        ratio_p90: q(&mut ratios, 0.9),
        cv_median: q(&mut cvs, 0.5),
    }))
}

#[cfg(test)]
mod tests {
    use super::super::index::NONE;
    use super::*;

    fn node(parent: u32, level: u32, m: u32) -> PNode {
        let mut n = PNode::new(parent, level, u64::from(m));
        n.m = m;
        n
    }

    fn grid(offset: f32, far: f32) -> Vec<Sample> {
        (0..400)
            .map(|i| Sample {
                p: [
                    (i % 20) as f32 + offset + far,
                    (i / 20) as f32 + offset,
                    0.0,
                ],
                ..Default::default()
            })
            .collect()
    }

    /// A 20 × 20 square grid of spacing 1 as the measured cloud (level 2, `r_j = 1`): the 6th
    /// neighbour of an interior sample is at √2, so the estimate is `√2 · c₆ = 1.045` inside
    /// and larger at the border (its probes see farther neighbours): within [1.0, 1.15]. With
    /// its parent's samples on the same grid shifted by half a step (a union of spacing
    /// 1/√2: the 6th neighbour inside is at 1), the ratio falls by √2 (to 0.05; the border
    /// probes move it by 0.03): ancestors are searched. The root and the
    /// parent (levels 0 and 1) and a cloud of fewer than `M` samples are not measured.
    #[test]
    fn measures_a_grid_and_searches_the_ancestors() {
        let run = |parent_offset: f32| {
            let nodes = [
                node(NONE, 0, 400),
                node(0, 1, 400),
                node(1, 2, 400),
                node(1, 2, 9),
            ];
            let clouds = [
                grid(0.0, 1000.0),
                grid(parent_offset, 0.0),
                grid(0.0, 0.0),
                grid(0.0, 0.0),
            ];
            cloud_spacing(&nodes, 400, |_| 1.0, |i| Ok(clouds[i].clone()))
                .unwrap()
                .unwrap()
        };
        let alone = run(1000.0);
        assert_eq!(alone.clouds, 1);
        assert!((1.0..=1.15).contains(&alone.ratio_median), "{alone:?}");
        assert_eq!(alone.ratio_p10, alone.ratio_median);
        let dense = run(0.5);
        let r = dense.ratio_median / alone.ratio_median;
        assert!(
            (r - std::f64::consts::FRAC_1_SQRT_2).abs() < 0.05,
            "{r} {dense:?}"
        );
        let none = cloud_spacing(&[node(NONE, 0, 400)], 400, |_| 1.0, |_| Ok(grid(0.0, 0.0)));
        assert_eq!(none.unwrap(), None);
    }
}
