//! PLY reading and writing: round trips in every format, extra elements skipped in ASCII and
//! binary files, mesh-derived normals and radii, and surface resampling.
#![allow(clippy::unwrap_used)]

mod common;

use common::{SQUARE, binary_square, random_cloud, read_plain, tmp, two_triangles, write_bytes};
use std::path::Path;

use glam::DVec3;
use scenes::ply::{self, PlyFormat, PlyOptions};
use scenes::{Attributes, PointCloud};

const FORMATS: [PlyFormat; 3] = [
    PlyFormat::Ascii,
    PlyFormat::BinaryLittleEndian,
    PlyFormat::BinaryBigEndian,
];

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
