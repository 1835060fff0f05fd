//! Culling tests shared by the methods: back-facing normal cones, and the cone that bounds a
//! set of normals or a union of cones (built bottom-up by LPC and MWKD).

use glam::Vec3;

/// A normal cone with a bounding sphere: the cluster is back-facing for `eye` if every node
/// normal `m` (angle to `axis` ≤ `half_angle`) and centre `p` (within the sphere) have
/// `m·(eye − p) < 0`. Conservative: `m·(eye − p) ≤ L·cos(max(θ − β, 0)) + R` with `L = |eye − c|`
/// and θ the angle between `axis` and `eye − c`.
pub fn cone_backfacing(axis: Vec3, half_angle: f32, center: Vec3, radius: f32, eye: Vec3) -> bool {
    let v = eye - center;
    let l = v.length();
    if l <= radius || half_angle >= std::f32::consts::PI {
        return false;
    }
    let theta = (axis.dot(v) / l).clamp(-1.0, 1.0).acos();
    let gap = theta - half_angle;
    gap > std::f32::consts::FRAC_PI_2 && l * gap.cos() + radius < 0.0
}

/// A normal cone: every normal `m` it bounds has `angle(m, axis) ≤ half_angle`. A half-angle
/// of π (or more) bounds everything and is never back-facing.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cone {
    /// Unit axis (zero when the cone bounds everything).
    pub axis: Vec3,
    /// Half-angle, radians, in `[0, π]`.
    pub half_angle: f32,
}

impl Cone {
    /// The cone that bounds everything (no normals, or normals in every direction).
    pub const ALL: Cone = Cone {
        axis: Vec3::ZERO,
        half_angle: std::f32::consts::PI,
    };

    /// A cone around the normalised mean of `normals` that contains every one of them
    /// ([`Cone::ALL`] when the mean vanishes or the set is empty). Non-unit normals are
    /// normalised; zero ones are ignored.
    pub fn of_normals(normals: impl Iterator<Item = Vec3> + Clone) -> Cone {
        let sum: Vec3 = normals.clone().map(|n| n.normalize_or_zero()).sum();
        let Some(axis) = sum.try_normalize() else {
            return Cone::ALL;
        };
        let half = normals
            .filter_map(|n| n.try_normalize())
            .map(|n| axis.dot(n).clamp(-1.0, 1.0).acos())
            .fold(0.0f32, f32::max);
        Cone::new(axis, half)
    }

    /// A cone containing every cone of `cones` (axis: the normalised sum of the axes; half-angle:
    /// the largest `angle(axis, axisᵢ) + halfᵢ`, rounded up by 1e-6 rad). [`Cone::ALL`] if any
    /// input is, or the axes cancel.
    pub fn union(cones: impl Iterator<Item = Cone> + Clone) -> Cone {
        if cones.clone().any(|c| c.half_angle >= std::f32::consts::PI) {
            return Cone::ALL;
        }
        let Some(axis) = cones.clone().map(|c| c.axis).sum::<Vec3>().try_normalize() else {
            return Cone::ALL;
        };
        let half = cones
            .map(|c| axis.dot(c.axis).clamp(-1.0, 1.0).acos() + c.half_angle)
            .fold(0.0f32, f32::max);
        Cone::new(axis, half)
    }

    /// A cone of the given axis and half-angle (rounded up by 1e-6 rad against `acos`
    /// rounding; π or more is [`Cone::ALL`]).
    pub fn new(axis: Vec3, half_angle: f32) -> Cone {
        let h = half_angle + 1e-6;
        if h >= std::f32::consts::PI || !h.is_finite() {
            Cone::ALL
        } else {
            Cone {
                axis,
                half_angle: h,
            }
        }
    }

    /// [`cone_backfacing`] of this cone with a bounding sphere.
    pub fn backfacing(&self, center: Vec3, radius: f32, eye: Vec3) -> bool {
        cone_backfacing(self.axis, self.half_angle, center, radius, eye)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cones_contain_their_normals_and_unions_their_cones() {
        let ns = [Vec3::Z, Vec3::new(0.3, 0.0, 1.0), Vec3::new(0.0, -0.5, 1.0)];
        let c = Cone::of_normals(ns.iter().copied());
        for n in ns {
            assert!(c.axis.angle_between(n) <= c.half_angle, "{n}");
        }
        let d = Cone::of_normals([Vec3::X, Vec3::new(1.0, 0.2, 0.0)].into_iter());
        let u = Cone::union([c, d].into_iter());
        for n in ns.iter().chain(&[Vec3::X]) {
            assert!(u.axis.angle_between(*n) <= u.half_angle, "{n}");
        }
        // Opposite normals bound everything; so does a union with ALL.
        assert_eq!(Cone::of_normals([Vec3::Z, -Vec3::Z].into_iter()), Cone::ALL);
        assert_eq!(Cone::union([c, Cone::ALL].into_iter()), Cone::ALL);
        assert_eq!(Cone::of_normals(std::iter::empty()), Cone::ALL);
        // A narrow cone facing away from the eye is back-facing; ALL never is.
        let z = Cone::new(Vec3::Z, 0.1);
        assert!(z.backfacing(Vec3::ZERO, 1.0, Vec3::new(0.0, 0.0, -10.0)));
        assert!(!z.backfacing(Vec3::ZERO, 1.0, Vec3::new(0.0, 0.0, 10.0)));
        assert!(!Cone::ALL.backfacing(Vec3::ZERO, 1.0, Vec3::new(0.0, 0.0, -10.0)));
    }
}
