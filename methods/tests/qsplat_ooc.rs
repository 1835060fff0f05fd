//! The QSplat build in units (`qsplat::ooc`) writes the same file, byte for byte, as the
//! in-memory build; its spill files are checked.

#![allow(clippy::unwrap_used)]

mod common;

use methods::qsplat::build::{BuildOptions, Combine, Split};
use methods::qsplat::ooc::{self, UNIT_BYTES_PER_SAMPLE};
use methods::qsplat::stats::QuantStats;
use scenes::generators::Generator;
use scenes::{NoProgress, PointCloud};

fn build(
    cloud: &PointCloud,
    opt: BuildOptions,
    cap: u64,
    out: &std::path::Path,
) -> (Vec<u8>, u64, QuantStats) {
    std::fs::create_dir_all(out).unwrap();
    let path = out.join("tree.qs");
    let t = ooc::build_file(
        cloud,
        opt,
        &path,
        ooc::Budget {
            mem_bytes: cap * UNIT_BYTES_PER_SAMPLE,
            dir: out,
            hook: None,
        },
        &NoProgress,
    )
    .unwrap();
    (std::fs::read(&path).unwrap(), t.units, t.quant)
}

#[test]
fn units_give_the_in_memory_file_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    for (g, n) in [(Generator::Statue, 20_000), (Generator::Terrain, 12_000)] {
        let cloud = g.generate(n, 3).unwrap();
        for split in [Split::Midpoint, Split::Median] {
            for combine in [Combine::Fewest, Combine::Pairs] {
                let opt = BuildOptions {
                    split,
                    combine,
                    ..Default::default()
                };
                let (whole, units, wq) = build(&cloud, opt, n as u64, &tmp.path().join("a"));
                assert_eq!(units, 1);
                for cap in [700u64, 3000] {
                    let (parts, units, pq) = build(&cloud, opt, cap, &tmp.path().join("b"));
                    assert!(
                        units >= (n as u64).div_ceil(cap),
                        "{g:?} {opt:?} cap {cap}: {units} units"
                    );
                    assert!(whole == parts, "{g:?} {opt:?} cap {cap}: files differ");
                    // The quantisation figures count the same nodes (their sums differ
                    // by the order of addition only).
                    let ((a, b), what) = ((&wq, &pq), format!("{g:?} {opt:?} cap {cap}"));
                    assert_eq!(
                        (a.spheres, a.not_enclosed, a.normals, a.children),
                        (b.spheres, b.not_enclosed, b.normals, b.children),
                        "{what}"
                    );
                    // Units number their levels from the whole tree's root.
                    assert_eq!(a.level_spheres, b.level_spheres, "{what}");
                    assert_eq!(
                        (a.sphere_codes, a.cone_codes),
                        (b.sphere_codes, b.cone_codes),
                        "{what}"
                    );
                    for (x, y) in [
                        (a.centre_error, b.centre_error),
                        (a.radius_error, b.radius_error),
                        (a.radius_error_l1, b.radius_error_l1),
                        (a.normal_error, b.normal_error),
                    ]
                    .into_iter()
                    .chain(a.level_centre_error.into_iter().zip(b.level_centre_error))
                    {
                        assert!((x - y).abs() <= 1e-9 * x.abs().max(1.0), "{what}");
                    }
                    assert_eq!(a.normal_error_max, b.normal_error_max, "{what}");
                }
            }
        }
    }
}

#[test]
fn leaf_radii_by_units_are_the_in_memory_ones_with_fallback_cap_and_given_radii() {
    let tmp = tempfile::tempdir().unwrap();
    let cloud = common::degenerate_statue(false);
    let radii = methods::leaf::leaf_radii(&cloud);
    assert!(radii.capped >= 6, "{} capped", radii.capped);
    let n = cloud.len() as u64;
    let opt = BuildOptions::default();
    let (whole, _, _) = build(&cloud, opt, n, &tmp.path().join("a"));
    let (parts, units, _) = build(&cloud, opt, 900, &tmp.path().join("b"));
    assert!(units >= 10);
    assert!(whole == parts, "k-NN radii by units differ");
    // A scene with its own radii carries them in the records.
    let given: Vec<f32> = (0..cloud.len())
        .map(|i| 0.001 + (i % 7) as f32 * 1e-4)
        .collect();
    let cloud = cloud.with_radii(given).unwrap();
    let (whole, _, _) = build(&cloud, opt, n, &tmp.path().join("c"));
    let (parts, _, _) = build(&cloud, opt, 900, &tmp.path().join("d"));
    assert!(whole == parts, "given radii by units differ");
}

/// Builds `cloud` in units of 2000 samples into `out`, calling `hook` on the spill files.
fn build_hooked(
    cloud: &PointCloud,
    out: &std::path::Path,
    hook: &dyn Fn(&[&methods::spill::Spill]),
) -> Result<ooc::TreeStats, methods::MethodError> {
    std::fs::create_dir_all(out).unwrap();
    ooc::build_file(
        cloud,
        BuildOptions::default(),
        &out.join("tree.qs"),
        ooc::Budget {
            mem_bytes: 2000 * UNIT_BYTES_PER_SAMPLE,
            dir: out,
            hook: Some(hook),
        },
        &NoProgress,
    )
}

#[test]
fn a_short_or_altered_spill_file_is_an_error_naming_it_and_leaves_nothing() {
    let cloud = Generator::Statue.generate(10_000, 5).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    common::spill_damage_is_named(tmp.path(), &|dir, hook| {
        build_hooked(&cloud, dir, hook).map(|_| ())
    });
    // The units' saved partitions (the hook's second call), damaged the same ways.
    let parts = tmp.path().join("partitions");
    common::spill_damage_is_named(&parts, &|dir, hook| {
        build_hooked(&cloud, dir, &|spills| {
            if spills[0].path.to_string_lossy().contains("partition-") {
                hook(spills);
            }
        })
        .map(|_| ())
    });
    // Undamaged, the same call succeeds and leaves only the tree.
    let out = tmp.path().join("fine");
    let t = build_hooked(&cloud, &out, &|_| {}).unwrap();
    assert_eq!(t.leaves, 10_000);
    assert_eq!(common::entries(&out), ["tree.qs"]);
}

#[test]
fn files_do_not_depend_on_the_thread_count() {
    // 40 k samples: ranges above PAR_THRESHOLD (2^15) split in parallel, in memory and in
    // units of 12 k.
    let cloud = Generator::Statue.generate(40_000, 6).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for threads in [1, 3] {
        for cap in [40_000u64, 12_000] {
            let out = tmp.path().join(format!("{threads}-{cap}"));
            files.push(
                common::with_threads(threads, || {
                    build(&cloud, BuildOptions::default(), cap, &out)
                })
                .0,
            );
        }
    }
    assert!(files.iter().all(|f| *f == files[0]));
}
