//! Images the viewer shows instead of the frame: the hole mask (the FLIP map and the
//! reference come from [`crate::metrics`] and the runner).

use crate::image::Image;
use crate::metrics::MetricsError;

/// Where the hole mask marks a hole: pure red.
pub const HOLE: [u8; 4] = [255, 0, 0, 255];

/// The frame `test` dimmed to a third, with every pixel the reference covers and the frame
/// does not ([`crate::metrics::hole_ratio`]'s holes) in [`HOLE`] red. Opaque.
pub fn hole_mask(reference: &Image, test: &Image) -> Result<Image, MetricsError> {
    if (reference.width, reference.height) != (test.width, test.height) {
        return Err(MetricsError::SizeMismatch {
            reference: (reference.width, reference.height),
            test: (test.width, test.height),
        });
    }
    let mut out = test.clone();
    for (o, r) in out
        .rgba
        .chunks_exact_mut(4)
        .zip(reference.rgba.chunks_exact(4))
    {
        if r[3] > 0 && o[3] == 0 {
            o.copy_from_slice(&HOLE);
        } else {
            for c in &mut o[..3] {
                *c /= 3;
            }
            o[3] = 255;
        }
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn holes_are_red_exactly_where_the_reference_has_a_splat_and_the_frame_none() {
        // Pixels: both covered, reference only (a hole), frame only, neither.
        let reference = Image::from_rgba(
            4,
            1,
            [[90, 90, 90, 255], [90, 90, 90, 255], [0; 4], [0; 4]].concat(),
        )
        .expect("image");
        let test = Image::from_rgba(
            4,
            1,
            [[30, 60, 90, 255], [0; 4], [60, 60, 60, 255], [0; 4]].concat(),
        )
        .expect("image");
        let m = hole_mask(&reference, &test).expect("same size");
        assert_eq!(m.pixel(0, 0), [10, 20, 30, 255]);
        assert_eq!(m.pixel(1, 0), HOLE);
        assert_eq!(m.pixel(2, 0), [20, 20, 20, 255]);
        assert_eq!(m.pixel(3, 0), [0, 0, 0, 255]);
        let holes = m.rgba.chunks_exact(4).filter(|p| *p == HOLE).count() as f64;
        let covered = reference.coverage_count() as f64;
        let ratio = crate::metrics::hole_ratio(&reference, &test).expect("same size");
        assert_eq!(holes / covered, ratio, "the mask shows the metric's holes");
        assert!(hole_mask(&reference, &Image::new(2, 1)).is_err());
    }
}
