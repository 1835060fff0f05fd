//! E57 reader (ASTM E2807, through the `e57` crate).
//!
//! - Every scan (`data3D` entry) of the file goes into one cloud, each moved into the file's
//!   frame by its pose (rotation quaternion + translation), as a registered multi-scan
//!   project is meant to be seen.
//! - Cartesian scans are read as they are; spherical scans (range, azimuth, elevation) are
//!   converted to cartesian (`r cos e cos a, r cos e sin a, r sin e`). A point whose coordinate is marked invalid, or only
//!   a direction (no range), is dropped and counted in [`E57::dropped`].
//! - Colour: each channel is mapped from the scan's colour limits (or its field's type range)
//!   to 0–255 and rounded. A cloud has colour for every sample or none: when a scan has no
//!   colour, or a kept point's colour is marked invalid, the colour column is dropped and a
//!   warning says why.
//! - Intensity ([`E57::intensity`], raw values, for `--shading intensity`) when every scan
//!   has the field and no kept point marks it invalid; otherwise none. Row/column indices,
//!   timestamps and images are not used.
//!
//! Positions are decoded in `f64` and stored as `f32` relative to the centre of their bounds.
//! Errors name the file and, for data errors, the scan.

use std::path::Path;

use crate::{PointCloud, SceneError};

/// An E57 file read into one cloud.
#[derive(Debug)]
pub struct E57 {
    /// The valid points of every scan, in the file's frame.
    pub cloud: PointCloud,
    /// Scans read.
    pub scans: usize,
    /// Points dropped for an invalid or direction-only coordinate.
    pub dropped: usize,
    /// The kept points' intensities, when every scan has them.
    pub intensity: Option<Vec<f32>>,
    /// What was dropped or ignored, one sentence each, naming the file and the attribute.
    pub warnings: Vec<String>,
}

fn ferr(path: &Path, msg: impl Into<String>) -> SceneError {
    SceneError::format(path, msg)
}

/// Reads every scan of an E57 file.
pub fn read(path: &Path) -> Result<E57, SceneError> {
    // Stat the file first so a missing file is an I/O error, not a format error.
    let file_len = std::fs::metadata(path)
        .map_err(|e| SceneError::io(path, e))?
        .len();
    let mut reader = e57::E57Reader::from_file(path)
        .map_err(|e| ferr(path, format!("not a readable E57 file: {e}")))?;
    let scans = reader.pointclouds();
    if scans.is_empty() {
        return Err(ferr(
            path,
            "the file holds no point cloud (no data3D entry)",
        ));
    }
    let declared: u64 = scans.iter().map(|s| s.records).sum();
    // A point takes at least one byte on disk: never reserve more than the file can hold.
    let cap = declared.min(file_len).min(1 << 26) as usize;
    let mut world: Vec<[f64; 3]> = Vec::with_capacity(cap);
    let mut colors: Option<Vec<[u8; 3]>> = Some(Vec::with_capacity(cap));
    let mut intensity: Option<Vec<f32>> = Some(Vec::with_capacity(cap));
    let mut warnings = Vec::new();
    let mut dropped = 0usize;
    for (k, scan) in scans.iter().enumerate() {
        let name = match &scan.name {
            Some(n) => format!("scan {k} ('{n}')"),
            None => format!("scan {k}"),
        };
        let layout = Layout::new(scan).map_err(|m| ferr(path, format!("{name}: {m}")))?;
        if colors.is_some() && layout.rgb.is_none() {
            warnings.push(format!(
                "{}: colour dropped: {name} has no colour",
                path.display()
            ));
            colors = None;
        }
        if layout.intensity.is_none() {
            intensity = None;
        }
        let pose = Pose::of(scan);
        let points = reader
            .pointcloud_raw(scan)
            .map_err(|e| ferr(path, format!("{name}: {e}")))?;
        let mut invalid_colour = 0usize;
        for (i, raw) in points.enumerate() {
            let bad = |e: e57::Error| ferr(path, format!("{name}, point {i}: {e}"));
            let raw = raw.map_err(bad)?;
            let Some(p) = layout.position(&raw).map_err(bad)? else {
                dropped += 1;
                continue;
            };
            world.push(pose.apply(p));
            if let Some(out) = intensity.as_mut() {
                match layout.intensity(&raw).map_err(bad)? {
                    Some(v) => out.push(v as f32),
                    None => intensity = None,
                }
            }
            if let Some(col) = colors.as_mut() {
                match layout.colour(&raw).map_err(bad)? {
                    Some(c) => col.push(c),
                    None => invalid_colour += 1,
                }
            }
        }
        if invalid_colour > 0 && colors.is_some() {
            warnings.push(format!(
                "{}: colour dropped: {invalid_colour} valid points of {name} have an invalid colour",
                path.display()
            ));
            colors = None;
        }
    }
    if world.is_empty() {
        return Err(ferr(
            path,
            format!("none of the {declared} points has a valid coordinate (nothing to draw)"),
        ));
    }
    let (origin, local) = crate::cloud::centred(&world);
    drop(world);
    let cloud = PointCloud::new(origin, local.into(), None, colors.map(Into::into), None)
        .map_err(|e| ferr(path, e.to_string()))?;
    Ok(E57 {
        cloud,
        scans: scans.len(),
        dropped,
        intensity,
        warnings,
    })
}

/// Where each field of a scan's raw records is, and how to read it.
///
/// Read from the raw records rather than through the crate's `pointcloud_simple`, whose
/// iterator (0.11.13) returns a spurious "logic error" for the first point of a scan with a
/// `cartesianInvalidState` field.
struct Layout {
    proto: Vec<e57::Record>,
    cartesian: Option<[usize; 3]>,
    cartesian_invalid: Option<usize>,
    spherical: Option<[usize; 3]>,
    spherical_invalid: Option<usize>,
    rgb: Option<[(usize, f64, f64); 3]>,
    colour_invalid: Option<usize>,
    intensity: Option<usize>,
    intensity_invalid: Option<usize>,
}

impl Layout {
    fn new(scan: &e57::PointCloud) -> Result<Self, String> {
        use e57::RecordName as N;
        let proto = scan.prototype.clone();
        let find = |n: N| proto.iter().position(|r| r.name == n);
        let triple = |a: N, b: N, c: N| match (find(a), find(b), find(c)) {
            (Some(a), Some(b), Some(c)) => Some([a, b, c]),
            _ => None,
        };
        let cartesian = triple(N::CartesianX, N::CartesianY, N::CartesianZ);
        let spherical = triple(
            N::SphericalRange,
            N::SphericalAzimuth,
            N::SphericalElevation,
        );
        if cartesian.is_none() && spherical.is_none() {
            return Err(
                "no cartesian (x y z) or spherical (range azimuth elevation) fields".into(),
            );
        }
        let limits = scan.color_limits.as_ref();
        let channel =
            |n: N, lim: Option<(&Option<e57::RecordValue>, &Option<e57::RecordValue>)>| {
                let i = find(n)?;
                let dt = &proto[i].data_type;
                let from_limits = lim.and_then(|(lo, hi)| {
                    Some((lo.as_ref()?.to_f64(dt).ok()?, hi.as_ref()?.to_f64(dt).ok()?))
                });
                let (lo, hi) = from_limits.unwrap_or_else(|| type_range(dt));
                Some((i, lo, hi))
            };
        let rgb = match (
            channel(N::ColorRed, limits.map(|l| (&l.red_min, &l.red_max))),
            channel(N::ColorGreen, limits.map(|l| (&l.green_min, &l.green_max))),
            channel(N::ColorBlue, limits.map(|l| (&l.blue_min, &l.blue_max))),
        ) {
            (Some(r), Some(g), Some(b)) => Some([r, g, b]),
            _ => None,
        };
        Ok(Self {
            cartesian_invalid: find(N::CartesianInvalidState),
            spherical_invalid: find(N::SphericalInvalidState),
            colour_invalid: find(N::IsColorInvalid),
            intensity: find(N::Intensity),
            intensity_invalid: find(N::IsIntensityInvalid),
            cartesian,
            spherical,
            rgb,
            proto,
        })
    }

    fn f64(&self, raw: &[e57::RecordValue], i: usize) -> Result<f64, e57::Error> {
        raw[i].to_f64(&self.proto[i].data_type)
    }

    fn state(&self, raw: &[e57::RecordValue], i: Option<usize>) -> Result<i64, e57::Error> {
        match i {
            Some(i) => raw[i].to_i64(&self.proto[i].data_type),
            None => Ok(0),
        }
    }

    /// The point's cartesian position in its scan's frame, if it has a valid one: the
    /// cartesian fields when their state is 0 (1 is a direction, 2 invalid), else the
    /// spherical ones when their state is 0 (1 means the range is not meaningful).
    fn position(&self, raw: &[e57::RecordValue]) -> Result<Option<[f64; 3]>, e57::Error> {
        if raw.len() != self.proto.len() {
            return Err(e57::Error::Invalid {
                desc: format!("{} values for {} fields", raw.len(), self.proto.len()),
                source: None,
            });
        }
        if let Some([x, y, z]) = self.cartesian
            && self.state(raw, self.cartesian_invalid)? == 0
        {
            let p = [self.f64(raw, x)?, self.f64(raw, y)?, self.f64(raw, z)?];
            return Ok(p.iter().all(|c| c.is_finite()).then_some(p));
        }
        if let Some([r, a, e]) = self.spherical
            && self.state(raw, self.spherical_invalid)? == 0
        {
            let (r, a, e) = (self.f64(raw, r)?, self.f64(raw, a)?, self.f64(raw, e)?);
            let p = [r * e.cos() * a.cos(), r * e.cos() * a.sin(), r * e.sin()];
            return Ok(p.iter().all(|c| c.is_finite()).then_some(p));
        }
        Ok(None)
    }

    /// The point's colour as 8 bits per channel (each channel mapped from its scan's colour
    /// limits, or its field's type range, to 0–255), or `None` when marked invalid.
    fn colour(&self, raw: &[e57::RecordValue]) -> Result<Option<[u8; 3]>, e57::Error> {
        let Some(rgb) = self.rgb else {
            return Ok(None);
        };
        if self.state(raw, self.colour_invalid)? != 0 {
            return Ok(None);
        }
        let mut out = [0u8; 3];
        for (o, (i, lo, hi)) in out.iter_mut().zip(rgb) {
            let v = self.f64(raw, i)?;
            let t = if hi > lo { (v - lo) / (hi - lo) } else { 0.0 };
            *o = (t.clamp(0.0, 1.0) * 255.0).round() as u8;
        }
        Ok(Some(out))
    }
}

impl Layout {
    /// The point's raw intensity, or `None` when the scan has none or marks it invalid.
    fn intensity(&self, raw: &[e57::RecordValue]) -> Result<Option<f64>, e57::Error> {
        let Some(i) = self.intensity else {
            return Ok(None);
        };
        if self.state(raw, self.intensity_invalid)? != 0 {
            return Ok(None);
        }
        self.f64(raw, i).map(Some)
    }
}

/// The value range of a field's type: its declared bounds, or 0–1 for an unbounded float
/// (the E57 convention for normalised colour).
fn type_range(dt: &e57::RecordDataType) -> (f64, f64) {
    use e57::RecordDataType as T;
    match *dt {
        T::Integer { min, max } => (min as f64, max as f64),
        T::ScaledInteger {
            min,
            max,
            scale,
            offset,
        } => (min as f64 * scale + offset, max as f64 * scale + offset),
        T::Single {
            min: Some(lo),
            max: Some(hi),
        } => (f64::from(lo), f64::from(hi)),
        T::Double {
            min: Some(lo),
            max: Some(hi),
        } => (lo, hi),
        _ => (0.0, 1.0),
    }
}

/// A scan's pose: rotation (from its unit quaternion) and translation into the file's frame.
struct Pose {
    r: [[f64; 3]; 3],
    t: [f64; 3],
}

impl Pose {
    fn of(scan: &e57::PointCloud) -> Self {
        let Some(tf) = &scan.transform else {
            return Self {
                r: [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
                t: [0.0; 3],
            };
        };
        let e57::Quaternion { w, x, y, z } = tf.rotation;
        Self {
            r: [
                [
                    w * w + x * x - y * y - z * z,
                    2.0 * (x * y - w * z),
                    2.0 * (x * z + w * y),
                ],
                [
                    2.0 * (x * y + w * z),
                    w * w - x * x + y * y - z * z,
                    2.0 * (y * z - w * x),
                ],
                [
                    2.0 * (x * z - w * y),
                    2.0 * (y * z + w * x),
                    w * w - x * x - y * y + z * z,
                ],
            ],
            t: [tf.translation.x, tf.translation.y, tf.translation.z],
        }
    }

    fn apply(&self, p: [f64; 3]) -> [f64; 3] {
        let row = |k: usize| self.r[k][0] * p[0] + self.r[k][1] * p[1] + self.r[k][2] * p[2];
        [row(0) + self.t[0], row(1) + self.t[1], row(2) + self.t[2]]
    }
}
