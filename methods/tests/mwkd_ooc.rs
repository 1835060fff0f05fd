//! The MWKD build in units (`mwkd::ooc`) writes the same repository and index, byte for
//! byte, as the in-memory build, for any unit size and thread count; its spill files are
//! checked.

#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::{entries, with_threads};
use methods::mwkd::ooc::{self, UNIT_BYTES_PER_SAMPLE};
use methods::mwkd::{MwkdParams, codec, index};
use methods::spill::{Budget, SpillHook};
use methods::{MethodError, MethodKind, Params};
use scenes::generators::Generator;
use scenes::{NoProgress, PointCloud};

/// The in-memory build through the registry: `repo.bin` and `index.bin`.
fn in_memory(cloud: &PointCloud, params: &[&str], dir: &Path) -> (Vec<u8>, Vec<u8>) {
    let p = Params::parse(params).unwrap();
    let stats = MethodKind::Mwkd
        .build(cloud, &p, "test", dir, &NoProgress)
        .unwrap();
    assert_eq!(stats.extra["units"].as_u64(), Some(1), "{:?}", stats.extra);
    let read = |f: &str| std::fs::read(dir.join(f)).unwrap();
    (read(codec::REPO_FILE), read("index.bin"))
}

/// The build in units of at most `cap` samples: the same two files, and the unit count.
fn in_units(
    cloud: &PointCloud,
    params: &[&str],
    cap: u64,
    dir: &Path,
    hook: Option<SpillHook<'_>>,
) -> Result<(Vec<u8>, Vec<u8>, u64), MethodError> {
    std::fs::create_dir_all(dir).unwrap();
    let p = MwkdParams::from_params(&Params::parse(params).unwrap()).unwrap();
    let shape = p.ooc_shape();
    let budget = Budget {
        mem_bytes: cap * UNIT_BYTES_PER_SAMPLE,
        dir,
        hook,
    };
    let repo = dir.join(codec::REPO_FILE);
    let b = ooc::write_repository(cloud, shape, &repo, budget, &NoProgress)?;
    index::write(&dir.join("index.bin"), &b.written.index)?;
    let read = |f: &str| std::fs::read(dir.join(f)).unwrap();
    Ok((read(codec::REPO_FILE), read("index.bin"), b.units))
}

#[test]
fn units_give_the_in_memory_files_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let colored = common::degenerate_statue(true);
    let clouds = [
        ("statue", Generator::Statue.generate(30_000, 3).unwrap()),
        ("terrain", Generator::Terrain.generate(24_000, 5).unwrap()),
        ("degenerate", colored),
    ];
    let shapes: [&[&str]; 3] = [
        &["vbo=400"],
        &["vbo=300", "fanout=3"],
        &["vbo=500", "tree=kd"],
    ];
    for (name, cloud) in &clouds {
        for params in shapes {
            let (repo, idx) = in_memory(cloud, params, &tmp.path().join("a"));
            let n = cloud.len() as u64;
            for cap in [n / 7, n / 2] {
                let (r, i, units) =
                    in_units(cloud, params, cap, &tmp.path().join("b"), None).unwrap();
                assert!(
                    units >= n.div_ceil(cap),
                    "{name} {params:?} cap {cap}: {units} units"
                );
                assert!(idx == i, "{name} {params:?} cap {cap}: index.bin differs");
                assert!(repo == r, "{name} {params:?} cap {cap}: repo.bin differs");
                // Only the build's files are left.
                assert_eq!(
                    entries(&tmp.path().join("b")),
                    ["index.bin", codec::REPO_FILE]
                );
            }
        }
    }
}

#[test]
fn units_keep_the_scene_radii_and_do_not_depend_on_the_thread_count() {
    let tmp = tempfile::tempdir().unwrap();
    let c = Generator::Statue.generate(20_000, 8).unwrap();
    let radii: Vec<f32> = (0..c.len())
        .map(|i| 0.001 + (i % 13) as f32 * 1e-4)
        .collect();
    let cloud = PointCloud::new(
        c.origin(),
        c.positions().to_vec().into(),
        c.normals().map(|n| n.to_vec().into()),
        None,
        Some(radii.into()),
    )
    .unwrap();
    let params: &[&str] = &["vbo=300"];
    let (repo, idx) = in_memory(&cloud, params, &tmp.path().join("a"));
    for threads in [1, 3] {
        let (r, i, _) = with_threads(threads, || {
            in_units(&cloud, params, 3_000, &tmp.path().join("b"), None).unwrap()
        });
        assert!(repo == r && idx == i, "{threads} threads: files differ");
    }
}

#[test]
fn the_in_memory_files_do_not_depend_on_mem_mb() {
    // mem_mb sets the in-memory build's parallel tasks (n/16 at most); nodes are written in
    // post-order whatever the tasks.
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(40_000, 2).unwrap();
    let a = in_memory(&cloud, &["vbo=300", "mem_mb=16"], &tmp.path().join("a"));
    let b = in_memory(&cloud, &["vbo=300", "mem_mb=4096"], &tmp.path().join("b"));
    assert!(a == b);
}

#[test]
fn damaged_spill_files_are_named_and_nothing_is_left() {
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(20_000, 4).unwrap();
    common::spill_damage_is_named(tmp.path(), &|dir, hook| {
        in_units(&cloud, &["vbo=300"], 2_000, dir, Some(hook)).map(|_| ())
    });
}

#[test]
fn a_unit_too_small_for_its_leaf_radii_is_refused() {
    // Units of 40 samples are leaves of fewer than LEAF_KNN_MIN samples, whose in-memory
    // radii come from their parent's samples.
    let tmp = tempfile::tempdir().unwrap();
    let cloud = Generator::Statue.generate(2_000, 4).unwrap();
    let e = in_units(&cloud, &["vbo=40"], 40, tmp.path(), None)
        .err()
        .unwrap()
        .to_string();
    assert!(e.contains("raise mem_mb"), "{e}");
    assert!(entries(tmp.path()).iter().all(|f| !f.ends_with(".tmp")));
}
