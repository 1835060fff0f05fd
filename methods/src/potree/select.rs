//! Potree's node selection (`Potree.updateVisibility` of the viewer, Schütz 2016 §3.3):
//! pure, over the nodes known so far.
//!
//! A priority queue holds nodes by *weight*, the projected radius of their bounding sphere
//! in pixels (`r·k/d`, `d` = distance from the eye to the sphere's centre; a sphere that
//! contains the eye weighs `∞`), the root first. Pop the heaviest node:
//! - if its points would take the visible points over the budget, **stop** (the whole
//!   traversal ends there, as in Potree);
//! - if its box is outside the frustum, drop it (its subtree with it);
//! - count its points as visible; if it is not loaded yet, it waits (the caller requests
//!   it, best first) and its children are not looked at;
//! - else draw it and push every child whose projected radius is at least
//!   `min_node_px` (Potree's `minimumNodePixelSize`).
//!
//! Potree's level of detail is *additive*: a node holds points none of its ancestors holds,
//! so what is drawn is a subtree from the root (every ancestor of a drawn node is drawn),
//! not a cut; while a child loads, its parent alone covers its region, sparser.
//!
//! For a tolerance `ε` px instead of a budget there is no budget, and a child is pushed iff
//! its parent's spacing, projected at the child's distance, exceeds `ε`: refinement goes on
//! while the points drawn would be more than `ε` pixels apart (`ε = 0` draws every node).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use scenes::View;
use scenes::camera::Containment;

use super::hierarchy::{NONE, Node};
use crate::Target;

/// What one traversal selected.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Selection {
    /// Loaded visible nodes, in the order they were popped (to draw).
    pub draw: Vec<u32>,
    /// Visible nodes not loaded yet, best first (to request).
    pub waiting: Vec<u32>,
    /// Points of `draw` and `waiting` together (Potree's `numVisiblePoints`).
    pub visible_points: u64,
    /// Points of `draw`.
    pub drawn_points: u64,
    /// Nodes dropped by the frustum test.
    pub culled: u32,
    /// True if the traversal stopped at the budget.
    pub budget_hit: bool,
}

/// Weight key: non-negative finite `f32` bits order like the values; ties go to the lower
/// node number (deterministic).
fn key(w: f32, id: u32) -> (u32, Reverse<u32>) {
    let w = if w.is_nan() { 0.0 } else { w.max(0.0) };
    (w.to_bits(), Reverse(id))
}

/// Selects for `view` and `target` over `nodes` (root 0); `spacing` is the root's spacing,
/// `min_node_px` Potree's smallest node radius in pixels (budget mode), `loaded(id)` tells
/// whether a node's points are in core.
pub fn select(
    nodes: &[Node],
    view: &View,
    target: Target,
    spacing: f64,
    min_node_px: f32,
    loaded: &dyn Fn(u32) -> bool,
) -> Selection {
    let mut s = Selection::default();
    if nodes.is_empty() {
        return s;
    }
    let frustum = view.frustum();
    let eye = view.camera.position;
    let k = view.proj_scale();
    let budget = target.budget_points().unwrap_or(u64::MAX);
    let mut heap = BinaryHeap::new();
    heap.push(key(f32::INFINITY, 0));
    while let Some((_, Reverse(id))) = heap.pop() {
        let n = &nodes[id as usize];
        if s.visible_points + u64::from(n.points) > budget {
            s.budget_hit = true;
            break;
        }
        if frustum.aabb(n.lo, n.hi) == Containment::Outside {
            s.culled += 1;
            continue;
        }
        s.visible_points += u64::from(n.points);
        if !loaded(id) {
            s.waiting.push(id);
            continue;
        }
        s.drawn_points += u64::from(n.points);
        s.draw.push(id);
        let node_spacing = (spacing / f64::from(1u32 << n.level.min(31))) as f32;
        for &c in n.children.iter().filter(|&&c| c != NONE) {
            let (center, radius) = nodes[c as usize].sphere();
            let d = center.distance(eye);
            let px = if d > 0.0 {
                radius * k / d
            } else {
                f32::INFINITY
            };
            let wanted = match target {
                Target::Budget(_) => px >= min_node_px,
                Target::Tolerance(eps) => d <= 0.0 || node_spacing * k / d > eps,
            };
            if !wanted {
                continue;
            }
            let weight = if d - radius < 0.0 { f32::INFINITY } else { px };
            heap.push(key(weight, c));
        }
    }
    s
}
