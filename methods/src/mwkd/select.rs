//! Which nodes form the rendering front: the paper's `LODSelection` on a budget (Fig. 5) and
//! the projected-pixel-size mode. Pure: reads the index array and the view, returns node ids.
//!
//! **Budget `B`** ([`budget_front`]): a priority queue of nodes keyed by
//! `ε_l = c₀·(l_max − l + 1) / (c₁·d + c₂·d²)`, `d` = distance from the eye to the node's box
//! (at least the near-plane distance), largest first (ties: lower id). Start with the root,
//! `count = |root|`; while the queue is not empty, look at the top node `n`: a leaf goes to
//! the front; an inner node is replaced by its children if `count − |n| + Σ|c| ≤ B`, else the
//! loop stops; what is left in the queue joins the front. Deviations from Fig. 5, each to
//! keep `count ≤ B` exact or to spend the budget better:
//! - the test uses the children's exact sizes `Σ|c|` instead of the bound `N·s` (leaves may
//!   hold `s + 1`, and culled children count 0);
//! - a leaf on top of the queue goes to the front without ending the loop (the paper's test
//!   would stop on it although refining it costs nothing);
//! - culled children (outside the frustum, or back-facing by their subtree's normal cone)
//!   are dropped: the budget they would take refines other nodes ("budget reclaimed from
//!   culled nodes");
//! - if the root alone exceeds `B`, the front is empty (the paper would draw the root).
//!
//! **Tolerance `ε` px** ([`eps_front`]): top down, a node is refined while the projected
//! diameter of its mean splat, `2·r̄·k/d`, is at least `ε` (so `ε = 0` refines to the
//! leaves). The paper refines or coarsens the last front incrementally; the front it
//! converges to is this one, computed from the root each frame (a few thousand nodes).
//!
//! **Held back** (occlusion culling): nodes found occluded last frame are put in the front
//! without being refined and without counting against the budget; the frame asks the
//! renderer to query them and draws them only if they turn out visible.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::Vec3;
use scenes::View;
use scenes::camera::{Containment, Frustum};

use super::index::IndexNode;

/// The constants of `ε_l`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Metric {
    /// `c₀` (> 0; scales every priority alike, so it never changes a front).
    pub c0: f32,
    /// `c₁` (≥ 0): weight of the perspective term `d`.
    pub c1: f32,
    /// `c₂` (≥ 0): weight of `d²`.
    pub c2: f32,
}

/// A selected front.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Front {
    /// Nodes to draw (an antichain: no node is an ancestor of another).
    pub nodes: Vec<u32>,
    /// Nodes held back (occluded last frame): drawn only if found visible.
    pub held_back: Vec<u32>,
    /// Splats in `nodes`.
    pub points: u64,
    /// Nodes culled (frustum or back-face) during the selection.
    pub culled: u32,
}

/// Per-frame constants.
pub struct Ctx<'a> {
    nodes: &'a [IndexNode],
    eye: Vec3,
    frustum: Frustum,
    k: f32,
    near: f32,
    l_max: u32,
    metric: Metric,
}

impl<'a> Ctx<'a> {
    /// Constants for `view` over the index `nodes` (in level order, as
    /// [`super::index::read`] guarantees: the last node is on the deepest level).
    pub fn new(nodes: &'a [IndexNode], view: &View, metric: Metric) -> Self {
        Ctx {
            nodes,
            eye: view.camera.position,
            frustum: view.frustum(),
            k: view.proj_scale(),
            near: view.camera.near.max(f32::MIN_POSITIVE),
            l_max: nodes.last().map_or(0, |n| n.level),
            metric,
        }
    }

    /// Outside the frustum, or the whole subtree back-facing.
    pub fn culled(&self, id: u32) -> bool {
        let n = &self.nodes[id as usize];
        let (c, r) = n.sphere();
        self.frustum.sphere(c, r) == Containment::Outside
            || crate::cull::cone_backfacing(
                Vec3::from(n.cone_axis),
                n.cone_half_angle,
                c,
                r,
                self.eye,
            )
    }

    /// Distance from the eye to the node's box, at least the near-plane distance.
    pub fn distance(&self, id: u32) -> f32 {
        self.nodes[id as usize]
            .box_distance(self.eye)
            .max(self.near)
    }

    /// The paper's `ε_l` of node `id`.
    pub fn eps_l(&self, id: u32) -> f32 {
        let n = &self.nodes[id as usize];
        let d = self.distance(id);
        let m = self.metric;
        m.c0 * (self.l_max - n.level + 1) as f32 / (m.c1 * d + m.c2 * d * d)
    }

    /// Projected diameter (pixels) of the node's mean splat at its box's nearest point.
    pub fn projected_px(&self, id: u32) -> f32 {
        2.0 * self.nodes[id as usize].radius_mean * self.k / self.distance(id)
    }
}

/// Priority key: `ε_l` (non-negative, so its bits order like the value), ties to lower ids.
fn key(ctx: &Ctx<'_>, id: u32) -> (u32, Reverse<u32>) {
    let e = ctx.eps_l(id);
    let e = if e.is_finite() { e.max(0.0) } else { f32::MAX };
    (e.to_bits(), Reverse(id))
}

/// `LODSelection` on a budget (see the module docs). `held_back(id)`: occluded last frame.
pub fn budget_front(ctx: &Ctx<'_>, budget: u64, held_back: &dyn Fn(u32) -> bool) -> Front {
    let nodes = ctx.nodes;
    let mut f = Front::default();
    if ctx.culled(0) {
        f.culled = 1;
        return f;
    }
    if held_back(0) {
        f.held_back.push(0);
        return f;
    }
    let mut count = u64::from(nodes[0].points);
    if count > budget {
        return f;
    }
    let mut queue = BinaryHeap::new();
    queue.push(key(ctx, 0));
    let mut kids = Vec::new();
    while let Some(&(_, Reverse(id))) = queue.peek() {
        let n = &nodes[id as usize];
        if n.is_leaf() {
            queue.pop();
            f.nodes.push(id);
            continue;
        }
        kids.clear();
        let mut add = 0u64;
        let mut culled = 0;
        for c in n.children() {
            if ctx.culled(c) {
                culled += 1;
            } else {
                if !held_back(c) {
                    add += u64::from(nodes[c as usize].points);
                }
                kids.push(c);
            }
        }
        if count - u64::from(n.points) + add > budget {
            break;
        }
        queue.pop();
        count = count - u64::from(n.points) + add;
        f.culled += culled;
        for &c in &kids {
            if held_back(c) {
                f.held_back.push(c);
            } else {
                queue.push(key(ctx, c));
            }
        }
    }
    let mut rest: Vec<u32> = queue.into_iter().map(|(_, Reverse(id))| id).collect();
    rest.sort_unstable();
    f.nodes.extend(rest);
    f.points = count;
    f
}

/// The projected-pixel-size front for tolerance `eps` (see the module docs).
pub fn eps_front(ctx: &Ctx<'_>, eps: f32, held_back: &dyn Fn(u32) -> bool) -> Front {
    let nodes = ctx.nodes;
    let mut f = Front::default();
    let mut stack = vec![0u32];
    while let Some(id) = stack.pop() {
        if ctx.culled(id) {
            f.culled += 1;
            continue;
        }
        if held_back(id) {
            f.held_back.push(id);
            continue;
        }
        let n = &nodes[id as usize];
        if n.is_leaf() || ctx.projected_px(id) < eps {
            f.nodes.push(id);
            f.points += u64::from(n.points);
        } else {
            stack.extend(n.children().rev());
        }
    }
    f
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use scenes::Camera;

    /// A binary tree of depth 2 along x: root 0 holds 10, inner 1, 2 hold 10, leaves 3–6
    /// hold 10 each, spread from x = 0 to x = 4.
    fn tree() -> Vec<IndexNode> {
        let mut n = vec![IndexNode::default(); 7];
        for (i, node) in n.iter_mut().enumerate() {
            let (level, lo, hi) = match i {
                0 => (0, 0.0, 4.0),
                1 | 2 => (1, 2.0 * (i - 1) as f32, 2.0 * i as f32),
                _ => (2, (i - 3) as f32, (i - 2) as f32),
            };
            *node = IndexNode {
                min: [lo, 0.0, 0.0],
                max: [hi, 1.0, 0.0],
                radius_min: 0.01,
                radius_max: 0.01,
                radius_mean: 0.01 * (3 - level) as f32,
                cone_half_angle: std::f32::consts::PI,
                id: i as u32,
                level,
                points: 10,
                first_child: if level < 2 { 2 * i as u32 + 1 } else { 0 },
                child_count: if level < 2 { 2 } else { 0 },
                subtree_points: [40, 20, 20, 10, 10, 10, 10][i],
                ..Default::default()
            };
        }
        n
    }

    fn view(eye: Vec3, target: Vec3) -> View {
        View {
            camera: Camera {
                position: eye,
                target,
                up: Vec3::Y,
                fov_y: 60f32.to_radians(),
                near: 0.01,
                far: 100.0,
            },
            width: 200,
            height: 200,
        }
    }

    const M: Metric = Metric {
        c0: 1.0,
        c1: 1.0,
        c2: 0.0,
    };

    #[test]
    fn budget_front_follows_lodselection() {
        let nodes = tree();
        // Eye near the left end: the left half refines first.
        let v = view(Vec3::new(0.5, 0.5, 3.0), Vec3::new(2.0, 0.5, 0.0));
        let ctx = Ctx::new(&nodes, &v, M);
        let none = |_: u32| false;
        let f = |b| {
            let mut f = budget_front(&ctx, b, &none);
            f.nodes.sort_unstable();
            f
        };
        assert_eq!(f(5), Front::default(), "the root alone exceeds B: empty");
        assert_eq!(f(10).nodes, vec![0]);
        assert_eq!(f(19).nodes, vec![0]);
        assert_eq!(f(20).nodes, vec![1, 2]);
        // 30: node 1 (nearer, higher ε) splits into 3, 4.
        let b30 = f(30);
        assert_eq!((b30.nodes.clone(), b30.points), (vec![2, 3, 4], 30));
        assert_eq!(f(40).nodes, vec![3, 4, 5, 6]);
        assert_eq!(f(1000).nodes, vec![3, 4, 5, 6]);
        for b in [1, 10, 15, 20, 25, 30, 35, 40, 100] {
            assert!(f(b).points <= b);
        }
        // Held back: not refined, not counted.
        let held = |id: u32| id == 1;
        let h = budget_front(&ctx, 40, &held);
        assert_eq!((h.nodes, h.held_back, h.points), (vec![5, 6], vec![1], 20));
    }

    #[test]
    fn eps_front_refines_by_projected_size_and_culls() {
        let nodes = tree();
        let v = view(Vec3::new(2.0, 0.5, 3.0), Vec3::new(2.0, 0.5, 0.0));
        let ctx = Ctx::new(&nodes, &v, M);
        let none = |_: u32| false;
        assert_eq!(eps_front(&ctx, 0.0, &none).nodes, vec![3, 4, 5, 6]);
        assert_eq!(eps_front(&ctx, 1e6, &none).nodes, vec![0]);
        let mut last = 0;
        for eps in [100.0, 8.0, 4.0, 2.0, 1.0, 0.0] {
            let p = eps_front(&ctx, eps, &none).points;
            assert!(p >= last);
            last = p;
        }
        // Looking away from the model: everything culled.
        let away = view(Vec3::new(2.0, 0.5, 3.0), Vec3::new(2.0, 0.5, 10.0));
        let ctx = Ctx::new(&nodes, &away, M);
        let f = eps_front(&ctx, 0.0, &none);
        assert!(f.nodes.is_empty() && f.culled == 1);
        assert_eq!(budget_front(&ctx, 100, &none).nodes, Vec::<u32>::new());
    }

    #[test]
    fn eps_l_is_the_papers_formula() {
        let nodes = tree();
        let v = view(Vec3::new(2.0, 0.5, 3.0), Vec3::new(2.0, 0.5, 0.0));
        let m = Metric {
            c0: 2.0,
            c1: 0.5,
            c2: 0.25,
        };
        let ctx = Ctx::new(&nodes, &v, m);
        let d = 3.0f32;
        assert!((ctx.distance(0) - d).abs() < 1e-6);
        // ε_l = c0·(l_max − l + 1)/(c1·d + c2·d²) with l_max = 2, l = 0.
        let (l_max, l) = (2u32, 0u32);
        let want = 2.0 * (l_max - l + 1) as f32 / (0.5 * d + 0.25 * d * d);
        assert!((ctx.eps_l(0) - want).abs() < 1e-6);
    }
}
