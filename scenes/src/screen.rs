//! Degenerate attribute columns, found at load and dropped with a warning.
//!
//! A file format often has a field whether or not the scanner filled it: LAS point formats 2,
//! 3, 5, 7, 8 and 10 always carry RGB, and many writers leave it 0; PLY exporters write a
//! constant normal or a placeholder colour. Such a column carries no information, but drawn it
//! is wrong in a way a metric cannot see: all-black points on a black background give every
//! method an error of 0. So a column whose every value is the same (all zero, or any single
//! value) is dropped and the load reports it, naming the source and the attribute; the cloud's
//! [`crate::Attributes`] then say the column is absent, and the renderer shades the points as
//! it does any cloud without that attribute.
//!
//! A genuinely constant column (a flat, single-colour test object) is kept with
//! `--keep-attributes` (`keep_attributes = true` in a scene file).
//!
//! Cost: one pass that stops at the first value differing from the first sample's, so a real
//! column is decided after a handful of samples.

use crate::PointCloud;

/// Drops the colour and normal columns of `cloud` that hold one value for every sample;
/// returns the cloud and one warning per dropped column, naming `source`.
pub fn drop_constant_columns(mut cloud: PointCloud, source: &str) -> (PointCloud, Vec<String>) {
    let mut warnings = Vec::new();
    let n = cloud.len();
    if n < 2 {
        // One sample: every column is trivially constant, and nothing is degenerate.
        return (cloud, warnings);
    }
    if let Some(c) = constant(cloud.colors()) {
        warnings.push(format!(
            "{source}: colour dropped: all {n} samples have colour ({}, {}, {}), which the \
             format stores but the scanner did not fill (keep it with --keep-attributes)",
            c[0], c[1], c[2]
        ));
        cloud = cloud.without_colors();
    }
    if let Some(v) = constant(cloud.normals()) {
        warnings.push(format!(
            "{source}: normals dropped: all {n} samples have normal ({}, {}, {}) \
             (keep them with --keep-attributes)",
            v[0], v[1], v[2]
        ));
        cloud = cloud.without_normals();
    }
    (cloud, warnings)
}

/// The single value of `column`, if every element equals the first.
fn constant<T: PartialEq + Copy>(column: Option<&[T]>) -> Option<T> {
    let c = column?;
    let first = *c.first()?;
    c.iter().all(|v| *v == first).then_some(first)
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn cloud(colors: Vec<[u8; 3]>, normals: Vec<[f32; 3]>) -> PointCloud {
        let p: Vec<[f32; 3]> = (0..colors.len()).map(|i| [i as f32, 0.0, 0.0]).collect();
        PointCloud::new(
            DVec3::ZERO,
            p.into(),
            Some(normals.into()),
            Some(colors.into()),
            None,
        )
        .unwrap()
    }

    #[test]
    fn constant_columns_are_dropped_and_named() {
        let c = cloud(vec![[0, 0, 0]; 3], vec![[0.0, 0.0, 1.0]; 3]);
        let (c, w) = drop_constant_columns(c, "tile.las");
        assert!(c.colors().is_none() && c.normals().is_none());
        assert_eq!(w.len(), 2);
        assert!(
            w[0].contains("tile.las") && w[0].contains("colour (0, 0, 0)"),
            "{w:?}"
        );
        assert!(w[1].contains("normal (0, 0, 1)"), "{w:?}");
        assert_eq!(c.attributes(), crate::Attributes::default());
    }

    #[test]
    fn a_column_with_two_values_is_kept() {
        // The last sample differs: the whole column must be scanned, not a prefix.
        let mut colors = vec![[7, 7, 7]; 1000];
        colors[999] = [7, 7, 8];
        let mut normals = vec![[1.0, 0.0, 0.0]; 1000];
        normals[999] = [0.0, 1.0, 0.0];
        let (c, w) = drop_constant_columns(cloud(colors, normals), "x");
        assert!(w.is_empty(), "{w:?}");
        assert!(c.attributes().colors && c.attributes().normals);
        // A single sample is not degenerate.
        let (c, w) = drop_constant_columns(cloud(vec![[0; 3]], vec![[0.0, 0.0, 1.0]]), "x");
        assert!(w.is_empty() && c.attributes().colors);
    }
}
