//! Helpers shared by the PLY and LAS/LAZ reader tests (`mod common;` in each test file):
//! temporary files, random clouds, binary PLY bytes, and small meshes.
#![allow(dead_code, clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use glam::DVec3;
use scenes::ply::{self, PlyFormat, PlyOptions};
use scenes::rng::Pcg32;
use scenes::{PointCloud, SceneError};

pub fn tmp() -> tempfile::TempDir {
    tempfile::tempdir().unwrap()
}

pub fn write_bytes(dir: &Path, name: &str, bytes: &[u8]) -> PathBuf {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p
}

pub fn read_plain(path: &Path) -> Result<PointCloud, SceneError> {
    ply::read(path, &PlyOptions::default())
}

pub fn random_cloud(n: usize, origin: DVec3, with_attrs: bool, seed: u64) -> PointCloud {
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

/// Bytes in a chosen byte order.
pub struct Bin {
    pub be: bool,
    pub buf: Vec<u8>,
}
impl Bin {
    pub fn u8(&mut self, v: u8) -> &mut Self {
        self.buf.push(v);
        self
    }
    pub fn i16(&mut self, v: i16) -> &mut Self {
        let b = if self.be {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    pub fn i32(&mut self, v: i32) -> &mut Self {
        let b = if self.be {
            v.to_be_bytes()
        } else {
            v.to_le_bytes()
        };
        self.buf.extend_from_slice(&b);
        self
    }
    pub fn f32(&mut self, v: f32) -> &mut Self {
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
pub fn binary_square(be: bool, vertex_list: bool) -> Vec<u8> {
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

pub const SQUARE: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
];

pub fn two_triangles(dir: &Path) -> PathBuf {
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
