//! The SPT build in units (`spt::ooc`) writes the same files, byte for byte, as the
//! in-memory build, and reports the same figures of its inner nodes; its spill files are
//! checked.

#![allow(clippy::unwrap_used)]

mod common;

use methods::Params;
use methods::spill::{Budget, SpillHook};
use methods::spt::{self, ooc::UNIT_BYTES_PER_SAMPLE};
use scenes::generators::Generator;
use scenes::{NoProgress, PointCloud};

const FILES: [&str; 3] = ["nodes.bin", "lod.bin", "index.json"];

/// The build's figures of its inner nodes (§3's bound e_g ≤ d, `spt::InnerNodes`).
const INNER: [&str; 5] = [
    "inner_nodes",
    "inner_eg_above_d",
    "inner_eg_over_d_max",
    "inner_eg_above_sphere",
    "inner_eg_over_sphere_max",
];

/// A build's files ([`FILES`]), its unit count and its [`INNER`] figures.
type Built = (Vec<Vec<u8>>, u64, Vec<f64>);

fn build(
    cloud: &PointCloud,
    params: &[&str],
    cap: u64,
    out: &std::path::Path,
    hook: Option<SpillHook<'_>>,
) -> Result<Built, methods::MethodError> {
    std::fs::create_dir_all(out).unwrap();
    let params = Params::parse(&params.iter().map(|s| s.to_string()).collect::<Vec<_>>()).unwrap();
    let stats = spt::build_with_budget(
        cloud,
        &params,
        "test",
        &NoProgress,
        Budget {
            mem_bytes: cap * UNIT_BYTES_PER_SAMPLE,
            dir: out,
            hook,
        },
    )?;
    // Only the build's files are left (the spill directory is gone).
    assert_eq!(
        common::entries(out),
        ["index.json", "lod.bin", "method.json", "nodes.bin"]
    );
    let files = FILES
        .iter()
        .map(|f| std::fs::read(out.join(f)).unwrap())
        .collect();
    let inner = INNER
        .iter()
        .map(|k| stats.extra[*k].as_f64().unwrap())
        .collect();
    Ok((files, stats.extra["units"].as_u64().unwrap(), inner))
}

#[test]
fn units_give_the_in_memory_files_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let clouds = [
        ("statue", Generator::Statue.generate(20_000, 3).unwrap()),
        ("terrain", Generator::Terrain.generate(15_000, 2).unwrap()),
        ("degenerate", common::degenerate_statue(true)),
    ];
    for (name, cloud) in &clouds {
        let n = cloud.len() as u64;
        let param_sets: &[&[&str]] = if cloud.normals().is_some() {
            &[&[], &["normal_clusters=true", "color_threshold=10"]]
        } else {
            &[&[]]
        };
        for params in param_sets {
            let (whole, units, inner) =
                build(cloud, params, n, &tmp.path().join("a"), None).unwrap();
            assert_eq!(units, 1);
            for cap in [600u64, 4000] {
                let (parts, units, parts_inner) =
                    build(cloud, params, cap, &tmp.path().join("b"), None).unwrap();
                assert_eq!(inner, parts_inner, "{name} {params:?} cap {cap}: {INNER:?}");
                assert!(units >= n.div_ceil(cap), "{name} cap {cap}: {units} units");
                for (f, (a, b)) in FILES.iter().zip(whole.iter().zip(&parts)) {
                    assert!(a == b, "{name} {params:?} cap {cap}: {f} differs");
                }
            }
        }
    }
}

#[test]
fn a_short_or_altered_spill_file_is_an_error_naming_it_and_leaves_nothing() {
    let cloud = Generator::Statue.generate(10_000, 5).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    common::spill_damage_is_named(tmp.path(), &|dir, hook| {
        build(&cloud, &[], 1500, dir, Some(hook)).map(|_| ())
    });
}

#[test]
fn files_do_not_depend_on_the_thread_count() {
    // 40 k samples: cells above PAR_SAMPLES (2^14) build their subtrees in parallel, in
    // memory and in units of 12 k.
    let cloud = Generator::Statue.generate(40_000, 6).unwrap();
    let tmp = tempfile::tempdir().unwrap();
    let mut files = Vec::new();
    for threads in [1, 3] {
        for cap in [40_000u64, 12_000] {
            let out = tmp.path().join(format!("{threads}-{cap}"));
            let (f, units, _) =
                common::with_threads(threads, || build(&cloud, &[], cap, &out, None)).unwrap();
            assert_eq!(units > 1, cap < 40_000);
            files.push(f);
        }
    }
    assert!(files.iter().all(|f| *f == files[0]));
}
