#![allow(clippy::unwrap_used)]
//! Corrupted and inconsistent inputs (issue 13): each must be an error naming the file, the
//! field and the byte or line — never an abort, a panic or silently dropped data. An abort
//! inside a decoder kills this test binary, which fails the test as surely as an assertion.

use std::path::{Path, PathBuf};

use scenes::ply::{self, PlyFormat, PlyOptions};

use glam::DVec3;
use scenes::PointCloud;

fn data(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/real")
        .join(name)
}

fn u32_at(b: &[u8], at: usize) -> u32 {
    u32::from_le_bytes(b[at..at + 4].try_into().unwrap())
}

fn put_u32(b: &mut [u8], at: usize, v: u32) {
    b[at..at + 4].copy_from_slice(&v.to_le_bytes());
}

fn put_u64(b: &mut [u8], at: usize, v: u64) {
    b[at..at + 8].copy_from_slice(&v.to_le_bytes());
}

/// Writes `bytes` as `name` in `dir`, reads it as LAS / LAZ and returns the error message,
/// checking that it names the file and contains every needle.
fn las_err(dir: &Path, name: &str, bytes: &[u8], needles: &[&str]) -> String {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    let m = scenes::las::read(&p)
        .map(|c| c.len())
        .expect_err("the read must fail")
        .to_string();
    assert!(m.contains(name), "the message does not name {name}: {m}");
    for n in needles {
        assert!(m.contains(n), "{name}: '{n}' missing from: {m}");
    }
    m
}

/// A small cloud at UTM-like coordinates.
fn tile(n: usize) -> PointCloud {
    let mut r = scenes::rng::Pcg32::new(5);
    let pos: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            [
                r.range_f32(-50.0, 50.0),
                r.range_f32(-50.0, 50.0),
                r.range_f32(0.0, 5.0),
            ]
        })
        .collect();
    PointCloud::new(
        DVec3::new(500_000.0, 4_100_000.0, 50.0),
        pos.into(),
        None,
        None,
        None,
    )
    .unwrap()
}

// ---------------------------------------------------------------------------------------------
// LAZ: fields the laz crate allocates by
// ---------------------------------------------------------------------------------------------

/// plane.laz (laspy): LAS 1.2, point format 3 compressed, 4 VLRs, points at byte 878, one
/// chunk of 28,185 points, its chunk table at byte 59,330 (14 bytes before the end).
const PLANE_POINTS_AT: usize = 878;

fn plane() -> Vec<u8> {
    let b = std::fs::read(data("plane.laz")).unwrap();
    assert_eq!(u32_at(&b, 96) as usize, PLANE_POINTS_AT);
    b
}

fn chunk_table_at(b: &[u8]) -> usize {
    i64::from_le_bytes(b[PLANE_POINTS_AT..PLANE_POINTS_AT + 8].try_into().unwrap()) as usize
}

#[test]
fn laz_chunk_count_beyond_the_file_is_an_error_not_an_abort() {
    let dir = tempfile::tempdir().unwrap();
    let orig = plane();
    let table = chunk_table_at(&orig);
    assert_eq!(u32_at(&orig, table + 4), 1);
    // The original reads.
    let ok = dir.path().join("plane.laz");
    std::fs::write(&ok, &orig).unwrap();
    assert_eq!(scenes::las::read(&ok).unwrap().len(), 28_185);
    // 2³² − 1 chunks: the laz crate reserved 64 GiB for them and aborted.
    for count in [u32::MAX, 1 << 28, 100_000] {
        let mut b = orig.clone();
        put_u32(&mut b, table + 4, count);
        las_err(
            dir.path(),
            "chunks.laz",
            &b,
            &[
                "LAZ chunk table at byte 59330",
                &format!("claims {count} chunks"),
            ],
        );
    }
    // Fixed-size chunks of 50,000: 28,185 points need at most 2 (one, and an empty last).
    let mut b = orig.clone();
    put_u32(&mut b, table + 4, 7);
    las_err(
        dir.path(),
        "seven.laz",
        &b,
        &["claims 7 chunks", "need at most 2"],
    );
}

#[test]
fn laz_chunk_table_offset_moved_onto_other_bytes_is_checked_there() {
    let dir = tempfile::tempdir().unwrap();
    let orig = plane();
    // Point the offset at bytes of the compressed points, and make them claim many chunks.
    let fake = 20_000usize;
    let mut b = orig.clone();
    put_u64(&mut b, PLANE_POINTS_AT, fake as u64);
    put_u32(&mut b, fake + 4, 0xFFFF_FF00);
    las_err(
        dir.path(),
        "moved.laz",
        &b,
        &["chunk table at byte 20000", "claims 4294967040 chunks"],
    );
    // An offset of 0 sends the crate to the last 8 bytes of the file: checked there too.
    let mut b = orig.clone();
    put_u64(&mut b, PLANE_POINTS_AT, 0);
    let n = b.len();
    put_u64(&mut b, n - 8, fake as u64);
    las_err(
        dir.path(),
        "tail.laz",
        &b,
        &["chunk table at byte 20000", "offset read at byte 59336"],
    );
}

#[test]
fn laz_items_must_match_the_record_length() {
    let dir = tempfile::tempdir().unwrap();
    let orig = plane();
    // The laszip VLR is the 4th: header 227 + (54 + 192) + (54 + 96) + (54 + 95) = 772; its
    // data at 826, items from 826 + 34: (6, 20, 2), (7, 8, 2), (8, 6, 2).
    let items = 826 + 34;
    assert_eq!(&orig[items..items + 2], &6u16.to_le_bytes());
    // Point10 declared as 60 bytes.
    let mut b = orig.clone();
    b[items + 2..items + 4].copy_from_slice(&60u16.to_le_bytes());
    las_err(
        dir.path(),
        "item.laz",
        &b,
        &["item 0 (Point10) as 60 bytes", "the type has 20"],
    );
    // Every item made extra bytes of size 0, and a record length of 0 to match: laz would
    // split its buffer into records of 0 bytes.
    let mut b = orig.clone();
    for k in 0..3 {
        b[items + 6 * k..items + 6 * k + 4].fill(0);
    }
    b[105..107].fill(0);
    las_err(
        dir.path(),
        "zero.laz",
        &b,
        &["3 items of 0 bytes per point"],
    );
    // Point record length 34 → 40 in the header.
    let mut b = orig.clone();
    b[105..107].copy_from_slice(&40u16.to_le_bytes());
    las_err(
        dir.path(),
        "reclen.laz",
        &b,
        &["34 bytes per point", "point record length is 40"],
    );
}

/// A LAS 1.4 file with point format `format` (6, or 7 with colours), LAZ-compressed if `laz`,
/// and one EVLR. (`fuzz/seeds/las14-*` were written by this function.)
fn las14(path: &Path, format: u8, laz: bool, n: usize) {
    let mut b = las::Builder::from((1, 4));
    b.point_format = las::point::Format::new(format).unwrap();
    b.point_format.is_compressed = laz;
    let t = las::Transform {
        scale: 0.001,
        offset: 0.0,
    };
    b.transforms = las::Vector { x: t, y: t, z: t };
    b.evlrs.push(las::Vlr {
        user_id: "splatbench".into(),
        record_id: 7,
        description: "test".into(),
        data: vec![1, 2, 3, 4, 5],
    });
    let mut w = las::Writer::from_path(path, b.into_header().unwrap()).unwrap();
    for i in 0..n {
        let f = i as f64;
        w.write_point(las::Point {
            x: f * 0.5,
            y: (f * 0.37).sin() * 10.0,
            z: f * 0.01,
            return_number: 1,
            number_of_returns: 1,
            gps_time: Some(f),
            color: (format == 7).then(|| las::Color {
                red: (i as u16).wrapping_mul(300),
                green: 7,
                blue: 65535,
            }),
            ..Default::default()
        })
        .unwrap();
    }
    w.close().unwrap();
}

#[test]
fn laz_layer_sizes_beyond_the_file_are_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("six.laz");
    las14(&p, 6, true, 3000);
    assert_eq!(scenes::las::read(&p).unwrap().len(), 3000);
    let orig = std::fs::read(&p).unwrap();
    let points_at = u32_at(&orig, 96) as usize;
    // Chunk 0: chunk table offset (8), first point raw (30), point count (4), 9 layer sizes.
    let sizes_at = points_at + 8 + 30 + 4;
    for layer in [0usize, 4, 8] {
        let mut b = orig.clone();
        put_u32(&mut b, sizes_at + 4 * layer, 0xFFFF_FFF0);
        las_err(
            dir.path(),
            "layer.laz",
            &b,
            &[
                &format!("LAZ chunk 0 (at byte {}): layer {layer}", points_at + 8),
                "declares 4294967280 bytes",
            ],
        );
    }
}

// ---------------------------------------------------------------------------------------------
// LAS header fields
// ---------------------------------------------------------------------------------------------

#[test]
fn las_evlr_longer_than_the_file_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    for (name, laz) in [("evlr.las", false), ("evlr.laz", true)] {
        let p = dir.path().join(name);
        las14(&p, 6, laz, 100);
        assert_eq!(scenes::las::read(&p).unwrap().len(), 100);
        let mut b = std::fs::read(&p).unwrap();
        let start = u64::from_le_bytes(b[235..243].try_into().unwrap()) as usize;
        assert_eq!(start + 60 + 5, b.len());
        put_u64(&mut b, start + 20, 1 << 40);
        las_err(
            dir.path(),
            name,
            &b,
            &[
                &format!("EVLR at byte {start} declares 1099511627776 bytes"),
                "5 bytes left",
            ],
        );
    }
}

#[test]
fn las_zero_or_non_finite_scale_names_the_axis() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.las");
    scenes::las::write(&p, &tile(200)).unwrap();
    let orig = std::fs::read(&p).unwrap();
    for (axis, at) in [("x", 131), ("y", 139), ("z", 147)] {
        let mut b = orig.clone();
        b[at..at + 8].copy_from_slice(&0f64.to_le_bytes());
        las_err(
            dir.path(),
            "scale.las",
            &b,
            &[&format!("{axis} scale factor is 0 (header byte {at})")],
        );
        b[at..at + 8].copy_from_slice(&f64::NAN.to_le_bytes());
        las_err(
            dir.path(),
            "scale.las",
            &b,
            &[&format!("{axis} scale factor is NaN")],
        );
    }
    let mut b = orig.clone();
    b[163..171].copy_from_slice(&f64::INFINITY.to_le_bytes());
    las_err(dir.path(), "offset.las", &b, &["y offset is inf"]);
    // And through LAZ too.
    let z = dir.path().join("ok.laz");
    scenes::las::write(&z, &tile(200)).unwrap();
    let mut b = std::fs::read(&z).unwrap();
    b[147..155].copy_from_slice(&0f64.to_le_bytes());
    las_err(dir.path(), "scale.laz", &b, &["z scale factor is 0"]);
}

#[test]
fn las_point_count_beyond_the_file_is_truncation_and_overflow_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.las");
    scenes::las::write(&p, &tile(200)).unwrap();
    let orig = std::fs::read(&p).unwrap();
    let mut b = orig.clone();
    put_u32(&mut b, 107, 4_000_000_000);
    las_err(
        dir.path(),
        "count.las",
        &b,
        &[
            "declares 4000000000 points of 20 bytes",
            "only 200 of 4000000000",
        ],
    );
    // LAS 1.4: a 64-bit count whose bytes overflow a file offset.
    let p = dir.path().join("ok14.las");
    las14(&p, 6, false, 10);
    let mut b = std::fs::read(&p).unwrap();
    put_u32(&mut b, 107, 0);
    put_u64(&mut b, 247, u64::MAX / 3);
    las_err(
        dir.path(),
        "huge.las",
        &b,
        &["points of 30 bytes: more bytes than a file can hold"],
    );
    let mut b = std::fs::read(dir.path().join("ok14.las")).unwrap();
    put_u32(&mut b, 107, 0);
    put_u64(&mut b, 247, u64::MAX / 3);
    b[104] |= 0x80; // as if compressed: the count still multiplies unchecked in the crate
    las_err(
        dir.path(),
        "huge.laz",
        &b,
        &["more bytes than a file can hold"],
    );
}

#[test]
fn las_trailing_records_without_evlrs_are_an_error_padding_and_evlrs_are_not() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.las");
    scenes::las::write(&p, &tile(200)).unwrap();
    let orig = std::fs::read(&p).unwrap();
    // The header under-counts: 150 of 200 points declared → 50 records left over.
    let mut b = orig.clone();
    put_u32(&mut b, 107, 150);
    let end = u32_at(&orig, 96) as usize + 150 * 20;
    las_err(
        dir.path(),
        "under.las",
        &b,
        &[
            "1000 bytes follow the last of the 150 point records",
            &format!("from byte {end}"),
            "50 records' worth",
            "no EVLRs",
        ],
    );
    // A few bytes of padding (less than one record) are accepted.
    let mut b = orig.clone();
    b.extend_from_slice(&[0, 0, 0x1a]);
    let q = dir.path().join("pad.las");
    std::fs::write(&q, &b).unwrap();
    assert_eq!(scenes::las::read(&q).unwrap().len(), 200);
    // EVLRs after the points (LAS 1.4), with padding before them, are accepted.
    let e = dir.path().join("evlr.las");
    las14(&e, 6, false, 100);
    assert_eq!(scenes::las::read(&e).unwrap().len(), 100);
    let mut b = std::fs::read(&e).unwrap();
    let start = u64::from_le_bytes(b[235..243].try_into().unwrap()) as usize;
    let evlr = b.split_off(start);
    b.extend_from_slice(&[0u8; 64]);
    put_u64(&mut b, 235, (start + 64) as u64);
    b.extend_from_slice(&evlr);
    let q = dir.path().join("padded-evlr.las");
    std::fs::write(&q, &b).unwrap();
    assert_eq!(scenes::las::read(&q).unwrap().len(), 100);
}

// ---------------------------------------------------------------------------------------------
// PLY
// ---------------------------------------------------------------------------------------------

/// Writes `bytes` as `name`, reads it as PLY and returns the error message, checking that it
/// names the file and contains every needle.
fn ply_err(dir: &Path, name: &str, bytes: &[u8], needles: &[&str]) -> String {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    let m = ply::read(&p, &PlyOptions::default())
        .map(|c| c.len())
        .expect_err("the read must fail")
        .to_string();
    assert!(m.contains(name), "the message does not name {name}: {m}");
    for n in needles {
        assert!(m.contains(n), "{name}: '{n}' missing from: {m}");
    }
    m
}

fn ply_ok(dir: &Path, name: &str, bytes: &[u8]) -> usize {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    ply::read(&p, &PlyOptions::default()).unwrap().len()
}

/// Byte offset of the body (just after `end_header\n`).
fn body_at(b: &[u8]) -> usize {
    b.windows(11).position(|w| w == b"end_header\n").unwrap() + 11
}

/// `bytes` with the first `from` replaced by `to` (in the header).
fn edit(bytes: &[u8], from: &str, to: &str) -> Vec<u8> {
    let at = bytes
        .windows(from.len())
        .position(|w| w == from.as_bytes())
        .unwrap();
    [&bytes[..at], to.as_bytes(), &bytes[at + from.len()..]].concat()
}

#[test]
fn ply_binary_header_under_counting_its_vertices_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ok.ply");
    ply::write(&p, &tile(100), PlyFormat::BinaryLittleEndian).unwrap();
    let orig = std::fs::read(&p).unwrap();
    assert_eq!(ply_ok(dir.path(), "ok.ply", &orig), 100);
    // 90 of 100 declared: 10 records of 3 doubles are left over.
    let b = edit(&orig, "element vertex 100", "element vertex 90");
    let end = body_at(&b) + 90 * 24;
    ply_err(
        dir.path(),
        "under.ply",
        &b,
        &[
            "240 bytes follow the last element 'vertex'",
            &format!("from byte {end}"),
        ],
    );
    // One stray byte is reported too, in both byte orders, after faces as well.
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian] {
        let m = dir.path().join("mesh.ply");
        let square = [
            [0.0, 0.0, 0.0],
            [1.0, 0.0, 0.0],
            [1.0, 1.0, 0.0],
            [0.0, 1.0, 0.0],
        ];
        ply::write_mesh(&m, &square, &[[0, 1, 2], [0, 2, 3]], format).unwrap();
        let mut b = std::fs::read(&m).unwrap();
        let len = b.len();
        b.push(b'\n');
        ply_err(
            dir.path(),
            "stray.ply",
            &b,
            &[&format!(
                "1 bytes follow the last element 'face', from byte {len}"
            )],
        );
    }
}

#[test]
fn ply_ascii_lines_after_the_last_element_name_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                property float z\nend_header\n0 0 0\n1 1 1\n2 2 2\n";
    ply_err(
        dir.path(),
        "under.ply",
        text.as_bytes(),
        &["line 10: '2 2 2' follows the last element 'vertex'"],
    );
    // Trailing blank lines are fine.
    let text = text.replace("2 2 2\n", "\n  \r\n\n");
    assert_eq!(ply_ok(dir.path(), "blank.ply", text.as_bytes()), 2);
}

#[test]
fn ply_extra_elements_after_the_needed_ones_are_still_checked_to_the_end() {
    let dir = tempfile::tempdir().unwrap();
    // A binary file whose last element ('edge', not read) hides 4 more bytes behind it.
    let mut b = b"ply\nformat binary_little_endian 1.0\nelement vertex 1\nproperty float x\n\
                  property float y\nproperty float z\nelement edge 2\nproperty int a\n\
                  end_header\n"
        .to_vec();
    for v in [1.5f32, 2.5, 3.5] {
        b.extend_from_slice(&v.to_le_bytes());
    }
    b.extend_from_slice(&[0u8; 8]);
    assert_eq!(ply_ok(dir.path(), "edges.ply", &b), 1);
    b.extend_from_slice(&[0u8; 4]);
    ply_err(
        dir.path(),
        "edges4.ply",
        &b,
        &["4 bytes follow the last element 'edge'"],
    );
}

#[test]
fn ply_ascii_body_under_a_binary_header_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("ascii.ply");
    ply::write(&p, &tile(50), PlyFormat::Ascii).unwrap();
    let orig = std::fs::read(&p).unwrap();
    for (fmt, name) in [
        ("binary_little_endian", "le.ply"),
        ("binary_big_endian", "be.ply"),
    ] {
        let b = edit(&orig, "format ascii 1.0", &format!("format {fmt} 1.0"));
        let body = body_at(&b);
        ply_err(
            dir.path(),
            name,
            &b,
            &[
                &format!("declares format {fmt} but the body (from byte {body}) is ascii text"),
                "is ascii text ('4",
            ],
        );
    }
    // Real binary bodies pass the rule: every format the writer has, positions only too.
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian] {
        let q = dir.path().join("bin.ply");
        ply::write(&q, &tile(50), format).unwrap();
        assert_eq!(ply::read(&q, &PlyOptions::default()).unwrap().len(), 50);
    }
}

#[test]
fn ply_ascii_fractional_or_out_of_range_integers_name_the_line_and_property() {
    let dir = tempfile::tempdir().unwrap();
    let head = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
                property float z\nproperty char flag\nproperty uchar red\nproperty uchar green\n\
                property uchar blue\nend_header\n";
    let ok = format!("{head}0 0 0 -3 10 20 30\n1 1 1 127 255 0 12.0\n");
    assert_eq!(ply_ok(dir.path(), "ok.ply", ok.as_bytes()), 2);
    ply_err(
        dir.path(),
        "frac.ply",
        format!("{head}0 0 0 0.302 10 20 30\n1 1 1 0 0 0 0\n").as_bytes(),
        &["line 12 (vertex 0): property 'flag' (char): '0.302' is not an integer"],
    );
    ply_err(
        dir.path(),
        "range.ply",
        format!("{head}0 0 0 1 10 20 30\n1 1 1 0 0 300 0\n").as_bytes(),
        &["line 13 (vertex 1): property 'green' (uchar): '300' is outside its range 0..=255"],
    );
    ply_err(
        dir.path(),
        "neg.ply",
        format!("{head}0 0 0 -129 10 20 30\n1 1 1 0 0 0 0\n").as_bytes(),
        &["property 'flag' (char): '-129' is outside its range -128..=127"],
    );
    ply_err(
        dir.path(),
        "nan.ply",
        format!("{head}0 0 0 0 nan 20 30\n1 1 1 0 0 0 0\n").as_bytes(),
        &["property 'red' (uchar): 'nan' is not an integer"],
    );
}

#[test]
fn laz_decoder_panics_on_a_corrupted_chunk_are_contained() {
    // Found by the fuzzer (target laz): one byte inside the layered chunk of a format-6 file
    // trips `debug_assert!(sym < (1 << 16))` in laz's arithmetic decoder, a panic in any
    // build with debug assertions (the tests'); the reader must return an error instead.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("six.laz");
    las14(&p, 6, true, 300);
    let mut b = std::fs::read(&p).unwrap();
    assert_eq!(
        (b.len(), b[2739]),
        (3182, 160),
        "the writer's output changed"
    );
    b[2739] = 156;
    let q = dir.path().join("sym.laz");
    std::fs::write(&q, &b).unwrap();
    let r = std::panic::catch_unwind(|| scenes::las::read(&q).map(|c| c.len()));
    let r = r.expect("a panic escaped the LAS/LAZ reader");
    if let Err(e) = r {
        assert!(e.to_string().contains("sym.laz"), "{e}");
    }
}

#[test]
fn laz_layered_items_under_a_pointwise_compressor_are_walked_where_the_crate_reads() {
    // Found by the fuzzer (target laz): the laszip VLR's compressor field changed from 3
    // (layered chunked) to 1 (pointwise). laz still picks the layered decoder (by the items'
    // version) but reads the chunk from the first byte of the point data, with no chunk-table
    // offset before it: the layer sizes it reads are other bytes, one of ~4 GiB, and the
    // process aborted allocating it. The check walked the chunks only for compressor 3.
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("seven.laz");
    las14(&p, 7, true, 200);
    assert_eq!(scenes::las::read(&p).unwrap().len(), 200);
    let mut b = std::fs::read(&p).unwrap();
    // The laszip VLR is the only VLR: header 375, VLR header 54, compressor at its data's 0.
    assert_eq!(&b[377..391], b"laszip encoded");
    assert_eq!(u16::from_le_bytes([b[429], b[430]]), 3);
    b[429] = 1;
    let points_at = u32_at(&b, 96);
    las_err(
        dir.path(),
        "pointwise.laz",
        &b,
        &[&format!("LAZ chunk 0 (at byte {points_at}): layer")],
    );
}
