//! A confidence interval for a time's change, so that a timing gate fails only a change the
//! frames show to be real (criterion's idea: a regression is a confidence interval beyond a
//! threshold, not one median beyond it). The ratio is median(new) ÷ median(old) over the
//! frames of each run; its 95 % interval is a percentile bootstrap, each run's frames
//! resampled with replacement [`RESAMPLES`] times from a fixed seed (the same runs give the
//! same interval). With fewer than [`MIN_FRAMES`] frames on either side there is no interval
//! and the gate compares the medians, as before.

use scenes::rng::Pcg32;

/// Frames each run needs for an interval (fewer: a median of a handful says little about
/// its spread).
pub const MIN_FRAMES: usize = 10;

/// Bootstrap resamples.
pub const RESAMPLES: usize = 2000;

/// The seed of the resampling (fixed: a check repeats).
const SEED: u64 = 0x5eed_c4ec;

/// The 95 % interval of median(`new`) ÷ median(`old`), or `None` with fewer than
/// [`MIN_FRAMES`] positive finite values on either side.
pub fn ratio_interval(old: &[f64], new: &[f64]) -> Option<(f64, f64)> {
    let clean = |v: &[f64]| -> Vec<f64> {
        v.iter()
            .copied()
            .filter(|x| x.is_finite() && *x > 0.0)
            .collect()
    };
    let (old, new) = (clean(old), clean(new));
    if old.len() < MIN_FRAMES || new.len() < MIN_FRAMES {
        return None;
    }
    let mut rng = Pcg32::new(SEED);
    let mut draw = |v: &[f64], buf: &mut Vec<f64>| {
        buf.clear();
        buf.extend((0..v.len()).map(|_| v[rng.below(v.len() as u32) as usize]));
        median_of(buf)
    };
    let (mut a, mut b) = (Vec::new(), Vec::new());
    let mut ratios: Vec<f64> = (0..RESAMPLES)
        .map(|_| {
            let m_old = draw(&old, &mut a);
            let m_new = draw(&new, &mut b);
            m_new / m_old
        })
        .collect();
    ratios.sort_by(f64::total_cmp);
    let at = |q: f64| ratios[((RESAMPLES - 1) as f64 * q).round() as usize];
    Some((at(0.025), at(0.975)))
}

/// Median of `v` (sorted in place; mean of the middle two for an even count).
fn median_of(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Frames of a time around `centre` with a spread of ± `spread` (deterministic).
    fn frames(centre: f64, spread: f64, n: usize) -> Vec<f64> {
        (0..n)
            .map(|i| centre + spread * (((i * 7) % 11) as f64 / 5.0 - 1.0))
            .collect()
    }

    #[test]
    fn the_interval_holds_the_true_ratio_and_needs_frames() {
        let old = frames(10.0, 1.0, 30);
        let twice: Vec<f64> = old.iter().map(|x| 2.0 * x).collect();
        let (lo, hi) = ratio_interval(&old, &twice).unwrap();
        assert!(lo <= 2.0 && 2.0 <= hi && hi - lo < 0.5, "{lo}–{hi}");
        // The same frames: an interval around 1.
        let (lo, hi) = ratio_interval(&old, &old).unwrap();
        assert!(lo <= 1.0 && 1.0 <= hi, "{lo}–{hi}");
        // Noisy frames widen it; too few frames give none.
        let noisy = frames(10.0, 8.0, 12);
        let (lo, hi) = ratio_interval(&old, &noisy).unwrap();
        assert!(hi - lo > 0.5, "{lo}–{hi}");
        assert_eq!(ratio_interval(&old[..9], &old), None);
        // The same runs give the same interval.
        assert_eq!(ratio_interval(&old, &noisy), ratio_interval(&old, &noisy));
    }
}
