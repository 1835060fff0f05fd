#![allow(clippy::unwrap_used)]
//! Column files: round trips for every attribute combination, the streaming writer's checks,
//! atomic replacement, and clear errors (never panics) for damaged files.

use std::path::Path;

use glam::DVec3;
use scenes::colfile::{self, ColumnWriter};
use scenes::{Attributes, PointCloud, SceneError};

fn cloud(n: usize, a: Attributes) -> PointCloud {
    let pos: Vec<[f32; 3]> = (0..n)
        .map(|i| [i as f32 * 0.5, -(i as f32), (i % 7) as f32])
        .collect();
    let nrm = a.normals.then(|| {
        (0..n)
            .map(|i| {
                if i % 2 == 0 {
                    [0.0, 0.0, 1.0]
                } else {
                    [0.6, 0.8, 0.0]
                }
            })
            .collect::<Vec<_>>()
            .into()
    });
    let col = a.colors.then(|| {
        (0..n)
            .map(|i| [i as u8, (i * 3) as u8, 255])
            .collect::<Vec<_>>()
            .into()
    });
    let rad = a.radii.then(|| {
        (0..n)
            .map(|i| 0.01 + i as f32 * 1e-3)
            .collect::<Vec<_>>()
            .into()
    });
    PointCloud::new(
        DVec3::new(500_000.25, 4_100_000.5, -12.0),
        pos.into(),
        nrm,
        col,
        rad,
    )
    .unwrap()
}

fn all_attributes() -> Vec<Attributes> {
    (0..8)
        .map(|b| Attributes {
            normals: b & 1 != 0,
            colors: b & 2 != 0,
            radii: b & 4 != 0,
        })
        .collect()
}

fn assert_same(a: &PointCloud, b: &PointCloud) {
    assert_eq!(a.len(), b.len());
    assert_eq!(a.origin(), b.origin());
    assert_eq!(a.attributes(), b.attributes());
    assert_eq!(a.bounds(), b.bounds());
    assert_eq!(a.positions(), b.positions());
    assert_eq!(a.normals(), b.normals());
    assert_eq!(a.colors(), b.colors());
    assert_eq!(a.radii(), b.radii());
}

fn format_error(e: SceneError) -> String {
    match &e {
        SceneError::Format { .. } => e.to_string(),
        other => panic!("expected a format error, got {other:?}"),
    }
}

#[test]
fn round_trip_every_attribute_combination() {
    let dir = tempfile::tempdir().unwrap();
    for a in all_attributes() {
        for n in [1usize, 5, 1000] {
            let c = cloud(n, a);
            let path = dir.path().join(format!("c-{a}-{n}.sbc"));
            let bytes = colfile::write(&path, &c).unwrap();
            assert_eq!(bytes, std::fs::metadata(&path).unwrap().len());
            assert!(!colfile::temp_path(&path).exists());
            let m = colfile::open(&path).unwrap();
            assert!(m.is_mapped(), "{a}");
            assert_same(&c, &m);
            // A mapped cloud writes back identically.
            let path2 = dir.path().join(format!("d-{a}-{n}.sbc"));
            colfile::write(&path2, &m).unwrap();
            assert_eq!(
                std::fs::read(&path).unwrap(),
                std::fs::read(&path2).unwrap()
            );
        }
    }
}

#[test]
fn regions_are_aligned_and_header_is_documented() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("a.sbc");
    let a = Attributes {
        normals: true,
        colors: true,
        radii: true,
    };
    colfile::write(&path, &cloud(3, a)).unwrap();
    let b = std::fs::read(&path).unwrap();
    assert_eq!(&b[..8], b"SPLATCOL");
    assert_eq!(u32::from_le_bytes(b[8..12].try_into().unwrap()), 1);
    assert_eq!(u32::from_le_bytes(b[12..16].try_into().unwrap()), 7);
    assert_eq!(u64::from_le_bytes(b[16..24].try_into().unwrap()), 3);
    let offsets: Vec<u64> = (0..4)
        .map(|i| u64::from_le_bytes(b[72 + 8 * i..80 + 8 * i].try_into().unwrap()))
        .collect();
    assert_eq!(offsets, vec![128, 192, 256, 320]);
    assert_eq!(b.len(), 320 + 12);
}

#[test]
fn streaming_writer_in_blocks() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("s.sbc");
    let a = Attributes {
        normals: true,
        colors: true,
        radii: false,
    };
    let c = cloud(10_000, a);
    let mut w = ColumnWriter::create(&path, a, c.origin(), 10_000).unwrap();
    assert!(colfile::temp_path(&path).exists() && !path.exists());
    let mut start = 0;
    for len in [1usize, 999, 4000, 5000] {
        let r = start..start + len;
        w.push(
            &c.positions()[r.clone()],
            Some(&c.normals().unwrap()[r.clone()]),
            Some(&c.colors().unwrap()[r]),
            None,
        )
        .unwrap();
        start += len;
    }
    assert_eq!(w.written(), 10_000);
    let m = w.finish().unwrap();
    assert!(m.is_mapped());
    assert_same(&c, &m);
    assert!(path.exists() && !colfile::temp_path(&path).exists());
}

#[test]
fn writer_rejects_wrong_counts_and_columns_and_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("w.sbc");
    let a = Attributes {
        normals: true,
        ..Attributes::default()
    };
    let p = [[0.0f32, 0.0, 0.0]; 4];
    let n = [[0.0f32, 0.0, 1.0]; 4];

    // Too few points at finish.
    let mut w = ColumnWriter::create(&path, a, DVec3::ZERO, 5).unwrap();
    w.push(&p, Some(&n), None, None).unwrap();
    let e = format_error(w.finish().unwrap_err());
    assert!(
        e.contains("4 points were written") && e.contains("for 5"),
        "{e}"
    );
    assert!(!path.exists() && !colfile::temp_path(&path).exists());

    // Too many points.
    let mut w = ColumnWriter::create(&path, a, DVec3::ZERO, 3).unwrap();
    let e = format_error(w.push(&p, Some(&n), None, None).unwrap_err());
    assert!(e.contains("exceed"), "{e}");
    drop(w);
    assert!(!path.exists() && !colfile::temp_path(&path).exists());

    // Missing, extra and short columns.
    let mut w = ColumnWriter::create(&path, a, DVec3::ZERO, 4).unwrap();
    let e = format_error(w.push(&p, None, None, None).unwrap_err());
    assert!(e.contains("normals"), "{e}");
    let e = format_error(
        w.push(&p, Some(&n), Some(&[[1, 2, 3]; 4]), None)
            .unwrap_err(),
    );
    assert!(e.contains("colors"), "{e}");
    let e = format_error(w.push(&p, Some(&n[..2]), None, None).unwrap_err());
    assert!(e.contains("2 normals for 4 positions"), "{e}");
    // An interrupted writer (dropped) leaves nothing behind.
    w.push(&p[..2], Some(&n[..2]), None, None).unwrap();
    drop(w);
    assert!(!path.exists() && !colfile::temp_path(&path).exists());

    // Invalid data is caught at finish (by PointCloud's validation), and nothing is left.
    let mut w = ColumnWriter::create(&path, a, DVec3::ZERO, 4).unwrap();
    w.push(&p, Some(&[[0.0, 0.0, 0.0]; 4]), None, None).unwrap();
    let e = format_error(w.finish().unwrap_err());
    assert!(e.contains("normal 0"), "{e}");
    assert!(!path.exists() && !colfile::temp_path(&path).exists());

    // Zero points and a non-finite origin are refused up front.
    assert!(ColumnWriter::create(&path, a, DVec3::ZERO, 0).is_err());
    assert!(ColumnWriter::create(&path, a, DVec3::NAN, 1).is_err());
}

#[test]
fn finishing_replaces_an_existing_file_atomically() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("r.sbc");
    let a = Attributes::default();
    colfile::write(&path, &cloud(10, a)).unwrap();
    let old = colfile::open(&path).unwrap();
    // An unfinished writer does not disturb the existing file.
    let mut w = ColumnWriter::create(&path, a, DVec3::ZERO, 2).unwrap();
    w.push(&[[1.0, 1.0, 1.0]], None, None, None).unwrap();
    drop(w);
    assert_same(&old, &colfile::open(&path).unwrap());
    // A finished one replaces it; the old mapping stays valid.
    colfile::write(&path, &cloud(20, a)).unwrap();
    assert_eq!(colfile::open(&path).unwrap().len(), 20);
    assert_same(&old, &cloud(10, a).clone());
}

fn write_sample(dir: &Path) -> (std::path::PathBuf, Vec<u8>) {
    let path = dir.join("t.sbc");
    let a = Attributes {
        normals: true,
        colors: true,
        radii: false,
    };
    colfile::write(&path, &cloud(100, a)).unwrap();
    let bytes = std::fs::read(&path).unwrap();
    (path, bytes)
}

#[test]
fn truncated_files_name_the_path_and_what_is_short() {
    let dir = tempfile::tempdir().unwrap();
    let (path, bytes) = write_sample(dir.path());
    let bad = dir.path().join("cut.sbc");
    // Cut inside the colours region (the last one).
    std::fs::write(&bad, &bytes[..bytes.len() - 10]).unwrap();
    let e = format_error(colfile::open(&bad).unwrap_err());
    assert!(
        e.contains("cut.sbc") && e.contains("truncated") && e.contains("colors"),
        "{e}"
    );
    // Cut inside the normals region.
    std::fs::write(&bad, &bytes[..1400]).unwrap();
    let e = format_error(colfile::open(&bad).unwrap_err());
    assert!(e.contains("cut.sbc") && e.contains("normals"), "{e}");
    // Shorter than the header, and empty.
    for len in [0, 7, 127] {
        std::fs::write(&bad, &bytes[..len]).unwrap();
        let e = format_error(colfile::open(&bad).unwrap_err());
        assert!(
            e.contains("cut.sbc") && e.contains("shorter than the 128-byte"),
            "{e}"
        );
    }
    // Trailing garbage is reported too.
    let mut long = bytes.clone();
    long.extend_from_slice(&[0; 5]);
    std::fs::write(&bad, &long).unwrap();
    let e = format_error(colfile::open(&bad).unwrap_err());
    assert!(e.contains("header says"), "{e}");
    // The intact file still opens.
    assert_eq!(colfile::open(&path).unwrap().len(), 100);
}

#[test]
fn damaged_headers_and_data_are_errors() {
    let dir = tempfile::tempdir().unwrap();
    let (_, bytes) = write_sample(dir.path());
    let bad = dir.path().join("bad.sbc");
    let check = |b: &[u8], want: &str| {
        std::fs::write(&bad, b).unwrap();
        let e = format_error(colfile::open(&bad).unwrap_err());
        assert!(
            e.contains("bad.sbc") && e.contains(want),
            "wanted '{want}' in: {e}"
        );
    };
    let mut b = bytes.clone();
    b[..8].copy_from_slice(b"PLYFILE!");
    check(&b, "not a splatbench column file");
    let mut b = bytes.clone();
    b[8] = 9;
    check(&b, "version 9");
    let mut b = bytes.clone();
    b[17] ^= 0x40; // the count
    check(&b, "checksum");
    // A position changed in the data: the bounds no longer match the header.
    let mut b = bytes.clone();
    b[128..132].copy_from_slice(&(-1000.0f32).to_le_bytes());
    check(&b, "bounds");
    // A NaN position in the data.
    let mut b = bytes.clone();
    b[140..144].copy_from_slice(&f32::NAN.to_le_bytes());
    check(&b, "position 1");
    // Not a file at all.
    let e = colfile::open(&dir.path().join("missing.sbc")).unwrap_err();
    assert!(
        matches!(e, SceneError::Io { .. }) && e.to_string().contains("missing.sbc"),
        "{e}"
    );
}

/// A file the disk cannot hold is refused before anything is written (issue 13: a
/// `statue:100000000000` scene used to fill the disk at write speed): the error names the
/// file, the bytes needed and the room left, and no `.tmp` is left behind. 10¹³ points are
/// 120 TB of positions, more than any test machine has.
#[cfg(unix)]
#[test]
fn a_file_larger_than_the_free_space_is_refused_before_writing() {
    let tmp = tempfile::tempdir().unwrap();
    let path = tmp.path().join("huge.sbc");
    let err = ColumnWriter::create(
        &path,
        Attributes::default(),
        DVec3::ZERO,
        10_000_000_000_000,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("huge.sbc") && err.contains("needs 120000000000") && err.contains("free"),
        "{err}"
    );
    assert!(!colfile::temp_path(&path).exists(), "no temporary file");
}
