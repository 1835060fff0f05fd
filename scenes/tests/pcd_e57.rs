//! PCD and E57 readers on files the tests write: exact point sets, organised clouds with
//! NaN holes, posed multi-scan E57, and bad files that must fail with the file and field named
//! (never a panic).
#![allow(clippy::unwrap_used)]

use std::path::Path;

use glam::DVec3;
use scenes::{SceneSpec, pcd};

// ---------------------------------------------------------------------------------------------
// PCD
// ---------------------------------------------------------------------------------------------

/// One PCD point: position, packed colour, normal, intensity.
#[derive(Clone, Copy)]
struct P {
    xyz: [f32; 3],
    rgb: [u8; 3],
    n: [f32; 3],
    intensity: f32,
}

/// An organised 4 × 3 grid (a depth camera's layout) whose points 3 and 7 are missing (NaN).
fn grid() -> Vec<P> {
    (0..12)
        .map(|i| {
            let (c, r) = ((i % 4) as f32, (i / 4) as f32);
            let xyz = if i == 3 || i == 7 {
                [f32::NAN; 3]
            } else {
                [0.25 * c - 1.0, 0.5 * r + 2.0, 0.125 * i as f32]
            };
            P {
                xyz,
                rgb: [(10 * i) as u8, 255 - i as u8, (i * i) as u8],
                n: [[1.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.0, 0.0, 1.0]][i % 3],
                intensity: i as f32 * 3.5,
            }
        })
        .collect()
}

fn packed(c: [u8; 3]) -> u32 {
    (u32::from(c[0]) << 16) | (u32::from(c[1]) << 8) | u32::from(c[2])
}

/// The header of a cloud of `points` (4 × 3 for `grid()`, else one row): positions, packed
/// float colour, normals, intensity and a padding field of two `u16` (skipped, but its bytes
/// must be stepped over).
fn header(points: usize, data: &str) -> String {
    let (w, h) = if points == 12 { (4, 3) } else { (points, 1) };
    format!(
        "# .PCD v0.7 - Point Cloud Data file format\nVERSION 0.7\n\
         FIELDS x y z rgb normal_x normal_y normal_z intensity _\n\
         SIZE 4 4 4 4 4 4 4 4 2\nTYPE F F F F F F F F U\nCOUNT 1 1 1 1 1 1 1 1 2\n\
         WIDTH {w}\nHEIGHT {h}\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS {points}\nDATA {data}\n"
    )
}

/// Bytes of one record of [`header`]'s fields.
const RECORD: usize = 8 * 4 + 2 * 2;

/// The fields of one point as little-endian bytes, in header order.
fn field_bytes(p: &P) -> Vec<Vec<u8>> {
    let f = |v: f32| v.to_le_bytes().to_vec();
    vec![
        f(p.xyz[0]),
        f(p.xyz[1]),
        f(p.xyz[2]),
        f(f32::from_bits(packed(p.rgb))),
        f(p.n[0]),
        f(p.n[1]),
        f(p.n[2]),
        f(p.intensity),
        [7u16.to_le_bytes(), 9u16.to_le_bytes()].concat(),
    ]
}

fn write_ascii(points: &[P]) -> Vec<u8> {
    let mut s = header(points.len(), "ascii");
    for p in points {
        let c = f32::from_bits(packed(p.rgb));
        // PCL prints NaN as "nan"; the packed colour as the float whose bits it is.
        s += &format!(
            "{} {} {} {c:e} {} {} {} {} 7 9\n",
            p.xyz[0], p.xyz[1], p.xyz[2], p.n[0], p.n[1], p.n[2], p.intensity
        )
        .replace("NaN", "nan");
    }
    s.into_bytes()
}

fn write_binary(points: &[P]) -> Vec<u8> {
    let mut b = header(points.len(), "binary").into_bytes();
    for p in points {
        b.extend(field_bytes(p).concat());
    }
    b
}

fn write_compressed(points: &[P]) -> Vec<u8> {
    // Column-major: every point's first field, then every point's second field, …
    let per_point: Vec<Vec<Vec<u8>>> = points.iter().map(field_bytes).collect();
    let mut raw = Vec::new();
    for f in 0..per_point[0].len() {
        for p in &per_point {
            raw.extend(&p[f]);
        }
    }
    let packed = lzf_compress(&raw);
    let mut b = header(points.len(), "binary_compressed").into_bytes();
    b.extend((packed.len() as u32).to_le_bytes());
    b.extend((raw.len() as u32).to_le_bytes());
    b.extend(packed);
    b
}

/// A greedy LZF compressor (liblzf's stream format: literal runs of ≤ 32 bytes, back-references
/// of 3–264 bytes up to 8 KiB back), enough to write `binary_compressed` files as PCL does.
fn lzf_compress(input: &[u8]) -> Vec<u8> {
    fn flush(out: &mut Vec<u8>, lit: &mut Vec<u8>) {
        for run in lit.chunks(32) {
            out.push((run.len() - 1) as u8);
            out.extend_from_slice(run);
        }
        lit.clear();
    }
    let mut out = Vec::new();
    let mut lit = Vec::new();
    let mut last = std::collections::HashMap::new();
    let mut i = 0;
    while i < input.len() {
        if i + 3 <= input.len() {
            let key = [input[i], input[i + 1], input[i + 2]];
            if let Some(&j) = last.get(&key)
                && i - j <= 8192
            {
                let mut len = 0;
                while i + len < input.len() && len < 264 && input[j + len] == input[i + len] {
                    len += 1;
                }
                flush(&mut out, &mut lit);
                let (l, off) = (len - 2, i - j - 1);
                if l < 7 {
                    out.push(((l << 5) | (off >> 8)) as u8);
                } else {
                    out.push(((7usize << 5) | (off >> 8)) as u8);
                    out.push((l - 7) as u8);
                }
                out.push(off as u8);
                for k in i..i + len {
                    if k + 3 <= input.len() {
                        last.insert([input[k], input[k + 1], input[k + 2]], k);
                    }
                }
                i += len;
                continue;
            }
            last.insert(key, i);
        }
        lit.push(input[i]);
        i += 1;
    }
    flush(&mut out, &mut lit);
    out
}

fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

/// The kept points of `grid()` as world positions, colours and normals.
fn expected(points: &[P]) -> Vec<(DVec3, [u8; 3], [f32; 3])> {
    points
        .iter()
        .filter(|p| p.xyz[0].is_finite())
        .map(|p| (DVec3::from(p.xyz.map(f64::from)), p.rgb, p.n))
        .collect()
}

fn got(c: &scenes::PointCloud) -> Vec<(DVec3, [u8; 3], [f32; 3])> {
    (0..c.len())
        .map(|i| {
            (
                c.world_position(i),
                c.colors().unwrap()[i],
                c.normals().unwrap()[i],
            )
        })
        .collect()
}

#[test]
fn pcd_organised_grid_is_exact_in_all_three_encodings() {
    let dir = tempfile::tempdir().unwrap();
    let points = grid();
    let want = expected(&points);
    assert_eq!(want.len(), 10);
    for (name, bytes) in [
        ("a.pcd", write_ascii(&points)),
        ("b.pcd", write_binary(&points)),
        ("c.pcd", write_compressed(&points)),
    ] {
        let path = write(dir.path(), name, &bytes);
        let r = pcd::read(&path).unwrap();
        assert_eq!(r.dropped, 2, "{name}: the two NaN points of the grid");
        assert!(r.warnings.is_empty(), "{name}: {:?}", r.warnings);
        assert_eq!(got(&r.cloud), want, "{name}");
        let a = r.cloud.attributes();
        assert!(a.colors && a.normals && !a.radii, "{name}: {a}");
    }
}

#[test]
fn pcd_compressed_uses_back_references_and_survives_every_mutation() {
    // A larger, repetitive cloud so the LZF stream holds long back-references.
    let points: Vec<P> = (0..600)
        .map(|i| P {
            xyz: [(i % 10) as f32, (i / 10 % 6) as f32, 1.0],
            rgb: [200, 100, 50],
            n: [0.0, 0.0, 1.0],
            intensity: 1.0,
        })
        .collect();
    let bytes = write_compressed(&points);
    let raw_len = points.len() * RECORD;
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "rep.pcd", &bytes);
    assert!(
        bytes.len() < raw_len / 4,
        "{} B compressed vs {raw_len} B raw",
        bytes.len()
    );
    let r = pcd::read(&path).unwrap();
    assert_eq!(r.cloud.len(), 600);
    assert_eq!(r.cloud.world_position(599), DVec3::new(9.0, 5.0, 1.0));
    // Every single-byte flip of the payload and every truncation: an Ok (a flip that still
    // decodes to valid numbers) or an error naming the file, never a panic.
    let body = header(points.len(), "binary_compressed").len();
    let mutant = dir.path().join("m.pcd");
    for at in body..bytes.len() {
        let mut b = bytes.clone();
        b[at] ^= 0xA5;
        std::fs::write(&mutant, &b).unwrap();
        if let Err(e) = pcd::read(&mutant) {
            assert!(e.to_string().contains("m.pcd"), "{e}");
        }
        std::fs::write(&mutant, &bytes[..at]).unwrap();
        let e = pcd::read(&mutant).unwrap_err().to_string();
        assert!(e.contains("m.pcd"), "cut at {at}: {e}");
    }
}

#[test]
fn pcd_double_coordinates_and_rgba_integers_keep_their_values() {
    // UTM-like doubles keep millimetres (f32 alone would keep 6 cm at 500 km), and PCL's
    // `rgba` as an unsigned 32-bit integer carries alpha in the top byte, ignored.
    let mut s = "FIELDS x y z rgba\nSIZE 8 8 8 4\nTYPE F F F U\nWIDTH 2\nPOINTS 2\nDATA binary\n"
        .as_bytes()
        .to_vec();
    for (p, c) in [
        ([500_000.001f64, 4_100_000.002, 12.5], 0xFF_10_20_30u32),
        ([500_010.0, 4_100_020.0, 13.0], 0x80_FF_00_7F),
    ] {
        for v in p {
            s.extend(v.to_le_bytes());
        }
        s.extend(c.to_le_bytes());
    }
    let dir = tempfile::tempdir().unwrap();
    let r = pcd::read(&write(dir.path(), "utm.pcd", &s)).unwrap();
    let w = r.cloud.world_position(0);
    assert!(
        (w - DVec3::new(500_000.001, 4_100_000.002, 12.5))
            .abs()
            .max_element()
            < 1e-3
    );
    assert_eq!(
        r.cloud.colors().unwrap(),
        &[[0x10, 0x20, 0x30], [0xFF, 0x00, 0x7F]]
    );
    assert!(r.cloud.normals().is_none());
}

#[test]
fn pcd_invalid_normals_drop_the_column_with_a_warning() {
    let mut points = grid();
    points[5].n = [f32::NAN; 3];
    points[6].n = [0.0; 3];
    let dir = tempfile::tempdir().unwrap();
    let path = write(dir.path(), "n.pcd", &write_binary(&points));
    let r = pcd::read(&path).unwrap();
    assert_eq!(r.cloud.len(), 10);
    assert!(r.cloud.normals().is_none());
    assert_eq!(r.warnings.len(), 1);
    let w = &r.warnings[0];
    assert!(
        w.contains("n.pcd") && w.contains("normals") && w.contains("2 of 10"),
        "{w}"
    );
    // Through the scene spec, the warnings travel with the cloud.
    let spec = SceneSpec::parse(path.to_str().unwrap(), None, 1).unwrap();
    let loaded = spec.load(None, &scenes::NoProgress).unwrap();
    assert_eq!(loaded.cloud.len(), 10);
    assert_eq!(loaded.warnings.len(), 2, "{:?}", loaded.warnings);
    assert!(
        loaded.warnings[1].contains("points dropped: 2 of 12"),
        "{:?}",
        loaded.warnings
    );
}

#[test]
fn pcd_bad_files_name_the_file_and_the_field() {
    let dir = tempfile::tempdir().unwrap();
    let good = "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nPOINTS 2\nDATA ascii\n";
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "keyword",
            good.replace("WIDTH", "WIDHT"),
            "header line 4 (WIDHT)",
        ),
        (
            "type",
            good.replace("SIZE 4 4 4", "SIZE 2 4 4"),
            "field 'x'",
        ),
        (
            "letter",
            good.replace("TYPE F F F", "TYPE F Q F"),
            "type 'Q'",
        ),
        (
            "sizes",
            good.replace("SIZE 4 4 4", "SIZE 4 4"),
            "SIZE has 2 entries",
        ),
        ("nodata", good.replace("DATA ascii\n", ""), "no DATA line"),
        (
            "points",
            good.replace("POINTS 2", "POINTS 3"),
            "POINTS 3 is not WIDTH 2",
        ),
        ("encoding", good.replace("ascii", "zip"), "'zip'"),
        ("noxyz", good.replace("x y z", "a b c"), "'x y z'"),
        ("partial", good.replace("x y z", "x y q"), "fields x y z"),
        (
            "short",
            format!("{good}1 2 3\n"),
            "stops at point 1 of the 2",
        ),
        ("count", format!("{good}1 2 3\n4 5\n"), "point 1: 2 values"),
        (
            "word",
            format!("{good}1 2 3\n4 five 6\n"),
            "point 1: 'five'",
        ),
        (
            "extra",
            format!("{good}1 2 3\n4 5 6\n7 8 9\n"),
            "more data lines",
        ),
        (
            "allnan",
            format!("{good}nan nan nan\nnan 1 2\n"),
            "all 2 points",
        ),
        (
            "binary",
            good.replace("ascii", "binary") + "\0\0\0\0\0\0\0\0\0\0\0\0\0\0",
            "stops at point 1",
        ),
        (
            "lzfsize",
            good.replace("ascii", "binary_compressed") + "\x05\0\0\0\x10\0\0\0abcde",
            "uncompressed size 16 B, but 2 points × 12 B = 24 B",
        ),
    ];
    for (name, text, needle) in cases {
        let path = write(dir.path(), &format!("{name}.pcd"), text.as_bytes());
        let e = pcd::read(&path)
            .map(|r| r.cloud.len())
            .expect_err(name)
            .to_string();
        assert!(
            e.contains(&format!("{name}.pcd")) && e.contains(needle),
            "{name}: {e}"
        );
    }
}

#[test]
fn lzf_rejects_streams_that_lie_about_their_size() {
    assert_eq!(
        pcd::lzf_decompress(&[2, b'a', b'b', b'c'], 3).unwrap(),
        b"abc"
    );
    // A back-reference of 3 bytes 1 back after "a": "aaaa".
    assert_eq!(
        pcd::lzf_decompress(&[0, b'a', 0x20, 0], 4).unwrap(),
        b"aaaa"
    );
    for (stream, size, needle) in [
        (&[2u8, b'a'][..], 3, "passes the end"),
        (&[0x20, 0], 3, "reaches 1 B back"),
        (&[2, b'a', b'b', b'c'], 2, "more than the declared 2 B"),
        (&[2, b'a', b'b', b'c'], 5, "decodes to 3 B"),
        (&[0, b'a', 0xE0], 9, "ends inside a code"),
    ] {
        let e = pcd::lzf_decompress(stream, size).unwrap_err();
        assert!(e.contains(needle), "{stream:?}: {e}");
    }
}

// ---------------------------------------------------------------------------------------------
// E57
// ---------------------------------------------------------------------------------------------

use e57::{E57Writer, Quaternion, Record, RecordValue, Transform, Translation};

/// Two scans: a cartesian one turned 180° about z and moved by (10, 0, 0), with one point
/// marked invalid; and a spherical one at the origin. Both coloured.
fn write_e57(path: &Path, second_has_colour: bool) {
    let mut w = E57Writer::from_file(path, "file-guid").unwrap();
    let proto = vec![
        Record::CARTESIAN_X_F64,
        Record::CARTESIAN_Y_F64,
        Record::CARTESIAN_Z_F64,
        Record::CARTESIAN_INVALID_STATE,
        Record::COLOR_RED_U8,
        Record::COLOR_GREEN_U8,
        Record::COLOR_BLUE_U8,
    ];
    let mut pc = w.add_pointcloud("scan-a", proto).unwrap();
    pc.set_name(Some("north".into()));
    pc.set_transform(Some(Transform {
        rotation: Quaternion {
            w: 0.0,
            x: 0.0,
            y: 0.0,
            z: 1.0,
        },
        translation: Translation {
            x: 10.0,
            y: 0.0,
            z: 0.0,
        },
    }));
    for (i, p) in [[1.0, 2.0, 3.0], [0.5, -1.0, 0.25], [9.0, 9.0, 9.0]]
        .iter()
        .enumerate()
    {
        let invalid = if i == 2 { 2 } else { 0 };
        let mut v: Vec<RecordValue> = p.iter().map(|c| RecordValue::Double(*c)).collect();
        v.push(RecordValue::Integer(invalid));
        v.extend([10, 20, 30].map(|c| RecordValue::Integer(c + i as i64)));
        pc.add_point(v).unwrap();
    }
    pc.finalize().unwrap();
    let mut proto = vec![
        Record::SPHERICAL_RANGE_F64,
        Record::SPHERICAL_AZIMUTH_F64,
        Record::SPHERICAL_ELEVATION_F64,
    ];
    if second_has_colour {
        proto.extend([
            Record::COLOR_RED_U8,
            Record::COLOR_GREEN_U8,
            Record::COLOR_BLUE_U8,
        ]);
    }
    let mut pc = w.add_pointcloud("scan-b", proto).unwrap();
    for (r, az, el) in [
        (4.0, 0.0, 0.0),
        (2.0, std::f64::consts::FRAC_PI_2, 0.0),
        (3.0, 0.0, std::f64::consts::FRAC_PI_2),
    ] {
        let mut v = vec![
            RecordValue::Double(r),
            RecordValue::Double(az),
            RecordValue::Double(el),
        ];
        if second_has_colour {
            v.extend([255, 0, 128].map(RecordValue::Integer));
        }
        pc.add_point(v).unwrap();
    }
    pc.finalize().unwrap();
    w.finalize().unwrap();
}

#[test]
fn e57_two_posed_scans_one_spherical_are_read_in_the_file_frame() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("site.e57");
    write_e57(&path, true);
    let r = scenes::e57::read(&path).unwrap();
    assert_eq!((r.scans, r.dropped), (2, 1));
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
    // Scan a: (x, y, z) ↦ (10 − x, −y, z); scan b: r (cos el cos az, cos el sin az, sin el).
    let want = [
        ([9.0, -2.0, 3.0], [10, 20, 30]),
        ([9.5, 1.0, 0.25], [11, 21, 31]),
        ([4.0, 0.0, 0.0], [255, 0, 128]),
        ([0.0, 2.0, 0.0], [255, 0, 128]),
        ([0.0, 0.0, 3.0], [255, 0, 128]),
    ];
    assert_eq!(r.cloud.len(), want.len());
    for (i, (p, c)) in want.iter().enumerate() {
        let d = (r.cloud.world_position(i) - DVec3::from(*p))
            .abs()
            .max_element();
        // Exact up to the f32 offsets from the centre (≤ 10 m · 2⁻²⁴ ≈ 0.6 µm) and the
        // spherical conversion's cos(π/2) ≈ 6e-17.
        assert!(
            d < 1e-6,
            "point {i}: {} vs {p:?}",
            r.cloud.world_position(i)
        );
        assert_eq!(r.cloud.colors().unwrap()[i], *c, "point {i}");
    }
    assert!(r.cloud.normals().is_none());
}

#[test]
fn e57_scan_without_colour_drops_the_colour_column_with_a_warning() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("mixed.e57");
    write_e57(&path, false);
    let r = scenes::e57::read(&path).unwrap();
    assert_eq!(r.cloud.len(), 5);
    assert!(r.cloud.colors().is_none());
    assert_eq!(r.warnings.len(), 1);
    assert!(
        r.warnings[0].contains("mixed.e57") && r.warnings[0].contains("scan 1"),
        "{:?}",
        r.warnings
    );
}

#[test]
fn e57_bad_files_name_the_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("site.e57");
    write_e57(&path, true);
    let bytes = std::fs::read(&path).unwrap();
    let cases = [
        (
            "garbage.e57",
            b"not an e57 file at all, just text".repeat(40),
        ),
        ("cut.e57", bytes[..bytes.len() / 2].to_vec()),
        ("empty.e57", Vec::new()),
    ];
    for (name, b) in cases {
        let p = write(dir.path(), name, &b);
        let e = scenes::e57::read(&p).unwrap_err().to_string();
        assert!(e.contains(name), "{name}: {e}");
    }
    // Flipped bytes through the whole file: an error naming it or a cloud, never a panic.
    let m = dir.path().join("flip.e57");
    for at in (0..bytes.len()).step_by(13) {
        let mut b = bytes.clone();
        b[at] ^= 0x5A;
        std::fs::write(&m, &b).unwrap();
        if let Err(e) = scenes::e57::read(&m) {
            assert!(e.to_string().contains("flip.e57"), "byte {at}: {e}");
        }
    }
}

#[test]
fn unsupported_extensions_are_named_with_the_supported_list() {
    for (spec, needle) in [
        ("scan.xyz", "'.xyz' files are not read"),
        ("dir/a.b/scan.PTS", "'.PTS'"),
    ] {
        let e = SceneSpec::parse(spec, None, 1).unwrap_err().to_string();
        assert!(e.contains(needle) && e.contains(".e57 .pcd"), "{spec}: {e}");
    }
    // Generators are not files, and still get the generator message.
    let e = SceneSpec::parse("statue", None, 1).unwrap_err().to_string();
    assert!(e.contains("missing point count"), "{e}");
    // A directory (issue 37: `laspy-2.7.0` was "'.0' files are not read") says so, with or
    // without a dot in its name.
    let dir = tempfile::tempdir().unwrap();
    for name in ["laspy-2.7.0", "scans"] {
        let d = dir.path().join(name);
        std::fs::create_dir(&d).unwrap();
        let e = SceneSpec::parse(d.to_str().unwrap(), None, 1)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains(name)
                && e.contains("is a directory: name one of its point-cloud files (.ply"),
            "{e}"
        );
    }
}

/// E57 intensity: kept per valid point when every scan has it, used by `--shading
/// intensity`; a file whose scans lack it says so.
#[test]
fn e57_intensity_is_read_for_shading() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("int.e57");
    let mut w = E57Writer::from_file(&path, "guid-int").unwrap();
    let proto = vec![
        Record::CARTESIAN_X_F64,
        Record::CARTESIAN_Y_F64,
        Record::CARTESIAN_Z_F64,
        Record::CARTESIAN_INVALID_STATE,
        Record::INTENSITY_U16,
    ];
    let mut pc = w.add_pointcloud("scan", proto).unwrap();
    for (i, v) in [100i64, 900, 555, 300].iter().enumerate() {
        let invalid = if i == 2 { 2 } else { 0 };
        pc.add_point(vec![
            RecordValue::Double(i as f64),
            RecordValue::Double(0.0),
            RecordValue::Double(1.0),
            RecordValue::Integer(invalid),
            RecordValue::Integer(*v),
        ])
        .unwrap();
    }
    pc.finalize().unwrap();
    w.finalize().unwrap();
    let r = scenes::e57::read(&path).unwrap();
    // The invalid point is dropped with its intensity.
    assert_eq!(r.intensity.as_deref(), Some(&[100.0, 900.0, 300.0][..]));
    let c = scenes::SceneSpec::parse(&path.to_string_lossy(), None, 1)
        .unwrap()
        .with_colour_from(Some(scenes::Scalar::Intensity))
        .load(None, &scenes::NoProgress)
        .unwrap()
        .cloud;
    let greys: Vec<u8> = c.colors().unwrap().iter().map(|c| c[0]).collect();
    assert_eq!(greys, vec![0, 255, 64]);
    // The two-scan file of the test above has no intensity.
    let none = dir.path().join("none.e57");
    write_e57(&none, true);
    assert!(scenes::e57::read(&none).unwrap().intensity.is_none());
    let m = scenes::SceneSpec::parse(&none.to_string_lossy(), None, 1)
        .unwrap()
        .with_colour_from(Some(scenes::Scalar::Intensity))
        .load(None, &scenes::NoProgress)
        .unwrap_err()
        .to_string();
    assert!(m.contains("none.e57") && m.contains("no intensity"), "{m}");
}
