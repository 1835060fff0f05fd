//! Spline maths shared by the paths: cubic Hermite segments, non-uniform Catmull–Rom tangents,
//! and a closed centripetal Catmull–Rom loop re-parameterised by arc length.

use glam::DVec3;

/// Cubic Hermite segment on `s ∈ [0, 1]` from `p0` to `p1` with end derivatives `m0`, `m1`
/// (with respect to `s`). Exactly `p0` at `s = 0` and exactly `p1` at `s = 1`.
pub(super) fn hermite(p0: DVec3, m0: DVec3, p1: DVec3, m1: DVec3, s: f64) -> DVec3 {
    let s2 = s * s;
    let s3 = s2 * s;
    p0 * (2.0 * s3 - 3.0 * s2 + 1.0)
        + m0 * (s3 - 2.0 * s2 + s)
        + p1 * (-2.0 * s3 + 3.0 * s2)
        + m1 * (s3 - s2)
}

/// Derivative at `p1` (with respect to the knot parameter) of the non-uniform Catmull–Rom
/// spline through `p0, p1, p2` with knot intervals `d0 = t1 − t0 > 0` and `d1 = t2 − t1 > 0`
/// (Barry–Goldman). Equals `(s0·d1 + s1·d0) / (d0 + d1)` for the slopes `s0`, `s1` of the
/// two chords.
pub(super) fn catmull_rom_tangent(p0: DVec3, p1: DVec3, p2: DVec3, d0: f64, d1: f64) -> DVec3 {
    (p1 - p0) / d0 - (p2 - p0) / (d0 + d1) + (p2 - p1) / d1
}

/// Samples per segment of the arc-length table.
const ARC_SAMPLES: usize = 64;

/// A closed centripetal Catmull–Rom loop through control points, evaluated by arc length.
#[derive(Debug, Clone)]
pub(super) struct ClosedLoop {
    points: Vec<DVec3>,
    /// Knot interval of segment `j` (from point `j` to `j + 1`): `|p_{j+1} − p_j|^½`.
    knots: Vec<f64>,
    /// Cumulative arc length at parameter `k / ARC_SAMPLES` (segment `k / ARC_SAMPLES`);
    /// `points.len() · ARC_SAMPLES + 1` entries, the last being the loop's length.
    arc: Vec<f64>,
}

impl ClosedLoop {
    /// The loop through `points` (at least 3, consecutive points distinct).
    pub(super) fn new(points: Vec<DVec3>) -> ClosedLoop {
        let n = points.len();
        let knots = (0..n)
            .map(|j| points[j].distance(points[(j + 1) % n]).sqrt().max(1e-12))
            .collect();
        let mut lp = ClosedLoop {
            points,
            knots,
            arc: Vec::with_capacity(n * ARC_SAMPLES + 1),
        };
        let mut total = 0.0;
        let mut prev = lp.point(0.0);
        lp.arc.push(0.0);
        for k in 1..=n * ARC_SAMPLES {
            let p = lp.point(k as f64 / ARC_SAMPLES as f64);
            total += p.distance(prev);
            lp.arc.push(total);
            prev = p;
        }
        lp
    }

    /// Length of the loop (of its arc-length table's polyline, 64 chords per segment).
    pub(super) fn length(&self) -> f64 {
        self.arc.last().copied().unwrap_or(0.0)
    }

    /// Point at parameter `u ∈ [0, n)`: segment `⌊u⌋`, local parameter `u − ⌊u⌋`.
    fn point(&self, u: f64) -> DVec3 {
        let n = self.points.len();
        let seg = (u.floor() as usize).min(n - 1);
        let s = (u - seg as f64).clamp(0.0, 1.0);
        let at = |j: usize| self.points[(j + n) % n];
        let knot = |j: usize| self.knots[(j + n) % n];
        let (p0, p1, p2, p3) = (at(seg + n - 1), at(seg), at(seg + 1), at(seg + 2));
        let (d0, d1, d2) = (knot(seg + n - 1), knot(seg), knot(seg + 1));
        let m1 = catmull_rom_tangent(p0, p1, p2, d0, d1) * d1;
        let m2 = catmull_rom_tangent(p1, p2, p3, d1, d2) * d1;
        hermite(p1, m1, p2, m2, s)
    }

    /// Point at arc length `len` from point 0 (taken modulo the length).
    pub(super) fn at_length(&self, len: f64) -> DVec3 {
        let total = self.length();
        if total.is_nan() || total <= 0.0 {
            return self.points[0];
        }
        let len = len.rem_euclid(total);
        // First table entry ≥ len; interpolate the parameter within the chord before it.
        let k = self
            .arc
            .partition_point(|&a| a < len)
            .clamp(1, self.arc.len() - 1);
        let (a0, a1) = (self.arc[k - 1], self.arc[k]);
        let f = if a1 > a0 { (len - a0) / (a1 - a0) } else { 0.0 };
        self.point((k as f64 - 1.0 + f) / ARC_SAMPLES as f64)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hermite_hits_its_ends_exactly() {
        let (a, b) = (DVec3::new(0.1, 0.2, 0.3), DVec3::new(-1.7, 2.9, 0.3));
        let (m0, m1) = (DVec3::new(5.0, -3.0, 1.0), DVec3::new(-2.0, 0.5, 7.0));
        assert_eq!(hermite(a, m0, b, m1, 0.0), a);
        assert_eq!(hermite(a, m0, b, m1, 1.0), b);
    }

    #[test]
    fn catmull_rom_tangent_of_collinear_evenly_timed_points_is_the_slope() {
        let m = catmull_rom_tangent(DVec3::ZERO, DVec3::X, DVec3::X * 2.0, 0.5, 0.5);
        assert!((m - DVec3::X * 2.0).length() < 1e-12);
    }

    #[test]
    fn closed_loop_wraps_and_moves_evenly() {
        let square = vec![
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, 1.0, 0.0),
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(0.0, -1.0, 0.0),
        ];
        let lp = ClosedLoop::new(square);
        let l = lp.length();
        assert!(
            l > 4.0 * 2f64.sqrt() && l < 2.0 * std::f64::consts::PI * 1.1,
            "{l}"
        );
        assert!((lp.at_length(0.0) - DVec3::X).length() < 1e-12);
        assert!((lp.at_length(l) - DVec3::X).length() < 1e-9);
        let steps: Vec<f64> = (0..100)
            .map(|i| {
                lp.at_length(l * i as f64 / 100.0)
                    .distance(lp.at_length(l * (i + 1) as f64 / 100.0))
            })
            .collect();
        let (lo, hi) = steps
            .iter()
            .fold((f64::MAX, 0f64), |(lo, hi), &s| (lo.min(s), hi.max(s)));
        assert!(hi / lo < 1.01, "constant speed: {lo} .. {hi}");
    }
}
