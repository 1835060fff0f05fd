//! What a check allows: the image metrics' absolute tolerances on the baseline's adapter
//! and on another, with the reason written beside them in the baseline file.

/// Allowed absolute differences of the image metrics; `None`: not compared.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImageTolerance {
    /// Mean FLIP.
    pub flip_mean: Option<f64>,
    /// Hole ratio.
    pub hole_ratio: Option<f64>,
    /// Extra coverage.
    pub extra_coverage: Option<f64>,
    /// PSNR, dB.
    pub psnr_db: Option<f64>,
    /// Mean SSIM.
    pub ssim: Option<f64>,
    /// Popping FLIP (a difference of two FLIP means); absent in baselines blessed before
    /// the column existed, which then do not compare it.
    #[serde(default)]
    pub popping_flip: Option<f64>,
    /// The warped popping figures (`warped_flip_*`, `warped_ref_flip_*`,
    /// `popping_warped_*`: FLIP means and their difference); absent in baselines blessed
    /// before they existed, which then do not compare them.
    #[serde(default)]
    pub popping_warped: Option<f64>,
    /// The warp's counts (`pop_events_*`, pixels; `warp_valid_*`, a fraction of pixels);
    /// absent in older baselines as above.
    #[serde(default)]
    pub warp_counts: Option<f64>,
}

impl ImageTolerance {
    /// The allowance of image column `column` (`None`: not compared).
    pub fn of(&self, column: &str) -> Option<f64> {
        match column {
            "flip_mean" => self.flip_mean,
            "hole_ratio" => self.hole_ratio,
            "extra_coverage" => self.extra_coverage,
            "psnr_db" => self.psnr_db,
            "ssim" => self.ssim,
            "popping_flip" => self.popping_flip,
            c if c.starts_with("warped_") || c.starts_with("popping_warped_") => {
                self.popping_warped
            }
            c if c.starts_with("pop_events_") || c.starts_with("warp_valid_") => self.warp_counts,
            _ => None,
        }
    }
}

/// The image tolerances of a baseline, with the reason for them. `--bless` keeps those of
/// the baseline it replaces, so that a tolerance set by hand survives re-blessing.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Tolerances {
    /// Why these values.
    pub note: String,
    /// When the run's adapter (name and backend) is the baseline run's.
    pub same_adapter: ImageTolerance,
    /// When it is another.
    pub other_adapter: ImageTolerance,
}

impl Default for Tolerances {
    /// On one adapter a run draws the same pixels every time (renders are byte-identical run
    /// to run, NOTES-wgpu.md, and the check of the committed suite repeats them), so the
    /// allowance only covers the metric code's floating point on another CPU. On another
    /// adapter: the golden-image tolerance of `harness/tests/render.rs` (FLIP ≤ 0.02, holes
    /// ≤ 0.01, set on llvmpipe); PSNR, SSIM and extra coverage swing with a few pixels of
    /// rasterisation and are not compared there. Popping FLIP is a difference of two FLIP
    /// means, so it gets twice FLIP's allowance, as do the warped popping figures; the
    /// warp's counts are exact on one adapter.
    fn default() -> Self {
        Self {
            note: "same adapter: renders repeat byte for byte, the allowance covers the \
                   metrics' floating point on another CPU; other adapter: the golden-image \
                   tolerance of harness/tests/render.rs (FLIP 0.02, holes 0.01), PSNR, SSIM \
                   and extra coverage not compared; popping FLIP, a difference of two FLIP \
                   means, twice FLIP's allowance, and so the warped popping figures; the \
                   warp's counts exact on one adapter, not compared on another (a pixel more \
                   or less at every splat edge)"
                .into(),
            same_adapter: ImageTolerance {
                flip_mean: Some(1e-6),
                hole_ratio: Some(1e-6),
                extra_coverage: Some(1e-6),
                psnr_db: Some(1e-4),
                ssim: Some(1e-6),
                popping_flip: Some(2e-6),
                popping_warped: Some(2e-6),
                warp_counts: Some(0.0),
            },
            other_adapter: ImageTolerance {
                flip_mean: Some(0.02),
                hole_ratio: Some(0.01),
                extra_coverage: None,
                psnr_db: None,
                ssim: None,
                popping_flip: Some(0.04),
                popping_warped: Some(0.04),
                warp_counts: None,
            },
        }
    }
}
