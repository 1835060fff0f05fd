//! Building QSplat's bounding-sphere hierarchy and quantising it.
//!
//! Contract: [`build_tree`] is a deterministic function of the cloud (and its leaf radii):
//! - a `u32` permutation of the samples is partitioned in place, top-down, at the median
//!   along the longest axis of each range's bounding box (`select_nth_unstable_by`, ties
//!   broken by sample index; halves in parallel with `rayon::join` above
//!   [`PAR_THRESHOLD`]). The binary tree is implicit: range `[lo, hi)` splits at
//!   `lo + (hi − lo)/2`;
//! - binary levels are combined: an inner node's children are its binary grandchildren (a
//!   binary child that is a leaf is taken as is) or, where that gives fewer interior nodes
//!   (decided per range size, see `Combine`), its binary children; so every inner node has
//!   2, 3 or 4 children and every leaf is one sample;
//! - nodes are numbered breadth-first (level by level), properties computed bottom-up
//!   (sphere bounding the children's spheres, normalised mean normal, cone covering the
//!   children's cones, leaf-weighted mean colour) and quantised top-down from the *decoded*
//!   parents ([`super::quant`]). Each level is processed in parallel; the output does not
//!   depend on the thread count.

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use scenes::PointCloud;

use super::quant;
use crate::MethodError;

/// Ranges at least this long are split in parallel.
pub const PAR_THRESHOLD: usize = 1 << 15;

/// One quantised node, exactly the fields stored in the file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct QNode {
    /// 13-bit child-sphere code (0 for the root, whose sphere is in the header).
    pub sphere: u16,
    /// 14-bit normal code (0 when the scene has no normals).
    pub normal: u16,
    /// 2-bit normal-cone class.
    pub cone: u8,
    /// Number of children: 0, 2, 3 or 4.
    pub children: u8,
    /// True if the node has children and none of them has children.
    pub all_leaves: bool,
    /// RGB565 colour (0 when the scene has no colours).
    pub color: u16,
}

/// A quantised tree in breadth-first order: `levels[l]` lists level `l`'s nodes; the
/// children of level `l`'s nodes are consecutive in level `l + 1`, in order.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct QTree {
    /// Nodes per level.
    pub levels: Vec<Vec<QNode>>,
    /// Root sphere: centre and radius.
    pub root: [f32; 4],
    /// The scene has normals.
    pub normals: bool,
    /// The scene has colours.
    pub colors: bool,
}

impl QTree {
    /// Total nodes.
    pub fn nodes(&self) -> u64 {
        self.levels.iter().map(|l| l.len() as u64).sum()
    }
    /// Nodes without children.
    pub fn leaves(&self) -> u64 {
        self.levels
            .iter()
            .flatten()
            .filter(|n| n.children == 0)
            .count() as u64
    }
}

/// True (unquantised) properties of a node.
#[derive(Debug, Clone, Copy)]
struct TrueNode {
    c: Vec3,
    r: f32,
    /// Mean normal, unit (zero when the scene has none or the children cancel).
    n: Vec3,
    /// Half-angle around `n` covering all normals below, radians (π = any).
    cone: f64,
    color: [f32; 3],
    weight: u32,
}

/// What [`build_tree`] returns besides the file contents.
#[derive(Debug, Clone)]
pub struct Built {
    /// The quantised tree.
    pub tree: QTree,
    /// True sphere per node per level (centre, radius), for tests.
    pub true_spheres: Vec<Vec<(Vec3, f32)>>,
    /// Decoded sphere per node per level, for tests.
    pub decoded_spheres: Vec<Vec<(Vec3, f32)>>,
    /// True unit normal per node per level (zero without normals), for tests: at a leaf,
    /// the sample's normal.
    pub true_normals: Vec<Vec<Vec3>>,
}

/// A sphere code and the sphere it decodes to.
type Encoded = (u16, (Vec3, f32));

/// Partitions `perm` in place into the implicit median-split binary tree.
fn partition(perm: &mut [u32], pos: &[[f32; 3]]) {
    let n = perm.len();
    if n <= 1 {
        return;
    }
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for &i in perm.iter() {
        let p = Vec3::from(pos[i as usize]);
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let s = hi - lo;
    let axis = if s.x >= s.y && s.x >= s.z {
        0
    } else if s.y >= s.z {
        1
    } else {
        2
    };
    let mid = n / 2;
    perm.select_nth_unstable_by(mid, |&a, &b| {
        pos[a as usize][axis]
            .total_cmp(&pos[b as usize][axis])
            .then(a.cmp(&b))
    });
    let (l, r) = perm.split_at_mut(mid);
    if n >= PAR_THRESHOLD {
        rayon::join(|| partition(l, pos), || partition(r, pos));
    } else {
        partition(l, pos);
        partition(r, pos);
    }
}

/// How binary levels are combined, per range size: `true` = the node's children are its
/// binary grandchildren (2–4 children), `false` = its binary children (2). Chosen per size by
/// dynamic programming to minimise the number of interior nodes (so the bottom of the tree
/// is 4-ary rather than ending in 2-child nodes); sizes at one depth take at most two
/// values, so the memo stays tiny.
#[derive(Default)]
struct Combine {
    memo: std::collections::HashMap<u32, (u64, bool)>,
}

impl Combine {
    /// `(interior nodes of a subtree of n samples, use grandchildren)`.
    fn plan(&mut self, n: u32) -> (u64, bool) {
        if n < 2 {
            return (0, false);
        }
        if let Some(&p) = self.memo.get(&n) {
            return p;
        }
        let (a, b) = (n / 2, n - n / 2);
        let binary = 1 + self.plan(a).0 + self.plan(b).0;
        let mut grand = 1;
        for h in [a, b] {
            if h > 1 {
                grand += self.plan(h / 2).0 + self.plan(h - h / 2).0;
            }
        }
        let p = if grand <= binary {
            (grand, true)
        } else {
            (binary, false)
        };
        self.memo.insert(n, p);
        p
    }

    /// Children of range `[lo, hi)` in the combined tree.
    fn children(&mut self, lo: u32, hi: u32, out: &mut Vec<(u32, u32)>) {
        if hi - lo < 2 {
            return;
        }
        let mid = lo + (hi - lo) / 2;
        let grand = self.plan(hi - lo).1;
        for (a, b) in [(lo, mid), (mid, hi)] {
            if b - a == 1 || !grand {
                out.push((a, b));
            } else {
                let m = a + (b - a) / 2;
                out.push((a, m));
                out.push((m, b));
            }
        }
    }
}

/// Smallest `f32` ≥ `v`.
fn f32_up(v: f64) -> f32 {
    let f = v as f32;
    if (f as f64) < v { f.next_up() } else { f }
}

fn combine(kids: &[TrueNode], normals: bool) -> TrueNode {
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

/// Builds and quantises the hierarchy of `cloud` with leaf radii `radii`.
pub fn build_tree(cloud: &PointCloud, radii: &[f32]) -> Result<Built, MethodError> {
    let n = cloud.len();
    if n == 0 {
        return Err(MethodError::Limit(
            "qsplat: the cloud has no samples".into(),
        ));
    }
    if n > u32::MAX as usize / 2 {
        return Err(MethodError::Limit(format!(
            "qsplat: {n} samples exceed the 32-bit index"
        )));
    }
    let pos = cloud.positions();
    let mut perm: Vec<u32> = (0..n as u32).collect();
    partition(&mut perm, pos);

    // Levels of ranges, breadth-first; child_start[l][i] indexes level l + 1.
    let mut ranges: Vec<Vec<(u32, u32)>> = vec![vec![(0, n as u32)]];
    let mut child_start: Vec<Vec<u32>> = Vec::new();
    let mut combine_plan = Combine::default();
    while let Some(cur) = ranges.last() {
        let mut next = Vec::new();
        let mut starts = Vec::with_capacity(cur.len() + 1);
        for &(lo, hi) in cur {
            starts.push(next.len() as u32);
            combine_plan.children(lo, hi, &mut next);
        }
        starts.push(next.len() as u32);
        child_start.push(starts);
        if next.is_empty() {
            break;
        }
        ranges.push(next);
    }

    // Bottom-up true properties.
    let normals = cloud.normals();
    let colors = cloud.colors();
    let has_n = normals.is_some();
    let mut truth: Vec<Vec<TrueNode>> = vec![Vec::new(); ranges.len()];
    for l in (0..ranges.len()).rev() {
        let (below, this) = {
            let (a, b) = truth.split_at_mut(l + 1);
            (b.first().map(|v| v.as_slice()).unwrap_or(&[]), &mut a[l])
        };
        let starts = &child_start[l];
        *this = ranges[l]
            .par_iter()
            .enumerate()
            .map(|(i, &(lo, hi))| {
                if hi - lo == 1 {
                    let s = perm[lo as usize] as usize;
                    let nrm = normals
                        .map(|v| Vec3::from(v[s]).normalize_or_zero())
                        .unwrap_or(Vec3::ZERO);
                    TrueNode {
                        c: Vec3::from(pos[s]),
                        r: radii[s].max(0.0),
                        n: nrm,
                        cone: if has_n && nrm != Vec3::ZERO {
                            0.0
                        } else {
                            std::f64::consts::PI
                        },
                        color: colors.map(|c| c[s].map(|v| v as f32)).unwrap_or([0.0; 3]),
                        weight: 1,
                    }
                } else {
                    combine(&below[starts[i] as usize..starts[i + 1] as usize], has_n)
                }
            })
            .collect();
    }

    // Top-down quantisation.
    let root = truth[0][0];
    let margin = quant::abs_margin(root.c.abs().max_element() + root.r);
    // The stored root sphere is the true one grown by the margins, so every child satisfies
    // `encode_sphere`'s precondition (and inductively every level below).
    let root_r = f32_up(quant::needed_radius(
        root.c.as_dvec3(),
        root.c.as_dvec3(),
        root.r as f64,
        margin,
    ));
    let mut decoded: Vec<Vec<(Vec3, f32)>> = vec![vec![(root.c, root_r)]];
    let mut sphere_codes: Vec<Vec<u16>> = vec![vec![0]];
    for l in 1..ranges.len() {
        let starts = &child_start[l - 1];
        let mut parent = Vec::with_capacity(ranges[l].len());
        for p in 0..ranges[l - 1].len() {
            parent.extend(std::iter::repeat_n(
                p as u32,
                (starts[p + 1] - starts[p]) as usize,
            ));
        }
        let pdec = &decoded[l - 1];
        let res: Result<Vec<Encoded>, MethodError> = truth[l]
            .par_iter()
            .zip(parent.par_iter())
            .enumerate()
            .map(|(i, (t, &p))| {
                let (pc, pr) = pdec[p as usize];
                quant::encode_sphere(pc, pr, t.c, t.r, margin)
                    .map(|(code, c, r)| (code as u16, (c, r)))
                    .ok_or_else(|| {
                        MethodError::Limit(format!(
                            "qsplat: node {i} of level {l} has no enclosing sphere code \
                             (sphere {} r {} in parent {pc} r {pr})",
                            t.c, t.r
                        ))
                    })
            })
            .collect();
        let (codes, dec): (Vec<u16>, Vec<(Vec3, f32)>) = res?.into_iter().unzip();
        sphere_codes.push(codes);
        decoded.push(dec);
    }

    let has_c = colors.is_some();
    let levels: Vec<Vec<QNode>> = (0..ranges.len())
        .map(|l| {
            let starts = &child_start[l];
            let next_starts = child_start.get(l + 1);
            (0..ranges[l].len())
                .into_par_iter()
                .map(|i| {
                    let t = &truth[l][i];
                    let children = (starts[i + 1] - starts[i]) as u8;
                    let all_leaves = children > 0
                        && next_starts.is_none_or(|ns| {
                            (starts[i]..starts[i + 1]).all(|c| ns[c as usize + 1] == ns[c as usize])
                        });
                    let (normal, cone) = quantise_normal(t.n, t.cone, has_n);
                    QNode {
                        sphere: sphere_codes[l][i],
                        normal,
                        cone,
                        children,
                        all_leaves,
                        color: if has_c { quant::rgb565(t.color) } else { 0 },
                    }
                })
                .collect()
        })
        .collect();

    Ok(Built {
        tree: QTree {
            levels,
            root: [root.c.x, root.c.y, root.c.z, root_r],
            normals: has_n,
            colors: has_c,
        },
        true_spheres: truth
            .iter()
            .map(|l| l.iter().map(|t| (t.c, t.r)).collect())
            .collect(),
        decoded_spheres: decoded,
        true_normals: truth
            .iter()
            .map(|l| l.iter().map(|t| t.n).collect())
            .collect(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenes::rng::Pcg32;

    #[test]
    fn quantised_cone_is_never_narrower() {
        let mut rng = Pcg32::new(17);
        for _ in 0..20_000 {
            let axis = rng.unit_vec3();
            let spread = rng.range_f32(0.0, 1.2);
            let kids: Vec<TrueNode> = (0..2 + rng.below(3))
                .map(|_| {
                    let n = (axis + rng.unit_vec3() * spread).normalize_or(Vec3::Z);
                    TrueNode {
                        c: rng.unit_vec3(),
                        r: rng.range_f32(0.01, 0.5),
                        n,
                        cone: if rng.below(2) == 0 {
                            0.0
                        } else {
                            rng.range_f32(0.0, 0.5) as f64
                        },
                        color: [0.0; 3],
                        weight: 1,
                    }
                })
                .collect();
            let t = combine(&kids, true);
            let (code, class) = quantise_normal(t.n, t.cone, true);
            if class == 3 {
                continue;
            }
            let qa = quant::decode_normal(code as u32).unwrap().as_dvec3();
            let q_angle = quant::cone_angle(class);
            // Contains the true cone, hence every child's cone.
            assert!(quant::angle(qa, t.n.as_dvec3()) + t.cone <= q_angle + 1e-12);
            for k in &kids {
                assert!(quant::angle(qa, k.n.as_dvec3()) + k.cone <= q_angle + 1e-9);
            }
        }
    }

    #[test]
    fn tree_invariants_on_a_small_statue() {
        let cloud = scenes::generators::Generator::Statue
            .generate(3000, 2)
            .unwrap();
        let radii = crate::leaf::leaf_radii(&cloud);
        let b = build_tree(&cloud, &radii).unwrap();
        let levels = &b.tree.levels;
        // Decoded spheres enclose the true ones at every node.
        for (l, (tl, dl)) in b.true_spheres.iter().zip(&b.decoded_spheres).enumerate() {
            for (i, (t, d)) in tl.iter().zip(dl).enumerate() {
                let gap = d.1 as f64 - (d.0.as_dvec3() - t.0.as_dvec3()).length() - t.1 as f64;
                assert!(
                    gap >= 0.0,
                    "level {l} node {i}: decoded sphere misses by {gap}"
                );
            }
        }
        // Every quantised cone contains every leaf normal below it.
        let mut below: Vec<Vec<Vec<Vec3>>> = vec![Vec::new(); levels.len()];
        for l in (0..levels.len()).rev() {
            let mut next = 0usize;
            below[l] = levels[l]
                .iter()
                .enumerate()
                .map(|(i, n)| {
                    if n.children == 0 {
                        return vec![b.true_normals[l][i]];
                    }
                    let kids = next..next + n.children as usize;
                    next += n.children as usize;
                    kids.flat_map(|k| below[l + 1][k].clone()).collect()
                })
                .collect();
            for (i, n) in levels[l].iter().enumerate() {
                assert!(n.children == 0 || (2..=4).contains(&n.children));
                if n.cone == 3 {
                    continue;
                }
                let a = quant::decode_normal(n.normal as u32).unwrap().as_dvec3();
                for v in &below[l][i] {
                    assert!(
                        quant::angle(a, v.as_dvec3()) <= quant::cone_angle(n.cone) + 1e-6,
                        "level {l} node {i}"
                    );
                }
            }
            if l + 1 < levels.len() {
                below[l + 1].clear();
            }
        }
        assert_eq!(b.tree.leaves(), 3000);
    }
}
