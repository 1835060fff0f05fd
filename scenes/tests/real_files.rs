//! The readers on real third-party files (`tests/data/real/`, sources and licences in its
//! README): what other libraries wrote must read, and what they wrote wrong must fail with
//! the file named.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use scenes::SceneSpec;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/real")
        .join(name)
}

fn load(name: &str) -> scenes::Loaded {
    SceneSpec::parse(data(name).to_str().unwrap(), None, 1)
        .unwrap()
        .load(None, &scenes::NoProgress)
        .unwrap_or_else(|e| panic!("{name}: {e}"))
}

#[test]
fn pypcd4_three_encodings_are_the_same_213_points() {
    let clouds: Vec<_> = ["ascii.pcd", "binary.pcd", "binary_compressed.pcd"]
        .map(load)
        .into_iter()
        .map(|l| {
            assert!(l.warnings.is_empty(), "{:?}", l.warnings);
            l.cloud
        })
        .collect();
    for c in &clouds {
        assert_eq!(c.len(), 213);
        assert!(c.attributes().colors && !c.attributes().normals);
    }
    // The ascii file prints each float with enough digits to round-trip: all three agree
    // exactly, positions and packed colours.
    for c in &clouds[1..] {
        for i in 0..213 {
            assert_eq!(
                c.world_position(i),
                clouds[0].world_position(i),
                "point {i}"
            );
        }
        assert_eq!(c.colors(), clouds[0].colors());
    }
}

#[test]
fn pypcd4_organised_grids_read_the_same_in_ascii_and_compressed() {
    // The eight corners of the unit cube, row by row (x, then y, then z bits of the index).
    let a = load("ascii_organized.pcd");
    let b = load("binary_compressed_organized.pcd");
    for l in [&a, &b] {
        assert_eq!(l.cloud.len(), 8);
        for i in 0..8 {
            let want = glam::DVec3::new((i >> 2) as f64, ((i >> 1) & 1) as f64, (i & 1) as f64);
            assert_eq!(l.cloud.world_position(i), want, "point {i}");
        }
    }
}

#[test]
fn e57_spherical_scan_with_colour() {
    let l = load("pipeSpherical.e57");
    assert_eq!(l.cloud.len(), 1220);
    assert!(l.cloud.attributes().colors, "{:?}", l.warnings);
    assert!(l.warnings.is_empty(), "{:?}", l.warnings);
}

#[test]
fn laspy_plane_has_all_zero_rgb_and_loses_it_with_a_warning() {
    let l = load("plane.laz");
    assert_eq!(l.cloud.len(), 28_185);
    assert!(l.cloud.colors().is_none());
    assert_eq!(l.warnings.len(), 1, "{:?}", l.warnings);
    assert!(l.warnings[0].contains("plane.laz") && l.warnings[0].contains("(0, 0, 0)"));
}

#[test]
fn broken_files_name_the_file_and_the_cause() {
    for (name, needle) in [
        ("ascii_invalid_header.pcd", "header line 3 (FIEL)"),
        ("justxml.e57", "not a readable E57 file"),
    ] {
        let e = SceneSpec::parse(data(name).to_str().unwrap(), None, 1)
            .unwrap()
            .load(None, &scenes::NoProgress)
            .map(|l| l.cloud.len())
            .unwrap_err()
            .to_string();
        assert!(e.contains(name) && e.contains(needle), "{name}: {e}");
    }
}
