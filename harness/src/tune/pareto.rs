//! The choice among settings, as plain functions of measured (cost, error) points: the
//! Pareto front, the error of each setting at a common cost, and whether a margin is larger
//! than run-to-run noise.
//!
//! **Equal cost.** At target `t` the settings' costs differ (a tolerance draws more or fewer
//! points depending on the setting; a budget takes more or less time). The common cost
//! `c_t` is the median of the settings' costs at `t`; each setting's error at `c_t` is read
//! off its own curve through its targets (sorted by cost), linearly in log cost between the
//! two targets that bracket `c_t`. A setting whose curve does not reach `c_t` counts only
//! when its nearest measured cost is within [`REACH`] of it (then that point's error is
//! used); otherwise it is "not comparable at this cost" and listed as such.
//!
//! **A budget is a cost.** When the targets are point budgets and the cost is points drawn,
//! the budget itself is the common cost: a setting draws at most that many points, so its
//! error there is simply its measured error at that target ([`Common::Target`]); a setting
//! that leaves part of the budget unused is not penalised by an interpolation to a cost it
//! never paid.

/// How far (relative) a setting's nearest measured cost may be from the common cost for its
/// error there to count, when its curve does not bracket the common cost.
pub const REACH: f64 = 0.10;

/// Which points are on the Pareto front of (cost, error), both to be minimised: a point is
/// on it when no other point is at most as costly and at most as wrong, and better in one.
/// Points with a non-finite coordinate are never on it.
pub fn front(points: &[(f64, f64)]) -> Vec<bool> {
    points
        .iter()
        .map(|&(c, e)| {
            c.is_finite()
                && e.is_finite()
                && !points.iter().any(|&(c2, e2)| {
                    c2.is_finite() && e2.is_finite() && c2 <= c && e2 <= e && (c2 < c || e2 < e)
                })
        })
        .collect()
}

/// A setting's error at cost `c`, from its `(cost, error)` points (any order; non-finite
/// ones ignored): interpolated linearly in log cost (in cost, if a cost is ≤ 0) between the
/// two points bracketing `c`, else the nearest point's error when its cost is within
/// [`REACH`] of `c`. `None`: the curve does not reach `c`.
pub fn error_at(curve: &[(f64, f64)], c: f64) -> Option<f64> {
    let mut pts: Vec<(f64, f64)> = curve
        .iter()
        .copied()
        .filter(|(x, y)| x.is_finite() && y.is_finite())
        .collect();
    if pts.is_empty() || !c.is_finite() {
        return None;
    }
    pts.sort_by(|a, b| a.0.total_cmp(&b.0));
    let log = pts[0].0 > 0.0 && c > 0.0;
    let x = |v: f64| if log { v.ln() } else { v };
    for w in pts.windows(2) {
        let ((c0, e0), (c1, e1)) = (w[0], w[1]);
        if c0 <= c && c <= c1 {
            if c1 == c0 {
                return Some(e0.min(e1));
            }
            let f = (x(c) - x(c0)) / (x(c1) - x(c0));
            return Some(e0 + f * (e1 - e0));
        }
    }
    let nearest = pts
        .iter()
        .min_by(|a, b| (a.0 - c).abs().total_cmp(&(b.0 - c).abs()))?;
    let scale = c.abs().max(f64::MIN_POSITIVE);
    ((nearest.0 - c).abs() <= REACH * scale).then_some(nearest.1)
}

/// The median of `v` (mean of the middle two); `None` when empty.
pub fn median(v: &[f64]) -> Option<f64> {
    crate::results::median(v.iter().copied())
}

/// The settings ranked at one target.
#[derive(Debug, Clone, PartialEq)]
pub struct Ranking {
    /// The common cost `c_t`.
    pub cost: f64,
    /// `(setting, error at c_t)`, lowest error first (ties: the earlier setting).
    pub ranked: Vec<(usize, f64)>,
    /// Settings whose curve does not reach `c_t`.
    pub unreachable: Vec<usize>,
}

/// Where the settings are compared at a target.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Common {
    /// At the median of their costs, each read off its curve (see the module docs).
    Median,
    /// At the target itself, a cost cap (a point budget when the cost is points): each
    /// setting's own measured error there; the ranking's cost is this value.
    Target(f64),
}

/// Ranks the settings at target `t`: `curves[s][t']` is setting `s`'s `(cost, error)` at
/// target `t'` (`None`: not measured), compared as `common` says. Settings with no point at
/// `t` take no part. `None` when no setting has a point at `t`.
pub fn rank(curves: &[Vec<Option<(f64, f64)>>], t: usize, common: Common) -> Option<Ranking> {
    let at_t: Vec<(usize, f64)> = curves
        .iter()
        .enumerate()
        .filter_map(|(s, c)| {
            c.get(t)
                .copied()
                .flatten()
                .filter(|(x, y)| x.is_finite() && y.is_finite())
                .map(|(x, _)| (s, x))
        })
        .collect();
    if let Common::Target(cap) = common {
        let mut ranked: Vec<(usize, f64)> = at_t
            .iter()
            .filter_map(|&(s, _)| Some((s, curves[s][t]?.1)))
            .collect();
        ranked.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
        return (!ranked.is_empty()).then_some(Ranking {
            cost: cap,
            ranked,
            unreachable: Vec::new(),
        });
    }
    let cost = median(&at_t.iter().map(|p| p.1).collect::<Vec<_>>())?;
    let mut ranked = Vec::new();
    let mut unreachable = Vec::new();
    for (s, _) in at_t {
        let curve: Vec<(f64, f64)> = curves[s].iter().flatten().copied().collect();
        match error_at(&curve, cost) {
            Some(e) => ranked.push((s, e)),
            None => unreachable.push(s),
        }
    }
    ranked.sort_by(|a, b| a.1.total_cmp(&b.1).then(a.0.cmp(&b.0)));
    Some(Ranking {
        cost,
        ranked,
        unreachable,
    })
}

/// Whether `margin` (runner-up's error − best's) is larger than run-to-run noise: the sum of
/// the two settings' changes between repeated runs (`None`: not measured, so unknown).
pub fn beyond_noise(margin: f64, noise: Option<(f64, f64)>) -> Option<bool> {
    noise.map(|(a, b)| margin > a + b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_front_keeps_what_nothing_beats() {
        let pts = [
            (1.0, 0.5),
            (2.0, 0.3),
            (2.0, 0.4), // beaten by (2, 0.3)
            (3.0, 0.3), // beaten by (2, 0.3)
            (4.0, 0.1),
            (f64::NAN, 0.0),
            (1.0, 0.5), // a tie is not beaten
        ];
        assert_eq!(front(&pts), [true, true, false, false, true, false, true]);
    }

    #[test]
    fn errors_are_read_at_a_common_cost() {
        let curve = [(100.0, 0.4), (400.0, 0.2), (1600.0, 0.1)];
        // Halfway in log cost between 100 and 400.
        assert!((error_at(&curve, 200.0).unwrap() - 0.3).abs() < 1e-12);
        assert_eq!(error_at(&curve, 400.0), Some(0.2));
        // Beyond the curve: the end point within 10 %, else nothing.
        assert_eq!(error_at(&curve, 1700.0), Some(0.1));
        assert_eq!(error_at(&curve, 2000.0), None);
        assert_eq!(error_at(&curve, 95.0), Some(0.4));
        assert_eq!(error_at(&[], 1.0), None);
        // A cost of 0 interpolates linearly.
        assert_eq!(error_at(&[(0.0, 1.0), (2.0, 0.0)], 1.0), Some(0.5));
    }

    #[test]
    fn ranking_on_hand_made_rows() {
        // Three settings × two budgets; costs are points drawn.
        let curves = vec![
            vec![Some((1000.0, 0.30)), Some((2000.0, 0.20))],
            vec![Some((1000.0, 0.25)), Some((2000.0, 0.22))],
            vec![Some((500.0, 0.50)), None],
        ];
        let r = rank(&curves, 0, Common::Median).unwrap();
        assert_eq!(r.cost, 1000.0);
        assert_eq!(r.ranked, [(1, 0.25), (0, 0.30)]);
        assert_eq!(
            r.unreachable,
            [2],
            "its one point is 50 % below the common cost"
        );
        let r = rank(&curves, 1, Common::Median).unwrap();
        assert_eq!(r.cost, 2000.0);
        assert_eq!(r.ranked, [(0, 0.20), (1, 0.22)]);
        assert!(rank(&[vec![None]], 0, Common::Median).is_none());
        // Within a budget of 1000 points, the setting that drew 500 takes part as it is.
        let r = rank(&curves, 0, Common::Target(1000.0)).unwrap();
        assert_eq!(r.ranked, [(1, 0.25), (0, 0.30), (2, 0.50)]);
        assert_eq!((r.cost, r.unreachable.len()), (1000.0, 0));
        assert_eq!(beyond_noise(0.02, Some((0.005, 0.004))), Some(true));
        assert_eq!(beyond_noise(0.02, Some((0.015, 0.01))), Some(false));
        assert_eq!(beyond_noise(0.02, None), None);
        assert_eq!(beyond_noise(1e-9, Some((0.0, 0.0))), Some(true));
    }
}
