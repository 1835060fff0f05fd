//! SPT's quantised files (`spt::quant`): every stored value against the exact tree it came
//! from — centres within half a step (plus the `f32` rounding), radii and errors never
//! smaller, errors still monotone along every chain with `e_par` the parent's `e` bit for
//! bit, `δ` bounding the distance between the decoded centres, `γ` the angle between the
//! decoded normals — the chains of the stored list hole-free, and damaged files named.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use glam::Vec3;
use methods::spt::{self, Spt, build::NO_PARENT, build::PointTree, quant, select};
use methods::{IntervalTest, Manifest};
use scenes::PointCloud;
use scenes::generators::Generator;
use scenes::paths::PathSpec;

fn build_open(cloud: &PointCloud, params: &[&str], dir: &Path) -> Spt {
    common::spt_build_open(cloud, params, dir).unwrap()
}

/// The exact tree of a default build (one cluster), its `lod` entries, and each tree node's
/// position in the list.
fn exact(cloud: &PointCloud) -> (PointTree, Vec<[f32; 4]>, Vec<usize>) {
    let radii = methods::leaf::leaf_radii(cloud);
    let tree = spt::build::build_tree(cloud, &radii, 40.0);
    let lod = spt::lod_entries(&tree.nodes);
    let mut keys: Vec<u128> = (0..lod.len())
        .map(|i| spt::list_key(0, &lod[i], i as u32))
        .collect();
    keys.sort_unstable();
    let mut at = vec![0; keys.len()];
    for (pos, k) in keys.iter().enumerate() {
        at[*k as u32 as usize] = pos;
    }
    (tree, lod, at)
}

fn angle(a: Vec3, b: Vec3) -> f32 {
    a.cross(b).length().atan2(a.dot(b))
}

#[test]
fn stored_values_bound_the_exact_ones() {
    let tmp = tempfile::tempdir().unwrap();
    let clouds = [
        ("statue", Generator::Statue.generate(20_000, 3).unwrap()),
        ("terrain", Generator::Terrain.generate(15_000, 2).unwrap()),
        ("degenerate", common::degenerate_statue(true)),
    ];
    for (name, cloud) in &clouds {
        let (tree, lod, at) = exact(cloud);
        let has_normals = cloud.normals().is_some();
        let mut modes = vec!["unified"];
        if has_normals {
            modes.push("split");
        }
        for mode in modes {
            let m = build_open(
                cloud,
                &[&format!("mode={mode}")],
                &tmp.path().join(format!("{name}-{mode}")),
            );
            let grid = m.nodes().layout().grid;
            assert_eq!(grid, quant::Extent::of(&tree.nodes).grid(), "{name}");
            println!("{name} {mode}: grid {grid:?}, {} bytes per node record", {
                m.nodes().layout().record_bytes()
            });
            let stored = m.lod();
            for (k, nd) in tree.nodes.iter().enumerate() {
                let i = at[k];
                let p = m.position(i);
                for a in 0..3 {
                    let err = (f64::from(p[a]) - f64::from(nd.p[a])).abs();
                    let half = 0.5 * grid.step(a) + f64::from(nd.p[a].abs()) * 1.2e-7;
                    assert!(err <= half, "{name} node {k} axis {a}: off by {err}");
                }
                let r = m.radius(i);
                assert!(
                    r >= nd.r && r <= nd.r * (1.0 + 1.0 / 2048.0),
                    "{name} node {k}"
                );
                assert_eq!(stored[i][0], nd.e_g, "{name} node {k}: e is stored exactly");
                assert_eq!(stored[i][..2], lod[k][..2], "{name} node {k}");
                if has_normals {
                    assert!(angle(m.gpu_normal(i), nd.n) < 1.2e-3, "{name} node {k}");
                }
                if mode == "split" {
                    assert_eq!(stored[i][3], lod[k][3], "{name} node {k}");
                }
                if nd.parent == NO_PARENT {
                    assert_eq!(stored[i][1], select::ROOT_PARENT_ERROR);
                    assert_eq!(stored[i][2], 0.0);
                    continue;
                }
                let j = at[nd.parent as usize];
                // Monotone, and the child's e_par is the parent's e.
                assert!(stored[i][0] <= stored[j][0], "{name} node {k}");
                assert_eq!(stored[i][1], stored[j][0], "{name} node {k}");
                // δ bounds the distance of the decoded centres (and of the exact ones).
                assert!(stored[i][2] >= p.distance(m.position(j)), "{name} node {k}");
                assert!(stored[i][2] >= nd.p.distance(tree.nodes[nd.parent as usize].p));
                if mode == "split" {
                    let q_gamma = stored[i][3] as u32 & 0xff;
                    if q_gamma < select::GAMMA_UNBOUNDED {
                        let gamma = q_gamma as f32 * select::GAMMA_STEP;
                        assert!(
                            angle(m.gpu_normal(i), m.gpu_normal(j)) <= gamma,
                            "{name} node {k}: γ below the decoded normals' angle"
                        );
                    }
                }
            }
        }
    }
}

/// Per leaf, how many nodes of its chain pass, every value as `open` decodes it.
fn stored_chain_counts(
    m: &Spt,
    tree: &PointTree,
    at: &[usize],
    eye: Vec3,
    test: &IntervalTest,
) -> Vec<u32> {
    let pass: Vec<bool> = (0..tree.nodes.len())
        .map(|k| {
            let i = at[k];
            select::interval_pass(m.position(i), m.gpu_normal(i), m.lod()[i], eye, test)
        })
        .collect();
    tree.leaf_of
        .iter()
        .map(|&leaf| {
            let (mut k, mut c) = (leaf, 0);
            loop {
                c += pass[k as usize] as u32;
                match tree.nodes[k as usize].parent {
                    NO_PARENT => break c,
                    p => k = p,
                }
            }
        })
        .collect()
}

/// The README's hole-free argument on the files: with overlap 1, every leaf's chain of the
/// stored list (decoded centres, normals and entries) has a node that passes, in both modes.
#[test]
fn chains_of_the_stored_list_have_no_holes() {
    let cloud = Generator::Statue.generate(30_000, 7).unwrap();
    let (tree, _, at) = exact(&cloud);
    let tmp = tempfile::tempdir().unwrap();
    let b = cloud.bounds();
    for (mode, code) in [
        ("unified", select::MODE_UNIFIED),
        ("split", select::MODE_SPLIT),
    ] {
        let m = build_open(&cloud, &[&format!("mode={mode}")], &tmp.path().join(mode));
        for (path, frame, frames) in [("orbit", 0, 4), ("orbit", 2, 4), ("zoom", 8, 10)] {
            let view = scenes::View {
                camera: PathSpec::parse(path).unwrap().camera(frame, frames, &b),
                width: 640,
                height: 480,
            };
            for eps in [1.0f32, 4.0] {
                let test = IntervalTest {
                    mode: code,
                    scale: eps / view.proj_scale(),
                    overlap: 1.0,
                };
                let c = stored_chain_counts(&m, &tree, &at, view.camera.position, &test);
                let holes = c.iter().filter(|&&c| c == 0).count();
                assert_eq!(holes, 0, "{mode} {path} {frame} eps {eps}: holes");
            }
        }
    }
}

/// Where the last record of a unified-mode `lod.bin` starts (the README's layout: a tag,
/// `e_par` in 0, 1–3 or 4 bytes, `e` in 0 or 4, `δ` in 2).
fn last_lod_record(b: &[u8]) -> usize {
    let count = u64::from_le_bytes(b[8..16].try_into().unwrap());
    let mut at = 40;
    let mut last = at;
    for _ in 0..count {
        last = at;
        let tag = b[at];
        at += 1;
        at += match tag & 3 {
            0 => 0,
            1 => b[at..].iter().position(|&x| x & 0x80 == 0).unwrap() + 1,
            _ => 4,
        };
        at += 4 * (tag as usize >> 2 & 1) + 2;
    }
    assert_eq!(at, b.len(), "the layout walks the whole file");
    last
}

/// Recomputes the checksum both files keep at byte 16 over the bytes from 24.
fn reseal(b: &mut [u8]) {
    let sum = scenes::hash::fnv1a64(&b[24..]);
    b[16..24].copy_from_slice(&sum.to_le_bytes());
}

#[test]
fn damaged_files_are_errors_naming_them() {
    let tmp = tempfile::tempdir().unwrap();
    let dir = tmp.path().join("b");
    let cloud = Generator::Statue.generate(3_000, 2).unwrap();
    build_open(&cloud, &[], &dir);
    let open = || match Spt::open(&dir, Manifest::read(&dir).unwrap()) {
        Ok(_) => panic!("a damaged build opened"),
        Err(e) => e.to_string(),
    };
    type Damage = fn(&mut Vec<u8>);
    let cases: [(&str, &str, Damage); 20] = [
        ("nodes.bin", "checksum", |b| *b.last_mut().unwrap() ^= 0x40),
        ("nodes.bin", "bytes", |b| b.truncate(b.len() - 5)),
        ("nodes.bin", "short header", |b| b.truncate(40)),
        ("nodes.bin", "magic", |b| b.clear()),
        ("nodes.bin", "magic", |b| {
            b[..8].copy_from_slice(b"SPLATCOL")
        }),
        ("nodes.bin", "index.json says", |b| {
            b[8] ^= 1;
            reseal(b)
        }),
        ("nodes.bin", "bytes per coordinate", |b| {
            b[56] = 5;
            reseal(b)
        }),
        ("nodes.bin", "out of range", |b| {
            b[44..48].copy_from_slice(&500i32.to_le_bytes());
            reseal(b)
        }),
        ("nodes.bin", "flags", |b| {
            b[24] = 0x80;
            reseal(b)
        }),
        ("nodes.bin", "method.json", |b| {
            b[24] ^= 1; // normals dropped: the record is 3 bytes shorter
            let rec = u32::from_le_bytes(b[28..32].try_into().unwrap()) - 3;
            b[28..32].copy_from_slice(&rec.to_le_bytes());
            let n = (b.len() - 64) / (rec as usize + 3);
            b.truncate(64 + n * rec as usize);
            reseal(b)
        }),
        ("nodes.bin", "radius", |b| {
            let n = b.len() - 2;
            b[n..].copy_from_slice(&[0, 0]);
            reseal(b)
        }),
        ("lod.bin", "checksum", |b| b[40] ^= 1),
        ("lod.bin", "end early", |b| {
            b.truncate(b.len() - 1);
            reseal(b)
        }),
        ("lod.bin", "checksum", |b| b.truncate(b.len() - 1)),
        ("lod.bin", "not finite", |b| {
            // The first record (the root): tag, then e_par raw.
            assert_eq!(b[40] & 3, 2);
            b[41..45].copy_from_slice(&f32::NAN.to_le_bytes());
            reseal(b)
        }),
        ("lod.bin", "bad tag", |b| {
            b[40] |= 0x80;
            reseal(b)
        }),
        ("lod.bin", "after the last", |b| {
            b.push(0);
            reseal(b)
        }),
        ("lod.bin", "lod scale", |b| {
            b[28..32].copy_from_slice(&0f32.to_le_bytes());
            reseal(b)
        }),
        ("lod.bin", "mode", |b| {
            b[24] = 1;
            reseal(b)
        }),
        ("lod.bin", "sorted", |b| {
            // The last node's e_par raised above the one before it (stored raw).
            let last = last_lod_record(b);
            let tag = b[last];
            let skip = match tag & 3 {
                0 => 0,
                1 => b[last + 1..].iter().position(|&x| x & 0x80 == 0).unwrap() + 1,
                _ => 4,
            };
            b[last] = (tag & !3) | 2;
            b.splice(last + 1..last + 1 + skip, 1e30f32.to_le_bytes());
            reseal(b)
        }),
    ];
    for (file, what, damage) in cases {
        let path = dir.join(file);
        let orig = std::fs::read(&path).unwrap();
        let mut b = orig.clone();
        damage(&mut b);
        std::fs::write(&path, &b).unwrap();
        let e = open();
        assert!(e.contains(file) && e.contains(what), "{file} {what}: {e}");
        std::fs::write(&path, &orig).unwrap();
    }
    std::fs::remove_file(dir.join("lod.bin")).unwrap();
    let e = open();
    assert!(e.contains("lod.bin"), "{e}");
    // A build of the previous format.
    let manifest = dir.join(Manifest::FILE);
    let text = std::fs::read_to_string(&manifest).unwrap();
    std::fs::write(
        &manifest,
        text.replace("\"format_version\": 2", "\"format_version\": 1"),
    )
    .unwrap();
    let e = open();
    assert!(
        e.contains("method.json") && e.contains("format_version 1"),
        "{e}"
    );
}
