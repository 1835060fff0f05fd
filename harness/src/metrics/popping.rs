//! Popping against exact motion (issue 38): how much a method's frame changes from frame
//! `i − k` to frame `i` once the camera's motion is removed, beside how much the reference's
//! does.
//!
//! Frame `i − k` is moved into frame `i`'s view with [`Warp`] (the two cameras and the
//! reference's depth; pixels disoccluded, outside frame `i − k` or without reference coverage
//! are masked), then compared with frame `i` by FLIP over the valid pixels, for the method's
//! frames (`method`) and for the reference's (`reference`). Their difference is the popping
//! the method adds: a level of detail that switches visibly scores above 0; `full`, whose
//! frames are the reference's, scores exactly 0. The plain `popping_flip` (lag 1, no warp)
//! is dominated by the motion itself on a moving camera; this is not.
//!
//! **Pop events** count the valid pixels whose warped change exceeds [`POP_THRESHOLD`] in
//! the method's frames while the reference's change there does not.

use std::collections::VecDeque;

use scenes::View;

pub use super::warp::DepthImage;
use super::warp::{Warp, masked_mean};
use super::{MetricsError, Prepared, flip, metric_background, prepare};
use crate::image::Image;

/// The lags measured, in frames: 1 and 7, as StopThePop (Radl et al., SIGGRAPH 2024)
/// measures temporal stability.
pub const LAGS: [usize; 2] = [1, 7];

/// A per-pixel FLIP error above which a pixel's change between two warped frames is a pop
/// event (when the reference's change there is not above it): 0.3, the per-pixel gate of the
/// golden-image tests (`harness/tests/common`), set where a rasteriser's rounding does not
/// reach: a camera moved a quarter of a pixel puts 0.7 % of the covered pixels above it, a
/// wrong splat kernel 4.7–28 % (measured on llvmpipe). A pixel above it changed by more than
/// sub-pixel motion and rounding explain.
pub const POP_THRESHOLD: f32 = 0.3;

/// Warped popping at one lag.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Lagged {
    /// Mean FLIP between the method's frame `i` and its frame `i − k` warped into it, over
    /// the valid pixels.
    pub method: f64,
    /// The same for the reference's frames.
    pub reference: f64,
    /// Pop events: valid pixels whose method error exceeds [`POP_THRESHOLD`] and whose
    /// reference error does not.
    pub pops: u64,
    /// Fraction of frame `i`'s pixels that are valid.
    pub valid: f64,
}

impl Lagged {
    /// `method − reference`: the popping the method adds.
    pub fn popping(&self) -> f64 {
        self.method - self.reference
    }
}

/// One earlier frame, kept for the lags.
#[derive(Debug)]
struct Past {
    view: View,
    depth: DepthImage,
    reference: Image,
    test: Image,
}

/// The frames of a path seen so far, as many as the longest lag needs.
#[derive(Debug, Default)]
pub struct WarpedHistory {
    past: VecDeque<Past>,
}

impl WarpedHistory {
    /// An empty path.
    pub fn new() -> Self {
        Self::default()
    }

    /// Measures frame `i` (its `view`, the reference's `depth`, the prepared reference and
    /// test images) against the frames [`LAGS`] before it, then keeps it. A lag is `None`
    /// before the path has that many frames, and when no pixel is valid.
    pub fn frame(
        &mut self,
        view: &View,
        depth: DepthImage,
        reference: &mut Prepared,
        test: &mut Prepared,
    ) -> Result<[Option<Lagged>; 2], MetricsError> {
        let mut out = [None; 2];
        for (slot, &k) in out.iter_mut().zip(&LAGS) {
            if let Some(past) = self.past.len().checked_sub(k).map(|at| &self.past[at]) {
                *slot = lagged(view, &depth, reference, test, past)?;
            }
        }
        let keep = LAGS.iter().copied().max().unwrap_or(0);
        if self.past.len() == keep {
            self.past.pop_front();
        }
        if keep > 0 {
            self.past.push_back(Past {
                view: *view,
                depth,
                reference: reference.image().clone(),
                test: test.image().clone(),
            });
        }
        Ok(out)
    }
}

/// Frame `i` against one earlier frame `past`.
fn lagged(
    view: &View,
    depth: &DepthImage,
    reference: &mut Prepared,
    test: &mut Prepared,
    past: &Past,
) -> Result<Option<Lagged>, MetricsError> {
    let warp = Warp::new(view, depth, &past.view, &past.depth)?;
    let valid = warp.valid();
    if valid == 0 {
        return Ok(None);
    }
    let warped_test = warp.apply(&past.test, test.image())?;
    let warped_ref = warp.apply(&past.reference, reference.image())?;
    let (method_map, reference_map) = rayon::join(
        || error_map(test, &warped_test),
        || error_map(reference, &warped_ref),
    );
    let (method_map, reference_map) = (method_map?, reference_map?);
    let pops = (0..warp.pixels())
        .filter(|&p| {
            warp.is_valid(p) && method_map[p] > POP_THRESHOLD && reference_map[p] <= POP_THRESHOLD
        })
        .count() as u64;
    Ok(Some(Lagged {
        method: masked_mean(&warp, &method_map),
        reference: masked_mean(&warp, &reference_map),
        pops,
        valid: valid as f64 / warp.pixels() as f64,
    }))
}

/// FLIP's per-pixel error between `a` (prepared, kept) and `b` on their pair's
/// [`metric_background`].
fn error_map(a: &mut Prepared, b: &Image) -> Result<Vec<f32>, MetricsError> {
    super::check_same_size(&a.image, b)?;
    let bg = metric_background(&a.image, b);
    let i = prepare(&mut a.flip, &a.image, bg);
    let fb = flip::FlipFeatures::new(b, Some(bg));
    Ok(flip::error_map(&a.flip[i].1, &fb))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::metrics::{PathMetrics, flip_mean};
    use glam::Vec3;
    use scenes::Camera;

    const W: u32 = 64;
    const H: u32 = 48;

    /// A still camera in front of a wall that covers the frame at depth 5.
    fn still() -> (View, DepthImage) {
        let view = View {
            camera: Camera {
                position: Vec3::new(0.0, 5.0, 0.0),
                target: Vec3::ZERO,
                up: Vec3::Z,
                fov_y: 0.8,
                near: 0.1,
                far: 100.0,
            },
            width: W,
            height: H,
        };
        let depth = DepthImage {
            width: W,
            height: H,
            depth: vec![5.0; (W * H) as usize],
        };
        (view, depth)
    }

    /// A textured frame; `swapped` recolours the 8 × 8 block at (20, 16) as a coarser level
    /// of the same node would (one colour for the block).
    fn frame(swapped: bool) -> Image {
        let mut img = Image::new(W, H);
        for y in 0..H {
            for x in 0..W {
                let k = ((y * W + x) * 4) as usize;
                let block = swapped && (20..28).contains(&x) && (16..24).contains(&y);
                let c = if block {
                    [200, 120, 40, 255]
                } else {
                    [(x * 4) as u8, (y * 5) as u8, ((x ^ y) * 8) as u8, 255]
                };
                img.rgba[k..k + 4].copy_from_slice(&c);
            }
        }
        img
    }

    #[test]
    fn a_level_swapped_at_frame_k_spikes_lag_1_at_k_and_lag_7_on_k_to_k_plus_6() {
        let (view, depth) = still();
        let (k, frames) = (5, 16);
        let (before, after) = (frame(false), frame(true));
        // The size of the swap: FLIP between the two levels' images (every pixel is valid
        // under a still camera, so the warped mean over valid pixels is the plain mean), and
        // the pixels it pushes over the threshold.
        let size = flip_mean(&before, &after).unwrap();
        let map = {
            let bg = metric_background(&before, &after);
            flip::error_map(
                &flip::FlipFeatures::new(&before, Some(bg)),
                &flip::FlipFeatures::new(&after, Some(bg)),
            )
        };
        let over = map.iter().filter(|&&e| e > POP_THRESHOLD).count() as u64;
        // At least the swapped block's 64 pixels, at most the block grown by FLIP's spatial
        // filters (a few pixels at 67 px per degree).
        assert!(
            (64..=16 * 16).contains(&over),
            "{over} pixels over the threshold"
        );
        let mut m = PathMetrics::new();
        for i in 0..frames {
            let test = if i < k { before.clone() } else { after.clone() };
            let f = m
                .frame_warped(&view, depth.clone(), before.clone(), test)
                .unwrap();
            let [l1, l7] = f.warped;
            // The reference never changes: its terms are 0, every pixel valid.
            for l in [l1, l7].into_iter().flatten() {
                assert_eq!((l.reference, l.valid), (0.0, 1.0), "frame {i}");
            }
            let spike = |l: Option<Lagged>, on: bool, lag: usize| {
                let Some(l) = l else {
                    assert!(i < lag, "frame {i}: lag {lag} missing");
                    return;
                };
                if on {
                    assert_eq!((l.popping(), l.pops), (size, over), "frame {i}, lag {lag}");
                } else {
                    assert_eq!((l.popping(), l.pops), (0.0, 0), "frame {i}, lag {lag}");
                }
            };
            spike(l1, i == k, 1);
            spike(l7, (k..k + 7).contains(&i), 7);
        }
    }
}
