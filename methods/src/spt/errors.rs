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

/// One bounding problem of [`enclosing_batch`]: circles (or balls) `(centre, radius)`, the
/// start of the search (their mean centre) and the centre of their bounding box.
pub(super) struct Problem<V> {
    items: SmallVec<[(V, f32); 8]>,
    mean: V,
    mid: V,
}

/// Bounding problems solved together by [`enclosing_batch`].
pub(super) const BATCH: usize = 4;

/// Smallest-found circle enclosing circles `(c, r)` (see the module doc), `(centre,
/// radius)`, for each of up to [`BATCH`] independent problems. The problems are stepped
/// together, one step of each in turn: a problem's 26 evaluations are one dependent chain
/// (a square root and a division per step), so a node alone leaves the core waiting, and
/// interleaving independent nodes fills it. Each problem's result is what it would be alone,
/// bit for bit: the same operations in the same order.
fn enclosing_batch<V>(
    problems: &[&Problem<V>],
    sub: impl Fn(V, V) -> V,
    len: impl Fn(V) -> f32,
    add_scaled: impl Fn(V, V, f32) -> V,
) -> SmallVec<[(V, f32); BATCH]>
where
    V: Copy,
{
    // The radius around `c` and the farthest point of the farthest circle from `c`, in
    // one pass (a Bădoiu–Clarkson step needs the second at the centre whose radius the step
    // before measured: one pass per step instead of two).
    // The farthest circle is chosen by selects, not branches (which circle is farthest
    // changes from step to step and was mispredicted), and its point computed once.
    let eval = |items: &[(V, f32)], c: V| {
        let (mut radius, mut fd, mut fi, mut fl) = (0.0f32, -1.0f32, usize::MAX, 0.0f32);
        for (i, &(q, r)) in items.iter().enumerate() {
            let l = len(sub(q, c));
            let t = l + r;
            radius = radius.max(t);
            let gt = t > fd;
            fd = if gt { t } else { fd };
            fi = if gt { i } else { fi };
            fl = if gt { l } else { fl };
        }
        let far = items.get(fi).map(|&(q, r)| {
            if fl > 0.0 {
                add_scaled(q, sub(q, c), r / fl)
            } else {
                q
            }
        });
        (radius, far)
    };
    // Per problem: the best (centre, radius) so far, the farthest point, the centre.
    type State<V> = ((V, f32), Option<V>, V);
    let mut state: SmallVec<[State<V>; BATCH]> = problems
        .iter()
        .map(|pb| {
            let (r0, far) = eval(&pb.items, pb.mean);
            let mut best = (pb.mean, r0);
            let rm = eval(&pb.items, pb.mid).0;
            if rm < best.1 {
                best = (pb.mid, rm);
            }
            (best, far, pb.mean)
        })
        .collect();
    for step in 1..=BC_STEPS {
        let t = 1.0 / (step as f32 + 1.0);
        for (pb, (best, far, c)) in problems.iter().zip(state.iter_mut()) {
            // A problem whose farthest circle was not found stops (as the search alone
            // breaks off).
            let Some(f) = *far else { continue };
            *c = add_scaled(*c, sub(f, *c), t);
            let (rc, next) = eval(&pb.items, *c);
            if rc < best.1 {
                *best = (*c, rc);
            }
            *far = next;
        }
    }
    state.into_iter().map(|(best, _, _)| best).collect()
}

/// A node's bounding disk as a problem in its plane: the plane's basis `(t1, t2)` and its
/// origin (the children's mean centre), and the circles in plane coordinates.
pub(super) struct DiskProblem {
    origin: Vec3,
    t1: Vec3,
    t2: Vec3,
    problem: Problem<Vec2>,
}

impl DiskProblem {
    /// The problem of [`bounding_disk`]`(n, children)`.
    pub(super) fn new(n: Vec3, children: &[ChildDisk]) -> Self {
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
        DiskProblem {
            origin: mean,
            t1,
            t2,
            problem: Problem {
                items,
                mean: Vec2::ZERO,
                mid: (lo + hi) * 0.5,
            },
        }
    }
}

/// [`bounding_disk`] of up to [`BATCH`] nodes at once (see [`enclosing_batch`]): the same
/// values as one at a time.
pub(super) fn bounding_disks(problems: &[DiskProblem]) -> SmallVec<[(Vec3, f32); BATCH]> {
    let plane: SmallVec<[&Problem<Vec2>; BATCH]> = problems.iter().map(|d| &d.problem).collect();
    enclosing_batch(&plane, |a, b| a - b, Vec2::length, |a, v, s| a + v * s)
        .into_iter()
        .zip(problems)
        .map(|((c, r), d)| (d.origin + d.t1 * c.x + d.t2 * c.y, r))
        .collect()
}

/// The problem of [`bounding_ball`]`(children)`.
pub(super) fn ball_problem(children: &[ChildDisk]) -> Problem<Vec3> {
    let k = children.len().max(1) as f32;
    let mean = children.iter().map(|c| c.p).sum::<Vec3>() / k;
    let items: SmallVec<[(Vec3, f32); 8]> = children.iter().map(|c| (c.p, c.r)).collect();
    let (lo, hi) = items.iter().fold(
        (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
        |(lo, hi), &(q, r)| (lo.min(q - r), hi.max(q + r)),
    );
    Problem {
        items,
        mean,
        mid: (lo + hi) * 0.5,
    }
}

/// [`bounding_ball`] of up to [`BATCH`] nodes at once (see [`enclosing_batch`]): the same
/// values as one at a time.
pub(super) fn bounding_balls(problems: &[Problem<Vec3>]) -> SmallVec<[(Vec3, f32); BATCH]> {
    let refs: SmallVec<[&Problem<Vec3>; BATCH]> = problems.iter().collect();
    enclosing_batch(&refs, |a, b| a - b, Vec3::length, |a, v, s| a + v * s)
}

/// The node's bounding disk in the plane with unit normal `n` through the children's mean
/// centre: `(centre, radius)`; the radius bounds every child disk (each projected child is
/// bounded by its full radius).
pub fn bounding_disk(n: Vec3, children: &[ChildDisk]) -> (Vec3, f32) {
    bounding_disks(&[DiskProblem::new(n, children)])[0]
}

/// Without normals: a ball bounding the children's balls, `(centre, radius)`.
pub fn bounding_ball(children: &[ChildDisk]) -> (Vec3, f32) {
    bounding_balls(&[ball_problem(children)])[0]
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

    /// Bounding problems searched together give each what it gives alone, bit for bit: for
    /// disks and balls, batches of 1 to [`BATCH`] problems of 1 to 10 children (more than an
    /// octree cell's 8 happen in cells of duplicates), among them coincident children.
    #[test]
    fn a_batch_solves_each_problem_as_alone() {
        let mut state = 0x2545_f491_4f6c_dd1du64;
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let bits = |(p, r): (Vec3, f32)| (p.to_array().map(f32::to_bits), r.to_bits());
        for trial in 0..500 {
            let problems: Vec<(Vec3, Vec<ChildDisk>)> = (0..1 + trial % BATCH)
                .map(|j| {
                    let k = 1 + (trial + j) % 10;
                    let mut c: Vec<ChildDisk> = (0..k)
                        .map(|_| ChildDisk {
                            p: Vec3::new(next(), next(), next()) * 5.0,
                            n: Vec3::new(next() - 0.5, next() - 0.5, 1.0).normalize(),
                            r: next(),
                        })
                        .collect();
                    if k > 1 && trial % 5 == 0 {
                        c[1] = c[0];
                    }
                    (Vec3::new(next(), next() - 0.5, 1.0).normalize(), c)
                })
                .collect();
            let disks: Vec<DiskProblem> = problems
                .iter()
                .map(|(n, c)| DiskProblem::new(*n, c))
                .collect();
            let together = bounding_disks(&disks);
            let balls: Vec<Problem<Vec3>> = problems.iter().map(|(_, c)| ball_problem(c)).collect();
            let together_balls = bounding_balls(&balls);
            assert_eq!(together.len(), problems.len());
            for (j, (n, c)) in problems.iter().enumerate() {
                assert_eq!(
                    bits(together[j]),
                    bits(bounding_disk(*n, c)),
                    "disk {j} of {c:?}"
                );
                assert_eq!(
                    bits(together_balls[j]),
                    bits(bounding_ball(c)),
                    "ball {j} of {c:?}"
                );
            }
        }
    }

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
