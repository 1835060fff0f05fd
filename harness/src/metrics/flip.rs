//! LDR-FLIP (Andersson, Nilsson, Akenine-Möller, Oskarsson, Åström, Fairchild 2020), our own
//! implementation, split so that each image is prepared once and any two prepared images are
//! compared cheaply.
//!
//! FLIP's per-pixel error depends on each image only through five per-pixel quantities: the
//! Hunt-adjusted CIELab colour `(L, a, b)` of the image filtered by the contrast sensitivity
//! functions, and the edge and point feature magnitudes of its normalised luminance. A
//! [`FlipFeatures`] holds those five planes ([`FlipFeatures::new`], the expensive part: two
//! separable convolutions); [`error_mean`] and [`error_map`] combine two of them per pixel
//! (HyAB distance, the colour and feature error exponents). A run therefore prepares each
//! rendered frame and each reference view once and reuses them for the frame-vs-reference
//! error and the frame-to-frame (popping) error.
//!
//! The steps and constants are FLIP's (the paper, and NVIDIA's reference C++ shipped in the
//! `nv-flip` crate, which the tests use as the oracle: mean error equal within 1e-4):
//!
//! 1. sRGB8 → linear RGB (`v/255`, the sRGB transfer function) → XYZ (D65) → YCxCz.
//! 2. Contrast sensitivity filtering at [`PIXELS_PER_DEGREE`]: Y and Cx by one Gaussian each,
//!    Cz by a sum of two Gaussians, each written as a product of 1-D kernels (the sum-of-two
//!    filter as two separable terms whose kernels are square roots of the 2-D ones), radius
//!    `ceil(3·sqrt(max b / (2π²))·ppd)` = 10 px at 67 ppd; edges clamped.
//! 3. Filtered YCxCz → XYZ → linear RGB clamped to 0..1 → XYZ → CIELab, with the Hunt
//!    adjustment `a ← 0.01·L·a`, `b ← 0.01·L·b`.
//! 4. Features on `Y/116 + 16/116`: first and second derivatives of a Gaussian with
//!    σ = 0.5·0.082·ppd (radius `ceil(3σ)` = 9 px at 67 ppd), positive and negative weights
//!    each normalised to ±1; edge = |∇|, point = |∇²| (per axis, combined by `hypot`).
//! 5. Per pixel: colour error `HyAB^0.7` remapped so `0.4·cmax` ↦ 0.95 and `cmax` ↦ 1 (cmax
//!    the green–blue distance); feature error `(max(|Δedge|, |Δpoint|)/√2)^0.5`; FLIP =
//!    `colour^(1 − feature)`.
//!
//! Convolutions accumulate the taps in the same order as the reference implementation (left
//! to right, top to bottom) in `f32`, so the two agree to rounding. Rows are processed in
//! parallel (rayon); each output row depends only on its inputs, and means are summed per row
//! in `f64` and then in row order, so results are the same bits whatever the thread count.

use std::sync::OnceLock;

use rayon::prelude::*;

use crate::image::Image;

/// Pixels per degree of visual angle: 67, the FLIP paper's default viewing setup (a 0.7 m
/// wide, 3840-pixel monitor seen from 0.7 m).
pub const PIXELS_PER_DEGREE: f32 = 67.0;

/// Colour error exponent q_c.
const QC: f32 = 0.7;
/// Fraction of the maximum colour distance mapped to [`PT`]: p_c.
const PC: f32 = 0.4;
/// Error value the colour distance `PC · cmax` maps to: p_t.
const PT: f32 = 0.95;
/// Feature filter width, in degrees: w.
const GW: f32 = 0.082;
/// Feature error exponent q_f.
const QF: f32 = 0.5;
/// CSF Gaussian amplitudes and scales (a1, b1, a2, b2) for Y, Cx, Cz; the second Gaussian is
/// used by Cz only.
const A1: [f32; 3] = [1.0, 1.0, 34.1];
const B1: [f32; 3] = [0.0047, 0.0053, 0.04];
const A2: [f32; 3] = [0.0, 0.0, 13.5];
const B2: [f32; 3] = [1.0e-5, 1.0e-5, 0.025];
/// The D65 white point (XYZ) and its reciprocal.
const WHITE: [f32; 3] = [0.950_428_55, 1.0, 1.088_900_4];
const INV_WHITE: [f32; 3] = [1.052_156_9, 1.0, 0.918_357_7];

/// The per-image planes FLIP compares, for one image at [`PIXELS_PER_DEGREE`].
#[derive(Debug, Clone)]
pub struct FlipFeatures {
    width: usize,
    height: usize,
    /// Per row, [`PLANES`] planes of `width` values: L, a, b (Hunt-adjusted), edge, point.
    rows: Vec<f32>,
}

/// Planes per row of [`FlipFeatures::rows`].
const PLANES: usize = 5;
/// Planes per row after the horizontal pass: Y, Cx, Cz ⊛ g1, Cz ⊛ g2 (colour), and
/// ∂x, ∂²x, Gaussian of the normalised luminance (features).
const X_PLANES: usize = 7;

/// The 1-D kernels, built once.
struct Kernels {
    /// Colour radius (px) and per-tap weights: Y, Cx, Cz first term, Cz second term.
    colour_radius: usize,
    colour: [Vec<f32>; 4],
    /// Feature radius (px) and per-tap weights: Gaussian, first and second derivative.
    feature_radius: usize,
    feature: [Vec<f32>; 3],
    /// The maximum colour distance `cmax` (green to blue, after the exponent).
    cmax: f32,
    /// sRGB8 → linear RGB.
    linear: [f32; 256],
}

fn kernels() -> &'static Kernels {
    static K: OnceLock<Kernels> = OnceLock::new();
    K.get_or_init(Kernels::new)
}

impl Kernels {
    fn new() -> Self {
        let pi = std::f32::consts::PI;
        let pi2 = pi * pi;
        let ppd = PIXELS_PER_DEGREE;
        // Colour (CSF) filters, in the FLIP paper's `a·sqrt(π/b)·exp(−π²x²/b)` form.
        let max_b = B1.iter().chain(&B2[..2]).copied().fold(B2[2], f32::max);
        let colour_radius = (3.0 * (max_b / (2.0 * pi2)).sqrt() * ppd).ceil() as usize;
        let gauss = |x2: f32, a: f32, b: f32| a * (pi / b).sqrt() * (-pi2 * x2 / b).exp();
        let gauss_sqrt =
            |x2: f32, a: f32, b: f32| (a * (pi / b).sqrt()).sqrt() * (-pi2 * x2 / b).exp();
        let taps = 2 * colour_radius + 1;
        let mut colour: [Vec<f32>; 4] = std::array::from_fn(|_| Vec::with_capacity(taps));
        for i in 0..taps {
            let x = (i as f32 - colour_radius as f32) * (1.0 / ppd);
            let x2 = x * x;
            colour[0].push(gauss(x2, A1[0], B1[0]));
            colour[1].push(gauss(x2, A1[1], B1[1]));
            colour[2].push(gauss_sqrt(x2, A1[2], B1[2]));
            colour[3].push(gauss_sqrt(x2, A2[2], B2[2]));
        }
        // Y and Cx sum to 1; the two Cz terms together have unit norm.
        for k in &mut colour[..2] {
            let s: f32 = k.iter().sum();
            k.iter_mut().for_each(|v| *v *= 1.0 / s);
        }
        let (s1, s2): (f32, f32) = (colour[2].iter().sum(), colour[3].iter().sum());
        let norm = 1.0 / (s1 * s1 + s2 * s2).sqrt();
        for k in &mut colour[2..] {
            k.iter_mut().for_each(|v| *v *= norm);
        }

        // Feature filters: Gaussian and its derivatives, in pixels.
        let sd = 0.5 * GW * ppd;
        let feature_radius = (3.0 * sd).ceil() as usize;
        let taps = 2 * feature_radius + 1;
        let mut feature: [Vec<f32>; 3] = std::array::from_fn(|_| Vec::with_capacity(taps));
        for i in 0..taps {
            let x = i as f32 - feature_radius as f32;
            let g = (-(x * x) / (2.0 * sd * sd)).exp();
            feature[0].push(g);
            feature[1].push(-x * g);
            feature[2].push((x * x / (sd * sd) - 1.0) * g);
        }
        let g_sum: f32 = feature[0].iter().sum();
        feature[0].iter_mut().for_each(|v| *v /= g_sum);
        for k in &mut feature[1..] {
            let pos: f32 = k.iter().filter(|v| **v > 0.0).sum();
            let neg: f32 = -k.iter().filter(|v| **v <= 0.0).sum::<f32>();
            k.iter_mut()
                .for_each(|v| *v /= if *v > 0.0 { pos } else { neg });
        }

        let lab_hunt = |rgb: [f32; 3]| hunt(lab(linear_to_xyz(rgb)));
        let cmax = hyab(lab_hunt([0.0, 1.0, 0.0]), lab_hunt([0.0, 0.0, 1.0])).powf(QC);
        let linear = std::array::from_fn(|v| srgb_to_linear(v as f32 / 255.0));
        Kernels {
            colour_radius,
            colour,
            feature_radius,
            feature,
            cmax,
            linear,
        }
    }
}

/// The sRGB transfer function, inverted.
fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// Linear sRGB → CIE XYZ (D65).
fn linear_to_xyz([r, g, b]: [f32; 3]) -> [f32; 3] {
    [
        (10_135_552.0 / 24_577_794.0) * r
            + (8_788_810.0 / 24_577_794.0) * g
            + (4_435_075.0 / 24_577_794.0) * b,
        (2_613_072.0 / 12_288_897.0) * r
            + (8_788_810.0 / 12_288_897.0) * g
            + (887_015.0 / 12_288_897.0) * b,
        (1_425_312.0 / 73_733_382.0) * r
            + (8_788_810.0 / 73_733_382.0) * g
            + (70_074_185.0 / 73_733_382.0) * b,
    ]
}

/// CIE XYZ (D65) → linear sRGB.
fn xyz_to_linear([x, y, z]: [f32; 3]) -> [f32; 3] {
    [
        3.241_003_3 * x - 1.537_398_9 * y - 0.498_615_87 * z,
        -0.969_224_3 * x + 1.875_930_1 * y + 0.041_554_224 * z,
        0.055_639_423 * x - 0.204_011_2 * y + 1.057_148_9 * z,
    ]
}

/// CIE XYZ → YCxCz (the linear, opponent colour space FLIP filters in).
fn xyz_to_ycxcz(xyz: [f32; 3]) -> [f32; 3] {
    let (x, y, z) = (
        xyz[0] * INV_WHITE[0],
        xyz[1] * INV_WHITE[1],
        xyz[2] * INV_WHITE[2],
    );
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// YCxCz → CIE XYZ.
fn ycxcz_to_xyz([l, cx, cz]: [f32; 3]) -> [f32; 3] {
    let y = (l + 16.0) / 116.0;
    [
        (y + cx / 500.0) * WHITE[0],
        y * WHITE[1],
        (y - cz / 200.0) * WHITE[2],
    ]
}

/// CIE XYZ → CIELab (D65).
fn lab(xyz: [f32; 3]) -> [f32; 3] {
    let f = |i: usize| lab_companding(xyz[i] * INV_WHITE[i]);
    lab_from_companded([f(0), f(1), f(2)])
}

/// CIELab's companding of a white-relative tristimulus value: the cube root above
/// (6/29)³, a line below. Branch-free (both sides computed, one selected), so that loops of
/// it vectorise.
fn lab_companding(v: f32) -> f32 {
    const DELTA: f32 = 6.0 / 29.0;
    const DELTA3: f32 = DELTA * DELTA * DELTA;
    let root = cbrt_positive(v.max(DELTA3));
    let line = (1.0 / (3.0 * DELTA * DELTA)) * v + 4.0 / 29.0;
    if v > DELTA3 { root } else { line }
}

/// CIELab from the companded X, Y, Z.
fn lab_from_companded([x, y, z]: [f32; 3]) -> [f32; 3] {
    [116.0 * y - 16.0, 500.0 * (x - y), 200.0 * (y - z)]
}

/// The Hunt effect: chroma scaled by 0.01·L.
fn hunt([l, a, b]: [f32; 3]) -> [f32; 3] {
    [l, 0.01 * l * a, 0.01 * l * b]
}

/// HyAB colour distance: |ΔL| + Euclidean distance in (a, b).
fn hyab(p: [f32; 3], q: [f32; 3]) -> f32 {
    (p[0] - q[0]).abs() + ((p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2])).sqrt()
}

/// Output pixels per block of the convolutions: 16 accumulators in registers (four SSE
/// vectors), so each tap costs one load per four pixels and no store.
const BLOCK: usize = 32;

/// `out[x] = Σ_k w[k] · src[x + k]` for every `x` of `out`, taps summed in order.
fn convolve_row(out: &mut [f32], src: &[f32], w: &[f32]) {
    let shifted: Vec<&[f32]> = (0..w.len()).map(|k| &src[k..]).collect();
    convolve(out, &shifted, w);
}

/// `out[x] = Σ_k w[k] · rows[k][x]` for every `x` of `out`, taps summed in order: the
/// horizontal pass with `rows[k]` the source shifted by `k`, the vertical pass with
/// `rows[k]` the `k`-th input row.
fn convolve(out: &mut [f32], rows: &[&[f32]], w: &[f32]) {
    let n = out.len();
    let mut x = 0;
    while x + BLOCK <= n {
        let mut acc = [0.0f32; BLOCK];
        for (row, &wk) in rows.iter().zip(w) {
            let s = &row[x..x + BLOCK];
            for i in 0..BLOCK {
                acc[i] += wk * s[i];
            }
        }
        out[x..x + BLOCK].copy_from_slice(&acc);
        x += BLOCK;
    }
    for (i, o) in out.iter_mut().enumerate().skip(x) {
        *o = rows
            .iter()
            .zip(w)
            .fold(0.0, |a, (row, &wk)| a + wk * row[i]);
    }
}

/// Cube root of `v` > 0 to within a few ulp: an exponent-thirding first guess (≈ 3 %) and
/// two Halley steps (cubic convergence). Branch-free, so the final per-pixel loop
/// vectorises; `f32::cbrt` (a libm call) was a fifth of the preparation time.
fn cbrt_positive(v: f32) -> f32 {
    // The bits divided by three in `f32` (exact enough for a first guess, and unlike an
    // integer division it vectorises on SSE2).
    let third = (v.to_bits() as i32 as f32 * (1.0 / 3.0)) as i32;
    let mut y = f32::from_bits((third + 0x2a51_4067) as u32);
    for _ in 0..2 {
        let y3 = y * y * y;
        y *= (y3 + 2.0 * v) / (2.0 * y3 + v);
    }
    y
}

impl FlipFeatures {
    /// Prepares `image` (its R, G, B; alpha ignored). With `background`, pixels with alpha 0
    /// take that colour instead of their own (see [`super::metric_background`]).
    pub fn new(image: &Image, background: Option<[u8; 3]>) -> Self {
        let (width, height) = (image.width as usize, image.height as usize);
        if width == 0 || height == 0 {
            return FlipFeatures {
                width,
                height,
                rows: Vec::new(),
            };
        }
        let k = kernels();
        let w = width;
        // Horizontal pass: per row, YCxCz and normalised luminance with clamped (edge-
        // replicated) borders, then the 1-D kernels along x.
        let pad = k.colour_radius.max(k.feature_radius);
        let mut xrows = vec![0.0f32; height * X_PLANES * w];
        xrows
            .par_chunks_mut(X_PLANES * w)
            .enumerate()
            .for_each_init(
                || [(); 4].map(|_| vec![0.0f32; w + 2 * pad]),
                |padded, (y, out)| {
                    let src = &image.rgba[y * w * 4..(y + 1) * w * 4];
                    let [py, pcx, pcz, pn] = padded;
                    // Linear R, G, B into the Y, Cx, Cz planes (table look-ups), then
                    // converted in place (a loop that vectorises), then the borders.
                    let (lr, lg, lb) = (
                        &mut py[pad..pad + w],
                        &mut pcx[pad..pad + w],
                        &mut pcz[pad..pad + w],
                    );
                    for (i, p) in src.chunks_exact(4).enumerate() {
                        let rgb = match background {
                            Some(bg) if p[3] == 0 => bg,
                            _ => [p[0], p[1], p[2]],
                        };
                        lr[i] = k.linear[usize::from(rgb[0])];
                        lg[i] = k.linear[usize::from(rgb[1])];
                        lb[i] = k.linear[usize::from(rgb[2])];
                    }
                    let pn = &mut pn[pad..pad + w];
                    for i in 0..w {
                        let [yy, cx, cz] = xyz_to_ycxcz(linear_to_xyz([lr[i], lg[i], lb[i]]));
                        lr[i] = yy;
                        lg[i] = cx;
                        lb[i] = cz;
                        pn[i] = yy * (1.0 / 116.0) + 16.0 / 116.0;
                    }
                    for plane in padded.iter_mut() {
                        let (first, last) = (plane[pad], plane[pad + w - 1]);
                        plane[..pad].fill(first);
                        plane[pad + w..].fill(last);
                    }
                    let [py, pcx, pcz, pn] = padded;
                    let (cr, fr) = (k.colour_radius, k.feature_radius);
                    let mut planes = out.chunks_exact_mut(w);
                    let mut next = || planes.next().expect("X_PLANES planes per row");
                    convolve_row(next(), &py[pad - cr..], &k.colour[0]);
                    convolve_row(next(), &pcx[pad - cr..], &k.colour[1]);
                    convolve_row(next(), &pcz[pad - cr..], &k.colour[2]);
                    convolve_row(next(), &pcz[pad - cr..], &k.colour[3]);
                    convolve_row(next(), &pn[pad - fr..], &k.feature[1]);
                    convolve_row(next(), &pn[pad - fr..], &k.feature[2]);
                    convolve_row(next(), &pn[pad - fr..], &k.feature[0]);
                },
            );

        // Vertical pass: per output row, the kernels along y over clamped input rows, then
        // the per-pixel colour conversion and feature magnitudes.
        let mut rows = vec![0.0f32; height * PLANES * w];
        rows.par_chunks_mut(PLANES * w).enumerate().for_each_init(
            || [(); 8].map(|_| vec![0.0f32; w]),
            |acc, (y, out)| {
                // Plane `p` of the input rows under a kernel of radius `r` centred on row
                // `y`, clamped to the image.
                let rows = |r: usize, p: usize| -> Vec<&[f32]> {
                    (0..=2 * r)
                        .map(|t| {
                            let row = (y + t).saturating_sub(r).min(height - 1);
                            &xrows[(row * X_PLANES + p) * w..][..w]
                        })
                        .collect()
                };
                let (cr, fr) = (k.colour_radius, k.feature_radius);
                let [ay, acx, acz1, acz2, adx, addx, ady, addy] = acc;
                convolve(ay, &rows(cr, 0), &k.colour[0]);
                convolve(acx, &rows(cr, 1), &k.colour[1]);
                convolve(acz1, &rows(cr, 2), &k.colour[2]);
                convolve(acz2, &rows(cr, 3), &k.colour[3]);
                convolve(adx, &rows(fr, 4), &k.feature[0]);
                convolve(addx, &rows(fr, 5), &k.feature[0]);
                let g = rows(fr, 6);
                convolve(ady, &g, &k.feature[1]);
                convolve(addy, &g, &k.feature[2]);
                let (l_, rest) = out.split_at_mut(w);
                let (a_, rest) = rest.split_at_mut(w);
                let (b_, rest) = rest.split_at_mut(w);
                let (edge, point) = rest.split_at_mut(w);
                // In three sweeps, so that the middle one (cube roots) vectorises: the
                // filtered colour as white-relative XYZ (clamped to the sRGB gamut) into the
                // L, a, b planes; their companding in place; then Lab and the Hunt effect.
                let (ay, acx, acz1, acz2) = (&ay[..w], &acx[..w], &acz1[..w], &acz2[..w]);
                let (adx, addx, ady, addy) = (&adx[..w], &addx[..w], &ady[..w], &addy[..w]);
                let (l_, a_, b_, edge) = (&mut l_[..w], &mut a_[..w], &mut b_[..w], &mut edge[..w]);
                let point = &mut point[..w];
                for x in 0..w {
                    let ycxcz = [ay[x], acx[x], acz1[x] + acz2[x]];
                    let [r, g, b] = xyz_to_linear(ycxcz_to_xyz(ycxcz));
                    let rgb = [r.clamp(0.0, 1.0), g.clamp(0.0, 1.0), b.clamp(0.0, 1.0)];
                    let xyz = linear_to_xyz(rgb);
                    l_[x] = xyz[0] * INV_WHITE[0];
                    a_[x] = xyz[1] * INV_WHITE[1];
                    b_[x] = xyz[2] * INV_WHITE[2];
                }
                for plane in [&mut *l_, &mut *a_, &mut *b_] {
                    for v in plane.iter_mut() {
                        *v = lab_companding(*v);
                    }
                }
                for x in 0..w {
                    let [l, a, b] = hunt(lab_from_companded([l_[x], a_[x], b_[x]]));
                    l_[x] = l;
                    a_[x] = a;
                    b_[x] = b;
                    edge[x] = (adx[x] * adx[x] + ady[x] * ady[x]).sqrt();
                    point[x] = (addx[x] * addx[x] + addy[x] * addy[x]).sqrt();
                }
            },
        );
        FlipFeatures {
            width,
            height,
            rows,
        }
    }

    /// (width, height) in pixels.
    pub fn size(&self) -> (usize, usize) {
        (self.width, self.height)
    }

    /// Row `y`'s planes: L, a, b, edge, point.
    fn row(&self, y: usize) -> [&[f32]; PLANES] {
        let w = self.width;
        let r = &self.rows[y * PLANES * w..][..PLANES * w];
        std::array::from_fn(|p| &r[p * w..][..w])
    }
}

/// Per-pixel FLIP error of row `y` of `a` against `b`, into `out`.
fn error_row(a: &FlipFeatures, b: &FlipFeatures, y: usize, out: &mut [f32]) {
    let k = kernels();
    let pccmax = PC * k.cmax;
    let [la, aa, ba, ea, pa] = a.row(y);
    let [lb, ab, bb, eb, pb] = b.row(y);
    for (x, o) in out.iter_mut().enumerate() {
        let d = hyab([la[x], aa[x], ba[x]], [lb[x], ab[x], bb[x]]).powf(QC);
        let colour = if d < pccmax {
            d * (PT / pccmax)
        } else {
            PT + ((d - pccmax) / (k.cmax - pccmax)) * (1.0 - PT)
        };
        let feature = (std::f32::consts::FRAC_1_SQRT_2
            * (ea[x] - eb[x]).abs().max((pa[x] - pb[x]).abs()))
        .powf(QF);
        *o = colour.powf(1.0 - feature);
    }
}

/// Panics unless both were prepared from images of one size (callers check sizes first).
fn assert_same_size(a: &FlipFeatures, b: &FlipFeatures) {
    assert_eq!(a.size(), b.size(), "FLIP features of different sizes");
}

/// Mean FLIP error of `b` against `a` (0 for empty images). Symmetric in its arguments.
pub fn error_mean(a: &FlipFeatures, b: &FlipFeatures) -> f64 {
    assert_same_size(a, b);
    let (w, h) = a.size();
    if w == 0 || h == 0 {
        return 0.0;
    }
    let row_sums: Vec<f64> = (0..h)
        .into_par_iter()
        .map_init(
            || vec![0.0f32; w],
            |row, y| {
                error_row(a, b, y, row);
                row.iter().map(|&e| f64::from(e)).sum::<f64>()
            },
        )
        .collect();
    row_sums.iter().sum::<f64>() / (w * h) as f64
}

/// The per-pixel FLIP error map (row-major, values in 0..1).
pub fn error_map(a: &FlipFeatures, b: &FlipFeatures) -> Vec<f32> {
    assert_same_size(a, b);
    let (w, h) = a.size();
    let mut map = vec![0.0f32; w * h];
    if w > 0 {
        map.par_chunks_mut(w)
            .enumerate()
            .for_each(|(y, row)| error_row(a, b, y, row));
    }
    map
}
