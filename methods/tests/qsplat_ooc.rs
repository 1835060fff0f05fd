//! The QSplat build in units (`qsplat::ooc`) writes the same file, byte for byte, as the
//! in-memory build; its spill files are checked.

#![allow(clippy::unwrap_used)]

use methods::qsplat::build::{BuildOptions, Combine, Split};
use methods::qsplat::ooc::{self, UNIT_BYTES_PER_SAMPLE};
use scenes::generators::Generator;
use scenes::{NoProgress, PointCloud};

fn build(cloud: &PointCloud, opt: BuildOptions, cap: u64, out: &std::path::Path) -> (Vec<u8>, u64) {
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
    (std::fs::read(&path).unwrap(), t.units)
}

#[test]
fn units_give_the_in_memory_file_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    for (g, n) in [(Generator::Statue, 20_000), (Generator::Terrain, 12_000)] {
        let cloud = g.generate(n, 3).unwrap();
        for split in [Split::Midpoint, Split::Median] {
            for combine in [Combine::Fewest, Combine::Pairs] {
                let opt = BuildOptions { split, combine };
                let (whole, units) = build(&cloud, opt, n as u64, &tmp.path().join("a"));
                assert_eq!(units, 1);
                for cap in [700u64, 3000] {
                    let (parts, units) = build(&cloud, opt, cap, &tmp.path().join("b"));
                    assert!(
                        units >= (n as u64).div_ceil(cap),
                        "{g:?} {opt:?} cap {cap}: {units} units"
                    );
                    assert!(whole == parts, "{g:?} {opt:?} cap {cap}: files differ");
                }
            }
        }
    }
}

/// A statue with the degenerate cases of the leaf radii: 7 exact copies of 30 samples
/// (their 6th neighbour is at distance 0: the fallback) and 6 far strays (capped as
/// isolated).
fn degenerate_statue() -> PointCloud {
    let c = Generator::Statue.generate(9_000, 4).unwrap();
    let mut pos = c.positions().to_vec();
    let mut nrm = c.normals().unwrap().to_vec();
    for i in 0..30 {
        for _ in 0..7 {
            pos.push(pos[i * 200]);
            nrm.push(nrm[i * 200]);
        }
    }
    for j in 0..6 {
        pos.push([40.0 + 9.0 * j as f32, -30.0, 25.0 * j as f32]);
        nrm.push([0.0, 0.0, 1.0]);
    }
    PointCloud::new(c.origin(), pos.into(), Some(nrm.into()), None, None).unwrap()
}

#[test]
fn leaf_radii_by_units_are_the_in_memory_ones_with_fallback_cap_and_given_radii() {
    let tmp = tempfile::tempdir().unwrap();
    let cloud = degenerate_statue();
    let radii = methods::leaf::leaf_radii(&cloud);
    assert!(radii.capped >= 6, "{} capped", radii.capped);
    let n = cloud.len() as u64;
    let opt = BuildOptions::default();
    let (whole, _) = build(&cloud, opt, n, &tmp.path().join("a"));
    let (parts, units) = build(&cloud, opt, 900, &tmp.path().join("b"));
    assert!(units >= 10);
    assert!(whole == parts, "k-NN radii by units differ");
    // A scene with its own radii carries them in the records.
    let given: Vec<f32> = (0..cloud.len())
        .map(|i| 0.001 + (i % 7) as f32 * 1e-4)
        .collect();
    let cloud = cloud.with_radii(given).unwrap();
    let (whole, _) = build(&cloud, opt, n, &tmp.path().join("c"));
    let (parts, _) = build(&cloud, opt, 900, &tmp.path().join("d"));
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
    let named = std::cell::RefCell::new(String::new());
    type Damage = fn(&std::path::Path);
    let cases: [(&str, Damage); 3] = [
        ("holds", |p| {
            let b = std::fs::read(p).unwrap();
            std::fs::write(p, &b[..b.len() - 3]).unwrap();
        }),
        ("checksum mismatch", |p| {
            let mut b = std::fs::read(p).unwrap();
            b[100] ^= 1;
            std::fs::write(p, &b).unwrap();
        }),
        ("No such file", |p| std::fs::remove_file(p).unwrap()),
    ];
    for (what, damage) in cases {
        let out = tmp.path().join(what);
        let err = build_hooked(&cloud, &out, &|spills| {
            assert!(spills.len() >= 5, "{} units", spills.len());
            let victim = &spills[spills.len() / 2].path;
            *named.borrow_mut() = victim.display().to_string();
            damage(victim);
        })
        .unwrap_err()
        .to_string();
        assert!(
            err.contains(named.borrow().as_str()) && err.contains(what),
            "{what}: {err}"
        );
        let left: Vec<_> = std::fs::read_dir(&out)
            .unwrap()
            .map(|e| e.unwrap().file_name())
            .collect();
        assert!(left.is_empty(), "{what}: left {left:?}");
    }
    // Undamaged, the same call succeeds and leaves only the tree.
    let out = tmp.path().join("fine");
    let t = build_hooked(&cloud, &out, &|_| {}).unwrap();
    assert_eq!(t.leaves, 10_000);
    let left: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["tree.qs"]);
}
