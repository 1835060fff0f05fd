//! Malformed PLY input, and write errors: bad headers, ASCII bodies, faces, truncated and
//! corrupted files, impossible sampling requests and missing files — each must give an error
//! naming its cause (and the file), never a panic.
#![allow(clippy::unwrap_used)]

mod common;

use std::path::Path;

use common::{
    Bin, SQUARE, binary_square, random_cloud, read_plain, tmp, two_triangles, write_bytes,
};
use glam::DVec3;
use scenes::SceneError;
use scenes::ply::{self, PlyFormat, PlyOptions};
use scenes::rng::Pcg32;

/// The error message of a read that must fail; also checks that it names the file.
fn ply_err(path: &Path, opts: &PlyOptions) -> String {
    let e = ply::read(path, opts).expect_err("the read must fail");
    let msg = e.to_string();
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(msg.contains(name), "message does not name the file: {msg}");
    msg
}

const GOOD_HEAD: &str = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\n\
                         property float y\nproperty float z\n";

fn bad(dir: &Path, name: &str, text: &str) -> String {
    let p = write_bytes(dir, name, text.as_bytes());
    ply_err(&p, &PlyOptions::default())
}

#[test]
fn malformed_headers_are_named() {
    let dir = tmp();
    let d = dir.path();
    let m = bad(d, "magic.ply", "plx\nformat ascii 1.0\n");
    assert!(m.contains("'ply' magic"), "{m}");
    let m = bad(d, "empty.ply", "");
    assert!(m.contains("'ply' magic"), "{m}");
    let binary_junk: Vec<u8> = (0..200_000u32).map(|i| (i * 7 + 1) as u8 | 1).collect();
    let p = write_bytes(d, "junk.ply", &binary_junk);
    let m = ply_err(&p, &PlyOptions::default());
    assert!(m.contains("'ply' magic"), "{m}");
    let m = bad(
        d,
        "fmt.ply",
        "ply\nformat binary_middle_endian 1.0\nend_header\n",
    );
    assert!(
        m.contains("unknown format 'binary_middle_endian'") && m.contains("line 2"),
        "{m}"
    );
    let m = bad(d, "noend.ply", &format!("{GOOD_HEAD}0 0 0\n1 1 1\n"));
    assert!(m.contains("end_header") && m.contains("line 7"), "{m}");
    let m = bad(d, "noend_eof.ply", GOOD_HEAD);
    assert!(m.contains("end_header"), "{m}");
    let m = bad(
        d,
        "noformat.ply",
        "ply\nelement vertex 1\nproperty float x\nend_header\n",
    );
    assert!(m.contains("no 'format' line"), "{m}");
    let m = bad(
        d,
        "novertex.ply",
        "ply\nformat ascii 1.0\nelement face 0\nend_header\n",
    );
    assert!(m.contains("no 'vertex' element"), "{m}");
    let m = bad(
        d,
        "zero.ply",
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\n\
         property float z\nend_header\n",
    );
    assert!(m.contains("count 0"), "{m}");
    let m = bad(
        d,
        "noz.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\n\
         end_header\n0 0\n",
    );
    assert!(m.contains("'z'"), "{m}");
    let m = bad(
        d,
        "type.ply",
        "ply\nformat ascii 1.0\nelement vertex 1\nproperty float128 x\nend_header\n",
    );
    assert!(m.contains("line 4") && m.contains("float128"), "{m}");
    let m = bad(
        d,
        "count.ply",
        "ply\nformat ascii 1.0\nelement vertex -3\nend_header\n",
    );
    assert!(m.contains("line 3") && m.contains("-3"), "{m}");
}

#[test]
fn malformed_ascii_bodies_name_the_line() {
    let dir = tmp();
    let d = dir.path();
    let head = format!("{GOOD_HEAD}end_header\n");
    let m = bad(d, "few.ply", &format!("{head}0 0 0\n1 1\n"));
    assert!(
        m.contains("line 9") && m.contains("too few values") && m.contains("'z'"),
        "{m}"
    );
    let m = bad(d, "many.ply", &format!("{head}0 0 0 4\n1 1 1\n"));
    assert!(m.contains("line 8") && m.contains("too many values"), "{m}");
    let m = bad(d, "nan_token.ply", &format!("{head}0 0 0\n1 abc 1\n"));
    assert!(
        m.contains("line 9") && m.contains("'abc' is not a number"),
        "{m}"
    );
    let m = bad(d, "short.ply", &format!("{head}0 0 0\n"));
    assert!(m.contains("unexpected end of file in vertex 1 of 2"), "{m}");
    let m = bad(d, "nan.ply", &format!("{head}0 0 0\nnan 1 2\n"));
    assert!(m.contains("vertex 1") && m.contains("not finite"), "{m}");
    let m = bad(d, "inf.ply", &format!("{head}inf 0 0\n0 1 2\n"));
    assert!(m.contains("vertex 0") && m.contains("not finite"), "{m}");
    let nrm = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
               property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
               end_header\n0 0 0 0 0 1\n1 1 1 0 0 0\n";
    // A zero normal is not an error: the column is dropped, with a warning naming the vertex.
    let zero = d.join("zero_normal.ply");
    std::fs::write(&zero, nrm).unwrap();
    let (c, w) = scenes::ply::read_noted(&zero, &Default::default()).unwrap();
    assert_eq!(c.len(), 2);
    assert!(c.normals().is_none());
    assert_eq!(w.len(), 1, "{w:?}");
    assert!(
        w[0].contains("zero_normal.ply") && w[0].contains("1 of 2") && w[0].contains("vertex 1"),
        "{w:?}"
    );
    // With faces, the dropped normals are derived from them (+Z for this triangle).
    let tri = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
               property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
               element face 1\nproperty list uchar int vertex_indices\nend_header\n\
               0 0 0 0 0 1\n1 0 0 0 0 0\n0 1 0 0 0 1\n3 0 1 2\n";
    let tri_path = d.join("zero_normal_tri.ply");
    std::fs::write(&tri_path, tri).unwrap();
    let (c, w) = scenes::ply::read_noted(&tri_path, &Default::default()).unwrap();
    assert_eq!(c.normals().unwrap(), &[[0.0, 0.0, 1.0]; 3]);
    assert!(
        w.len() == 1 && w[0].contains("derived from the faces"),
        "{w:?}"
    );
    let rad = "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\n\
               property float z\nproperty float radius\nend_header\n0 0 0 1\n1 1 1 -2\n";
    let m = bad(d, "neg_radius.ply", rad);
    assert!(m.contains("radius 1"), "{m}");
}

fn face_file(faces: &str, count: usize) -> String {
    format!(
        "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
         property float z\nelement face {count}\nproperty list uchar int vertex_indices\n\
         end_header\n0 0 0\n1 0 0\n0 1 0\n{faces}"
    )
}

#[test]
fn malformed_faces_are_named() {
    let dir = tmp();
    let d = dir.path();
    let m = bad(d, "range.ply", &face_file("3 0 1 2\n3 0 1 3\n", 2));
    assert!(
        m.contains("face 1") && m.contains("out of range") && m.contains("line 14"),
        "{m}"
    );
    let m = bad(d, "negidx.ply", &face_file("3 0 -1 2\n", 1));
    assert!(m.contains("face 0") && m.contains("-1"), "{m}");
    let m = bad(d, "negcount.ply", &face_file("-3 0 1 2\n", 1));
    assert!(m.contains("list count '-3'"), "{m}");
    let m = bad(d, "bigcount.ply", &face_file("9 0 1 2\n", 1));
    assert!(m.contains("too few values"), "{m}");
    // Binary: a list count the rest of the file cannot hold, and a negative one.
    for (name, count, expect) in [
        (
            "bin_big.ply",
            1_000_000_i32,
            "list count 1000000 needs 4000000 bytes",
        ),
        ("bin_neg.ply", -4, "negative list count -4"),
    ] {
        let mut b = Bin {
            be: false,
            buf: b"ply\nformat binary_little_endian 1.0\nelement vertex 3\nproperty float x\n\
                   property float y\nproperty float z\nelement face 1\n\
                   property list int int vertex_indices\nend_header\n"
                .to_vec(),
        };
        for v in [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]] {
            b.f32(v[0]).f32(v[1]).f32(v[2]);
        }
        b.i32(count).i32(0).i32(1).i32(2);
        let p = write_bytes(d, name, &b.buf);
        let m = ply_err(&p, &PlyOptions::default());
        assert!(m.contains(expect) && m.contains("face 0"), "{m}");
    }
}

#[test]
fn truncated_binary_names_the_vertex() {
    let dir = tmp();
    let cloud = random_cloud(100, DVec3::ZERO, false, 1);
    for format in [PlyFormat::BinaryLittleEndian, PlyFormat::BinaryBigEndian] {
        let p = dir.path().join("trunc.ply");
        ply::write(&p, &cloud, format).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let body = bytes
            .windows(11)
            .position(|w| w == b"end_header\n")
            .unwrap()
            + 11;
        // 17 whole records of 3 doubles, then 10 bytes of the 18th (inside 'y').
        let cut = body + 17 * 24 + 10;
        std::fs::write(&p, &bytes[..cut]).unwrap();
        let m = ply_err(&p, &PlyOptions::default());
        assert!(
            m.contains("unexpected end of file in vertex 17 of 100") && m.contains("'y'"),
            "{m}"
        );
    }
    // Truncated inside the faces.
    let p = dir.path().join("trunc_faces.ply");
    ply::write_mesh(
        &p,
        &SQUARE,
        &[[0, 1, 2], [0, 2, 3]],
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    let bytes = std::fs::read(&p).unwrap();
    std::fs::write(&p, &bytes[..bytes.len() - 3]).unwrap();
    let m = ply_err(&p, &PlyOptions::default());
    assert!(m.contains("unexpected end of file in face 1 of 2"), "{m}");
}

#[test]
fn corrupted_files_never_panic() {
    let dir = tmp();
    let ascii = face_file("3 0 1 2\n", 1).into_bytes();
    let mut originals = vec![
        ascii,
        binary_square(false, true),
        binary_square(true, false),
    ];
    let mesh = dir.path().join("m.ply");
    ply::write_mesh(
        &mesh,
        &SQUARE,
        &[[0, 1, 2], [0, 2, 3]],
        PlyFormat::BinaryLittleEndian,
    )
    .unwrap();
    originals.push(std::fs::read(&mesh).unwrap());
    let sample = PlyOptions {
        sample: Some(50),
        seed: 1,
    };
    // Fresh names: rewriting one file in place makes ext4 flush on every truncation.
    let mut k = 0;
    let mut check = |bytes: &[u8], also_sample: bool| {
        k += 1;
        let p = dir.path().join(format!("corrupt{k}.ply"));
        std::fs::write(&p, bytes).unwrap();
        let _ = read_plain(&p);
        if also_sample {
            let _ = ply::read(&p, &sample);
        }
        std::fs::remove_file(&p).unwrap();
    };
    let mut r = Pcg32::new(99);
    for orig in &originals {
        // Every prefix.
        for len in 0..orig.len() {
            check(&orig[..len], false);
        }
        // Random byte changes, header included.
        for _ in 0..400 {
            let mut bytes = orig.clone();
            for _ in 0..1 + r.below(4) {
                let i = r.below(bytes.len() as u32) as usize;
                bytes[i] = match r.below(3) {
                    0 => r.next_u32() as u8,
                    1 => b"0123456789-. \n"[r.below(14) as usize],
                    _ => 0xff,
                };
            }
            check(&bytes, true);
        }
    }
}

#[test]
fn sample_needs_faces_and_a_positive_count() {
    let dir = tmp();
    let d = dir.path();
    let cloud = random_cloud(10, DVec3::ZERO, false, 1);
    let p = d.join("points.ply");
    ply::write(&p, &cloud, PlyFormat::BinaryLittleEndian).unwrap();
    let opts = PlyOptions {
        sample: Some(100),
        seed: 1,
    };
    let m = ply_err(&p, &opts);
    assert!(m.contains("no faces"), "{m}");
    let mesh = two_triangles(d);
    let m = ply_err(
        &mesh,
        &PlyOptions {
            sample: Some(0),
            seed: 1,
        },
    );
    assert!(m.contains("0 points"), "{m}");
    // Only degenerate triangles: nothing to sample.
    let flat = d.join("flat.ply");
    ply::write_mesh(
        &flat,
        &[[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]],
        &[[0, 1, 2]],
        PlyFormat::Ascii,
    )
    .unwrap();
    let m = ply_err(&flat, &opts);
    assert!(m.contains("zero area"), "{m}");
    // Without sampling the degenerate mesh still reads, with finite positive radii.
    let c = read_plain(&flat).unwrap();
    assert!(c.radii().unwrap().iter().all(|r| r.is_finite() && *r > 0.0));
}

#[test]
fn missing_file_is_an_io_error_naming_it() {
    let dir = tmp();
    let p = dir.path().join("does_not_exist.ply");
    let e = read_plain(&p).unwrap_err();
    assert!(matches!(e, SceneError::Io { .. }));
    assert!(e.to_string().contains("does_not_exist.ply"));
    let e = scenes::las::read(&dir.path().join("nope.laz")).unwrap_err();
    assert!(e.to_string().contains("nope.laz"), "{e}");
}

#[test]
fn write_mesh_rejects_bad_indices_and_leaves_no_file() {
    let dir = tmp();
    let p = dir.path().join("bad_mesh.ply");
    let e = ply::write_mesh(&p, &SQUARE, &[[0, 1, 4]], PlyFormat::Ascii).unwrap_err();
    assert!(e.to_string().contains("face 0"), "{e}");
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let e = ply::write(
        &dir.path().join("no_such_dir").join("x.ply"),
        &random_cloud(3, DVec3::ZERO, false, 1),
        PlyFormat::Ascii,
    )
    .unwrap_err();
    assert!(e.to_string().contains("x.ply"), "{e}");
}
