//! Leaf radii: isolated samples are capped, the generators' samples never are.
#![allow(clippy::unwrap_used)]

use glam::DVec3;
use methods::leaf::{OUTLIER_CAP, OUTLIER_QUANTILE, cap_isolated, leaf_radii};
use scenes::PointCloud;
use scenes::generators::Generator;

#[test]
fn no_generator_sample_is_capped() {
    // The cap must leave the scenes every reproduced figure is measured on untouched,
    // including terrain, whose density varies more than 100×.
    for g in [Generator::Statue, Generator::Isosurface, Generator::Terrain] {
        let cloud = g.generate(200_000, 1).unwrap();
        let r = leaf_radii(&cloud);
        assert_eq!(r.capped, 0, "{}", g.name());
    }
}

#[test]
fn a_far_stray_gets_the_cap_and_nothing_else_moves() {
    let mut p: Vec<[f32; 3]> = (0..4000)
        .map(|i| [(i % 64) as f32 * 0.01, (i / 64) as f32 * 0.01, 0.0])
        .collect();
    let clean =
        leaf_radii(&PointCloud::new(DVec3::ZERO, p.clone().into(), None, None, None).unwrap())
            .radii
            .into_owned();
    p.push([6.0e3, 0.0, 0.0]);
    let cloud = PointCloud::new(DVec3::ZERO, p.into(), None, None, None).unwrap();
    let r = leaf_radii(&cloud);
    assert_eq!(r.capped, 1);
    // The stray's radius is the cap: OUTLIER_CAP × the quantile of the grid's radii. No grid
    // point's 6th neighbour is farther than 3 steps (0.03; a corner's is √5 steps), so the
    // cap is at most 4 × 0.03, where uncapped the stray's radius would be 6 km.
    let stray = r[4000];
    assert!(stray > 0.0 && stray <= OUTLIER_CAP * 0.03, "{stray}");
    // Its neighbours in the grid are not its neighbours: the others are unchanged.
    assert_eq!(&r[..4000], &clean[..]);
}

#[test]
fn cap_isolated_uses_the_stated_quantile() {
    // 1001 radii 1..=1000 and 5000: the 0.999 quantile is the value at floor(1000 × 0.999) =
    // index 999 of the sorted radii, 1000, so the cap is 4 × 1000 and only 5000 is above it.
    let mut r: Vec<f32> = (1..=1000).map(|v| v as f32).collect();
    r.push(5000.0);
    assert_eq!(OUTLIER_QUANTILE, 0.999);
    assert_eq!(cap_isolated(&mut r), 1);
    assert_eq!(r[1000], 4.0 * 1000.0);
    assert_eq!(cap_isolated(&mut [1.0]), 0);
}
