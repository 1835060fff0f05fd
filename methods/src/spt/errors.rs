//! SPT node geometry and error measures (Dachsbacher et al. 2003, §3.2–3.3), as pure functions
//! of a node's children, each given as a disk ([`ChildDisk`]: centre, unit normal, radius).
//!
//! - [`bounding_disk`]: centre and radius of a disk (in the plane through the children's mean
//!   centre, normal `n`) that contains every child disk projected into that plane. Each
//!   projected child (an ellipse) is bounded by the circle of the child's full radius, and the
//!   circle enclosing those circles is approximated: the best of the centroid, the bounding-box
//!   centre and 24 Bădoiu–Clarkson steps (conservative: it always contains every child; at
//!   most a few per cent larger than the minimal one for ≤ 8 children).
//!   Without normals ([`bounding_ball`]) the same is done with balls in 3D.
//! - [`perpendicular_error`]: `e_p = max_i((pᵢ−p)·n + ρᵢ) − min_i((pᵢ−p)·n − ρᵢ)`,
//!   `ρᵢ = rᵢ·sqrt(1 − (nᵢ·n)²)`.
//! - [`tangential_error`]: `e_t = max(0, d − w)`, `w` the width of the tightest of
//!   [`SLAB_DIRECTIONS`] slabs (directions `u_j`, `j·π/8` apart in the node's plane) around
//!   the child disks; a disk's extent along `u` is `pᵢ·u ± rᵢ·sqrt(1 − (nᵢ·u)²)`, which is
//!   also the extent of its projection into the plane.
//! - [`geometric_error`]: `e_g = sqrt(e_p² + e_t²)`.
//! - [`color_spread`]: the largest per-channel difference among children's colours (the
//!   colour rule raises a node's error to its diameter when it exceeds a threshold).

use glam::{Vec2, Vec3};
use smallvec::SmallVec;

/// Number of slab orientations of the tangential error (the paper asks for "several").
pub const SLAB_DIRECTIONS: usize = 8;
/// Bădoiu–Clarkson refinement steps of the bounding circle/ball.
const BC_STEPS: usize = 24;

/// A child of a node seen as a disk.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ChildDisk {
    /// Centre.
    pub p: Vec3,
    /// Unit normal (ignored by the normal-less functions).
    pub n: Vec3,
    /// Radius (`d/2`).
    pub r: f32,
}

/// An orthonormal basis `(t1, t2)` of the plane orthogonal to unit `n` (deterministic).
pub fn tangent_basis(n: Vec3) -> (Vec3, Vec3) {
    let a = if n.x.abs() < 0.6 { Vec3::X } else { Vec3::Y };
    let t1 = n.cross(a).normalize();
    (t1, n.cross(t1))
}

/// Lanes of [`Reach`]: an octree node's most children.
const LANES: usize = 8;

/// Up to [`LANES`] circles or balls (a circle is a ball with `z = 0`: every distance, step
/// and point below is then bit for bit the 2-D one), coordinates apart so that the distances
/// from a centre to all of them are one vectorised loop.
struct Reach {
    x: [f32; LANES],
    y: [f32; LANES],
    z: [f32; LANES],
    r: [f32; LANES],
    len: usize,
}

impl Reach {
    fn new(items: &[(Vec3, f32)]) -> Self {
        let mut s = Self {
            x: [0.0; LANES],
            y: [0.0; LANES],
            z: [0.0; LANES],
            // Unused lanes never reach farthest.
            r: [f32::NEG_INFINITY; LANES],
            len: items.len(),
        };
        for (j, &(q, r)) in items.iter().enumerate() {
            (s.x[j], s.y[j], s.z[j], s.r[j]) = (q.x, q.y, q.z, r);
        }
        s
    }

    /// `(|qⱼ − c|, |qⱼ − c| + rⱼ)` of every lane, the length as `(qⱼ − c).length()`
    /// computes it.
    fn from(&self, c: Vec3) -> ([f32; LANES], [f32; LANES]) {
        let (mut len, mut reach) = ([0.0; LANES], [0.0; LANES]);
        for j in 0..LANES {
            let (dx, dy, dz) = (self.x[j] - c.x, self.y[j] - c.y, self.z[j] - c.z);
            len[j] = (dx * dx + dy * dy + dz * dz).sqrt();
            reach[j] = len[j] + self.r[j];
        }
        (len, reach)
    }

    /// The first of the used lanes whose reach is the largest that is not NaN, if any
    /// exceeds −1: what a scan keeping the first strictly larger reach above −1 finds, with
    /// a tree of `max` in place of its eight dependent compares.
    fn farthest(&self, reach: &[f32; LANES]) -> Option<usize> {
        let m = reach.map(|d| if d.is_nan() { f32::NEG_INFINITY } else { d });
        let a = [
            m[0].max(m[4]),
            m[1].max(m[5]),
            m[2].max(m[6]),
            m[3].max(m[7]),
        ];
        let top = a[0].max(a[2]).max(a[1].max(a[3]));
        if top > -1.0 {
            m[..self.len].iter().position(|&d| d == top)
        } else {
            None
        }
    }
}

/// Smallest-found ball enclosing balls `(c, r)` (circles: `z = 0`; see the module doc):
/// `(centre, radius)`.
fn enclosing(items: &[(Vec3, f32)], mean: Vec3, mid: Vec3) -> (Vec3, f32) {
    let lanes = (items.len() <= LANES).then(|| Reach::new(items));
    // The radius around `c` and the farthest point of the farthest ball from `c`, in one
    // pass (a Bădoiu–Clarkson step needs the second at the centre whose radius the step
    // before measured: one pass per step instead of two). The point is formed once, for the
    // first ball reaching farthest: reaches never fall below −1 (lengths and radii are ≥ 0)
    // and NaN reaches are skipped, as `f32::max` skips them in the radius.
    let eval = |c: Vec3| {
        // (reach, lane, its length) of the farthest.
        let found = match &lanes {
            Some(l) => {
                let (len, reach) = l.from(c);
                l.farthest(&reach).map(|j| (reach[j], j, len[j]))
            }
            None => {
                let mut found = None;
                for (j, &(q, r)) in items.iter().enumerate() {
                    let len = (q - c).length();
                    if len + r > found.map_or(-1.0, |f: (f32, usize, f32)| f.0) {
                        found = Some((len + r, j, len));
                    }
                }
                found
            }
        };
        match found {
            Some((reach, j, l)) => {
                let (q, r) = items[j];
                let v = q - c;
                let far = if l > 0.0 { q + v * (r / l) } else { q };
                (reach.max(0.0), Some(far))
            }
            None => (0.0, None),
        }
    };
    let (r0, mut far) = eval(mean);
    let mut best = (mean, r0);
    let rm = eval(mid).0;
    if rm < best.1 {
        best = (mid, rm);
    }
    let mut c = mean;
    for step in 1..=BC_STEPS {
        let Some(f) = far else { break };
        c += (f - c) * (1.0 / (step as f32 + 1.0));
        let (rc, next) = eval(c);
        if rc < best.1 {
            best = (c, rc);
        }
        far = next;
    }
    best
}

/// The node's bounding disk in the plane with unit normal `n` through the children's mean
/// centre: `(centre, radius)`; the radius bounds every child disk (each projected child is
/// bounded by its full radius).
pub fn bounding_disk(n: Vec3, children: &[ChildDisk]) -> (Vec3, f32) {
    let k = children.len().max(1) as f32;
    let mean = children.iter().map(|c| c.p).sum::<Vec3>() / k;
    let (t1, t2) = tangent_basis(n);
    let items: SmallVec<[(Vec2, f32); 8]> = children
        .iter()
        .map(|c| {
            let v = c.p - mean;
            (Vec2::new(v.dot(t1), v.dot(t2)), c.r)
        })
        .collect();
    let (lo, hi) = items.iter().fold(
        (Vec2::splat(f32::INFINITY), Vec2::splat(f32::NEG_INFINITY)),
        |(lo, hi), &(q, r)| (lo.min(q - r), hi.max(q + r)),
    );
    let flat: SmallVec<[(Vec3, f32); 8]> = items.iter().map(|&(q, r)| (q.extend(0.0), r)).collect();
    let (c, r) = enclosing(&flat, Vec3::ZERO, ((lo + hi) * 0.5).extend(0.0));
    (mean + t1 * c.x + t2 * c.y, r)
}

/// Without normals: a ball bounding the children's balls, `(centre, radius)`.
pub fn bounding_ball(children: &[ChildDisk]) -> (Vec3, f32) {
    let k = children.len().max(1) as f32;
    let mean = children.iter().map(|c| c.p).sum::<Vec3>() / k;
    let items: SmallVec<[(Vec3, f32); 8]> = children.iter().map(|c| (c.p, c.r)).collect();
    let (lo, hi) = items.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &(q, r)| (lo.min(q - r), hi.max(q + r)),
    );
    enclosing(&items, mean, (lo + hi) * 0.5)
}

/// `ρ = r·sqrt(1 − (a·b)²)`: the half-extent of a disk of radius `r`, normal `a`, along unit `b`.
#[inline]
fn half_extent(r: f32, a: Vec3, b: Vec3) -> f32 {
    r * (1.0 - a.dot(b).powi(2)).max(0.0).sqrt()
}

/// Perpendicular error `e_p` of a node with centre `p` and unit normal `n`.
pub fn perpendicular_error(p: Vec3, n: Vec3, children: &[ChildDisk]) -> f32 {
    let (mut hi, mut lo) = (f32::NEG_INFINITY, f32::INFINITY);
    for c in children {
        let h = (c.p - p).dot(n);
        let rho = half_extent(c.r, c.n, n);
        hi = hi.max(h + rho);
        lo = lo.min(h - rho);
    }
    if children.is_empty() {
        0.0
    } else {
        (hi - lo).max(0.0)
    }
}

/// Width of the slab with in-plane unit direction `u` around the child disks.
pub fn slab_width(u: Vec3, children: &[ChildDisk]) -> f32 {
    let (mut hi, mut lo) = (f32::NEG_INFINITY, f32::INFINITY);
    for c in children {
        let h = c.p.dot(u);
        let e = half_extent(c.r, c.n, u);
        hi = hi.max(h + e);
        lo = lo.min(h - e);
    }
    if children.is_empty() { 0.0 } else { hi - lo }
}

/// Tangential error `e_t = max(0, d − w)` of a node with unit normal `n` and diameter `d`.
pub fn tangential_error(n: Vec3, d: f32, children: &[ChildDisk]) -> f32 {
    let (t1, t2) = tangent_basis(n);
    let w = (0..SLAB_DIRECTIONS)
        .map(|j| {
            let a = j as f32 * std::f32::consts::PI / SLAB_DIRECTIONS as f32;
            slab_width(t1 * a.cos() + t2 * a.sin(), children)
        })
        .fold(f32::INFINITY, f32::min);
    (d - w).max(0.0)
}

/// Geometric error `e_g = sqrt(e_p² + e_t²)`.
#[inline]
pub fn geometric_error(e_p: f32, e_t: f32) -> f32 {
    (e_p * e_p + e_t * e_t).sqrt()
}

/// Largest per-channel difference between any two children's colours (0..=255).
pub fn color_spread(colors: &[[u8; 3]]) -> u8 {
    (0..3)
        .map(|ch| {
            let (lo, hi) = colors
                .iter()
                .fold((u8::MAX, 0u8), |(lo, hi), c| (lo.min(c[ch]), hi.max(c[ch])));
            hi.saturating_sub(lo)
        })
        .max()
        .unwrap_or(0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bounding_disk_contains_children_and_is_tight_for_two() {
        let c = [
            ChildDisk {
                p: Vec3::new(-1.0, 0.0, 0.0),
                n: Vec3::Z,
                r: 0.5,
            },
            ChildDisk {
                p: Vec3::new(1.0, 0.0, 0.0),
                n: Vec3::Z,
                r: 0.5,
            },
        ];
        let (p, r) = bounding_disk(Vec3::Z, &c);
        assert!(p.length() < 1e-4 && (r - 1.5).abs() < 1e-3, "{p} {r}");
        let (p, r) = bounding_ball(&c);
        assert!(p.length() < 1e-4 && (r - 1.5).abs() < 1e-3, "{p} {r}");
    }
}
