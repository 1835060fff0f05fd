//! The LPC refinement traversal (paper §4) and its budget search. Pure: it reads the index
//! tree and an availability predicate and returns what to draw and what to fetch.

use glam::Vec3;
use scenes::View;
use scenes::camera::{Containment, Frustum};

use super::index::Node;
use crate::Target;
use crate::spt::select::cone_backfacing;

/// Smallest splat drawn, pixels: a tolerance below one pixel still draws one-pixel splats
/// (the selection gets denser, the splats cannot get smaller).
pub const MIN_SPLAT_PX: f32 = 1.0;
/// Tolerance range searched in budget mode, pixels.
pub const BUDGET_EPS_RANGE: (f32, f32) = (1e-3, 1e5);
/// Bisection steps of the budget search (on `log ε`: a relative step of 2⁻²⁰ over the range).
pub const BUDGET_STEPS: u32 = 40;

/// One cloud to draw.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Draw {
    /// Node (= cloud id).
    pub node: u32,
    /// Splats (the whole cloud).
    pub points: u32,
    /// Splat size, pixels.
    pub size_px: f32,
}

/// The result of one selection.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Selection {
    /// Clouds to draw, in traversal order (parents before children).
    pub draws: Vec<Draw>,
    /// Unavailable children wanted, in priority order (ascending node index), no repeats.
    pub fetch: Vec<u32>,
    /// Tolerance used (the target's, or the one the budget search found).
    pub eps_px: f32,
    /// Clouds drawn enlarged because a child they needed was unavailable.
    pub coarse: u32,
    /// Total splats.
    pub points: u64,
}

/// Per-frame constants of the traversal.
struct Ctx {
    eye: Vec3,
    frustum: Frustum,
    k: f32,
    near: f32,
}

impl Ctx {
    fn new(view: &View) -> Self {
        Self {
            eye: view.camera.position,
            frustum: view.frustum(),
            k: view.proj_scale(),
            near: view.camera.near.max(f32::MIN_POSITIVE),
        }
    }
    /// Outside the frustum or entirely back-facing.
    fn culled(&self, n: &Node) -> bool {
        let c = Vec3::from(n.center);
        self.frustum.sphere(c, n.radius) == Containment::Outside
            || cone_backfacing(
                Vec3::from(n.cone_axis),
                n.cone_half_angle,
                c,
                n.radius,
                self.eye,
            )
    }
    /// Apparent size (pixels) of a sphere of diameter `r_j` at the bounding-sphere point
    /// closest to the eye (at least the near-plane distance away).
    fn projected(&self, n: &Node) -> f32 {
        let d = (self.eye.distance(Vec3::from(n.center)) - n.radius).max(self.near);
        n.spacing * self.k / d
    }
}

/// Scratch space reused across frames.
#[derive(Debug, Default)]
pub struct Traversal {
    stack: Vec<u32>,
    stopped: Vec<(u32, f32)>,
}

impl Traversal {
    /// Scratch for a tree of `nodes` nodes.
    pub fn new(nodes: usize) -> Self {
        Self {
            stack: Vec::with_capacity(64),
            stopped: Vec::with_capacity(nodes.min(1 << 16)),
        }
    }

    /// What to draw for `view` at `target`, given which clouds are available now.
    pub fn select(
        &mut self,
        nodes: &[Node],
        view: &View,
        target: Target,
        avail: &dyn Fn(u32) -> bool,
    ) -> Selection {
        let ctx = Ctx::new(view);
        match target {
            Target::Tolerance(eps) => self.run(nodes, &ctx, eps, avail),
            Target::Budget(b) => self.budget(nodes, &ctx, b, avail),
        }
    }

    /// One traversal at tolerance `eps`. Also leaves in `self.stopped` the drawn nodes that
    /// stopped below the tolerance with children to refine into, with their projected size.
    fn run(
        &mut self,
        nodes: &[Node],
        ctx: &Ctx,
        eps: f32,
        avail: &dyn Fn(u32) -> bool,
    ) -> Selection {
        let mut sel = Selection {
            eps_px: eps,
            ..Default::default()
        };
        self.stopped.clear();
        self.stack.clear();
        let fine = eps.max(MIN_SPLAT_PX);
        if nodes.is_empty() {
            return sel;
        }
        self.stack.push(0);
        while let Some(i) = self.stack.pop() {
            let n = &nodes[i as usize];
            if ctx.culled(n) {
                continue;
            }
            let proj = ctx.projected(n);
            let mut draw = |size_px: f32| {
                sel.points += n.points as u64;
                sel.draws.push(Draw {
                    node: i,
                    points: n.points,
                    size_px,
                });
            };
            if proj <= eps {
                draw(fine);
                if !n.is_leaf() {
                    self.stopped.push((i, proj));
                }
                continue;
            }
            // Refinement wanted: only into the visible children, and only if all of them are
            // in core or on the GPU now.
            let mut visible = [u32::MAX; 2];
            let mut nv = 0;
            for c in n.child_ids() {
                if !ctx.culled(&nodes[c as usize]) {
                    visible[nv] = c;
                    nv += 1;
                }
            }
            let visible = &visible[..nv];
            if visible.is_empty() {
                // A leaf (or children all culled): nothing finer to show here.
                draw(proj.max(fine));
                continue;
            }
            let missing = visible.iter().filter(|&&c| !avail(c)).count();
            if missing == 0 {
                draw(fine);
                // Push in reverse so the first child is visited first.
                self.stack.extend(visible.iter().rev());
            } else {
                draw(proj.max(fine));
                sel.coarse += 1;
                sel.fetch.extend(visible.iter().filter(|&&c| !avail(c)));
            }
        }
        sel.fetch.sort_unstable();
        sel
    }

    /// Budget `b`: bisection of the tolerance counting points with the same traversal, then
    /// single children added while they fit. Never above `b`.
    fn budget(
        &mut self,
        nodes: &[Node],
        ctx: &Ctx,
        b: u64,
        avail: &dyn Fn(u32) -> bool,
    ) -> Selection {
        let (lo_eps, hi_eps) = BUDGET_EPS_RANGE;
        let mut hi = self.run(nodes, ctx, hi_eps, avail);
        if hi.points > b {
            // Even the coarsest admissible cut is too large (the eye inside spheres forces
            // refinement): keep clouds in traversal order (coarse first) while they fit.
            let mut kept = Vec::with_capacity(hi.draws.len());
            let mut total = 0u64;
            for d in hi.draws {
                if total + d.points as u64 <= b {
                    total += d.points as u64;
                    kept.push(d);
                }
            }
            hi.draws = kept;
            hi.points = total;
            return hi;
        }
        let lo = self.run(nodes, ctx, lo_eps, avail);
        if lo.points <= b {
            return lo;
        }
        // Invariant: count(lo) > b ≥ count(hi); count is non-increasing in ε.
        let (mut l, mut h) = (lo_eps.ln(), hi_eps.ln());
        for _ in 0..BUDGET_STEPS {
            let m = 0.5 * (l + h);
            let s = self.run(nodes, ctx, m.exp(), avail);
            if s.points <= b {
                h = m;
            } else {
                l = m;
            }
        }
        let mut sel = self.run(nodes, ctx, h.exp(), avail);
        // Fill: the next refinements are the stopped nodes with the largest projected
        // spacing; add their visible, available children one cloud at a time while they fit.
        let mut stopped = std::mem::take(&mut self.stopped);
        stopped.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
        let fine = sel.eps_px.max(MIN_SPLAT_PX);
        'fill: for &(i, _) in &stopped {
            for c in nodes[i as usize].child_ids() {
                let cn = &nodes[c as usize];
                if ctx.culled(cn) || !avail(c) {
                    continue;
                }
                if sel.points + cn.points as u64 > b {
                    break 'fill;
                }
                sel.points += cn.points as u64;
                sel.draws.push(Draw {
                    node: c,
                    points: cn.points,
                    size_px: fine,
                });
            }
        }
        self.stopped = stopped;
        sel
    }
}
