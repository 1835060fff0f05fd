//! Writing clouds and meshes, through a temporary file renamed into place.

use std::io::{BufWriter, Write};
use std::path::Path;

use super::{PlyFormat, ferr};
use crate::atomic::{finish, write_atomically};
use crate::{PointCloud, SceneError};

// ---------------------------------------------------------------------------------------------
// Writing
// ---------------------------------------------------------------------------------------------

/// Appends `v` in the chosen byte order.
trait PutBytes {
    fn put(self, out: &mut Vec<u8>, big_endian: bool);
}
macro_rules! put_impl {
    ($($t:ty),*) => {$(
        impl PutBytes for $t {
            #[inline(always)]
            fn put(self, out: &mut Vec<u8>, big_endian: bool) {
                if big_endian {
                    out.extend_from_slice(&self.to_be_bytes());
                } else {
                    out.extend_from_slice(&self.to_le_bytes());
                }
            }
        }
    )*};
}
put_impl!(u8, u32, f32, f64);

/// Writes a cloud as PLY: `double x,y,z` world coordinates (origin + local), then
/// `float nx,ny,nz`, `uchar red,green,blue` and `float radius` for the columns the cloud has.
/// Returns the number of bytes written. The file appears atomically (temporary file + rename).
pub fn write(path: &Path, cloud: &PointCloud, format: PlyFormat) -> Result<u64, SceneError> {
    write_atomically(path, |file| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        let io_err = |e| SceneError::io(path, e);
        let normals = cloud.normals();
        let colors = cloud.colors();
        let radii = cloud.radii();
        let mut head = format!(
            "ply\nformat {} 1.0\ncomment written by splatbench\nelement vertex {}\n\
             property double x\nproperty double y\nproperty double z\n",
            format.header_name(),
            cloud.len()
        );
        if normals.is_some() {
            head.push_str("property float nx\nproperty float ny\nproperty float nz\n");
        }
        if colors.is_some() {
            head.push_str("property uchar red\nproperty uchar green\nproperty uchar blue\n");
        }
        if radii.is_some() {
            head.push_str("property float radius\n");
        }
        head.push_str("end_header\n");
        w.write_all(head.as_bytes()).map_err(io_err)?;
        let origin = cloud.origin();
        let world = |i: usize| {
            let p = cloud.positions()[i];
            [
                origin.x + f64::from(p[0]),
                origin.y + f64::from(p[1]),
                origin.z + f64::from(p[2]),
            ]
        };
        match format {
            PlyFormat::Ascii => {
                let mut line = String::with_capacity(128);
                for i in 0..cloud.len() {
                    use std::fmt::Write as _;
                    line.clear();
                    let p = world(i);
                    let _ = write!(line, "{} {} {}", p[0], p[1], p[2]);
                    if let Some(n) = normals {
                        let _ = write!(line, " {} {} {}", n[i][0], n[i][1], n[i][2]);
                    }
                    if let Some(c) = colors {
                        let _ = write!(line, " {} {} {}", c[i][0], c[i][1], c[i][2]);
                    }
                    if let Some(r) = radii {
                        let _ = write!(line, " {}", r[i]);
                    }
                    line.push('\n');
                    w.write_all(line.as_bytes()).map_err(io_err)?;
                }
            }
            PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                let be = format == PlyFormat::BinaryBigEndian;
                let mut buf = Vec::with_capacity(1 << 20);
                for i in 0..cloud.len() {
                    for c in world(i) {
                        c.put(&mut buf, be);
                    }
                    if let Some(n) = normals {
                        for c in n[i] {
                            c.put(&mut buf, be);
                        }
                    }
                    if let Some(c) = colors {
                        buf.extend_from_slice(&c[i]);
                    }
                    if let Some(r) = radii {
                        r[i].put(&mut buf, be);
                    }
                    if buf.len() >= (1 << 20) - 64 {
                        w.write_all(&buf).map_err(io_err)?;
                        buf.clear();
                    }
                }
                w.write_all(&buf).map_err(io_err)?;
            }
        }
        finish(w, path)
    })
}

/// Writes a triangle mesh as PLY: `double x,y,z` vertices (world coordinates) and faces as
/// `list uchar int vertex_indices`. Every index must be below `vertices_world.len()`.
/// Returns the number of bytes written. The file appears atomically (temporary file + rename).
pub fn write_mesh(
    path: &Path,
    vertices_world: &[[f64; 3]],
    faces: &[[u32; 3]],
    format: PlyFormat,
) -> Result<u64, SceneError> {
    let n = vertices_world.len();
    if let Some((i, f)) = faces
        .iter()
        .enumerate()
        .find(|(_, f)| f.iter().any(|&v| v as usize >= n))
    {
        return Err(ferr(
            path,
            format!("cannot write face {i} {f:?}: there are only {n} vertices"),
        ));
    }
    if u32::try_from(n).is_err() || i32::try_from(n).is_err() {
        return Err(ferr(
            path,
            format!("{n} vertices do not fit 'int' face indices"),
        ));
    }
    write_atomically(path, |file| {
        let mut w = BufWriter::with_capacity(1 << 20, file);
        let io_err = |e| SceneError::io(path, e);
        let head = format!(
            "ply\nformat {} 1.0\ncomment written by splatbench\nelement vertex {n}\n\
             property double x\nproperty double y\nproperty double z\nelement face {}\n\
             property list uchar int vertex_indices\nend_header\n",
            format.header_name(),
            faces.len()
        );
        w.write_all(head.as_bytes()).map_err(io_err)?;
        match format {
            PlyFormat::Ascii => {
                for p in vertices_world {
                    writeln!(w, "{} {} {}", p[0], p[1], p[2]).map_err(io_err)?;
                }
                for f in faces {
                    writeln!(w, "3 {} {} {}", f[0], f[1], f[2]).map_err(io_err)?;
                }
            }
            PlyFormat::BinaryLittleEndian | PlyFormat::BinaryBigEndian => {
                let be = format == PlyFormat::BinaryBigEndian;
                let mut buf = Vec::with_capacity(1 << 16);
                for p in vertices_world {
                    for c in p {
                        c.put(&mut buf, be);
                    }
                    if buf.len() >= (1 << 16) - 32 {
                        w.write_all(&buf).map_err(io_err)?;
                        buf.clear();
                    }
                }
                for f in faces {
                    3u8.put(&mut buf, be);
                    for &v in f {
                        v.put(&mut buf, be);
                    }
                    if buf.len() >= (1 << 16) - 32 {
                        w.write_all(&buf).map_err(io_err)?;
                        buf.clear();
                    }
                }
                w.write_all(&buf).map_err(io_err)?;
            }
        }
        finish(w, path)
    })
}
