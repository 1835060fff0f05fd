//! PLY reader and writer (Stanford polygon format), written for speed and precise errors.
//!
//! # What is read
//! - Formats `ascii 1.0`, `binary_little_endian 1.0` and `binary_big_endian 1.0`; header lines
//!   `comment` / `obj_info` (ignored), `element NAME COUNT`, `property TYPE NAME`,
//!   `property list CTYPE ITYPE NAME`, `end_header`. Every PLY scalar type: `char`/`int8`,
//!   `uchar`/`uint8`, `short`/`int16`, `ushort`/`uint16`, `int`/`int32`, `uint`/`uint32`,
//!   `float`/`float32`, `double`/`float64`. Elements other than `vertex` and `face` (`edge`,
//!   `material`, …) are skipped in all three formats, list properties included (fixed-size
//!   binary elements by a seek), so that what follows the last element can be checked.
//! - The body must end with the last element: bytes after it (binary) or non-blank lines
//!   after it (ascii) are an error naming the byte offset and count, or the line — that is
//!   what a header under-counting its vertices looks like, and reading on would silently
//!   drop them.
//! - A body of ascii text under a `binary_*` header is an error, not garbage coordinates.
//!   The rule: the first 64 bytes of the body (all of it if shorter, and at least 8) hold
//!   only the characters of ascii numbers (`0-9 + - . e E`, space, tab, `\r`, `\n`), at least
//!   one digit and at least one newline. Binary records almost never do: a float whose four
//!   bytes are such characters is below 10⁻⁸ or above 10⁸ in magnitude, and 64 such bytes in
//!   a row with a newline among them do not occur in real binary data.
//! - `vertex`: `x`, `y`, `z` (required, any numeric type, read as `f64`); `nx`, `ny`, `nz`
//!   (optional, renormalised; if any is zero or not finite the column is dropped with a
//!   warning naming the count and the first such vertex — with faces, normals are then
//!   derived from them as below; see [`read_noted`]);
//!   colour from `red`/`green`/`blue`, else `diffuse_red`/`diffuse_green`/`diffuse_blue`, else
//!   `r`/`g`/`b` (all three needed, otherwise the file has no colour): 8-bit and 32-bit integer
//!   values are clamped to 0‥255, 16-bit integer values are divided by 257 (rounded), `float`
//!   / `double` values in 0‥1 are multiplied by 255 and rounded; optional `radius`. Other vertex
//!   properties (alpha, intensity, …) are skipped.
//! - Ascii bodies hold one record per line, as every writer emits them; blank lines are
//!   skipped, `\r\n` line ends accepted.
//! - `face`: the list `vertex_indices` (or `vertex_index`), any integer count/index types.
//!   Polygons are fan-triangulated (`v0 vk vk+1`); faces with fewer than 3 indices add no
//!   triangle (some exporters write them); an index outside `0..vertex_count` is an error
//!   naming the face.
//!
//! # What is derived
//! - Origin = centre of the `f64` bounding box of all vertices (of the inliers' quantile box
//!   when far strays lie outside it, [`crate::framing::inlier_origin`], as the other readers
//!   do); local positions = `(p − origin)` rounded to `f32`, so georeferenced files keep their
//!   precision.
//! - When the file has triangles and no normals: vertex normal = area-weighted sum of the
//!   incident face normals (the unnormalised cross products), normalised. A vertex whose sum
//!   is zero (its faces cancel) takes the normal of its largest incident face; a vertex with no
//!   incident face of non-zero area (unreferenced, or only degenerate faces) gets +Z. Never NaN.
//! - When the file has triangles and no `radius`: vertex radius = the largest minimal
//!   bounding-sphere radius of its incident triangles (QSplat's rule, so the splats of
//!   neighbouring vertices touch). A vertex with no incident triangle of non-zero size takes
//!   the median of the other vertices' radii (unreferenced vertices in meshes are leftovers;
//!   the median keeps the read O(n) where a k-nearest-neighbour search would not). Only when
//!   no vertex has a usable radius (every triangle degenerate) is
//!   [`crate::spacing::knn_spacing`] used, and a last resort of 1/1000 of the bounding-box
//!   diagonal (or 1 for a single point) keeps every radius finite and > 0.
//! - Without faces nothing is invented: a file with positions only gives a cloud with
//!   `Attributes::default()`.
//! - [`PlyOptions::sample`] = `Some(N)` resamples the triangle surface to exactly `N` points,
//!   area-weighted (CDF over triangle areas + binary search), with uniform barycentric
//!   coordinates (`√r₁` trick). Block `b` of 65 536 samples draws from
//!   `Pcg32::stream(seed, b)` (block 0 is `Pcg32::new(seed)`), so the output depends on the
//!   seed only, not on the thread count. Normal = interpolated vertex normals (renormalised)
//!   when the file has normals, else the face normal; colour interpolated when the file has
//!   colours; no radius column (downstream estimates spacing). The origin stays the centre of
//!   the vertex bounding box.
//!
//! # Errors
//! Every problem is a [`SceneError::Format`] naming the file and the header line, body line
//! (ascii; numbered from the top of the file), or element, record index and property
//! (binary): missing `ply` magic, unknown format, no `end_header`, no `vertex` element or a
//! count of 0, missing `x`/`y`/`z`, truncated data ("unexpected end of file in vertex 17 of
//! 100"), too few / too many / non-numeric values on an ascii line, a fractional or
//! out-of-range value for an integer property (`0.302` or `300` for a `uchar`), negative or
//! oversized list counts, face indices out of range, non-finite coordinates, data after the
//! last element, an ascii body under a binary header. Reading never
//! panics, and no allocation is sized by a header count alone: pre-allocation is capped by
//! what the remaining file bytes can hold.
//!
//! # Speed
//! The body is streamed through a 4 MiB buffer (no memory map: the workspace denies `unsafe`).
//! A binary vertex element without list properties is decoded record by record from a
//! precomputed `(offset, type)` layout, monomorphised per endianness. Measured by criterion
//! (`cargo bench -p methods --bench kernels -- scene_io/`, figures in
//! `results/measurements/issue-2-spine.md`).
//!
//! # Writing
//! [`write()`] writes a cloud (world `double x,y,z`; `float nx,ny,nz`, `uchar red,green,blue`,
//! `float radius` only for the columns the cloud has) and [`write_mesh`] a triangle mesh, in any
//! of the three formats, through a temporary file renamed into place, so a failed write never
//! leaves a complete-looking file. Ascii output uses shortest round-trip formatting, so an
//! ascii file holds exactly the values a binary one would.

use std::fs::File;
use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use crate::{PointCloud, SceneError};

mod faces;
mod header;
mod input;
mod mesh;
mod records;
mod vertices;
mod write;

use faces::{face_list, read_faces, skip_element};
use header::{Encoding, parse_header};
use input::Input;
use mesh::{mesh_normals, mesh_radii, sample_surface};
use vertices::{Vertices, read_vertices, select_vertex};
pub use write::{write, write_mesh};

/// The most points `--sample` may resample a mesh to (the result is held in memory).
pub const MAX_SAMPLE: usize = 500_000_000;

/// Reading options.
#[derive(Debug, Clone, Copy, Default)]
pub struct PlyOptions {
    /// Resample the mesh surface to this many points (area-weighted, seeded). Needs faces.
    pub sample: Option<usize>,
    /// Seed for resampling.
    pub seed: u64,
}

/// The body encoding of a PLY file (for [`write()`] and [`write_mesh`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum PlyFormat {
    /// `format ascii 1.0`.
    Ascii,
    /// `format binary_little_endian 1.0`.
    BinaryLittleEndian,
    /// `format binary_big_endian 1.0`.
    BinaryBigEndian,
}

impl PlyFormat {
    fn header_name(self) -> &'static str {
        match self {
            PlyFormat::Ascii => "ascii",
            PlyFormat::BinaryLittleEndian => "binary_little_endian",
            PlyFormat::BinaryBigEndian => "binary_big_endian",
        }
    }
}

fn ferr(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::format(path, msg)
}

/// `s` shortened for an error message.
fn excerpt(s: &str) -> String {
    let mut out: String = s.chars().take(40).collect();
    if s.chars().count() > 40 {
        out.push('…');
    }
    out
}

// ---------------------------------------------------------------------------------------------
// Reading: the entry point
// ---------------------------------------------------------------------------------------------

/// Reads a PLY file into a [`PointCloud`] (see the module docs for what is read, derived and
/// rejected). With `opts.sample = Some(N)` the triangle surface is resampled to exactly `N`
/// points. What was dropped on the way is not reported: use [`read_noted`] where a user
/// should hear of it.
pub fn read(path: &Path, opts: &PlyOptions) -> Result<PointCloud, SceneError> {
    read_noted(path, opts).map(|(cloud, _)| cloud)
}

/// [`read`], with one warning per column dropped (a normal column with a zero or non-finite
/// normal), naming the file, the count and the first such vertex.
pub fn read_noted(path: &Path, opts: &PlyOptions) -> Result<(PointCloud, Vec<String>), SceneError> {
    if opts.sample == Some(0) {
        return Err(ferr(
            path,
            "cannot resample to 0 points: the sample count must be at least 1",
        ));
    }
    if let Some(n) = opts.sample.filter(|&n| n > MAX_SAMPLE) {
        return Err(ferr(
            path,
            format!(
                "cannot resample to {n} points: the limit is {} (held in memory)",
                MAX_SAMPLE
            ),
        ));
    }
    let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
    let file_len = file.metadata().map_err(|e| SceneError::io(path, e))?.len();
    let mut input = Input::new(file, file_len);
    let header = parse_header(&mut input, path)?;

    let vi = header
        .elements
        .iter()
        .position(|e| e.name == "vertex")
        .ok_or_else(|| ferr(path, "the header declares no 'vertex' element"))?;
    let vel = &header.elements[vi];
    if vel.count == 0 {
        return Err(ferr(
            path,
            "element vertex has count 0: the file holds no points",
        ));
    }
    let sel = select_vertex(vel, path)?;
    let fi = header.elements.iter().position(|e| e.name == "face");
    let face = match fi {
        Some(fi) => Some((fi, face_list(&header.elements[fi], path)?)),
        None => None,
    };
    if face.is_some() && vel.count > u64::from(u32::MAX) {
        return Err(ferr(
            path,
            format!(
                "{} vertices with faces: at most {} vertices are supported in a mesh",
                vel.count,
                u32::MAX
            ),
        ));
    }
    if opts.sample.is_some() && face.is_none_or(|(fi, _)| header.elements[fi].count == 0) {
        return Err(ferr(
            path,
            "cannot resample the surface: the file has no faces (it is a point cloud, not a mesh)",
        ));
    }

    let mut verts = None;
    let mut tris = None;
    let mut line_no = header.lines;
    if let Encoding::Binary { big_endian } = header.encoding {
        reject_ascii_body(&mut input, big_endian, path)?;
    }
    for (ei, el) in header.elements.iter().enumerate() {
        if ei == vi {
            verts = Some(read_vertices(
                &mut input,
                &header,
                el,
                &sel,
                &mut line_no,
                path,
            )?);
        } else if let Some((fi, list)) = face
            && ei == fi
        {
            tris = Some(read_faces(
                &mut input,
                &header,
                el,
                list,
                vel.count,
                &mut line_no,
                path,
            )?);
        } else {
            skip_element(&mut input, &header, el, &mut line_no, path)?;
        }
    }
    check_body_end(&mut input, &header, line_no, path)?;
    let mut verts = verts.ok_or_else(|| ferr(path, "the vertex element could not be read"))?;
    let tris = tris.unwrap_or_default();
    let mut warnings = Vec::new();
    if let Some((i, n)) = verts.first_bad {
        warnings.push(format!(
            "{}: normals dropped: {} of {} vertices have a zero or non-finite normal (first: \
             vertex {i}, ({}, {}, {})){}",
            path.display(),
            verts.bad_normals,
            verts.pos.len(),
            n[0],
            n[1],
            n[2],
            if tris.is_empty() {
                ""
            } else {
                "; normals are derived from the faces instead"
            }
        ));
        verts.normals = None;
    }
    Ok((assemble(path, verts, &tris, opts)?, warnings))
}

/// Characters of an ascii PLY body of numbers.
fn ascii_number_byte(b: u8) -> bool {
    b.is_ascii_digit()
        || matches!(
            b,
            b'+' | b'-' | b'.' | b'e' | b'E' | b' ' | b'\t' | b'\r' | b'\n'
        )
}

/// Rejects an ascii body under a binary header (the rule is in the module docs).
fn reject_ascii_body(input: &mut Input, big_endian: bool, path: &Path) -> Result<(), SceneError> {
    const WINDOW: usize = 64;
    let want = usize::try_from(input.remaining()).map_or(WINDOW, |r| r.min(WINDOW));
    if want < 8 {
        return Ok(());
    }
    input.fill(want).map_err(|e| SceneError::io(path, e))?;
    let head = &input.avail()[..want.min(input.avail().len())];
    if head.iter().all(|&b| ascii_number_byte(b))
        && head.contains(&b'\n')
        && head.iter().any(u8::is_ascii_digit)
    {
        let first = head.split(|&b| b == b'\n').next().unwrap_or_default();
        return Err(ferr(
            path,
            format!(
                "the header declares format {} but the body (from byte {}) is ascii text \
                 ('{}'): the format line is wrong",
                if big_endian {
                    "binary_big_endian"
                } else {
                    "binary_little_endian"
                },
                input.position(),
                excerpt(String::from_utf8_lossy(first).trim_end())
            ),
        ));
    }
    Ok(())
}

/// After the last element: nothing but the end of the file (ascii: blank lines).
fn check_body_end(
    input: &mut Input,
    header: &header::Header,
    mut line_no: u64,
    path: &Path,
) -> Result<(), SceneError> {
    let last = header
        .elements
        .last()
        .map_or_else(|| "header".to_owned(), |e| format!("element '{}'", e.name));
    match header.encoding {
        Encoding::Ascii => {
            if let Some((n, line)) = records::next_ascii_line(input, &mut line_no, path)? {
                return Err(ferr(
                    path,
                    format!(
                        "line {n}: '{}' follows the last {last} (the header's counts are too \
                         small, or the file has text after its data)",
                        excerpt(line.trim())
                    ),
                ));
            }
        }
        Encoding::Binary { .. } => {
            let extra = input.remaining();
            if extra > 0 {
                return Err(ferr(
                    path,
                    format!(
                        "{extra} bytes follow the last {last}, from byte {} to the end of the \
                         file (the header's counts are too small, or the file has data after \
                         its elements)",
                        input.position()
                    ),
                ));
            }
        }
    }
    Ok(())
}

/// Maps a [`SceneError::InvalidCloud`] from validation to a format error naming the file.
fn cloud_err(path: &Path, e: SceneError) -> SceneError {
    match e {
        SceneError::InvalidCloud(m) => ferr(path, format!("invalid vertex data: {m}")),
        other => other,
    }
}

fn assemble(
    path: &Path,
    v: Vertices,
    tris: &[[u32; 3]],
    opts: &PlyOptions,
) -> Result<PointCloud, SceneError> {
    if let Some(i) = v.pos.iter().position(|p| !p.iter().all(|c| c.is_finite())) {
        let p = v.pos[i];
        return Err(ferr(
            path,
            format!(
                "vertex {i}: position ({}, {}, {}) is not finite",
                p[0], p[1], p[2]
            ),
        ));
    }
    let (lo, hi) = v
        .pos
        .par_iter()
        .fold_with(
            ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(lo, hi), p| {
                (
                    [lo[0].min(p[0]), lo[1].min(p[1]), lo[2].min(p[2])],
                    [hi[0].max(p[0]), hi[1].max(p[1]), hi[2].max(p[2])],
                )
            },
        )
        .reduce(
            || ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]),
            |(a, b), (c, d)| {
                (
                    [a[0].min(c[0]), a[1].min(c[1]), a[2].min(c[2])],
                    [b[0].max(d[0]), b[1].max(d[1]), b[2].max(d[2])],
                )
            },
        );
    let (lo, hi) = (DVec3::from(lo), DVec3::from(hi));
    let origin = crate::framing::inlier_origin(&v.pos, lo, hi).unwrap_or((lo + hi) * 0.5);

    if let Some(n) = opts.sample {
        return sample_surface(path, &v, tris, origin, n, opts.seed);
    }

    let o = origin;
    let local: Vec<[f32; 3]> = v
        .pos
        .par_iter()
        .map(|p| {
            [
                (p[0] - o.x) as f32,
                (p[1] - o.y) as f32,
                (p[2] - o.z) as f32,
            ]
        })
        .collect();
    let Vertices {
        pos,
        normals,
        colors,
        radii,
        ..
    } = v;
    let (normals, radii) = if tris.is_empty() {
        (normals, radii)
    } else {
        let normals = match normals {
            Some(n) => n,
            None => mesh_normals(&pos, tris),
        };
        let radii = match radii {
            Some(r) => r,
            None => mesh_radii(&pos, tris, &local, (hi - lo).length()),
        };
        (Some(normals), Some(radii))
    };
    drop(pos);
    PointCloud::new(
        origin,
        local.into(),
        normals.map(Into::into),
        colors.map(Into::into),
        radii.map(Into::into),
    )
    .map_err(|e| cloud_err(path, e))
}
