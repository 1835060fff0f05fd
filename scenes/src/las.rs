//! LAS / LAZ reader and writer (ASPRS LAS through the `las` crate, LAZ with its `laz` feature).
//!
//! # Reading ([`read`])
//! - Any LAS version and point format the `las` crate reads; `.laz` (LASzip) files are detected
//!   from the header, not the extension.
//! - Positions are decoded to world `f64` and stored as `f32` relative to an origin. The origin
//!   is the centre of the header bounds. When those bounds are not finite, or do not contain
//!   every point (within two scale units), the header is wrong: the file is read a second time
//!   with the origin at the centre of the data's own bounding box, so precision never depends
//!   on a writer having filled the header correctly. When the file has far outliers (samples
//!   beyond half the robust extent of the 0.1–99.9 % quantile box, [`crate::framing`]), the
//!   file is read again with the origin at the centre of that box: two stray points at
//!   (0, 0, 0) beside a UTM tile would otherwise put the origin 3,000 km from the tile, where
//!   `f32` keeps 0.25 m.
//! - Colour column only when the point format has RGB (formats 2, 3, 5, 7, 8, 10). LAS stores
//!   16-bit channels; if every channel value in the file is ≤ 255 the writer stored 8-bit
//!   values and they are kept as they are, otherwise the high byte is taken (`v >> 8`, exact
//!   for the usual `c × 257` or `c × 256` scalings). No normals, no radii (downstream estimates
//!   spacing).
//! - Intensity and classification (every point format has both) are read only when asked
//!   ([`read_with`], for `--shading intensity|classification`, see [`crate::scalar`]).
//! - Points are streamed in batches of 65 536 through one reused `las::PointData` buffer and
//!   decoded column-wise; no `las::Point` is built. Pre-allocation is capped by what the file
//!   size can hold.
//! - Errors are [`SceneError`]s naming the file: unreadable header, a file with 0 points,
//!   truncated point data (naming the batch of points), non-finite coordinates (naming the
//!   point). Before the `las` crate sees the file, the header fields it and `laz` allocate or
//!   compute by are checked against the file's size (`las_check.rs`: the LAZ chunk table and
//!   layer sizes, the laszip items, the first EVLR, point count × record length), as are the
//!   scale factors and trailing point records; each failure names the field and the byte. A
//!   panic inside the crates (the `laz` decoder asserts on some corrupted chunks) is caught
//!   and returned as an error naming the file.
//!
//! # Writing ([`write()`])
//! - LAS 1.2 (1.4 above 2³² − 1 points), point format 2 (with RGB, each 8-bit channel × 257 so
//!   that 255 ↦ 65535) when the cloud has colours, else format 0. Return number and number of
//!   returns are 1. Normals and radii are not stored (LAS has no place for them).
//! - Offset = the cloud's origin. Scale = the smallest power of ten ≥ `span / 2³⁰` and ≥ 10⁻⁷,
//!   where `span` = twice the largest absolute local coordinate, so every quantised value fits
//!   an `i32` with a factor 2 to spare and the quantisation error (scale / 2) is as small as the
//!   format allows: 10 µm-scale for a 10 km terrain, ≤ 0.5 mm up to ≈ 1000 km. See
//!   [`choose_scale`].
//! - LAZ compression when the extension is `.laz` (case-insensitive).
//! - The file is written to a temporary file in the same directory and renamed into place once
//!   complete and flushed, so a failure never leaves a complete-looking file.

use std::fs::File;
use std::io::BufWriter;
use std::path::Path;

use glam::DVec3;
use las::point::Format;
use las::{Builder, Color, Point, PointDataBuilder, Reader, Transform, Vector, Writer};

use crate::atomic::{finish, write_atomically};
use crate::{PointCloud, Scalar, SceneError};

/// Points decoded per batch.
const BATCH: u64 = 1 << 16;

fn ferr(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::format(path, msg)
}

fn las_err(path: &Path, e: las::Error) -> SceneError {
    match e {
        las::Error::Io(e) => SceneError::io(path, e),
        other => ferr(path, other.to_string()),
    }
}

fn open(path: &Path) -> Result<Reader, SceneError> {
    let file = File::open(path).map_err(|e| SceneError::io(path, e))?;
    Reader::new(std::io::BufReader::with_capacity(1 << 20, file))
        .map_err(|e| ferr(path, format!("not a readable LAS/LAZ file: {e}")))
}

/// One pass over the points.
struct Pass {
    local: Vec<[f32; 3]>,
    rgb: Option<Vec<[u16; 3]>>,
    /// The scalar asked for, one per stored point.
    scalar: Option<Vec<f32>>,
    lo: DVec3,
    hi: DVec3,
    /// An even stride of at most [`SAMPLE_MAX`] world positions, for
    /// [`crate::framing::inlier_origin`].
    sample: Vec<[f64; 3]>,
    /// Every colour channel of the file is ≤ 255 (8-bit values stored as they are).
    eight_bit: bool,
}

/// Where [`read_pass`] puts the points it stores.
enum Store<'a> {
    /// Nowhere (bounds and sample only).
    None,
    /// In the pass's vectors.
    Memory,
    /// Streamed to a column writer, colours converted with the given 8-bit flag.
    Columns(&'a mut crate::colfile::ColumnWriter, bool),
}

/// At most this many world positions are kept per pass to find far outliers.
const SAMPLE_MAX: u64 = 1 << 16;

/// Reads every point; stores local positions relative to `origin` if `store`.
fn read_pass(
    path: &Path,
    origin: DVec3,
    mut to: Store<'_>,
    want: Option<Scalar>,
) -> Result<Pass, SceneError> {
    let store = matches!(to, Store::Memory);
    let streamed = matches!(to, Store::Columns(..));
    let mut reader = open(path)?;
    let header = reader.header();
    let n = header.number_of_points();
    let format = *header.point_format();
    let has_color = format.has_color;
    let file_len = std::fs::metadata(path)
        .map_err(|e| SceneError::io(path, e))?
        .len();
    // Compressed files hold more points than their size / record length; 16× covers LASzip.
    let record = u64::from(format.len()).max(1);
    let per_byte = if format.is_compressed { 16 } else { 1 };
    let cap = if store {
        usize::try_from(n.min((file_len / record + 1).saturating_mul(per_byte))).unwrap_or(0)
    } else {
        0
    };
    let mut local = Vec::with_capacity(cap);
    let mut rgb = (store && has_color).then(|| Vec::with_capacity(cap));
    let mut scalar = want.filter(|_| store).map(|_| Vec::with_capacity(cap));
    let mut lo = DVec3::INFINITY;
    let mut hi = DVec3::NEG_INFINITY;
    let stride = n.div_ceil(SAMPLE_MAX).max(1);
    let mut sample = Vec::with_capacity(n.min(SAMPLE_MAX) as usize);
    let mut pd = PointDataBuilder::new().for_header(reader.header()).build();
    let mut done: u64 = 0;
    let mut eight_bit = true;
    let (mut block_pos, mut block_rgb): (Vec<[f32; 3]>, Vec<[u8; 3]>) = (Vec::new(), Vec::new());
    while done < n {
        let got = reader.fill_points(BATCH, &mut pd).map_err(|e| {
            ferr(
                path,
                format!(
                    "reading points {done}..{} of {n}: {e}",
                    (done + BATCH).min(n)
                ),
            )
        })?;
        if got == 0 {
            break;
        }
        for (j, ((x, y), z)) in pd.x().zip(pd.y()).zip(pd.z()).enumerate() {
            let p = DVec3::new(x, y, z);
            if !p.is_finite() {
                return Err(ferr(
                    path,
                    format!(
                        "point {}: position ({x}, {y}, {z}) is not finite",
                        done + j as u64
                    ),
                ));
            }
            lo = lo.min(p);
            hi = hi.max(p);
            if (done + j as u64).is_multiple_of(stride) {
                sample.push(p.to_array());
            }
            if store || streamed {
                let l = p - origin;
                let l = [l.x as f32, l.y as f32, l.z as f32];
                if store {
                    local.push(l);
                } else {
                    block_pos.push(l);
                }
            }
        }
        if let Some(cols) = pd.rgb() {
            if let Some(out) = rgb.as_mut() {
                out.extend(cols.map(|(r, g, b)| [r, g, b]));
            } else if let Store::Columns(_, eight) = to {
                block_rgb.extend(cols.map(|(r, g, b)| [r, g, b].map(|v| narrow(v, eight))));
            } else {
                eight_bit &= cols
                    .into_iter()
                    .all(|(r, g, b)| r <= 255 && g <= 255 && b <= 255);
            }
        }
        if let Store::Columns(w, _) = &mut to {
            w.push(
                &block_pos,
                None,
                has_color.then_some(block_rgb.as_slice()),
                None,
            )?;
            block_pos.clear();
            block_rgb.clear();
        }
        if let Some(out) = scalar.as_mut() {
            match want {
                Some(Scalar::Intensity) => out.extend(pd.intensity().map(f32::from)),
                Some(Scalar::Classification) => out.extend(pd.classification().map(f32::from)),
                None => {}
            }
        }
        done += got;
    }
    if done < n {
        return Err(ferr(
            path,
            format!("the header declares {n} points but only {done} could be read"),
        ));
    }
    if let Some(c) = &rgb
        && c.len() != local.len()
    {
        return Err(ferr(
            path,
            format!("{} colours for {} points", c.len(), local.len()),
        ));
    }
    if let Some(v) = &scalar
        && v.len() != local.len()
    {
        return Err(ferr(
            path,
            format!("{} scalar values for {} points", v.len(), local.len()),
        ));
    }
    if let Some(c) = &rgb {
        eight_bit = c.iter().all(|c| c.iter().all(|&v| v <= 255));
    }
    Ok(Pass {
        local,
        rgb,
        scalar,
        lo,
        hi,
        sample,
        eight_bit,
    })
}

/// A 16-bit LAS colour channel as 8 bits: as it is in a file of 8-bit values, else its high
/// byte.
fn narrow(v: u16, eight_bit: bool) -> u8 {
    if eight_bit { v as u8 } else { (v >> 8) as u8 }
}

/// Reads a LAS or LAZ file into a [`PointCloud`] (see the module docs).
pub fn read(path: &Path) -> Result<PointCloud, SceneError> {
    read_with(path, None).map(|(cloud, _)| cloud)
}

/// [`read`], and the per-point values of `want` (intensity or classification) when asked.
pub fn read_with(
    path: &Path,
    want: Option<Scalar>,
) -> Result<(PointCloud, Option<Vec<f32>>), SceneError> {
    crate::las_check::check(path)?;
    crate::las_check::contained(path, || read_checked(path, want))
}

/// What the header says about where the points are.
struct HeaderFrame {
    n: u64,
    /// Centre of the header bounds (zero when they are unusable).
    guess: DVec3,
    header_ok: bool,
    hlo: DVec3,
    hhi: DVec3,
    scale: DVec3,
}

fn header_frame(path: &Path) -> Result<HeaderFrame, SceneError> {
    let reader = open(path)?;
    let header = reader.header();
    let n = header.number_of_points();
    if n == 0 {
        return Err(ferr(
            path,
            "the file holds no points (the header declares 0)",
        ));
    }
    let b = header.bounds();
    let t = header.transforms();
    let (hlo, hhi) = (
        DVec3::new(b.min.x, b.min.y, b.min.z),
        DVec3::new(b.max.x, b.max.y, b.max.z),
    );
    let scale = DVec3::new(t.x.scale.abs(), t.y.scale.abs(), t.z.scale.abs());
    let header_ok = hlo.is_finite() && hhi.is_finite() && hlo.cmple(hhi).all();
    let guess = if header_ok {
        (hlo + hhi) * 0.5
    } else {
        DVec3::ZERO
    };
    Ok(HeaderFrame {
        n,
        guess,
        header_ok,
        hlo,
        hhi,
        scale,
    })
}

impl HeaderFrame {
    /// The origin the points are stored relative to, given the first pass over them (read
    /// relative to `guess`): `None` keeps `guess` (the first pass's positions stand),
    /// `Some(o)` asks for a pass relative to `o` (see the module docs).
    fn origin(&self, first: &Pass) -> Option<DVec3> {
        let contains = |lo: DVec3, hi: DVec3| {
            let tol = 2.0 * self.scale + 1e-9 * self.hlo.abs().max(self.hhi.abs());
            self.header_ok && (lo - self.hlo).cmpge(-tol).all() && (self.hhi - hi).cmpge(-tol).all()
        };
        match crate::framing::inlier_origin(&first.sample, first.lo, first.hi) {
            // Far outliers: the origin goes to the inliers' centre, so they keep their
            // precision.
            Some(origin) => Some(origin),
            None if contains(first.lo, first.hi) => None,
            None => Some((first.lo + first.hi) * 0.5),
        }
    }
}

/// [`read_with`] after the header checks, with panics of the crates not yet contained.
fn read_checked(
    path: &Path,
    want: Option<Scalar>,
) -> Result<(PointCloud, Option<Vec<f32>>), SceneError> {
    let h = header_frame(path)?;
    let first = read_pass(
        path,
        h.guess,
        if h.header_ok {
            Store::Memory
        } else {
            Store::None
        },
        want,
    )?;
    let (origin, pass) = match h.origin(&first) {
        None => (h.guess, first),
        Some(origin) => (origin, read_pass(path, origin, Store::Memory, want)?),
    };
    let eight_bit = pass.eight_bit;
    let colors = pass.rgb.map(|rgb| {
        rgb.into_iter()
            .map(|c| c.map(|v| narrow(v, eight_bit)))
            .collect::<Vec<[u8; 3]>>()
    });
    let cloud = PointCloud::new(
        origin,
        pass.local.into(),
        None,
        colors.map(Into::into),
        None,
    )
    .map_err(|e| match e {
        SceneError::InvalidCloud(m) => ferr(path, format!("invalid point data: {m}")),
        other => other,
    })?;
    Ok((cloud, pass.scalar))
}

/// The number of points the header of the LAS/LAZ file `path` declares (after the header
/// checks of [`read`]).
pub fn point_count(path: &Path) -> Result<u64, SceneError> {
    crate::las_check::check(path)?;
    crate::las_check::contained(path, || Ok(open(path)?.header().number_of_points()))
}

/// Reads a LAS or LAZ file into the column file `out` ([`crate::colfile`]) and opens it
/// mapped: the same cloud as [`read`] (origin, positions, colours), but streamed, so a file
/// larger than memory can be read. One pass finds the bounds, the far outliers and whether
/// the colours are 8-bit; a second writes the columns.
pub fn read_to_columns(path: &Path, out: &Path) -> Result<PointCloud, SceneError> {
    crate::las_check::check(path)?;
    crate::las_check::contained(path, || {
        let h = header_frame(path)?;
        let first = read_pass(path, h.guess, Store::None, None)?;
        let origin = h.origin(&first).unwrap_or(h.guess);
        let has_color = open(path)?.header().point_format().has_color;
        let attrs = crate::Attributes {
            colors: has_color,
            ..Default::default()
        };
        let mut w = crate::colfile::ColumnWriter::create(out, attrs, origin, h.n)?;
        read_pass(path, origin, Store::Columns(&mut w, first.eight_bit), None)?;
        w.finish()
    })
}

/// The LAS coordinate scale [`write()`] uses for a cloud whose local coordinates span `span`
/// (twice the largest absolute local coordinate): the smallest power of ten that is
/// ≥ `span / 2³⁰` and ≥ 10⁻⁷. Quantised values then stay within ±2²⁹ (an `i32` with room to
/// spare) and the quantisation error is `scale / 2`.
pub fn choose_scale(span: f64) -> f64 {
    let raw = span / f64::from(1u32 << 30);
    let k = if raw.is_finite() && raw > 0.0 {
        (raw.log10().ceil() as i32).max(-7)
    } else {
        -7
    };
    let pow10 = |k: i32| {
        if k < 0 {
            1.0 / 10f64.powi(-k)
        } else {
            10f64.powi(k)
        }
    };
    // Guard against log10 rounding: make sure the scale really is ≥ raw.
    let s = pow10(k);
    if s < raw { pow10(k + 1) } else { s }
}

/// Writes a cloud as LAS (or LAZ when the extension is `.laz`); returns the bytes written.
/// See the module docs for the point format, scale and offset.
pub fn write(path: &Path, cloud: &PointCloud) -> Result<u64, SceneError> {
    let compress = path
        .extension()
        .and_then(|e| e.to_str())
        .is_some_and(|e| e.eq_ignore_ascii_case("laz"));
    let origin = cloud.origin();
    let b = cloud.bounds();
    let reach = b.min.abs().max(b.max.abs()).max_element();
    let scale = choose_scale(2.0 * f64::from(reach));
    let colors = cloud.colors();
    let n = cloud.len();
    let version = if u32::try_from(n).is_ok() {
        (1, 2)
    } else {
        (1, 4)
    };
    let mut builder = Builder::from(version);
    builder.point_format =
        Format::new(if colors.is_some() { 2 } else { 0 }).map_err(|e| las_err(path, e))?;
    builder.point_format.is_compressed = compress;
    builder.transforms = Vector {
        x: Transform {
            scale,
            offset: origin.x,
        },
        y: Transform {
            scale,
            offset: origin.y,
        },
        z: Transform {
            scale,
            offset: origin.z,
        },
    };
    builder.generating_software = "splatbench".into();
    builder.system_identifier = "splatbench".into();
    let header = builder.into_header().map_err(|e| las_err(path, e))?;
    write_atomically(path, |file| {
        let mut w = Writer::new(BufWriter::with_capacity(1 << 20, file), header)
            .map_err(|e| las_err(path, e))?;
        let mut start = 0usize;
        while start < n {
            let end = (start + BATCH as usize).min(n);
            let points = (start..end).map(|i| {
                let p = cloud.world_position(i);
                Point {
                    x: p.x,
                    y: p.y,
                    z: p.z,
                    return_number: 1,
                    number_of_returns: 1,
                    color: colors.map(|c| Color {
                        red: u16::from(c[i][0]) * 257,
                        green: u16::from(c[i][1]) * 257,
                        blue: u16::from(c[i][2]) * 257,
                    }),
                    ..Default::default()
                }
            });
            let pd = PointDataBuilder::new()
                .for_header(w.header())
                .build_from_points(points)
                .map_err(|e| las_err(path, e))?;
            w.write_points(&pd).map_err(|e| las_err(path, e))?;
            start = end;
        }
        let inner = w.into_inner().map_err(|e| las_err(path, e))?;
        finish(inner, path)
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scale_is_a_power_of_ten_with_room() {
        assert_eq!(choose_scale(0.0), 1e-7);
        assert_eq!(choose_scale(1.0), 1e-7);
        assert_eq!(choose_scale(1000.0), 1e-6);
        assert_eq!(choose_scale(10_000.0), 1e-5);
        assert_eq!(choose_scale(1.0e6), 1e-3);
        for span in [3.7, 250.0, 8.0e4, 3.0e6, 1.0e9] {
            let s = choose_scale(span);
            assert!(span / s <= f64::from(1u32 << 30), "{span} {s}");
            assert!(
                span / s > f64::from(1u32 << 30) / 10.0 || s == 1e-7,
                "{span} {s}"
            );
        }
    }
}
