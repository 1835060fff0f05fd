#![allow(clippy::unwrap_used)]
//! Integration tests of the PLY and LAS/LAZ readers and writers: round trips in every format,
//! mesh-derived normals and radii, surface resampling, and malformed inputs (each must give an
//! error naming its cause, never a panic).

use std::path::{Path, PathBuf};

use glam::DVec3;
use scenes::ply::{self, PlyFormat, PlyOptions};
use scenes::rng::Pcg32;
use scenes::{Attributes, PointCloud, SceneError};

const FORMATS: [PlyFormat; 3] = [
    PlyFormat::Ascii,
    PlyFormat::BinaryLittleEndian,
    PlyFormat::BinaryBigEndian,
];

fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

fn write_bytes(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

fn read_plain(path: &Path) -> Result<PointCloud, SceneError> {
    ply::read(path, &PlyOptions::default())
}

/// The error message of a read that must fail; also checks that it names the file.
fn ply_err(path: &Path, opts: &PlyOptions) -> String {
    let e = ply::read(path, opts).expect_err("the read must fail");
    let msg = e.to_string();
    let name = path.file_name().unwrap().to_str().unwrap();
    assert!(msg.contains(name), "message does not name the file: {msg}");
    msg
}

fn random_cloud(n: usize, origin: DVec3, with_attrs: bool, seed: u64) -> PointCloud {
    let mut r = Pcg32::new(seed);
    let pos: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            [
                r.range_f32(-50.0, 50.0),
                r.range_f32(-20.0, 20.0),
                r.range_f32(-5.0, 5.0),
            ]
        })
        .collect();
    if !with_attrs {
        return PointCloud::new(origin, pos.into(), None, None, None).unwrap();
    }
    let nrm: Vec<[f32; 3]> = (0..n).map(|_| r.unit_vec3().to_array()).collect();
    let col: Vec<[u8; 3]> = (0..n)
        .map(|_| [r.below(256) as u8, r.below(256) as u8, r.below(256) as u8])
        .collect();
    let rad: Vec<f32> = (0..n).map(|_| r.range_f32(0.001, 0.5)).collect();
    PointCloud::new(
        origin,
        pos.into(),
        Some(nrm.into()),
        Some(col.into()),
        Some(rad.into()),
    )
    .unwrap()
}

fn assert_world_close(a: &PointCloud, b: &PointCloud, rel: f64) {
    assert_eq!(a.len(), b.len());
    for i in 0..a.len() {
        let (p, q) = (a.world_position(i), b.world_position(i));
        let tol = rel * p.abs().max_element().max(1.0);
        assert!((p - q).abs().max_element() <= tol, "point {i}: {p} vs {q}");
    }
}

// ---------------------------------------------------------------------------------------------
// PLY round trips
// ---------------------------------------------------------------------------------------------

#[test]
fn ply_round_trip_every_format_with_all_attributes() {
    let dir = tmp();
    let cloud = random_cloud(1000, DVec3::new(1234.5, -987.25, 42.0), true, 7);
    for format in FORMATS {
        let p = dir.path().join(format!("{format:?}.ply"));
        let bytes = ply::write(&p, &cloud, format).unwrap();
        assert_eq!(bytes, std::fs::metadata(&p).unwrap().len());
        let back = read_plain(&p).unwrap();
        assert_eq!(back.len(), cloud.len(), "{format:?}");
        assert_eq!(
            back.attributes(),
            Attributes {
                normals: true,
                colors: true,
                radii: true
            }
        );
        assert_world_close(&cloud, &back, 1e-6);
        for (a, b) in cloud.normals().unwrap().iter().zip(back.normals().unwrap()) {
            for k in 0..3 {
                assert!((a[k] - b[k]).abs() <= 1e-6, "{format:?}: {a:?} vs {b:?}");
            }
        }
        assert_eq!(
            cloud.colors().unwrap(),
            back.colors().unwrap(),
            "{format:?}"
        );
        assert_eq!(cloud.radii().unwrap(), back.radii().unwrap(), "{format:?}");
    }
    // Only the three output files: no temporary file left behind.
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 3);
}

#[test]
fn ply_positions_only_invents_no_attribute() {
    let dir = tmp();
    let cloud = random_cloud(200, DVec3::new(500_000.0, 4_100_000.0, 12.0), false, 3);
    for format in FORMATS {
        let p = dir.path().join(format!("{format:?}.ply"));
        ply::write(&p, &cloud, format).unwrap();
        let back = read_plain(&p).unwrap();
        assert_eq!(back.attributes(), Attributes::default(), "{format:?}");
        assert_world_close(&cloud, &back, 1e-6);
        // Origin = centre of the f64 bounding box: near the data, so f32 keeps precision.
        assert!((back.origin() - cloud.origin()).length() < 100.0);
    }
}

#[test]
fn ply_reads_float_colours_and_alternative_names() {
    let dir = tmp();
    let text = "ply\nformat ascii 1.0\nelement vertex 2\nproperty double x\nproperty double y\n\
                property double z\nproperty float diffuse_red\nproperty float diffuse_green\n\
                property float diffuse_blue\nproperty float radius\nproperty int intensity\n\
                end_header\n0 0 0 1.0 0.5 0.0 0.25 17\n1 2 3 0.2 0.4 0.6 0.5 18\n";
    let p = write_bytes(dir.path(), "float_colours.ply", text.as_bytes());
    let c = read_plain(&p).unwrap();
    assert_eq!(c.colors().unwrap(), &[[255, 128, 0], [51, 102, 153]]);
    assert_eq!(c.radii().unwrap(), &[0.25, 0.5]);
    assert!(c.normals().is_none());
}

// ---------------------------------------------------------------------------------------------
// Extra elements
// ---------------------------------------------------------------------------------------------

const UNIT_SQUARE_RADIUS: f32 = std::f64::consts::FRAC_1_SQRT_2 as f32;

fn assert_unit_square(c: &PointCloud, colors: &[[u8; 3]]) {
    assert_eq!(c.len(), 4);
    let expect = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [1.0, 1.0, 0.0],
        [0.0, 1.0, 0.0],
    ];
    for (i, e) in expect.iter().enumerate() {
        assert!((c.world_position(i) - DVec3::from(*e)).length() < 1e-7);
    }
    assert_eq!(c.colors().unwrap(), colors);
    for n in c.normals().unwrap() {
        assert_eq!(*n, [0.0, 0.0, 1.0]);
    }
    for r in c.radii().unwrap() {
        assert!((r - UNIT_SQUARE_RADIUS).abs() <= 1e-7, "{r}");
    }
}

#[test]
fn ascii_skips_extra_elements_before_and_after_faces() {
    let dir = tmp();
    let text = "ply\r\nformat ascii 1.0\ncomment hand written, CRLF on the first line\n\
        obj_info made for a test\n\
        element vertex 4\nproperty float x\nproperty float y\nproperty float z\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element edge 2\nproperty list uchar int vertex_pair\nproperty uchar crease\n\
        element face 2\nproperty list uchar uint vertex_indices\n\
        element edge_after 2\nproperty list uchar int stuff\nend_header\n\
        0 0 0 255 0 0\n1 0 0 0 255 0\n1 1 0 0 0 255\n0 1 0 10 20 30\n\
        2 0 1 7\n2 2 3 0\n\
        4 0 1 2 3\n2 0 1\n\
        3 1 2 3\nnot even numbers\n";
    let p = write_bytes(dir.path(), "extra.ply", text.as_bytes());
    let c = read_plain(&p).unwrap();
    // The quad is fan-triangulated; the 2-index face adds no triangle.
    assert_unit_square(&c, &[[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]]);
}

#[test]
fn ascii_handles_crlf_and_lines_longer_than_the_read_buffer() {
    let dir = tmp();
    let n = 2_500_000; // "1 " × n: a 5 MB line, longer than the 4 MiB read buffer
    let mut text = String::from(
        "ply\r\nformat ascii 1.0\r\nelement vertex 2\r\nproperty float x\r\n\
         property float y\r\nproperty float z\r\nproperty list uint float blob\r\n\
         end_header\r\n",
    );
    text.push_str(&format!("1 2 3 {n}"));
    text.push_str(&" 1".repeat(n));
    text.push_str("\r\n\r\n4 5 6 0\r\n");
    let p = write_bytes(dir.path(), "long.ply", text.as_bytes());
    let c = read_plain(&p).unwrap();
    assert_eq!(c.len(), 2);
    assert!((c.world_position(1) - DVec3::new(4.0, 5.0, 6.0)).length() < 1e-9);
    assert_eq!(c.attributes(), Attributes::default());
}

/// Bytes in a chosen byte order.
struct Bin {
    be: bool,
    buf: Vec<u8>,
}
impl Bin {
    fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }
    fn i16(&mut self, v: i16) -> &mut Self {
        let b = if self.be {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    fn i32(&mut self, v: i32) -> &mut Self {
        let b = if self.be {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    fn f32(&mut self, v: f32) -> &mut Self {
        let b = if self.be {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
}

/// A binary unit square with unknown elements before, between and after the ones read; with
/// `vertex_list` the vertex records hold a list too (the variable-size path).
fn binary_square(be: bool, vertex_list: bool) -> Vec<u8> {
    let format = if be {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let vlist = if vertex_list {
        "property list uchar float extra\n"
    } else {
        ""
    };
    let header = format!(
        "ply\nformat {format} 1.0\nelement edge 2\nproperty list uchar int vertex_pair\n\
         property uchar crease\nelement vertex 4\nproperty float x\nproperty float y\n\
         property float z\n{vlist}property uchar red\nproperty uchar green\nproperty uchar blue\n\
         element note 3\nproperty short a\nproperty short b\n\
         element face 1\nproperty uchar flags\nproperty list uchar int vertex_indices\n\
         element material 1\nproperty list int char name\nend_header\n"
    );
    let mut b = Bin {
        be,
        buf: header.into_bytes(),
    };
    b.u8(2).i32(0).i32(1).u8(7);
    b.u8(2).i32(2).i32(3).u8(0);
    let verts = [
        [0.0, 0.0, 0.0, 255.0, 0.0, 0.0],
        [1.0, 0.0, 0.0, 0.0, 255.0, 0.0],
        [1.0, 1.0, 0.0, 0.0, 0.0, 255.0],
        [0.0, 1.0, 0.0, 10.0, 20.0, 30.0],
    ];
    for (i, v) in verts.iter().enumerate() {
        b.f32(v[0]).f32(v[1]).f32(v[2]);
        if vertex_list {
            b.u8(i as u8);
            for k in 0..i {
                b.f32(k as f32);
            }
        }
        b.u8(v[3] as u8).u8(v[4] as u8).u8(v[5] as u8);
    }
    for k in 0..3 {
        b.i16(k).i16(-k);
    }
    b.u8(9).u8(4).i32(0).i32(1).i32(2).i32(3);
    b.i32(5);
    b.buf.extend_from_slice(b"steel");
    b.buf
}

#[test]
fn binary_skips_extra_elements_in_both_byte_orders() {
    let dir = tmp();
    for be in [false, true] {
        for vertex_list in [false, true] {
            let name = format!("bin_{be}_{vertex_list}.ply");
            let p = write_bytes(dir.path(), &name, &binary_square(be, vertex_list));
            let c = read_plain(&p).unwrap_or_else(|e| panic!("{name}: {e}"));
            assert_unit_square(&c, &[[255, 0, 0], [0, 255, 0], [0, 0, 255], [10, 20, 30]]);
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Meshes: derived normals and radii
// ---------------------------------------------------------------------------------------------

const SQUARE: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
];

#[test]
fn mesh_square_normals_follow_winding_and_radii_are_triangle_spheres() {
    let dir = tmp();
    for format in FORMATS {
        let p = dir.path().join(format!("sq_{format:?}.ply"));
        ply::write_mesh(&p, &SQUARE, &[[0, 1, 2], [0, 2, 3]], format).unwrap();
        let c = read_plain(&p).unwrap();
        assert_eq!(
            c.attributes(),
            Attributes {
                normals: true,
                colors: false,
                radii: true
            }
        );
        for n in c.normals().unwrap() {
            assert_eq!(*n, [0.0, 0.0, 1.0], "{format:?}");
        }
        for r in c.radii().unwrap() {
            assert!((r - UNIT_SQUARE_RADIUS).abs() <= 1e-7, "{format:?}: {r}");
        }
        // Clockwise seen from +Z: normals flip.
        let q = dir.path().join(format!("sq_cw_{format:?}.ply"));
        ply::write_mesh(&q, &SQUARE, &[[0, 2, 1], [0, 3, 2]], format).unwrap();
        for n in read_plain(&q).unwrap().normals().unwrap() {
            assert_eq!(*n, [0.0, 0.0, -1.0], "{format:?}");
        }
    }
}

#[test]
fn mesh_tetrahedron_normals_point_outward() {
    let dir = tmp();
    let v = [
        [0.0, 0.0, 0.0],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    let f = [[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]];
    let p = dir.path().join("tet.ply");
    ply::write_mesh(&p, &v, &f, PlyFormat::BinaryLittleEndian).unwrap();
    let c = read_plain(&p).unwrap();
    let centroid = DVec3::splat(0.25);
    let s = 1.0 / 3.0f32.sqrt();
    let expect = [
        [-s, -s, -s],
        [1.0, 0.0, 0.0],
        [0.0, 1.0, 0.0],
        [0.0, 0.0, 1.0],
    ];
    for (i, n) in c.normals().unwrap().iter().enumerate() {
        let out = DVec3::from(v[i]) - centroid;
        assert!(
            out.dot(glam::Vec3::from(*n).as_dvec3()) > 0.0,
            "vertex {i}: {n:?}"
        );
        for k in 0..3 {
            assert!((n[k] - expect[i][k]).abs() < 1e-6, "vertex {i}: {n:?}");
        }
    }
    // Every face of the tetrahedron is a right triangle with legs 1 (hypotenuse √2), except the
    // equilateral one with side √2 (circumradius √2/√3); vertices 1-3 touch it.
    let r = c.radii().unwrap();
    assert!((r[0] - UNIT_SQUARE_RADIUS).abs() < 1e-7);
    let eq = (2.0f64.sqrt() / 3.0f64.sqrt()) as f32;
    for &ri in &r[1..] {
        assert!((ri - eq).abs() < 1e-6, "{ri} vs {eq}");
    }
}

#[test]
fn mesh_unreferenced_vertex_gets_fallback_normal_and_median_radius() {
    let dir = tmp();
    let mut v = SQUARE.to_vec();
    v.push([5.0, 5.0, 5.0]);
    let p = dir.path().join("loose.ply");
    ply::write_mesh(&p, &v, &[[0, 1, 2], [0, 2, 3]], PlyFormat::Ascii).unwrap();
    let c = read_plain(&p).unwrap();
    assert_eq!(c.normals().unwrap()[4], [0.0, 0.0, 1.0]);
    assert!((c.radii().unwrap()[4] - UNIT_SQUARE_RADIUS).abs() < 1e-7);
    // Faces that cancel (a doubled, opposite-wound triangle) still give a unit normal.
    let q = dir.path().join("cancel.ply");
    ply::write_mesh(&q, &SQUARE[..3], &[[0, 1, 2], [0, 2, 1]], PlyFormat::Ascii).unwrap();
    for n in read_plain(&q).unwrap().normals().unwrap() {
        assert!((glam::Vec3::from(*n).length() - 1.0).abs() < 1e-6, "{n:?}");
        assert!(n[2].abs() > 0.999, "{n:?}");
    }
}

// ---------------------------------------------------------------------------------------------
// Surface resampling
// ---------------------------------------------------------------------------------------------

fn two_triangles(dir: &Path) -> PathBuf {
    // Area 3 at z = 0 and area 1 at z = 5, far apart.
    let v = [
        [0.0, 0.0, 0.0],
        [3.0, 0.0, 0.0],
        [0.0, 2.0, 0.0],
        [10.0, 0.0, 5.0],
        [11.0, 0.0, 5.0],
        [10.0, 2.0, 5.0],
    ];
    let p = dir.join("two.ply");
    ply::write_mesh(&p, &v, &[[0, 1, 2], [3, 4, 5]], PlyFormat::BinaryBigEndian).unwrap();
    p
}

fn sampled(path: &Path, n: usize, seed: u64) -> PointCloud {
    ply::read(
        path,
        &PlyOptions {
            sample: Some(n),
            seed,
        },
    )
    .unwrap()
}

#[test]
fn sample_gives_exactly_n_points_deterministically() {
    let dir = tmp();
    let p = two_triangles(dir.path());
    for n in [1, 7, 1000, 70_000] {
        let c = sampled(&p, n, 1);
        assert_eq!(c.len(), n);
        assert_eq!(
            c.attributes(),
            Attributes {
                normals: true,
                colors: false,
                radii: false
            }
        );
    }
    let a = sampled(&p, 70_000, 42);
    let b = sampled(&p, 70_000, 42);
    let c = sampled(&p, 70_000, 43);
    assert_eq!(a.origin(), b.origin());
    assert_eq!(a.positions(), b.positions());
    assert_eq!(a.normals(), b.normals());
    assert_ne!(a.positions(), c.positions());
}

#[test]
fn sample_is_area_weighted_and_on_the_triangles() {
    let dir = tmp();
    let p = two_triangles(dir.path());
    let c = sampled(&p, 40_000, 9);
    let (mut big, mut small) = (0usize, 0usize);
    for i in 0..c.len() {
        let w = c.world_position(i);
        let n = c.normals().unwrap()[i];
        assert_eq!(n, [0.0, 0.0, 1.0]);
        let eps = 1e-5;
        if w.z.abs() < eps {
            big += 1;
            assert!(
                w.x >= -eps && w.y >= -eps && w.x / 3.0 + w.y / 2.0 <= 1.0 + eps,
                "{w}"
            );
        } else {
            assert!((w.z - 5.0).abs() < eps, "point {i} off both planes: {w}");
            small += 1;
            let (x, y) = (w.x - 10.0, w.y);
            assert!(x >= -eps && y >= -eps && x + y / 2.0 <= 1.0 + eps, "{w}");
        }
    }
    let ratio = big as f64 / small as f64;
    assert!(
        (ratio - 3.0).abs() <= 0.15,
        "ratio {ratio} ({big} : {small})"
    );
}

#[test]
fn sample_interpolates_file_normals_and_colours() {
    let dir = tmp();
    let text = "ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\n\
        property float z\nproperty float nx\nproperty float ny\nproperty float nz\n\
        property uchar red\nproperty uchar green\nproperty uchar blue\n\
        element face 1\nproperty list uchar int vertex_indices\nend_header\n\
        0 0 0 0 0 2 100 0 0\n1 0 0 0 0 1 100 0 0\n0 1 0 0 0 3 100 0 0\n3 0 1 2\n";
    let p = write_bytes(dir.path(), "nc.ply", text.as_bytes());
    let c = sampled(&p, 500, 5);
    assert!(c.colors().unwrap().iter().all(|&col| col == [100, 0, 0]));
    assert!(c.normals().unwrap().iter().all(|&n| n == [0.0, 0.0, 1.0]));
    assert!(c.radii().is_none());
}

// ---------------------------------------------------------------------------------------------
// Malformed PLY input
// ---------------------------------------------------------------------------------------------

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

// ---------------------------------------------------------------------------------------------
// LAS / LAZ
// ---------------------------------------------------------------------------------------------

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
