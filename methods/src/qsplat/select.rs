//! Per-frame traversal of the mapped `.qs` file, decoding nodes as it goes.
//!
//! Contract: [`select_threshold`] is QSplat's recursive traversal: frustum culling (a sphere
//! entirely inside stops the tests below it), back-face culling with the quantised normal
//! cone (entirely back-facing ⇒ dropped; entirely front-facing ⇒ no more tests below), and a
//! splat per node that is a leaf or whose projected diameter `2·r·k/z` is ≤ the threshold.
//! [`select_budget`] refines coarse-first (largest projected size first, ties by file
//! offset) and stops at the first refinement that would exceed the budget; a larger budget
//! runs a longer prefix of the same refinements and never draws fewer splats. Both are
//! deterministic, allocate only the output (and, for budgets, the queue) and return an
//! error, never panic, on malformed bytes.
//!
//! Culling is conservative: a node's decoded sphere encloses every sample below it and its
//! cone every normal below it, so a sample inside the frustum and facing the eye is never
//! culled (the contract's tolerance-0 rule).
//!
//! Monotonicity: a node can pass the culling tests while every leaf below it fails them
//! (its sphere grazes the frustum, or its wider cone is mixed while its children's face
//! away). Such a node is not drawn ([`Counters::dropped_empty`]): before a non-leaf node is
//! drawn, a depth-first look-ahead confirms some leaf below it is reached through kept
//! nodes (immediate for subtrees entirely inside and front-facing). Then every drawn node
//! has a kept leaf below it, so a smaller threshold, which reaches every node a larger one
//! drew, draws at least one splat under each: the count never decreases as the threshold
//! shrinks. In budget mode every node queued has a kept leaf below it, so each refinement
//! keeps at least one child and never lowers the count.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use glam::Vec3;
use scenes::View;
use scenes::camera::{Containment, Frustum};

use super::format::{self, Header};
use super::quant;
use crate::{MethodError, SplatBatch};

/// Per-frame counters (the method's extra CSV columns, in order).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct Counters {
    /// Nodes decoded and tested.
    pub nodes_visited: u64,
    /// Splats emitted.
    pub splats_emitted: u64,
    /// Nodes dropped by the frustum test.
    pub culled_frustum: u64,
    /// Nodes dropped by the normal-cone test.
    pub culled_backface: u64,
    /// Nodes not drawn although they pass the culling tests, because no leaf below them
    /// does (see the module doc).
    pub dropped_empty: u64,
    /// The threshold used (budget mode: the projected size of the largest node left
    /// unrefined, 0 if every visible leaf was reached).
    pub threshold_px: f64,
    /// One past the last byte of the node body holding a node the frame drew. Groups are
    /// stored breadth-first, so a frame's splats come from a prefix of the file, the shorter
    /// the coarser (§3.1: "we only need to read in the first part of a file in order to
    /// visualize the model at low resolution").
    pub draw_end: u64,
    /// One past the last byte of the node body the frame read: beyond [`Self::draw_end`] by
    /// the look-ahead (module doc), which probes down to a leaf before drawing a node.
    pub read_end: u64,
}

/// A decoded node with what is needed to reach its children.
#[derive(Debug, Clone, Copy, Default)]
struct Node {
    c: Vec3,
    r: f32,
    normal: u16,
    cone: u8,
    color: u16,
    children: u8,
    child_off: u32,
    child_ptr: bool,
    /// One past its own bytes in the body.
    end: u32,
}

#[derive(Clone, Copy, PartialEq, Eq)]
enum Facing {
    Back,
    Front,
    Mixed,
}

/// Cosines of the cone classes' half-angles.
const CONE_COS: [f32; 4] = [0.998_045, 0.968_245_9, 0.826_797_3, 0.0];

struct Ctx<'a> {
    body: &'a [u8],
    nb: usize,
    colors: bool,
    /// Back-face culling by normal cone: the model has normals and `two_sided` is off.
    cull: bool,
    frustum: Frustum,
    eye: Vec3,
    fwd: Vec3,
    k2: f32,
    near: f32,
    oct: &'a [u32],
    spheres: &'a [[f32; 4]],
    dirs: &'a [Vec3],
    out: SplatBatch,
    n: Counters,
}

fn corrupt(h: &str, off: usize) -> MethodError {
    MethodError::Limit(format!(
        "qsplat: malformed node group at body byte {off} ({h})"
    ))
}

impl<'a> Ctx<'a> {
    fn new(
        body: &'a [u8],
        header: &Header,
        view: &View,
        capacity: usize,
        cull_backfaces: bool,
    ) -> Self {
        let colors = header.flags & format::FLAG_COLORS != 0;
        let normals = header.flags & format::FLAG_NORMALS != 0;
        let attrs = scenes::Attributes {
            normals,
            colors,
            radii: true,
        };
        Ctx {
            body,
            nb: header.node_bytes(),
            colors,
            cull: normals && cull_backfaces,
            frustum: view.frustum(),
            eye: view.camera.position,
            fwd: view.camera.forward(),
            k2: 2.0 * view.proj_scale(),
            near: view.camera.near,
            oct: quant::normal_oct_table(),
            spheres: &quant::sphere_table().entries,
            dirs: quant::normal_table(),
            out: SplatBatch::with_attributes(attrs, capacity),
            n: Counters::default(),
        }
    }

    /// Notes that the group of `count` nodes at `off` was read ([`Counters::read_end`]).
    #[inline(always)]
    fn note_read(&mut self, off: usize, count: usize, has_ptr: bool) {
        let end = (off + count * self.nb + 4 * usize::from(has_ptr)) as u64;
        self.n.read_end = self.n.read_end.max(end);
    }

    /// Decodes the group at `off` (children of the decoded sphere `(pc, pr)`).
    #[inline]
    fn group(
        &mut self,
        off: usize,
        count: usize,
        has_ptr: bool,
        pc: Vec3,
        pr: f32,
    ) -> Result<([Node; 4], usize), MethodError> {
        self.note_read(off, count, has_ptr);
        let mut out = [Node::default(); 4];
        let mut p = off;
        let mut cursor = 0usize;
        if has_ptr {
            cursor =
                format::read_u32(self.body, p).ok_or_else(|| corrupt("pointer", off))? as usize;
            p += 4;
        }
        for slot in out.iter_mut().take(count) {
            let mut n = self.node_at(p, off, pc, pr)?;
            if n.children > 0 {
                n.child_off = cursor as u32;
                cursor += n.children as usize * self.nb + 4 * n.child_ptr as usize;
            }
            *slot = n;
            p += self.nb;
        }
        Ok((out, count))
    }

    fn root(&mut self, header: &Header) -> Result<Node, MethodError> {
        let (mut nodes, _) = self.group(0, 1, header.nodes > 1, Vec3::ZERO, 0.0)?;
        let [x, y, z, r] = header.root;
        nodes[0].c = Vec3::new(x, y, z);
        nodes[0].r = r;
        Ok(nodes[0])
    }

    #[inline]
    fn facing(&self, n: &Node) -> Facing {
        if n.cone >= 3 {
            return Facing::Mixed;
        }
        let v = self.eye - n.c;
        let d2 = v.length_squared();
        if d2 <= n.r * n.r {
            return Facing::Mixed;
        }
        let inv = d2.sqrt().recip();
        let sb = n.r * inv;
        let cb = (1.0 - sb * sb).max(0.0).sqrt();
        let (st, ct) = (quant::CONE_SIN[n.cone as usize], CONE_COS[n.cone as usize]);
        if ct * cb - st * sb <= 0.0 {
            return Facing::Mixed;
        }
        let s = st * cb + ct * sb;
        let axis = self.normal_vec(n.normal);
        let ca = axis.dot(v) * inv;
        if ca < -s - 1e-4 {
            Facing::Back
        } else if ca > s + 1e-4 {
            Facing::Front
        } else {
            Facing::Mixed
        }
    }

    #[inline]
    fn normal_vec(&self, code: u16) -> Vec3 {
        self.dirs.get(code as usize).copied().unwrap_or(Vec3::Z)
    }

    /// Culling tests without counters: `Some(true)` frustum-culled, `Some(false)` back-face
    /// culled, `None` kept (updating the flags).
    #[inline(always)]
    fn cull(&self, n: &Node, inside: &mut bool, front: &mut bool) -> Option<bool> {
        if !*inside {
            match self.frustum.sphere(n.c, n.r) {
                Containment::Outside => return Some(true),
                Containment::Inside => *inside = true,
                Containment::Intersects => {}
            }
        }
        if !*front && self.cull {
            match self.facing(n) {
                Facing::Back => return Some(false),
                Facing::Front => *front = true,
                Facing::Mixed => {}
            }
        }
        None
    }

    /// Culls `n`; returns false if dropped, updating the flags and counters.
    #[inline]
    fn keep(&mut self, n: &Node, inside: &mut bool, front: &mut bool) -> bool {
        self.n.nodes_visited += 1;
        match self.cull(n, inside, front) {
            None => true,
            Some(true) => {
                self.n.culled_frustum += 1;
                false
            }
            Some(false) => {
                self.n.culled_backface += 1;
                false
            }
        }
    }

    /// True if some leaf below the kept node `n` is reached through kept nodes only (depth
    /// first, stopping at the first). A subtree entirely inside and front-facing answers at
    /// once. Nodes looked at count as visited.
    fn has_visible_leaf(
        &mut self,
        n: &Node,
        inside: bool,
        front: bool,
    ) -> Result<bool, MethodError> {
        if n.children == 0 || (inside && (front || !self.cull)) {
            return Ok(true);
        }
        let (kids, count) = self.group(
            n.child_off as usize,
            n.children as usize,
            n.child_ptr,
            n.c,
            n.r,
        )?;
        for kid in &kids[..count] {
            let (mut i, mut f) = (inside, front);
            self.n.nodes_visited += 1;
            if self.cull(kid, &mut i, &mut f).is_none() && self.has_visible_leaf(kid, i, f)? {
                return Ok(true);
            }
        }
        Ok(false)
    }

    /// Projected diameter in pixels (∞ when the centre is not beyond the near plane).
    #[inline]
    fn size(&self, n: &Node) -> f32 {
        let z = (n.c - self.eye).dot(self.fwd);
        if z > self.near {
            n.r * self.k2 / z
        } else {
            f32::INFINITY
        }
    }

    #[inline]
    fn emit(&mut self, n: &Node) {
        self.out.positions.push(n.c.to_array());
        if let Some(v) = self.out.normals.as_mut() {
            v.push(self.oct.get(n.normal as usize).copied().unwrap_or(0));
        }
        if let Some(v) = self.out.colors.as_mut() {
            v.push(crate::draw::pack_color(quant::rgb888(n.color)));
        }
        if let Some(v) = self.out.radii.as_mut() {
            v.push(n.r);
        }
        self.n.splats_emitted += 1;
        self.n.draw_end = self.n.draw_end.max(u64::from(n.end));
    }

    /// Decodes the node word at body byte `p` (of the group at `off`) relative to the
    /// decoded parent `(pc, pr)`; `child_off` is left 0 for the caller to fill.
    #[inline(always)]
    fn node_at(&self, p: usize, off: usize, pc: Vec3, pr: f32) -> Result<Node, MethodError> {
        let w = format::read_u32(self.body, p).ok_or_else(|| corrupt("node", off))?;
        let n = format::unpack(w);
        // Same arithmetic as `quant::decode_sphere` (bit-identical to the build's).
        let e = self
            .spheres
            .get(n.sphere as usize)
            .ok_or_else(|| corrupt("sphere code", off))?;
        let color = if self.colors {
            format::read_u16(self.body, p + 4).ok_or_else(|| corrupt("colour", off))?
        } else {
            0
        };
        Ok(Node {
            c: pc + Vec3::new(e[0], e[1], e[2]) * pr,
            r: e[3] * pr,
            normal: n.normal,
            cone: n.cone,
            color,
            children: n.children,
            child_off: 0,
            child_ptr: !n.all_leaves,
            end: (p + self.nb) as u32,
        })
    }

    /// Tolerance traversal of the group at `off`, node by node (no group buffer).
    #[expect(
        clippy::too_many_arguments,
        reason = "hot recursive path; a struct costs copies"
    )]
    fn visit_group(
        &mut self,
        off: usize,
        count: usize,
        has_ptr: bool,
        pc: Vec3,
        pr: f32,
        inside: bool,
        front: bool,
        thr: f32,
    ) -> Result<(), MethodError> {
        self.note_read(off, count, has_ptr);
        let mut p = off;
        let mut cursor = 0usize;
        if has_ptr {
            cursor =
                format::read_u32(self.body, p).ok_or_else(|| corrupt("pointer", off))? as usize;
            p += 4;
        }
        for _ in 0..count {
            let mut n = self.node_at(p, off, pc, pr)?;
            p += self.nb;
            if n.children > 0 {
                n.child_off = cursor as u32;
                cursor += n.children as usize * self.nb + 4 * n.child_ptr as usize;
            }
            self.visit(&n, inside, front, thr)?;
        }
        Ok(())
    }

    /// Tolerance traversal of one decoded node.
    #[inline(always)]
    fn visit(
        &mut self,
        n: &Node,
        mut inside: bool,
        mut front: bool,
        thr: f32,
    ) -> Result<(), MethodError> {
        if !self.keep(n, &mut inside, &mut front) {
            return Ok(());
        }
        if n.children == 0 {
            self.emit(n);
            return Ok(());
        }
        if self.size(n) <= thr {
            if self.has_visible_leaf(n, inside, front)? {
                self.emit(n);
            } else {
                self.n.dropped_empty += 1;
            }
            return Ok(());
        }
        self.visit_group(
            n.child_off as usize,
            n.children as usize,
            n.child_ptr,
            n.c,
            n.r,
            inside,
            front,
            thr,
        )
    }
}

/// Tolerance mode: the recursive traversal with threshold `thr_px`.
pub fn select_threshold(
    body: &[u8],
    header: &Header,
    view: &View,
    thr_px: f32,
    capacity: usize,
    cull_backfaces: bool,
) -> Result<(SplatBatch, Counters), MethodError> {
    let mut ctx = Ctx::new(body, header, view, capacity, cull_backfaces);
    let root = ctx.root(header)?;
    ctx.visit(&root, false, false, thr_px)?;
    ctx.n.threshold_px = thr_px as f64;
    Ok((ctx.out, ctx.n))
}

/// Budget mode: coarse-first refinement within `budget` splats.
pub fn select_budget(
    body: &[u8],
    header: &Header,
    view: &View,
    budget: u64,
    capacity: usize,
    cull_backfaces: bool,
) -> Result<(SplatBatch, Counters), MethodError> {
    let mut ctx = Ctx::new(body, header, view, capacity, cull_backfaces);
    let root = ctx.root(header)?;
    // Arena of (node, inside, front); the heap orders indices by (size, earliest offset).
    let mut arena: Vec<(Node, bool, bool)> = Vec::new();
    let mut done: Vec<usize> = Vec::new();
    let mut heap: BinaryHeap<(u32, Reverse<u32>, usize)> = BinaryHeap::new();
    let (mut inside, mut front) = (false, false);
    let mut count = 0u64;
    let push = |ctx: &Ctx,
                arena: &mut Vec<(Node, bool, bool)>,
                heap: &mut BinaryHeap<_>,
                done: &mut Vec<usize>,
                n: Node,
                i: bool,
                f: bool| {
        arena.push((n, i, f));
        let idx = arena.len() - 1;
        if n.children == 0 {
            done.push(idx);
        } else {
            heap.push((ctx.size(&n).to_bits(), Reverse(n.child_off), idx));
        }
    };
    if ctx.keep(&root, &mut inside, &mut front) && ctx.has_visible_leaf(&root, inside, front)? {
        push(&ctx, &mut arena, &mut heap, &mut done, root, inside, front);
        count = 1;
    }
    let mut kept: [(Node, bool, bool); 4] = [(Node::default(), false, false); 4];
    while let Some(&(_, _, idx)) = heap.peek() {
        let (n, inside, front) = arena[idx];
        let (kids, cnt) = ctx.group(
            n.child_off as usize,
            n.children as usize,
            n.child_ptr,
            n.c,
            n.r,
        )?;
        let mut visible = 0;
        for kid in &kids[..cnt] {
            let (mut i, mut f) = (inside, front);
            if ctx.keep(kid, &mut i, &mut f) {
                if ctx.has_visible_leaf(kid, i, f)? {
                    kept[visible] = (*kid, i, f);
                    visible += 1;
                } else {
                    ctx.n.dropped_empty += 1;
                }
            }
        }
        if count - 1 + visible as u64 > budget {
            break;
        }
        heap.pop();
        count = count - 1 + visible as u64;
        for &(kid, i, f) in &kept[..visible] {
            push(&ctx, &mut arena, &mut heap, &mut done, kid, i, f);
        }
    }
    ctx.n.threshold_px = heap
        .peek()
        .map(|&(bits, _, _)| f32::from_bits(bits) as f64)
        .unwrap_or(0.0);
    // Output order: finished leaves, then the heap's array (deterministic: the same
    // operations give the same array; sorting it would cost more than the traversal).
    for idx in done
        .into_iter()
        .chain(heap.into_vec().into_iter().map(|(_, _, i)| i))
    {
        let n = arena[idx].0;
        ctx.emit(&n);
    }
    Ok((ctx.out, ctx.n))
}
