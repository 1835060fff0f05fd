//! Per-point scalars that scanners record — LAS intensity and classification, E57 and PCD
//! intensity — and the colours splatbench shades them with (`--shading intensity` and
//! `--shading classification`).
//!
//! A scalar reaches the methods only as the cloud's colour column, and only when a run
//! shades by it ([`SceneSpec::colour_from`](crate::SceneSpec::colour_from)): every method
//! then stores, streams and draws it as it does any colour (QSplat and LPC quantise it, SPT
//! and MWKD keep 8 bits), the reference included, and no method carries a column it does
//! not draw. The LAS reader decodes it only when asked; the PCD and E57 readers keep their
//! intensity field with the points (4 bytes a point while loading) and the loader drops it
//! unless asked.
//!
//! - **Intensity** → grey, linear in the sRGB-encoded value over the robust range: the 1 %
//!   and 99 % quantiles of the cloud's intensities map to 0 and 255, values beyond clamp
//!   (LiDAR intensity has rare very bright returns — retro-reflectors — that would otherwise
//!   leave everything else near black). A constant intensity is an error: there is nothing
//!   to shade by, and a uniform grey would pass for a result.
//! - **Classification** → the fixed palette [`class_colour`] of the ASPRS LAS 1.4 standard
//!   classes (ground brown, vegetation greens, buildings orange, water blue, noise magenta,
//!   …), the same colours for every file so that images of different tiles compare. One
//!   class for every point is an error, as a constant intensity is.

use std::path::Path;

use crate::SceneError;

/// A per-point scalar a scene can be coloured by.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Scalar {
    /// Return strength (LAS `intensity`, E57 `intensity`, PCD field `intensity`).
    Intensity,
    /// LAS point class (ASPRS codes, 0–255).
    Classification,
}

impl Scalar {
    /// The name in messages, flags and hashes.
    pub fn name(self) -> &'static str {
        match self {
            Scalar::Intensity => "intensity",
            Scalar::Classification => "classification",
        }
    }
}

impl std::fmt::Display for Scalar {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

/// Quantiles of the intensity range that map to black and white.
pub const INTENSITY_QUANTILES: (f64, f64) = (0.01, 0.99);

/// The colours of `values` (one per point, the scalar `field` of `path`), as described in the
/// module docs. Errors name the file and the field: no values, a non-finite value, or a
/// constant intensity.
pub fn colours(path: &Path, field: Scalar, values: &[f32]) -> Result<Vec<[u8; 3]>, SceneError> {
    let err = |msg: String| SceneError::format(path, format!("{field}: {msg}"));
    if values.is_empty() {
        return Err(err("no values".into()));
    }
    if let Some(i) = values.iter().position(|v| !v.is_finite()) {
        return Err(err(format!("point {i} has the value {}", values[i])));
    }
    match field {
        Scalar::Intensity => {
            let (lo, hi) = intensity_range(values);
            if hi <= lo {
                let (min, max) = values
                    .iter()
                    .fold((f32::INFINITY, f32::NEG_INFINITY), |(a, b), &v| {
                        (a.min(v), b.max(v))
                    });
                if min == max {
                    return Err(err(format!(
                        "every point has the intensity {min}: nothing to shade by (choose \
                         another --shading)"
                    )));
                }
                // Fewer than 2 % of the points differ: spread the full range instead.
                return Ok(values.iter().map(|&v| grey(v, min, max)).collect());
            }
            Ok(values.iter().map(|&v| grey(v, lo, hi)).collect())
        }
        Scalar::Classification => {
            if values.iter().all(|&v| v == values[0]) {
                return Err(err(format!(
                    "every point has the class {}: nothing to shade by (choose another \
                     --shading)",
                    values[0]
                )));
            }
            Ok(values
                .iter()
                .map(|&v| class_colour(v.clamp(0.0, 255.0) as u8))
                .collect())
        }
    }
}

/// The intensities at [`INTENSITY_QUANTILES`] (nearest rank, over every value).
pub fn intensity_range(values: &[f32]) -> (f32, f32) {
    let mut v = values.to_vec();
    let last = (v.len() - 1) as f64;
    let i_lo = (last * INTENSITY_QUANTILES.0).floor() as usize;
    let i_hi = (last * INTENSITY_QUANTILES.1).ceil() as usize;
    let lo = *v.select_nth_unstable_by(i_lo, f32::total_cmp).1;
    let hi = *v.select_nth_unstable_by(i_hi, f32::total_cmp).1;
    (lo, hi)
}

fn grey(v: f32, lo: f32, hi: f32) -> [u8; 3] {
    let g = (((v - lo) / (hi - lo)).clamp(0.0, 1.0) * 255.0).round() as u8;
    [g, g, g]
}

/// sRGB colour of an ASPRS class code (LAS 1.4 R15, table 17): 0–1 never classified and
/// unassigned grey, 2 ground brown, 3–5 low / medium / high vegetation light to dark green,
/// 6 building orange, 7 low noise and 18 high noise magenta, 9 water blue, 10 rail dark
/// red, 11 road surface dark grey, 13–16 wires and towers yellow, 17 bridge deck tan; any
/// other code (reserved, user-defined, overlap) light blue-grey.
pub fn class_colour(code: u8) -> [u8; 3] {
    match code {
        0 | 1 => [170, 170, 170],
        2 => [150, 110, 60],
        3 => [150, 220, 110],
        4 => [60, 170, 60],
        5 => [20, 100, 30],
        6 => [240, 140, 40],
        7 | 18 => [230, 40, 220],
        9 => [40, 110, 230],
        10 => [140, 30, 30],
        11 => [80, 80, 80],
        13..=16 => [240, 220, 40],
        17 => [200, 180, 130],
        _ => [150, 180, 210],
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn intensity_maps_the_robust_range_to_black_and_white() {
        // 1,000 values 0..999 and one retro-reflector at 65,535.
        let mut v: Vec<f32> = (0..1000).map(|i| i as f32).collect();
        v.push(65_535.0);
        let c = colours(Path::new("t.las"), Scalar::Intensity, &v).unwrap();
        let (lo, hi) = intensity_range(&v);
        assert_eq!((lo, hi), (10.0, 990.0));
        assert_eq!(c[0], [0, 0, 0]);
        assert_eq!(c[1000], [255, 255, 255]);
        // The middle value sits in the middle, not crushed near black by the outlier.
        assert_eq!(c[500][0], 128);
    }

    #[test]
    fn constant_intensity_is_an_error_naming_the_field() {
        let e = colours(Path::new("t.las"), Scalar::Intensity, &[7.0; 10]).unwrap_err();
        let m = e.to_string();
        assert!(
            m.contains("t.las") && m.contains("intensity") && m.contains('7'),
            "{m}"
        );
        // Nearly constant: fewer than 2 % differ, the full range is used.
        let mut v = vec![5.0; 200];
        v[3] = 9.0;
        let c = colours(Path::new("t.las"), Scalar::Intensity, &v).unwrap();
        assert_eq!((c[0], c[3]), ([0; 3], [255; 3]));
    }

    #[test]
    fn classes_get_the_palette() {
        let c = colours(Path::new("t.las"), Scalar::Classification, &[2.0, 6.0, 9.0]).unwrap();
        assert_eq!(c, vec![class_colour(2), class_colour(6), class_colour(9)]);
        assert_ne!(class_colour(2), class_colour(5));
        let e = colours(Path::new("t.las"), Scalar::Classification, &[f32::NAN]).unwrap_err();
        assert!(e.to_string().contains("classification"), "{e}");
    }
}
