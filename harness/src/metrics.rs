//! Image metrics: how far a method's frame (the *test*) is from the no-LOD reference frame.
//!
//! Every function takes the reference first and the test second; both must have the same
//! size, otherwise [`MetricsError::SizeMismatch`] (never a panic). All functions are pure and
//! deterministic: the same inputs give the same bits whatever the thread count.
//!
//! Colour metrics read R, G, B (sRGB-encoded 8-bit, see [`crate::image`]) of **every** pixel,
//! covered or not, and ignore alpha; uncovered pixels hold the background colour.
//!
//! - [`psnr_db`]: `10 · log10(255² / MSE)`, MSE over the R, G, B channels of all pixels.
//!   Identical images have infinite PSNR; it is **capped at [`PSNR_CAP_DB`] = 100 dB** (an MSE
//!   below 255²·10⁻¹⁰ also reads 100) so that CSV and JSON stay finite.
//! - [`ssim`]: mean SSIM (Wang, Bovik, Sheikh, Simoncelli 2004) on luma
//!   `Y' = 0.2126 R + 0.7152 G + 0.0722 B` (Rec. 709 weights applied to the 8-bit
//!   *sRGB-encoded* values, not linearised ones: SSIM models perceived structure, and this
//!   matches what common tools compute), dynamic range L = 255, K1 = 0.01, K2 = 0.03,
//!   Gaussian window 11×11 with σ = 1.5 (weights normalised to sum 1), and the mean taken
//!   over the **valid** region only (windows that fit inside the image: (w−10)×(h−10)
//!   positions). Images narrower or shorter than 11 px use the largest odd window that fits
//!   (same σ, renormalised). Computed as separable Gaussian blurs of x, y, x², y², xy in
//!   `f32`, per-row sums in `f64` added in row order. Identical images give exactly 1.0.
//! - [`flip_mean`]: mean of the LDR-FLIP error map (Andersson et al. 2020) of the RGB images
//!   at [`FLIP_PIXELS_PER_DEGREE`] = 67 pixels per degree (FLIP's default viewing setup: a
//!   0.7 m wide 3840-pixel monitor seen from 0.7 m). The mean is the plain `f64` average of
//!   the per-pixel errors in 0..1. Identical images give 0.0. Computed by [`flip`], our
//!   separable, parallel implementation, which prepares each image once; the tests hold it
//!   to NVIDIA's reference (the `nv-flip` crate) within 1e-4. [`flip_map`] returns the error
//!   map through FLIP's magma colour map (`nv-flip`'s table), for golden-image failures
//!   (`-difference` images).
//! - [`hole_ratio`] = |covered in reference ∧ not covered in test| / |covered in reference|;
//!   [`extra_coverage`] = |covered in test ∧ not covered in reference| / |covered in
//!   reference|. "Covered" means alpha > 0. Both are **0 when the reference covers nothing**
//!   (the ratio is undefined there; 0 keeps results finite, and such a frame carries no
//!   coverage information).
//! - [`compare`] computes all five into an [`ImageMetrics`] row fragment, with FLIP and SSIM
//!   running in parallel (rayon). It first puts both images on the **metric background**
//!   ([`metric_background`]): uncovered pixels (alpha 0) take a colour no covered pixel of
//!   either image is near, so a missing splat always costs colour error, even when the
//!   points are black like the renderer's clear colour. Coverage comes from alpha, never
//!   from colour.
//!
//! Empty (0×0) images compare as identical: PSNR 100, SSIM 1, FLIP 0, ratios 0.

pub mod flip;
pub mod magma;
pub mod popping;
pub mod warp;

use rayon::prelude::*;

use scenes::View;

use crate::image::{Image, ImageError};
use flip::FlipFeatures;

/// PSNR reported for identical images (and any MSE small enough to exceed it), in dB.
pub const PSNR_CAP_DB: f64 = 100.0;

/// Pixels per degree of visual angle used for FLIP: 67.0 (as `nv_flip::DEFAULT_PIXELS_PER_DEGREE`), the FLIP paper's default (0.7 m wide, 3840 px monitor viewed from 0.7 m).
pub const FLIP_PIXELS_PER_DEGREE: f32 = flip::PIXELS_PER_DEGREE;

/// SSIM Gaussian window radius: 11×11 window.
const SSIM_RADIUS: usize = 5;
/// SSIM Gaussian window standard deviation, in pixels.
const SSIM_SIGMA: f64 = 1.5;
/// SSIM dynamic range of 8-bit values.
const SSIM_L: f64 = 255.0;
/// SSIM luminance stabiliser constant K1.
const SSIM_K1: f64 = 0.01;
/// SSIM contrast stabiliser constant K2.
const SSIM_K2: f64 = 0.03;

/// Errors from comparing images.
#[derive(Debug, thiserror::Error)]
pub enum MetricsError {
    /// The reference and test images differ in size.
    #[error(
        "image sizes differ: reference is {}x{}, test is {}x{}",
        reference.0, reference.1, test.0, test.1
    )]
    SizeMismatch {
        /// Reference (width, height).
        reference: (u32, u32),
        /// Test (width, height).
        test: (u32, u32),
    },
    /// An image's buffer is malformed (see [`ImageError::BufferSize`]).
    #[error(transparent)]
    Image(#[from] ImageError),
}

/// The five per-frame image metrics, named as the `frames.csv` columns.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct ImageMetrics {
    /// PSNR over RGB in dB, capped at [`PSNR_CAP_DB`].
    pub psnr_db: f64,
    /// Mean SSIM on luma, at most 1.
    pub ssim: f64,
    /// Mean LDR-FLIP error in 0..1.
    pub flip_mean: f64,
    /// Fraction of reference-covered pixels the test leaves uncovered.
    pub hole_ratio: f64,
    /// Test-covered pixels the reference leaves uncovered, as a fraction of reference-covered.
    pub extra_coverage: f64,
}

/// The smallest distance (Euclidean, sRGB8 levels) between the metric background and any
/// covered pixel's colour, when black is not kept: 64 levels, a quarter of the range. A
/// covered pixel closer to black than this makes [`metric_background`] pick another colour.
pub const BACKGROUND_MIN_DISTANCE: f32 = 64.0;

/// Candidate metric backgrounds, in order of preference: black (the renderer's clear
/// colour, so images of ordinary scenes compare exactly as they are drawn), then white and
/// the six primaries and secondaries.
pub const BACKGROUND_CANDIDATES: [[u8; 3]; 8] = [
    [0, 0, 0],
    [255, 255, 255],
    [255, 0, 255],
    [0, 255, 0],
    [0, 0, 255],
    [255, 0, 0],
    [0, 255, 255],
    [255, 255, 0],
];

/// The background colour [`compare`] gives the uncovered pixels of both images: black when
/// no covered pixel of either lies within [`BACKGROUND_MIN_DISTANCE`] of it, else the
/// candidate of [`BACKGROUND_CANDIDATES`] farthest from every covered colour (distances
/// measured to 8-level bins of the colours present, i.e. within 7 levels per channel; the
/// first candidate wins ties). Deterministic, and the same for both images.
pub fn metric_background(reference: &Image, test: &Image) -> [u8; 3] {
    // Colours present, binned to 5 bits per channel (32³ bins).
    let mut present = vec![false; 1 << 15];
    let bin = |p: &[u8]| {
        ((p[0] as usize >> 3) << 10) | ((p[1] as usize >> 3) << 5) | (p[2] as usize >> 3)
    };
    for img in [reference, test] {
        for p in img.rgba.chunks_exact(4).filter(|p| p[3] > 0) {
            present[bin(p)] = true;
        }
    }
    let bins: Vec<[f32; 3]> = (0..present.len())
        .filter(|&b| present[b])
        .map(|b| [(b >> 10) & 31, (b >> 5) & 31, b & 31].map(|v| (v << 3) as f32))
        .collect();
    // Nearest distance from `c` to any present colour, each bin taken at its nearest point.
    let nearest = |c: [u8; 3]| -> f32 {
        let mut best = f32::INFINITY;
        for lo in &bins {
            let d2: f32 = (0..3)
                .map(|k| {
                    let v = f32::from(c[k]);
                    let d = if v < lo[k] {
                        lo[k] - v
                    } else {
                        (v - (lo[k] + 7.0)).max(0.0)
                    };
                    d * d
                })
                .sum();
            best = best.min(d2);
        }
        best.sqrt()
    };
    let black = BACKGROUND_CANDIDATES[0];
    if nearest(black) >= BACKGROUND_MIN_DISTANCE {
        return black;
    }
    let mut best = (black, nearest(black));
    for &c in &BACKGROUND_CANDIDATES[1..] {
        let d = nearest(c);
        if d > best.1 {
            best = (c, d);
        }
    }
    best.0
}

/// `img` with every uncovered pixel's colour set to `bg` (alpha kept).
pub fn on_background(img: &Image, bg: [u8; 3]) -> Image {
    let mut out = img.clone();
    for p in out.rgba.chunks_exact_mut(4).filter(|p| p[3] == 0) {
        p[..3].copy_from_slice(&bg);
    }
    out
}

/// All five metrics of `test` against `reference`, on the [`metric_background`].
pub fn compare(reference: &Image, test: &Image) -> Result<ImageMetrics, MetricsError> {
    check_same_size(reference, test)?;
    compare_prepared(
        &mut Prepared::new(reference.clone()),
        &mut Prepared::new(test.clone()),
    )
}

/// An image with its FLIP preparation ([`FlipFeatures`]) for each metric background it has
/// been compared on, so that an image compared several times (a frame against its reference
/// and against the previous frame) is filtered once.
#[derive(Debug, Clone)]
pub struct Prepared {
    image: Image,
    flip: Vec<([u8; 3], FlipFeatures)>,
}

impl Prepared {
    /// `image`, not yet prepared.
    pub fn new(image: Image) -> Self {
        Self {
            image,
            flip: Vec::new(),
        }
    }

    /// The image.
    pub fn image(&self) -> &Image {
        &self.image
    }
}

/// Prepares `image` on background `bg` into `flip` unless it already is there; returns its
/// index in `flip`.
fn prepare(flip: &mut Vec<([u8; 3], FlipFeatures)>, image: &Image, bg: [u8; 3]) -> usize {
    match flip.iter().position(|(b, _)| *b == bg) {
        Some(i) => i,
        None => {
            flip.push((bg, FlipFeatures::new(image, Some(bg))));
            flip.len() - 1
        }
    }
}

/// [`compare`] of prepared images: their FLIP preparations on this pair's background are
/// made if missing (in parallel with SSIM and PSNR) and kept for later comparisons.
pub fn compare_prepared(
    reference: &mut Prepared,
    test: &mut Prepared,
) -> Result<ImageMetrics, MetricsError> {
    check_same_size(&reference.image, &test.image)?;
    let (r, t) = (&reference.image, &test.image);
    let bg = metric_background(r, t);
    let placed;
    let (placed_ref, placed_test) = if bg == [0, 0, 0] && !has_uncovered_colour(r, t) {
        (r, t)
    } else {
        placed = (on_background(r, bg), on_background(t, bg));
        (&placed.0, &placed.1)
    };
    let (rf, tf) = (&mut reference.flip, &mut test.flip);
    let ((i, j), (ssim, (psnr_db, (hole_ratio, extra_coverage)))) = rayon::join(
        || rayon::join(|| prepare(rf, r, bg), || prepare(tf, t, bg)),
        || {
            rayon::join(
                || ssim_unchecked(placed_ref, placed_test),
                || {
                    (
                        psnr_unchecked(placed_ref, placed_test),
                        coverage_unchecked(r, t),
                    )
                },
            )
        },
    );
    Ok(ImageMetrics {
        psnr_db,
        ssim,
        flip_mean: flip::error_mean(&reference.flip[i].1, &test.flip[j].1),
        hole_ratio,
        extra_coverage,
    })
}

/// Mean FLIP between two prepared images on their pair's [`metric_background`] (as in
/// [`compare`]), preparing them on it if needed.
pub fn flip_prepared(a: &mut Prepared, b: &mut Prepared) -> Result<f64, MetricsError> {
    check_same_size(&a.image, &b.image)?;
    let bg = metric_background(&a.image, &b.image);
    let (ia, fa, ib, fb) = (&a.image, &mut a.flip, &b.image, &mut b.flip);
    let (i, j) = rayon::join(|| prepare(fa, ia, bg), || prepare(fb, ib, bg));
    Ok(flip::error_mean(&a.flip[i].1, &b.flip[j].1))
}

/// Per-frame metrics along a camera path: each frame against its reference ([`compare`])
/// and the **popping** FLIP, `FLIP(frame i, frame i−1) − FLIP(ref i, ref i−1)`: how much
/// more the method's image changes from one frame to the next than the full-resolution
/// reference does at the same views. A level of detail that switches visibly between
/// frames (popping) scores above 0; one that changes like the reference scores ≈ 0; the
/// `full` method scores exactly 0. Each image is FLIP-prepared once and kept one frame.
///
/// With the reference's depth ([`PathMetrics::frame_warped`]) it also measures popping
/// against exact motion at lags 1 and 7 ([`popping`]).
#[derive(Debug, Default)]
pub struct PathMetrics {
    /// The previous frame's (reference, test).
    previous: Option<(Prepared, Prepared)>,
    /// The frames the warped lags look back to.
    warped: popping::WarpedHistory,
}

/// What [`PathMetrics::frame`] measures for one frame.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FrameMetrics {
    /// The test against its reference.
    pub image: ImageMetrics,
    /// Popping FLIP (see [`PathMetrics`]); `None` for the first frame of a path.
    pub popping_flip: Option<f64>,
    /// Warped popping at [`popping::LAGS`] (`None` without depth, before the path has
    /// that many frames, or with no valid pixel).
    pub warped: [Option<popping::Lagged>; 2],
}

impl PathMetrics {
    /// An empty path: the next frame is the first.
    pub fn new() -> Self {
        Self::default()
    }

    /// Measures the next frame of the path; all frames of a path must have one size.
    pub fn frame(&mut self, reference: Image, test: Image) -> Result<FrameMetrics, MetricsError> {
        self.measure(reference, test, None)
    }

    /// [`PathMetrics::frame`] with the frame's `view` and the reference's `depth`, which
    /// the warped popping lags need; a path measures all its frames one way or the other.
    pub fn frame_warped(
        &mut self,
        view: &View,
        depth: popping::DepthImage,
        reference: Image,
        test: Image,
    ) -> Result<FrameMetrics, MetricsError> {
        self.measure(reference, test, Some((view, depth)))
    }

    fn measure(
        &mut self,
        reference: Image,
        test: Image,
        warp: Option<(&View, popping::DepthImage)>,
    ) -> Result<FrameMetrics, MetricsError> {
        let (mut reference, mut test) = (Prepared::new(reference), Prepared::new(test));
        let image = compare_prepared(&mut reference, &mut test)?;
        let warped = match warp {
            Some((view, depth)) => self.warped.frame(view, depth, &mut reference, &mut test)?,
            None => [None; 2],
        };
        let popping_flip = match self.previous.as_mut() {
            Some((previous_reference, previous_test)) => Some(
                flip_prepared(&mut test, previous_test)?
                    - flip_prepared(&mut reference, previous_reference)?,
            ),
            None => None,
        };
        self.previous = Some((reference, test));
        Ok(FrameMetrics {
            image,
            popping_flip,
            warped,
        })
    }
}

/// True when an uncovered pixel of either image holds a colour other than black (images
/// the renderer drew never do).
fn has_uncovered_colour(a: &Image, b: &Image) -> bool {
    [a, b].iter().any(|img| {
        img.rgba
            .chunks_exact(4)
            .any(|p| p[3] == 0 && p[..3] != [0, 0, 0])
    })
}

/// PSNR in dB over the R, G, B channels of all pixels, peak 255, capped at [`PSNR_CAP_DB`].
pub fn psnr_db(reference: &Image, test: &Image) -> Result<f64, MetricsError> {
    check_same_size(reference, test)?;
    Ok(psnr_unchecked(reference, test))
}

/// Mean SSIM on Rec. 709 luma, 11×11 Gaussian window (σ = 1.5), valid region only.
pub fn ssim(reference: &Image, test: &Image) -> Result<f64, MetricsError> {
    check_same_size(reference, test)?;
    Ok(ssim_unchecked(reference, test))
}

/// Mean LDR-FLIP error (0..1) at [`FLIP_PIXELS_PER_DEGREE`].
pub fn flip_mean(reference: &Image, test: &Image) -> Result<f64, MetricsError> {
    check_same_size(reference, test)?;
    Ok(flip_mean_unchecked(reference, test))
}

/// The LDR-FLIP error map through FLIP's magma colour map (opaque RGBA; black = no error).
pub fn flip_map(reference: &Image, test: &Image) -> Result<Image, MetricsError> {
    check_same_size(reference, test)?;
    let (width, height) = (reference.width, reference.height);
    if reference.pixel_count() == 0 {
        return Ok(Image {
            width,
            height,
            rgba: Vec::new(),
        });
    }
    let (r, t) = flip_features_of(reference, test);
    let errors = flip::error_map(&r, &t);
    let mut rgba = Vec::with_capacity(errors.len() * 4);
    for &e in &errors {
        let [r, g, b] = magma::colour(e);
        rgba.extend_from_slice(&[r, g, b, 255]);
    }
    Ok(Image::from_rgba(width, height, rgba)?)
}

/// Fraction of the reference's covered pixels that the test leaves uncovered (0 if the
/// reference covers nothing).
pub fn hole_ratio(reference: &Image, test: &Image) -> Result<f64, MetricsError> {
    check_same_size(reference, test)?;
    Ok(coverage_unchecked(reference, test).0)
}

/// Pixels covered in the test but not in the reference, divided by the reference's covered
/// pixels (0 if the reference covers nothing).
pub fn extra_coverage(reference: &Image, test: &Image) -> Result<f64, MetricsError> {
    check_same_size(reference, test)?;
    Ok(coverage_unchecked(reference, test).1)
}

/// Errors unless both images have the same width and height (and well-formed buffers).
fn check_same_size(reference: &Image, test: &Image) -> Result<(), MetricsError> {
    if (reference.width, reference.height) != (test.width, test.height) {
        return Err(MetricsError::SizeMismatch {
            reference: (reference.width, reference.height),
            test: (test.width, test.height),
        });
    }
    for image in [reference, test] {
        // The fields are public: re-check the buffer so the kernels can index freely.
        let expected = (u64::from(image.width) * u64::from(image.height)).saturating_mul(4);
        if image.rgba.len() as u64 != expected {
            return Err(ImageError::BufferSize {
                width: image.width,
                height: image.height,
                expected,
                actual: image.rgba.len() as u64,
            }
            .into());
        }
    }
    Ok(())
}

/// PSNR of same-sized images.
fn psnr_unchecked(reference: &Image, test: &Image) -> f64 {
    let n = reference.pixel_count() as u64 * 3;
    if n == 0 {
        return PSNR_CAP_DB;
    }
    let sse: u64 = reference
        .rgba
        .par_chunks(4 * 4096)
        .zip(test.rgba.par_chunks(4 * 4096))
        .map(|(a, b)| {
            a.chunks_exact(4)
                .zip(b.chunks_exact(4))
                .map(|(p, q)| {
                    (0..3)
                        .map(|c| {
                            let d = u64::from(p[c].abs_diff(q[c]));
                            d * d
                        })
                        .sum::<u64>()
                })
                .sum::<u64>()
        })
        .sum();
    if sse == 0 {
        return PSNR_CAP_DB;
    }
    let mse = sse as f64 / n as f64;
    (10.0 * (SSIM_L * SSIM_L / mse).log10()).min(PSNR_CAP_DB)
}

/// (hole ratio, extra coverage) of same-sized images.
fn coverage_unchecked(reference: &Image, test: &Image) -> (f64, f64) {
    let (mut covered, mut holes, mut extra) = (0u64, 0u64, 0u64);
    for (p, q) in reference
        .rgba
        .chunks_exact(4)
        .zip(test.rgba.chunks_exact(4))
    {
        let (r, t) = (p[3] > 0, q[3] > 0);
        covered += u64::from(r);
        holes += u64::from(r && !t);
        extra += u64::from(t && !r);
    }
    if covered == 0 {
        return (0.0, 0.0);
    }
    (holes as f64 / covered as f64, extra as f64 / covered as f64)
}

/// Mean FLIP error of same-sized images.
fn flip_mean_unchecked(reference: &Image, test: &Image) -> f64 {
    let (r, t) = flip_features_of(reference, test);
    flip::error_mean(&r, &t)
}

/// Both images FLIP-prepared as they are (no metric background), in parallel.
fn flip_features_of(reference: &Image, test: &Image) -> (FlipFeatures, FlipFeatures) {
    rayon::join(
        || FlipFeatures::new(reference, None),
        || FlipFeatures::new(test, None),
    )
}

/// Rec. 709 luma of the 8-bit sRGB-encoded values, one `f32` per pixel.
fn luma(image: &Image) -> Vec<f32> {
    image
        .rgba
        .chunks_exact(4)
        .map(|p| 0.2126 * f32::from(p[0]) + 0.7152 * f32::from(p[1]) + 0.0722 * f32::from(p[2]))
        .collect()
}

/// Normalised 1-D Gaussian of `2 * radius + 1` taps with σ = [`SSIM_SIGMA`].
fn gaussian_kernel(radius: usize) -> Vec<f32> {
    let raw: Vec<f64> = (0..=2 * radius)
        .map(|i| {
            let d = i as f64 - radius as f64;
            (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
        })
        .collect();
    let sum: f64 = raw.iter().sum();
    raw.iter().map(|&v| (v / sum) as f32).collect()
}

/// Per-row scratch for the SSIM kernel: vertical sums (width `w`) of x, y, x², y², xy.
struct SsimScratch {
    /// Vertically blurred x, y, x², y², xy, each `w` long.
    vertical: [Vec<f32>; 5],
    /// Horizontally blurred versions, each `w - 2r` long.
    horizontal: [Vec<f32>; 5],
}

/// Mean SSIM of same-sized images.
fn ssim_unchecked(reference: &Image, test: &Image) -> f64 {
    let (w, h) = (reference.width as usize, reference.height as usize);
    if w == 0 || h == 0 {
        return 1.0;
    }
    let radius = SSIM_RADIUS.min((w.min(h) - 1) / 2);
    let kernel = gaussian_kernel(radius);
    let (ow, oh) = (w - 2 * radius, h - 2 * radius);
    let (x, y) = rayon::join(|| luma(reference), || luma(test));
    let c1 = ((SSIM_K1 * SSIM_L) * (SSIM_K1 * SSIM_L)) as f32;
    let c2 = ((SSIM_K2 * SSIM_L) * (SSIM_K2 * SSIM_L)) as f32;

    let row_sums: Vec<f64> = (0..oh)
        .into_par_iter()
        .map_init(
            || SsimScratch {
                vertical: std::array::from_fn(|_| vec![0.0; w]),
                horizontal: std::array::from_fn(|_| vec![0.0; ow]),
            },
            |s, row| {
                let [vx, vy, vxx, vyy, vxy] = &mut s.vertical;
                for v in [&mut *vx, &mut *vy, &mut *vxx, &mut *vyy, &mut *vxy] {
                    v.fill(0.0);
                }
                // Vertical pass over the 2r + 1 input rows of this output row.
                for (k, &wk) in kernel.iter().enumerate() {
                    let start = (row + k) * w;
                    let (xs, ys) = (&x[start..start + w], &y[start..start + w]);
                    for i in 0..w {
                        let (a, b) = (xs[i], ys[i]);
                        vx[i] += wk * a;
                        vy[i] += wk * b;
                        vxx[i] += wk * (a * a);
                        vyy[i] += wk * (b * b);
                        vxy[i] += wk * (a * b);
                    }
                }
                // Horizontal pass, valid columns only.
                for (out, v) in s.horizontal.iter_mut().zip(&s.vertical) {
                    out.fill(0.0);
                    for (k, &wk) in kernel.iter().enumerate() {
                        for (o, &vi) in out.iter_mut().zip(&v[k..k + ow]) {
                            *o += wk * vi;
                        }
                    }
                }
                let [mx, my, mxx, myy, mxy] = &s.horizontal;
                let mut sum = 0.0f64;
                for i in 0..ow {
                    let (ux, uy) = (mx[i], my[i]);
                    let (uxx, uyy, uxy) = (ux * ux, uy * uy, ux * uy);
                    let (sxx, syy, sxy) = (mxx[i] - uxx, myy[i] - uyy, mxy[i] - uxy);
                    let num = (2.0 * uxy + c1) * (2.0 * sxy + c2);
                    let den = (uxx + uyy + c1) * (sxx + syy + c2);
                    sum += f64::from(num / den);
                }
                sum
            },
        )
        .collect();
    row_sums.iter().sum::<f64>() / (ow * oh) as f64
}
