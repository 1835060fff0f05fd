//! The SPT build in units (`spt::ooc`) writes the same files, byte for byte, as the
//! in-memory build; its spill files are checked.

#![allow(clippy::unwrap_used)]

use methods::Params;
use methods::spill::{Budget, Spill};
use methods::spt::{self, ooc::UNIT_BYTES_PER_SAMPLE};
use scenes::generators::Generator;
use scenes::{NoProgress, PointCloud};

const FILES: [&str; 3] = ["nodes.sbc", "lod.bin", "index.json"];

fn build(
    cloud: &PointCloud,
    params: &[&str],
    cap: u64,
    out: &std::path::Path,
    hook: Option<&dyn Fn(&[&Spill])>,
) -> Result<(Vec<Vec<u8>>, u64), methods::MethodError> {
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
    let files = FILES
        .iter()
        .map(|f| std::fs::read(out.join(f)).unwrap())
        .collect();
    Ok((files, stats.extra["units"].as_u64().unwrap()))
}

/// A statue with 7 copies of 30 samples (degenerate k-NN distances) and 6 far strays.
fn degenerate_statue() -> PointCloud {
    let c = Generator::Statue.generate(9_000, 4).unwrap();
    let mut pos = c.positions().to_vec();
    let mut nrm = c.normals().unwrap().to_vec();
    // Colours (the statue has none) make the colour rule part of the comparison.
    let mut col: Vec<[u8; 3]> = (0..c.len())
        .map(|i| [(i % 251) as u8, 90, (i % 7) as u8 * 30])
        .collect();
    for i in 0..30 {
        for _ in 0..7 {
            pos.push(pos[i * 200]);
            nrm.push(nrm[i * 200]);
            col.push(col[i * 200]);
        }
    }
    for j in 0..6 {
        pos.push([40.0 + 9.0 * j as f32, -30.0, 25.0 * j as f32]);
        nrm.push([0.0, 0.0, 1.0]);
        col.push([255, 0, 0]);
    }
    PointCloud::new(
        c.origin(),
        pos.into(),
        Some(nrm.into()),
        Some(col.into()),
        None,
    )
    .unwrap()
}

#[test]
fn units_give_the_in_memory_files_byte_for_byte() {
    let tmp = tempfile::tempdir().unwrap();
    let clouds = [
        ("statue", Generator::Statue.generate(20_000, 3).unwrap()),
        ("terrain", Generator::Terrain.generate(15_000, 2).unwrap()),
        ("degenerate", degenerate_statue()),
    ];
    for (name, cloud) in &clouds {
        let n = cloud.len() as u64;
        let param_sets: &[&[&str]] = if cloud.normals().is_some() {
            &[&[], &["normal_clusters=true", "color_threshold=10"]]
        } else {
            &[&[]]
        };
        for params in param_sets {
            let (whole, units) = build(cloud, params, n, &tmp.path().join("a"), None).unwrap();
            assert_eq!(units, 1);
            for cap in [600u64, 4000] {
                let (parts, units) =
                    build(cloud, params, cap, &tmp.path().join("b"), None).unwrap();
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
    let named = std::cell::RefCell::new(String::new());
    type Damage = fn(&std::path::Path);
    let cases: [(&str, Damage); 2] = [
        ("holds", |p| {
            let b = std::fs::read(p).unwrap();
            std::fs::write(p, &b[..b.len() - 5]).unwrap();
        }),
        ("checksum mismatch", |p| {
            let mut b = std::fs::read(p).unwrap();
            b[20] ^= 4;
            std::fs::write(p, &b).unwrap();
        }),
    ];
    for (what, damage) in cases {
        let out = tmp.path().join(what);
        let hook = |spills: &[&Spill]| {
            assert!(spills.len() >= 5, "{} units", spills.len());
            let victim = &spills[spills.len() / 2].path;
            *named.borrow_mut() = victim.display().to_string();
            damage(victim);
        };
        let err = build(&cloud, &[], 1500, &out, Some(&hook))
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
}
