//! LAS and LAZ reading and writing: round trips with and without colours, colour depth,
//! wrong header bounds, errors naming the file, the streamed reader to column files, the
//! column-file cache of large files, and files whose extension names another format.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::{tmp, write_bytes};
use glam::DVec3;
use scenes::rng::Pcg32;
use scenes::{Attributes, PointCloud};

/// A LiDAR-like terrain tile of 1 km² at UTM-like coordinates, with colours if asked.
fn terrain(n: usize, colors: bool) -> PointCloud {
    let mut r = Pcg32::new(11);
    let pos: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            let x = r.range_f32(-500.0, 500.0);
            let y = r.range_f32(-500.0, 500.0);
            let z = 20.0 * (x * 0.01).sin() * (y * 0.013).cos() + r.range_f32(-0.2, 0.2);
            [x, y, z]
        })
        .collect();
    let col: Option<Vec<[u8; 3]>> = colors.then(|| {
        (0..n)
            .map(|_| [r.below(256) as u8, r.below(256) as u8, r.below(256) as u8])
            .collect()
    });
    PointCloud::new(
        DVec3::new(500_000.0, 4_100_000.0, 50.0),
        pos.into(),
        None,
        col.map(Into::into),
        None,
    )
    .unwrap()
}

/// World positions equal within quantisation (scale / 2) plus the f32 rounding of the read
/// cloud's local coordinates (half an ulp of the largest local coordinate).
fn assert_las_positions(a: &PointCloud, b: &PointCloud) {
    assert_eq!(a.len(), b.len());
    let reach = a.bounds().min.abs().max(a.bounds().max.abs()).max_element();
    let scale = scenes::las::choose_scale(2.0 * f64::from(reach));
    assert!(
        scale <= 1e-5,
        "a 1 km tile must get a fine scale, got {scale}"
    );
    let f32_round = 2.0 * f64::from(reach) * f64::from(f32::EPSILON) * 0.5;
    let tol = 0.5 * scale + f32_round + 1e-9;
    for i in 0..a.len() {
        let d = (a.world_position(i) - b.world_position(i))
            .abs()
            .max_element();
        assert!(d <= tol, "point {i}: off by {d} > {tol}");
    }
}

#[test]
fn las_and_laz_round_trip_with_colours() {
    let dir = tmp();
    let cloud = terrain(20_000, true);
    let mut sizes = Vec::new();
    for name in ["tile.las", "tile.laz", "TILE.LAZ"] {
        let p = dir.path().join(name);
        let bytes = scenes::las::write(&p, &cloud).unwrap();
        assert_eq!(bytes, std::fs::metadata(&p).unwrap().len());
        sizes.push(bytes);
        let h = las::Reader::from_path(&p).unwrap();
        assert_eq!(h.header().point_format().to_u8().unwrap(), 2);
        assert_eq!(h.header().point_format().is_compressed, name != "tile.las");
        assert_eq!(h.header().number_of_points(), 20_000);
        drop(h);
        let back = scenes::las::read(&p).unwrap();
        assert_eq!(
            back.attributes(),
            Attributes {
                normals: false,
                colors: true,
                radii: false
            }
        );
        assert_las_positions(&cloud, &back);
        assert_eq!(cloud.colors().unwrap(), back.colors().unwrap(), "{name}");
        assert!((back.origin() - cloud.origin()).length() < 30.0);
    }
    assert!(sizes[1] < sizes[0], "LAZ must compress: {sizes:?}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
}

#[test]
fn las_without_colours_uses_format_0() {
    let dir = tmp();
    let cloud = terrain(5000, false);
    for name in ["plain.las", "plain.laz"] {
        let p = dir.path().join(name);
        scenes::las::write(&p, &cloud).unwrap();
        let h = las::Reader::from_path(&p).unwrap();
        assert_eq!(h.header().point_format().to_u8().unwrap(), 0);
        drop(h);
        let back = scenes::las::read(&p).unwrap();
        assert_eq!(back.attributes(), Attributes::default());
        assert_las_positions(&cloud, &back);
    }
}

/// Writes points with the `las` crate directly (other writers' conventions).
fn write_raw_las(path: &Path, points: &[(f64, f64, f64, Option<[u16; 3]>)]) {
    let mut b = las::Builder::from((1, 2));
    b.point_format = las::point::Format::new(if points.iter().any(|p| p.3.is_some()) {
        2
    } else {
        0
    })
    .unwrap();
    b.transforms = las::Vector {
        x: las::Transform {
            scale: 0.01,
            offset: 300_000.0,
        },
        y: las::Transform {
            scale: 0.01,
            offset: 5_000_000.0,
        },
        z: las::Transform {
            scale: 0.01,
            offset: 0.0,
        },
    };
    let mut w = las::Writer::from_path(path, b.into_header().unwrap()).unwrap();
    for &(x, y, z, c) in points {
        w.write_point(las::Point {
            x,
            y,
            z,
            color: c.map(|c| las::Color {
                red: c[0],
                green: c[1],
                blue: c[2],
            }),
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

#[test]
fn las_colour_depth_is_detected() {
    let dir = tmp();
    let p8 = dir.path().join("eight.las");
    write_raw_las(
        &p8,
        &[
            (300_001.0, 5_000_001.0, 1.0, Some([10, 200, 255])),
            (300_002.0, 5_000_002.0, 2.0, Some([0, 1, 2])),
        ],
    );
    assert_eq!(
        scenes::las::read(&p8).unwrap().colors().unwrap(),
        &[[10, 200, 255], [0, 1, 2]]
    );
    let p16 = dir.path().join("sixteen.laz");
    write_raw_las(
        &p16,
        &[
            (300_001.0, 5_000_001.0, 1.0, Some([0x1234, 0xff00, 0x00ff])),
            (300_002.0, 5_000_002.0, 2.0, Some([65535, 256, 0])),
        ],
    );
    let c = scenes::las::read(&p16).unwrap();
    assert_eq!(c.colors().unwrap(), &[[0x12, 0xff, 0x00], [255, 1, 0]]);
    assert!((c.world_position(1) - DVec3::new(300_002.0, 5_000_002.0, 2.0)).length() < 1e-3);
}

#[test]
fn las_with_wrong_header_bounds_keeps_precision() {
    let dir = tmp();
    let cloud = terrain(3000, false);
    let p = dir.path().join("badbounds.las");
    scenes::las::write(&p, &cloud).unwrap();
    // LAS 1.2 header: max x, min x, max y, min y, max z, min z as f64 at bytes 179..227.
    let mut bytes = std::fs::read(&p).unwrap();
    bytes[179..227].fill(0);
    std::fs::write(&p, &bytes).unwrap();
    let back = scenes::las::read(&p).unwrap();
    assert_las_positions(&cloud, &back);
    // The origin moved to the data, not to (0, 0, 0).
    assert!(
        (back.origin() - cloud.origin()).length() < 30.0,
        "{}",
        back.origin()
    );
}

#[test]
fn las_errors_name_the_file() {
    let dir = tmp();
    let d = dir.path();
    // Not a LAS file.
    let p = write_bytes(d, "fake.las", b"ply\nformat ascii 1.0\n");
    let m = scenes::las::read(&p).unwrap_err().to_string();
    assert!(m.contains("fake.las"), "{m}");
    // No points.
    let empty = d.join("empty.las");
    write_raw_las(&empty, &[]);
    let m = scenes::las::read(&empty).unwrap_err().to_string();
    assert!(m.contains("empty.las") && m.contains("no points"), "{m}");
    // Truncated point data.
    let t = d.join("trunc.las");
    scenes::las::write(&t, &terrain(1000, true)).unwrap();
    let bytes = std::fs::read(&t).unwrap();
    std::fs::write(&t, &bytes[..bytes.len() - 100]).unwrap();
    let m = scenes::las::read(&t).unwrap_err().to_string();
    assert!(m.contains("trunc.las") && m.contains("of 1000"), "{m}");
    // Truncated LAZ.
    let z = d.join("trunc.laz");
    scenes::las::write(&z, &terrain(1000, true)).unwrap();
    let bytes = std::fs::read(&z).unwrap();
    std::fs::write(&z, &bytes[..bytes.len() / 2]).unwrap();
    let m = scenes::las::read(&z).unwrap_err().to_string();
    assert!(m.contains("trunc.laz"), "{m}");
}

/// The streamed LAS reader gives exactly the in-memory reader's cloud (origin, positions,
/// colours): good header, wrong header bounds, 16-bit colours in LAZ, far strays.
#[test]
fn las_read_to_columns_is_the_in_memory_cloud() {
    let dir = tmp();
    let d = dir.path();
    let tile = d.join("tile.las");
    scenes::las::write(&tile, &terrain(5000, true)).unwrap();
    let bad = d.join("badbounds.las");
    scenes::las::write(&bad, &terrain(3000, false)).unwrap();
    let mut bytes = std::fs::read(&bad).unwrap();
    bytes[179..227].fill(0);
    std::fs::write(&bad, &bytes).unwrap();
    let deep = d.join("sixteen.laz");
    let strays = d.join("strays.las");
    let mut r = Pcg32::new(3);
    let mut pts: Vec<(f64, f64, f64, Option<[u16; 3]>)> = (0..4000)
        .map(|i| {
            let (x, y) = (r.f32() as f64 * 500.0, r.f32() as f64 * 500.0);
            (
                300_000.0 + x,
                5_000_000.0 + y,
                20.0 + (x * 0.01).sin(),
                Some([i as u16 * 16, 300, 7]),
            )
        })
        .collect();
    write_raw_las(&deep, &pts);
    pts.push((0.0, 0.0, 0.0, Some([0, 0, 0])));
    pts.push((0.0, 1.0, 0.0, Some([0, 0, 0])));
    write_raw_las(&strays, &pts);
    for p in [&tile, &bad, &deep, &strays] {
        let mem = scenes::las::read(p).unwrap();
        let out = d.join("cols.sbc");
        let col = scenes::las::read_to_columns(p, &out).unwrap();
        assert!(col.is_mapped());
        assert_eq!(col.origin(), mem.origin(), "{}", p.display());
        assert_eq!(col.positions(), mem.positions(), "{}", p.display());
        assert_eq!(col.colors(), mem.colors(), "{}", p.display());
        assert_eq!(col.attributes(), mem.attributes(), "{}", p.display());
    }
    // The strays moved the origin to the inliers (not to the strays' side).
    let s = scenes::las::read(&strays).unwrap();
    assert!(s.origin().x > 299_000.0, "{}", s.origin());
    // Errors name the file, and no column file is left.
    let fake = write_bytes(d, "fake.las", b"ply\nformat ascii 1.0\n");
    let out = d.join("fake.sbc");
    let m = scenes::las::read_to_columns(&fake, &out)
        .unwrap_err()
        .to_string();
    assert!(m.contains("fake.las"), "{m}");
    assert!(!out.exists());
}

/// A LAS file of at least `CACHE_MIN_POINTS` points loads through a column file in the cache
/// (the second load maps it), and an edited file is read again.
#[test]
fn large_las_files_are_cached_as_column_files() {
    let dir = tmp();
    let d = dir.path();
    let las = d.join("big.las");
    let cloud = scenes::generators::Generator::Terrain
        .generate(scenes::spec::CACHE_MIN_POINTS, 1)
        .unwrap()
        .without_normals();
    scenes::las::write(&las, &cloud).unwrap();
    let cache = d.join("cache");
    let spec = scenes::spec::SceneSpec::parse(las.to_str().unwrap(), None, 1).unwrap();
    let load = || spec.load(Some(&cache), &scenes::NoProgress).unwrap().cloud;
    let first = load();
    assert!(first.is_mapped());
    let cached = scenes::spec::las_cache_path(&cache, &las).unwrap();
    assert!(cached.exists());
    let stamp = std::fs::metadata(&cached).unwrap().modified().unwrap();
    let second = load();
    assert_eq!(
        std::fs::metadata(&cached).unwrap().modified().unwrap(),
        stamp
    );
    let mem = scenes::las::read(&las).unwrap();
    assert_eq!(second.positions(), mem.positions());
    assert_eq!(second.colors(), mem.colors());
    assert_eq!(second.origin(), mem.origin());
    // Without a cache directory the file is read in memory.
    assert!(
        !spec
            .load(None, &scenes::NoProgress)
            .unwrap()
            .cloud
            .is_mapped()
    );
    // An edited file gets another cache entry: here rewritten as most tools save (a new file
    // renamed over the old), with the same length and its modification time set back, so
    // only the file's identity (`scenes::os::FileStamp`: a new inode) tells them apart. (An
    // in-place rewrite moves the inode's change time: `os::tests`.)
    let mtime = std::fs::metadata(&las).unwrap().modified().unwrap();
    let edited = d.join("edited.las");
    scenes::las::write(&edited, &cloud).unwrap();
    std::fs::File::options()
        .write(true)
        .open(&edited)
        .unwrap()
        .set_modified(mtime)
        .unwrap();
    std::fs::rename(&edited, &las).unwrap();
    assert_eq!(std::fs::metadata(&las).unwrap().modified().unwrap(), mtime);
    assert_ne!(scenes::spec::las_cache_path(&cache, &las).unwrap(), cached);
    // A small file is not cached.
    let small = d.join("small.las");
    scenes::las::write(&small, &terrain(100, true)).unwrap();
    assert_eq!(scenes::spec::las_cache_path(&cache, &small), None);
}

/// A file whose first bytes are another known format's than its extension names (a LAS file
/// renamed `.ply`, a PLY file renamed `.las`) is refused naming what it is and the extension
/// to give it (issue 37, item 7), not with the expected reader's "not a PLY file".
#[test]
fn a_file_with_another_formats_extension_is_named_for_what_it_is() {
    let dir = tmp();
    let d = dir.path();
    let cloud = scenes::generators::Generator::Statue
        .generate(500, 1)
        .unwrap();
    let las = d.join("scan.las");
    scenes::las::write(&las, &cloud.clone().without_normals()).unwrap();
    let ply = d.join("scan.ply");
    scenes::ply::write(&ply, &cloud, scenes::ply::PlyFormat::BinaryLittleEndian).unwrap();
    let cases = [
        (
            &las,
            "renamed.ply",
            "this is a LAS file (it starts with \"LASF\"), not a PLY file as its extension says: give it the extension .las or .laz",
        ),
        (
            &ply,
            "renamed.las",
            "this is a PLY file (it starts with \"ply\"), not a LAS file as its extension says: give it the extension .ply",
        ),
        (
            &ply,
            "renamed.pcd",
            "this is a PLY file (it starts with \"ply\"), not a PCD file as its extension says",
        ),
    ];
    for (from, name, needle) in cases {
        let to = d.join(name);
        std::fs::copy(from, &to).unwrap();
        let spec = scenes::spec::SceneSpec::parse(to.to_str().unwrap(), None, 1).unwrap();
        let e = spec
            .load(None, &scenes::NoProgress)
            .unwrap_err()
            .to_string();
        assert!(e.contains(name) && e.contains(needle), "{name}: {e}");
    }
    // The right extensions still load.
    for f in [&las, &ply] {
        let spec = scenes::spec::SceneSpec::parse(f.to_str().unwrap(), None, 1).unwrap();
        assert_eq!(
            spec.load(None, &scenes::NoProgress).unwrap().cloud.len(),
            500
        );
    }
}
