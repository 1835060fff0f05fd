//! The LPC refinement traversal (paper §4) and its budget search. Pure: it reads the index
//! tree and an availability predicate and returns what to draw and what to fetch.

use glam::Vec3;
use scenes::View;
use scenes::camera::{Containment, Frustum};

use super::index::Node;
use crate::Target;
use crate::cull::cone_backfacing;

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

/// Which clouds take the enlarged splat size of a node whose refinement stops above the
/// tolerance (a leaf, or a node whose children are not available yet).
///
/// The paper: "the node is rendered with an increased splat size, equal to its projected
/// mean sample distance, to cover holes". That distance, `r_j` of eq. (2), is the average
/// spacing of the node's *region once its clouds are merged* — the node's own cloud and the
/// clouds of its ancestors, drawn at ε. Only all of them together reach that density, so
/// only all of them enlarged cover the region (README, "Rendering"; measured on
/// `paper/paths/still-close.toml`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Enlarge {
    /// Our reading of the paper (default): the node and every drawn ancestor take at least
    /// the node's enlarged size (one size per cloud: an ancestor takes the largest size any
    /// of its drawn descendants asks for).
    #[default]
    Layers,
    /// The literal reading: only the stopped node's own cloud is enlarged; its ancestors stay
    /// at ε. Its cloud alone holds about half the samples of its region, so the region keeps
    /// holes that grow as the view refines (a departure kept to show it).
    Cloud,
}

/// Scratch space reused across frames.
#[derive(Debug, Default)]
pub struct Traversal {
    /// Nodes to visit, each with the index in `draws` of its drawn parent (`u32::MAX` for
    /// the root).
    stack: Vec<(u32, u32)>,
    stopped: Vec<(u32, f32)>,
    /// Per draw of the last traversal, the index of its parent's draw (`u32::MAX`: none).
    parent_draw: Vec<u32>,
    /// How enlarged sizes spread to the ancestors.
    enlarge: Enlarge,
}

impl Traversal {
    /// Scratch for a tree of `nodes` nodes.
    pub fn new(nodes: usize) -> Self {
        Self::with_enlarge(nodes, Enlarge::default())
    }

    /// Scratch for a tree of `nodes` nodes, enlarging as `enlarge` says.
    pub fn with_enlarge(nodes: usize, enlarge: Enlarge) -> Self {
        Self {
            stack: Vec::with_capacity(64),
            stopped: Vec::with_capacity(nodes.min(1 << 16)),
            parent_draw: Vec::with_capacity(nodes.min(1 << 16)),
            enlarge,
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
        self.parent_draw.clear();
        let fine = eps.max(MIN_SPLAT_PX);
        if nodes.is_empty() {
            return sel;
        }
        self.stack.push((0, u32::MAX));
        while let Some((i, parent)) = self.stack.pop() {
            let n = &nodes[i as usize];
            if ctx.culled(n) {
                continue;
            }
            let proj = ctx.projected(n);
            let me = sel.draws.len() as u32;
            let mut draw = |size_px: f32| {
                sel.points += n.points as u64;
                sel.draws.push(Draw {
                    node: i,
                    points: n.points,
                    size_px,
                });
                self.parent_draw.push(parent);
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
                self.stack.extend(visible.iter().rev().map(|&c| (c, me)));
            } else {
                draw(proj.max(fine));
                sel.coarse += 1;
                sel.fetch.extend(visible.iter().filter(|&&c| !avail(c)));
            }
        }
        if self.enlarge == Enlarge::Layers {
            spread_to_ancestors(&mut sel.draws, &self.parent_draw);
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
        // The best selection within the budget so far, with its stopped nodes (the fill
        // step needs them), so the final ε is not traversed again.
        let mut hi_stopped = self.stopped.clone();
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
                hi = s;
                std::mem::swap(&mut hi_stopped, &mut self.stopped);
            } else {
                l = m;
            }
        }
        let mut sel = hi;
        // Fill: the next refinements are the stopped nodes with the largest projected
        // spacing; add their visible, available children one cloud at a time while they fit.
        let mut stopped = hi_stopped;
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

/// Raises every draw's splat size to the largest size of its drawn descendants
/// ([`Enlarge::Layers`]). `parent[i]` is the index of draw `i`'s parent draw (`u32::MAX`
/// for none); parents come before their children, so one backward pass carries a size up
/// any number of levels.
fn spread_to_ancestors(draws: &mut [Draw], parent: &[u32]) {
    for i in (0..draws.len()).rev() {
        let p = parent[i];
        if p != u32::MAX {
            let size = draws[i].size_px;
            let up = &mut draws[p as usize].size_px;
            *up = up.max(size);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::lpc::index::NONE;
    use scenes::Camera;

    /// A complete binary tree of `levels` levels over the segment x ∈ [-8, 8] (y = z = 0):
    /// node spheres halve with depth, spacing halves with depth, `m` points per cloud.
    fn tree(levels: u32, m: u32) -> Vec<Node> {
        let mut nodes = Vec::new();
        for level in 0..levels {
            let count = 1u32 << level;
            let width = 16.0 / count as f32;
            for j in 0..count {
                let first_child = (1u32 << (level + 1)) - 1 + 2 * j;
                let children = if level + 1 < levels {
                    [first_child, first_child + 1]
                } else {
                    [NONE, NONE]
                };
                let i = nodes.len() as u32;
                nodes.push(Node {
                    center: [-8.0 + width * (j as f32 + 0.5), 0.0, 0.0],
                    radius: width * 0.5,
                    cone_axis: [0.0; 3],
                    cone_half_angle: std::f32::consts::PI,
                    spacing: 1.0 / (1u32 << level) as f32,
                    children,
                    cloud: i,
                    points: m,
                    level,
                    ..Default::default()
                });
            }
        }
        nodes
    }

    fn view_from(z: f32) -> View {
        View {
            camera: Camera {
                position: Vec3::new(0.0, 0.0, z),
                target: Vec3::ZERO,
                up: Vec3::Y,
                fov_y: 1.0,
                near: 0.01,
                far: 1000.0,
            },
            width: 256,
            height: 256,
        }
    }

    fn all(_: u32) -> bool {
        true
    }

    #[test]
    fn refinement_stops_below_tolerance() {
        let nodes = tree(5, 100);
        let mut t = Traversal::new(nodes.len());
        // From 40 units the leaves project below 1 px; from 12 units to 1.3 px (and the
        // frustum culls the outermost leaves).
        for (z, eps) in [
            (40.0, 0.5f32),
            (40.0, 2.0),
            (40.0, 8.0),
            (40.0, 64.0),
            (12.0, 1.0),
        ] {
            let view = view_from(z);
            let ctx = Ctx::new(&view);
            let sel = t.select(&nodes, &view, Target::Tolerance(eps), &all);
            let drawn: std::collections::HashSet<u32> = sel.draws.iter().map(|d| d.node).collect();
            // A node is drawn iff it is the root or its parent was refined (its parent's
            // projected spacing exceeded ε); with everything available and visible.
            let mut parent = vec![NONE; nodes.len()];
            for (i, n) in nodes.iter().enumerate() {
                for c in n.child_ids() {
                    parent[c as usize] = i as u32;
                }
            }
            for (i, _) in nodes.iter().enumerate() {
                let expect = !ctx.culled(&nodes[i])
                    && (i == 0 || {
                        let p = parent[i] as usize;
                        drawn.contains(&(p as u32)) && ctx.projected(&nodes[p]) > eps
                    });
                assert_eq!(drawn.contains(&(i as u32)), expect, "node {i} at ε={eps}");
            }
            assert!(sel.fetch.is_empty() && sel.coarse == 0);
            assert_eq!(sel.points, 100 * sel.draws.len() as u64);
            // A leaf above ε keeps its projected spacing; every other cloud is drawn at ε,
            // raised to the largest size of its drawn descendants (`Enlarge::Layers`).
            let own = |i: usize| {
                let proj = ctx.projected(&nodes[i]);
                if nodes[i].is_leaf() && proj > eps {
                    proj.max(MIN_SPLAT_PX)
                } else {
                    eps.max(MIN_SPLAT_PX)
                }
            };
            fn subtree_max(
                nodes: &[Node],
                drawn: &std::collections::HashSet<u32>,
                own: &dyn Fn(usize) -> f32,
                i: usize,
            ) -> f32 {
                nodes[i]
                    .child_ids()
                    .filter(|c| drawn.contains(c))
                    .map(|c| subtree_max(nodes, drawn, own, c as usize))
                    .fold(own(i), f32::max)
            }
            let mut raised = 0;
            for d in &sel.draws {
                let i = d.node as usize;
                let expect = subtree_max(&nodes, &drawn, &own, i);
                assert_eq!(d.size_px, expect, "node {i} at ε={eps}");
                raised += usize::from(expect > own(i));
            }
            // The literal reading leaves every cloud at its own size.
            let mut literal = Traversal::with_enlarge(nodes.len(), Enlarge::Cloud);
            let lit = literal.select(&nodes, &view, Target::Tolerance(eps), &all);
            assert_eq!(lit.points, sel.points);
            for d in &lit.draws {
                assert_eq!(d.size_px, own(d.node as usize), "literal, ε={eps}, z={z}");
            }
            if z == 12.0 {
                assert!(raised > 0, "leaves above ε: their ancestors are raised");
            }
        }
        let view = view_from(40.0);
        // Coarser tolerance ⇒ never more clouds.
        let counts: Vec<u64> = [0.5f32, 1.0, 2.0, 4.0, 8.0, 16.0]
            .iter()
            .map(|&e| t.select(&nodes, &view, Target::Tolerance(e), &all).points)
            .collect();
        assert!(counts.windows(2).all(|w| w[0] >= w[1]), "{counts:?}");
        assert!(counts[0] > counts[5]);
    }

    #[test]
    fn unavailable_children_draw_the_parent_larger_and_queue_fetches() {
        let nodes = tree(4, 10);
        let view = view_from(30.0);
        let ctx = Ctx::new(&view);
        let mut t = Traversal::new(nodes.len());
        // Only the root and its children are available.
        let avail = |id: u32| id <= 2;
        let sel = t.select(&nodes, &view, Target::Tolerance(0.5), &avail);
        let drawn: Vec<u32> = sel.draws.iter().map(|d| d.node).collect();
        assert_eq!(drawn, vec![0, 1, 2]);
        assert_eq!(sel.coarse, 2);
        // The root's cloud is half of the layers that cover its children's regions: it takes
        // the larger of their enlarged sizes.
        let children_max = sel.draws[1..].iter().map(|d| d.size_px).fold(0.0, f32::max);
        assert_eq!(sel.draws[0].size_px, children_max);
        assert!(children_max > 0.5);
        assert_eq!(
            sel.fetch,
            vec![3, 4, 5, 6],
            "coarse first, by node index, once each"
        );
        for d in &sel.draws[1..] {
            let proj = ctx.projected(&nodes[d.node as usize]);
            assert!(proj > 0.5);
            assert_eq!(d.size_px, proj.max(MIN_SPLAT_PX));
        }
        // One missing child blocks refinement of its parent only.
        let avail = |id: u32| id != 4;
        let sel = t.select(&nodes, &view, Target::Tolerance(0.5), &avail);
        assert!(sel.fetch == vec![4]);
        assert!(!sel.draws.iter().any(|d| d.node == 3 || d.node == 4));
        assert!(sel.draws.iter().any(|d| d.node == 5));
    }

    #[test]
    fn culled_branches_are_skipped() {
        let nodes = tree(5, 10);
        // Looking along +x from x = 20 towards x = 40: everything is behind the camera.
        let mut view = view_from(0.0);
        view.camera.position = Vec3::new(20.0, 0.0, 0.0);
        view.camera.target = Vec3::new(40.0, 0.0, 0.0);
        let sel = Traversal::new(nodes.len()).select(&nodes, &view, Target::Tolerance(1.0), &all);
        assert!(sel.draws.is_empty());
        // Back-facing cone: normals all +z, the eye at z = -40 (behind the z = 0 segment).
        let mut nodes = tree(3, 10);
        for n in &mut nodes {
            n.cone_axis = [0.0, 0.0, 1.0];
            n.cone_half_angle = 0.1;
        }
        let sel = Traversal::new(nodes.len()).select(
            &nodes,
            &view_from(-40.0),
            Target::Tolerance(1.0),
            &all,
        );
        assert!(sel.draws.is_empty());
        let sel = Traversal::new(nodes.len()).select(
            &nodes,
            &view_from(40.0),
            Target::Tolerance(1.0),
            &all,
        );
        assert!(!sel.draws.is_empty());
    }

    #[test]
    fn budget_never_exceeded_and_within_one_cloud() {
        let nodes = tree(7, 50);
        let view = view_from(25.0);
        let mut t = Traversal::new(nodes.len());
        let everything = t.select(&nodes, &view, Target::Tolerance(0.0), &all).points;
        for b in [
            50u64,
            51,
            99,
            100,
            149,
            333,
            1000,
            2500,
            4999,
            everything,
            everything + 7,
        ] {
            let sel = t.select(&nodes, &view, Target::Budget(b), &all);
            assert!(sel.points <= b, "budget {b}: {}", sel.points);
            assert_eq!(
                sel.points,
                sel.draws.iter().map(|d| d.points as u64).sum::<u64>()
            );
            let gap = b - sel.points;
            assert!(
                gap < 50 || sel.points == everything,
                "budget {b}: {} drawn",
                sel.points
            );
            // Every drawn node's parent is drawn too (a valid cut).
            let drawn: std::collections::HashSet<u32> = sel.draws.iter().map(|d| d.node).collect();
            for (i, n) in nodes.iter().enumerate() {
                for c in n.child_ids() {
                    assert!(!drawn.contains(&c) || drawn.contains(&(i as u32)));
                }
            }
        }
        // A budget below the root cloud selects nothing (`Lpc::frame` refuses it first).
        let sel = t.select(&nodes, &view, Target::Budget(49), &all);
        assert_eq!(sel.points, 0);
    }
}
