//! The combined tree's true properties and their quantisation: a forest of combined-tree
//! nodes laid out level by level below its roots ([`Forest`]), properties bottom-up
//! ([`combine`]), and stored nodes top-down from the *decoded* parents ([`Forest::quantise`]).
//! The in-memory build has one forest (the whole tree); the build in units one per unit.

use glam::{DVec3, Vec3};
use rayon::prelude::*;

use super::node::{Binary, Encoded, QNode, TrueNode};
use super::quant;
use super::stats::QuantStats;
use crate::MethodError;

pub(super) use crate::spill::samples::SampleView as Samples;

/// Smallest `f32` ≥ `v`.
pub(super) fn f32_up(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) < v { f.next_up() } else { f }
}

pub(super) fn combine(kids: &[TrueNode], normals: bool) -> TrueNode {
    let mut lo = DVec3::splat(f64::INFINITY);
    let mut hi = DVec3::splat(f64::NEG_INFINITY);
    for k in kids {
        let c = k.c.as_dvec3();
        lo = lo.min(c - k.r as f64);
        hi = hi.max(c + k.r as f64);
    }
    let c = ((lo + hi) * 0.5).as_vec3();
    let r = kids
        .iter()
        .map(|k| (k.c.as_dvec3() - c.as_dvec3()).length() + k.r as f64)
        .fold(0.0, f64::max);
    let (n, cone) = if normals {
        let sum: DVec3 = kids.iter().map(|k| k.n.as_dvec3()).sum();
        if sum.length() < 1e-9 || kids.iter().any(|k| k.n == Vec3::ZERO) {
            (Vec3::ZERO, std::f64::consts::PI)
        } else {
            let a = sum.normalize();
            let cone = kids
                .iter()
                .map(|k| quant::angle(a, k.n.as_dvec3()) + k.cone)
                .fold(0.0, f64::max)
                .min(std::f64::consts::PI);
            (a.as_vec3(), cone)
        }
    } else {
        (Vec3::ZERO, std::f64::consts::PI)
    };
    let weight: u32 = kids.iter().map(|k| k.weight).sum();
    let mut color = [0.0f32; 3];
    for (ch, out) in color.iter_mut().enumerate() {
        let s: f64 = kids
            .iter()
            .map(|k| k.color[ch] as f64 * k.weight as f64)
            .sum();
        *out = (s / weight.max(1) as f64) as f32;
    }
    TrueNode {
        c,
        r: f32_up(r),
        n,
        cone,
        color,
        weight,
    }
}

/// Quantises a node's normal and cone: the 14-bit normal nearest to `n`, and the smallest
/// cone class whose half-angle covers `cone` widened by the normal's quantisation error, so
/// the quantised cone contains every normal the true cone contains. No normals, or a cone
/// of π (children cancel out), give class 3 (never culled).
pub fn quantise_normal(n: Vec3, cone: f64, has_normals: bool) -> (u16, u8) {
    if !has_normals {
        return (0, 3);
    }
    let code = quant::encode_normal(n);
    if cone >= std::f64::consts::PI {
        return (code as u16, 3);
    }
    let q = quant::decode_normal(code).unwrap_or(n);
    let need = cone + quant::angle(n.as_dvec3(), q.as_dvec3());
    (code as u16, quant::cone_class(need))
}

/// The combined-tree nodes below a list of roots, breadth-first: `ranges[l]` lists level
/// `l`'s nodes as `(lo, hi, split)`; `child_start[l][i]..child_start[l][i + 1]` indexes the
/// children of node `i` in level `l + 1`.
pub(super) struct Forest {
    pub ranges: Vec<Vec<(u32, u32, u32)>>,
    pub child_start: Vec<Vec<u32>>,
}

impl Forest {
    /// The combined subtrees of `roots` (nodes of `tree`), level by level.
    pub(super) fn new(tree: &Binary, roots: Vec<(u32, u32, u32)>) -> Self {
        let mut ranges: Vec<Vec<(u32, u32, u32)>> = vec![roots];
        let mut child_start: Vec<Vec<u32>> = Vec::new();
        while let Some(cur) = ranges.last() {
            let mut next = Vec::new();
            let mut starts = Vec::with_capacity(cur.len() + 1);
            for &r in cur {
                starts.push(next.len() as u32);
                tree.children(r, &mut next);
            }
            starts.push(next.len() as u32);
            child_start.push(starts);
            if next.is_empty() {
                break;
            }
            ranges.push(next);
        }
        Self {
            ranges,
            child_start,
        }
    }

    /// True properties of every node, bottom-up. The leaf at tree position `p` is sample
    /// `perm[p]` of `s`, or sample `p` when `perm` is `None` (`s` already in tree order).
    pub(super) fn truths(&self, perm: Option<&[u32]>, s: Samples<'_>) -> Vec<Vec<TrueNode>> {
        let has_n = s.normals.is_some();
        let mut truth: Vec<Vec<TrueNode>> = vec![Vec::new(); self.ranges.len()];
        for l in (0..self.ranges.len()).rev() {
            let (below, this) = {
                let (a, b) = truth.split_at_mut(l + 1);
                (b.first().map(|v| v.as_slice()).unwrap_or(&[]), &mut a[l])
            };
            let starts = &self.child_start[l];
            *this = self.ranges[l]
                .par_iter()
                .enumerate()
                .map(|(i, &(lo, hi, _))| {
                    if hi - lo == 1 {
                        leaf_truth(s, perm.map_or(lo as usize, |p| p[lo as usize] as usize))
                    } else {
                        combine(&below[starts[i] as usize..starts[i + 1] as usize], has_n)
                    }
                })
                .collect();
        }
        truth
    }
}

fn leaf_truth(s: Samples<'_>, i: usize) -> TrueNode {
    let nrm = s
        .normals
        .map(|v| Vec3::from(v[i]).normalize_or_zero())
        .unwrap_or(Vec3::ZERO);
    TrueNode {
        c: Vec3::from(s.pos[i]),
        r: s.radii[i].max(0.0),
        n: nrm,
        cone: if s.normals.is_some() && nrm != Vec3::ZERO {
            0.0
        } else {
            std::f64::consts::PI
        },
        color: s.colors.map(|c| c[i].map(|v| v as f32)).unwrap_or([0.0; 3]),
        weight: 1,
    }
}

/// A sphere's absolute quantisation margin, from its own coordinates ([`quant::abs_margin`]
/// of its |centre| + radius).
fn sphere_margin(t: &TrueNode) -> f64 {
    quant::abs_margin(t.c.abs().max_element() + t.r)
}

/// The decoded root sphere and its margin: the true sphere grown by its margin, so every
/// child satisfies [`quant::encode_sphere`]'s precondition.
pub(super) fn root_sphere(root: &TrueNode) -> ((Vec3, f32), f64) {
    let margin = sphere_margin(root);
    let r = f32_up(quant::needed_radius(
        root.c.as_dvec3(),
        root.c.as_dvec3(),
        root.r as f64,
        margin,
    ));
    ((root.c, r), margin)
}

/// The sphere code of `t` inside its parent's decoded sphere `(pc, pr)` of margin
/// `pmargin`. Each sphere's absolute margin is taken from its own coordinates, capped by its
/// parent's: a child inside its parent has `|c|∞ + r ≤ |C|∞ + R`, so the cap only absorbs
/// `f32` rounding, and margins shrink down the tree. `what` names the node in the error.
pub(super) fn encode_child(
    t: &TrueNode,
    (pc, pr): (Vec3, f32),
    pmargin: f64,
    fit: quant::Fit,
    what: impl FnOnce() -> String,
) -> Result<Encoded, MethodError> {
    let margin = sphere_margin(t).min(pmargin);
    quant::encode_sphere(pc, pr, t.c, t.r, margin, fit)
        .map(|(code, c, r)| (code as u16, (c, r), margin))
        .ok_or_else(|| {
            MethodError::Bug(format!(
                "qsplat: {} has no enclosing sphere code (sphere {} r {} in parent {pc} r {pr})",
                what(),
                t.c,
                t.r
            ))
        })
}

/// The stored node of `t`, given its sphere code and child structure.
pub(super) fn qnode(
    t: &TrueNode,
    sphere: u16,
    children: u8,
    all_leaves: bool,
    has_n: bool,
    has_c: bool,
) -> QNode {
    let (normal, cone) = quantise_normal(t.n, t.cone, has_n);
    QNode {
        sphere,
        normal,
        cone,
        children,
        all_leaves,
        color: if has_c { quant::rgb565(t.color) } else { 0 },
    }
}

/// Where the roots of a forest get their spheres from.
#[derive(Debug, Clone, Copy)]
pub(super) enum Parent {
    /// The forest is the whole tree: its one root's sphere goes into the header.
    Root,
    /// The roots are children of a node with this decoded sphere and margin.
    Node((Vec3, f32), f64),
}

/// A forest quantised top-down: stored nodes per level, and (with `debug`) the decoded
/// spheres.
pub(super) struct Quantised {
    pub levels: Vec<Vec<QNode>>,
    /// The header's root sphere ([`Parent::Root`] only).
    pub root: [f32; 4],
    pub decoded: Vec<Vec<(Vec3, f32)>>,
    /// What quantisation did to these nodes.
    pub stats: QuantStats,
}

impl Forest {
    /// Quantises every node top-down from the *decoded* parents. `base_level` numbers the
    /// roots' level in errors.
    pub(super) fn quantise(
        &self,
        truth: &[Vec<TrueNode>],
        parent: Parent,
        (has_n, has_c): (bool, bool),
        fit: quant::Fit,
        base_level: usize,
        debug: bool,
    ) -> Result<Quantised, MethodError> {
        let mut root = [0.0; 4];
        let mut decoded: Vec<Vec<(Vec3, f32)>> = Vec::new();
        let mut margins: Vec<Vec<f64>> = Vec::new();
        let mut levels: Vec<Vec<QNode>> = Vec::with_capacity(self.ranges.len());
        let mut stats = QuantStats::default();
        for l in 0..self.ranges.len() {
            let res: Vec<Encoded> = if l == 0 {
                match parent {
                    Parent::Root => {
                        let ((c, r), m) = root_sphere(&truth[0][0]);
                        root = [c.x, c.y, c.z, r];
                        vec![(0, (c, r), m)]
                    }
                    Parent::Node(pd, pm) => {
                        let res: Vec<Encoded> = truth[0]
                            .iter()
                            .enumerate()
                            .map(|(i, t)| {
                                encode_child(t, pd, pm, fit, || {
                                    format!("node {i} of level {base_level}")
                                })
                            })
                            .collect::<Result<_, _>>()?;
                        stats.merge(&QuantStats::spheres(&truth[0], &res, base_level, |_| pd));
                        res
                    }
                }
            } else {
                let starts = &self.child_start[l - 1];
                let mut parent = Vec::with_capacity(self.ranges[l].len());
                for p in 0..self.ranges[l - 1].len() {
                    parent.extend(std::iter::repeat_n(
                        p as u32,
                        (starts[p + 1] - starts[p]) as usize,
                    ));
                }
                let (pdec, pmargin) = (&decoded[l - 1], &margins[l - 1]);
                let res: Vec<Encoded> = truth[l]
                    .par_iter()
                    .zip(parent.par_iter())
                    .enumerate()
                    .map(|(i, (t, &p))| {
                        encode_child(t, pdec[p as usize], pmargin[p as usize], fit, || {
                            format!("node {i} of level {}", base_level + l)
                        })
                    })
                    .collect::<Result<_, _>>()?;
                stats.merge(&QuantStats::spheres(&truth[l], &res, base_level + l, |i| {
                    pdec[parent[i] as usize]
                }));
                res
            };
            let codes: Vec<u16> = res.iter().map(|e| e.0).collect();
            levels.push(self.stored_level(l, truth, &codes, has_n, has_c));
            stats.merge(&QuantStats::nodes(&truth[l], &levels[l], has_n));
            decoded.push(res.iter().map(|e| e.1).collect());
            margins.push(res.iter().map(|e| e.2).collect());
            // The level above is no longer needed (its children are encoded).
            if l >= 1 && !debug {
                decoded[l - 1] = Vec::new();
                margins[l - 1] = Vec::new();
            }
        }
        Ok(Quantised {
            levels,
            root,
            decoded,
            stats,
        })
    }

    fn stored_level(
        &self,
        l: usize,
        truth: &[Vec<TrueNode>],
        codes: &[u16],
        has_n: bool,
        has_c: bool,
    ) -> Vec<QNode> {
        let starts = &self.child_start[l];
        let next_starts = self.child_start.get(l + 1);
        (0..self.ranges[l].len())
            .into_par_iter()
            .map(|i| {
                let children = (starts[i + 1] - starts[i]) as u8;
                let all_leaves = children > 0
                    && next_starts.is_none_or(|ns| {
                        (starts[i]..starts[i + 1]).all(|c| ns[c as usize + 1] == ns[c as usize])
                    });
                qnode(&truth[l][i], codes[i], children, all_leaves, has_n, has_c)
            })
            .collect()
    }
}
