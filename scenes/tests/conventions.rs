//! Scanner conventions at load: constant attribute columns dropped with a warning (kept on
//! request), and the file's up axis turned to +Z.
#![allow(clippy::unwrap_used)]

use glam::DVec3;
use scenes::{PointCloud, SceneSpec};

/// A LAS tile as many scanners write it: point format with RGB, every channel 0.
fn black_las(dir: &std::path::Path) -> std::path::PathBuf {
    let n = 500;
    let p: Vec<[f32; 3]> = (0..n)
        .map(|i| [(i % 25) as f32, (i / 25) as f32, 0.1 * (i % 7) as f32])
        .collect();
    let cloud = PointCloud::new(
        DVec3::new(500_000.0, 4_100_000.0, 0.0),
        p.into(),
        None,
        Some(vec![[0, 0, 0]; n].into()),
        None,
    )
    .unwrap();
    let path = dir.join("tile.las");
    scenes::las::write(&path, &cloud).unwrap();
    path
}

#[test]
fn all_zero_las_colour_is_dropped_with_a_warning_and_kept_on_request() {
    let dir = tempfile::tempdir().unwrap();
    let path = black_las(dir.path());
    let text = path.to_str().unwrap();
    // The reader itself keeps what the file holds.
    assert!(scenes::las::read(&path).unwrap().colors().is_some());
    let spec = SceneSpec::parse(text, None, 1).unwrap();
    let loaded = spec.load(None, &scenes::NoProgress).unwrap();
    assert!(loaded.cloud.colors().is_none());
    assert_eq!(loaded.cloud.len(), 500);
    assert_eq!(loaded.warnings.len(), 1, "{:?}", loaded.warnings);
    let w = &loaded.warnings[0];
    assert!(
        w.contains("tile.las") && w.contains("colour dropped") && w.contains("(0, 0, 0)"),
        "{w}"
    );
    let keep = spec.clone().with_keep_attributes(true);
    let kept = keep.load(None, &scenes::NoProgress).unwrap();
    assert!(kept.cloud.colors().is_some() && kept.warnings.is_empty());
    // The two are different scenes: cached builds and references must not be shared.
    assert_ne!(spec.content_hash().unwrap(), keep.content_hash().unwrap());
    // A scene file says the same with `keep_attributes = true`.
    let toml = dir.path().join("tile.toml");
    std::fs::write(&toml, "file = \"tile.las\"\nkeep_attributes = true\n").unwrap();
    let s = SceneSpec::parse(toml.to_str().unwrap(), None, 1).unwrap();
    assert!(s.keep_attributes);
    assert!(
        s.load(None, &scenes::NoProgress)
            .unwrap()
            .cloud
            .colors()
            .is_some()
    );
}

#[test]
fn generated_scenes_are_never_screened() {
    // A generator fills every column it declares; screening them would only cost a pass.
    let s = SceneSpec::parse("statue:2000:3", None, 1).unwrap();
    let l = s.load(None, &scenes::NoProgress).unwrap();
    assert!(l.warnings.is_empty());
    assert_eq!(
        l.cloud.attributes(),
        scenes::generators::Generator::Statue
            .generate(2000, 3)
            .unwrap()
            .attributes()
    );
}

#[test]
fn a_y_up_ply_stands_on_z_after_up_y() {
    // A tall thin object along +Y, as Stanford's scans are stored, with normals.
    let n = 64;
    let p: Vec<[f32; 3]> = (0..n)
        .map(|i| [0.25 * (i % 4) as f32, 2.0 * i as f32, -0.5 * (i % 3) as f32])
        .collect();
    let normals: Vec<[f32; 3]> = (0..n)
        .map(|i| [[0.0, 1.0, 0.0], [1.0, 0.0, 0.0]][i % 2])
        .collect();
    let cloud = PointCloud::new(
        DVec3::new(1.0, 2.0, 3.0),
        p.clone().into(),
        Some(normals.clone().into()),
        None,
        None,
    )
    .unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bunny.ply");
    scenes::ply::write(&path, &cloud, scenes::ply::PlyFormat::BinaryLittleEndian).unwrap();
    let plain = SceneSpec::parse(path.to_str().unwrap(), None, 1).unwrap();
    let y_up = plain.clone().with_up(Some(scenes::Up::Y));
    assert_ne!(plain.content_hash().unwrap(), y_up.content_hash().unwrap());
    let turned = y_up.load(None, &scenes::NoProgress).unwrap().cloud;
    let orig = plain.load(None, &scenes::NoProgress).unwrap().cloud;
    // The long axis is z now, and every point and normal is the exact rotation (x, −z, y).
    let (so, st) = (orig.bounds().size(), turned.bounds().size());
    assert_eq!((st.x, st.y, st.z), (so.x, so.z, so.y));
    for i in 0..n {
        let (w, t) = (orig.world_position(i), turned.world_position(i));
        assert_eq!(t, DVec3::new(w.x, -w.z, w.y), "point {i}");
        let (a, b) = (orig.normals().unwrap()[i], turned.normals().unwrap()[i]);
        assert_eq!(b, [a[0], -a[2], a[1]], "normal {i}");
    }
    // The same through a scene file, and a bad axis names the key.
    let toml = dir.path().join("bunny.toml");
    std::fs::write(&toml, "file = \"bunny.ply\"\nup = \"y\"\n").unwrap();
    let s = SceneSpec::parse(toml.to_str().unwrap(), None, 1).unwrap();
    assert_eq!(s.up, scenes::Up::Y);
    std::fs::write(&toml, "file = \"bunny.ply\"\nup = \"w\"\n").unwrap();
    let e = SceneSpec::parse(toml.to_str().unwrap(), None, 1)
        .unwrap_err()
        .to_string();
    assert!(e.contains("bunny.toml") && e.contains("up: 'w'"), "{e}");
}

#[test]
fn far_strays_do_not_cost_the_inliers_their_precision() {
    // A 1 km UTM tile on a 1 cm grid, and two strays at the world origin (as a buggy writer
    // leaves them). The origin must stay at the tile: half way to the strays (3,130 km out)
    // f32 keeps only 0.25 m.
    let tile = DVec3::new(699_000.0, 6_259_621.0, 0.0);
    let p: Vec<[f32; 3]> = (0..10_000)
        .map(|i| {
            let (x, y) = (
                (i % 100) as f32 * 10.0 - 500.0,
                (i / 100) as f32 * 7.5 - 375.0,
            );
            [
                x + 0.01 * (i % 7) as f32,
                y + 0.01 * (i % 5) as f32,
                0.01 * (i % 11) as f32,
            ]
        })
        .collect();
    let mut want: Vec<DVec3> = p
        .iter()
        .map(|v| tile + glam::Vec3::from(*v).as_dvec3())
        .collect();
    want.extend([DVec3::ZERO; 2]);
    // Written with the las crate at a 1 cm scale (our writer picks its scale from the span).
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("strays.las");
    let mut b = las::Builder::from((1, 2));
    let t = |offset: f64| las::Transform {
        scale: 0.01,
        offset,
    };
    b.transforms = las::Vector {
        x: t(tile.x),
        y: t(tile.y),
        z: t(tile.z),
    };
    let mut w = las::Writer::from_path(&path, b.into_header().unwrap()).unwrap();
    for v in &want {
        w.write_point(las::Point {
            x: v.x,
            y: v.y,
            z: v.z,
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
    let read = scenes::las::read(&path).unwrap();
    assert_eq!(read.len(), 10_002);
    // Every tile point within half the 1 cm scale, plus f32 at ≤ 1 km from the origin.
    let worst = want[..10_000]
        .iter()
        .enumerate()
        .map(|(i, w)| (read.world_position(i) - *w).abs().max_element())
        .fold(0.0, f64::max);
    assert!(worst <= 0.005 + 1e-4, "worst error {worst} m");
    // The origin is the centre of the inliers' quantile box: inside the tile.
    let o = read.origin() - tile;
    assert!(
        o.x.abs() < 500.0 && o.y.abs() < 375.0,
        "origin {}",
        read.origin()
    );
}

#[test]
fn far_strays_do_not_cost_a_ply_s_inliers_their_precision() {
    // The PLY reader picks its origin like the others: at the inliers when strays lie far out.
    let tile = DVec3::new(699_000.0, 6_259_621.0, 0.0);
    let mut p: Vec<[f32; 3]> = (0..5_000)
        .map(|i| {
            [
                (i % 50) as f32 * 20.0 - 500.0,
                (i / 50) as f32 * 7.5 - 375.0,
                0.0,
            ]
        })
        .collect();
    let n = p.len();
    p.extend([(-tile).as_vec3().to_array(); 2]);
    let cloud = PointCloud::new(tile, p.into(), None, None, None).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("strays.ply");
    scenes::ply::write(&path, &cloud, scenes::ply::PlyFormat::BinaryLittleEndian).unwrap();
    let read = scenes::ply::read(&path, &Default::default()).unwrap();
    // The writer stores f64 world positions: only the reader's f32 offsets can lose anything,
    // ≤ half an ulp at 1 km from the origin (3e-5 m), where half way to the strays it is 0.125 m.
    let worst = (0..n)
        .map(|i| {
            (read.world_position(i) - cloud.world_position(i))
                .abs()
                .max_element()
        })
        .fold(0.0, f64::max);
    assert!(worst < 1e-4, "worst error {worst} m");
}
