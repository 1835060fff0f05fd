//! What quantisation did to a build's nodes: the figures of the paper's §3.1 ("a mean
//! quantization error of 0.04 in the x, y, and z components of a child sphere, and a mean
//! error of 0.15 in the child sphere's radius" for a parent of radius 1; "a mean quantization
//! error of approximately 0.01 radian" for normals; quantised spheres that "completely
//! enclose" the true ones; children per node in {0, 2, 3, 4}), measured on every node the
//! build encodes, against the true (unquantised) node. Also what the paper says the format
//! does, counted on what a build used: offsets and radii "quantized to 13 values", cone
//! widths in "just 2 bits", and positions "encoded relative to the quantized position" of the
//! parent, so that the error does not grow with depth (the mean centre error per level).

use glam::Vec3;
use rayon::prelude::*;

use super::node::{Encoded, QNode, TrueNode};
use super::quant;

/// Sums over a build's nodes (merge the parts of a build with [`QuantStats::merge`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct QuantStats {
    /// Child spheres encoded relative to a decoded parent (every node but the root).
    pub spheres: u64,
    /// Σ over those of `Σ_axis |decoded − true centre| / decoded parent radius`.
    pub centre_error: f64,
    /// Σ over those of `(decoded − true radius) / decoded parent radius`.
    pub radius_error: f64,
    /// Σ over those of the radius error, in parent radii, had the radius been grown by the
    /// centre's error in the L1 norm (`|Δx| + |Δy| + |Δz|`, a bound of the Euclidean one)
    /// before rounding up to the next 13th: an experiment on the paper's 0.15 (README,
    /// "Quantisation error").
    pub radius_error_l1: f64,
    /// Decoded spheres that do not enclose the true sphere (`|Δc| + r > r_decoded`).
    pub not_enclosed: u64,
    /// Nodes with a normal (the scene has normals and the node's mean normal is not zero).
    pub normals: u64,
    /// Σ over those of the angle between the true and the decoded normal, radians.
    pub normal_error: f64,
    /// The largest of those angles.
    pub normal_error_max: f64,
    /// Nodes by number of children: 0, 1, 2, 3, 4, more.
    pub children: [u64; 6],
    /// Child spheres per tree level (the root is level 0; deeper levels count in the last).
    pub level_spheres: [u64; LEVELS],
    /// Σ of the centre error (as [`Self::centre_error`]) per tree level.
    pub level_centre_error: [f64; LEVELS],
    /// The sphere codes used, one bit per code of the 13-bit field.
    pub sphere_codes: [u64; SPHERE_WORDS],
    /// The cone classes used, one bit per class of the 2-bit field.
    pub cone_codes: u8,
    /// Back-face culls with exact and with quantised cones ([`ConeCulls`]).
    pub cone_culls: ConeCulls,
}

/// §3.1: "backface culling with these quantized normal cones discards over 90 percent of
/// nodes that would be culled using exact normal cone widths" and "we are always conservative
/// in representing normal cone widths, so we never discard geometry that should be
/// displayed". Each node with a normal is tested from [`CULL_VIEWS`] distant viewing
/// directions (orthographic: the eye far away, so a cone is back-facing from direction `v`
/// when every normal in it has `n·v < 0`): with its exact cone (its true normal and the true
/// half-angle covering every normal below it) and with its stored one (the decoded normal
/// and the 2-bit class's half-angle, with the traversal's 10⁻⁴ slack). Index 0 counts every
/// node, 1 the inner nodes (a leaf's cone is its single normal's).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ConeCulls {
    /// (node, direction) pairs back-facing with the exact cone.
    pub exact: [u64; 2],
    /// Pairs back-facing with the stored cone.
    pub quantised: [u64; 2],
    /// Pairs back-facing with the stored cone but not the exact one: geometry that should be
    /// displayed, discarded (the paper: never).
    pub wrong: u64,
}

/// Viewing directions of [`ConeCulls`]: a Fibonacci sphere of this many points.
pub const CULL_VIEWS: usize = 16;

impl ConeCulls {
    /// The directions, unit vectors spread evenly over the sphere (computed once).
    pub fn views() -> &'static [glam::DVec3; CULL_VIEWS] {
        static VIEWS: std::sync::LazyLock<[glam::DVec3; CULL_VIEWS]> =
            std::sync::LazyLock::new(|| {
                let golden = std::f64::consts::PI * (3.0 - 5f64.sqrt());
                std::array::from_fn(|i| {
                    let z = 1.0 - (2 * i + 1) as f64 / CULL_VIEWS as f64;
                    let r = (1.0 - z * z).sqrt();
                    let a = golden * i as f64;
                    glam::DVec3::new(r * a.cos(), r * a.sin(), z)
                })
            });
        &VIEWS
    }

    /// Tests one node: true normal `n` and half-angle `cone`, decoded normal `q` and class
    /// `class`; `inner` when it has children. A node that neither cone can cull (an
    /// exact half-angle of π/2 or more and the never-culled class 3, as every node of a scene
    /// without normals has) counts nothing and is not tested: with the 16 directions
    /// recomputed per node, `perf` had put ≈ 9 % of a terrain 10 M build's samples on this
    /// test (skipping it and computing the directions once: the build's CPU ×0.97, paired).
    pub fn add(&mut self, n: glam::DVec3, cone: f64, q: glam::DVec3, class: u8, inner: bool) {
        let exact_sin = (cone < std::f64::consts::FRAC_PI_2).then(|| cone.sin());
        let quant_sin = (class < 3).then(|| f64::from(quant::CONE_SIN[usize::from(class)]));
        if exact_sin.is_none() && quant_sin.is_none() {
            return;
        }
        for &v in Self::views() {
            let exact = exact_sin.is_some_and(|s| n.dot(v) < -s);
            let quantised = quant_sin.is_some_and(|s| q.dot(v) < -s - 1e-4);
            for (k, on) in [(0, true), (1, inner)] {
                if on {
                    self.exact[k] += u64::from(exact);
                    self.quantised[k] += u64::from(quantised);
                }
            }
            self.wrong += u64::from(quantised && !exact);
        }
    }

    fn merge(&mut self, o: &Self) {
        for k in 0..2 {
            self.exact[k] += o.exact[k];
            self.quantised[k] += o.quantised[k];
        }
        self.wrong += o.wrong;
    }

    /// Culls with the stored cones ÷ culls with the exact ones (all nodes, inner nodes).
    pub fn share(&self, k: usize) -> f64 {
        self.quantised[k] as f64 / self.exact[k] as f64
    }
}

/// Tree levels counted apart by [`QuantStats::level_spheres`] (a statue of 10⁹ samples is
/// ≈ 20 levels deep).
pub const LEVELS: usize = 64;
const SPHERE_WORDS: usize = (1 << quant::SPHERE_BITS) / 64;
/// Levels with fewer child spheres are left out of [`QuantStats::centre_error_level_spread`]:
/// a mean over a few nodes (the levels near the root) is noise, not a trend.
pub const SPREAD_MIN_SPHERES: u64 = 1000;

impl Default for QuantStats {
    fn default() -> Self {
        Self {
            spheres: 0,
            centre_error: 0.0,
            radius_error: 0.0,
            radius_error_l1: 0.0,
            not_enclosed: 0,
            normals: 0,
            normal_error: 0.0,
            normal_error_max: 0.0,
            children: [0; 6],
            level_spheres: [0; LEVELS],
            level_centre_error: [0.0; LEVELS],
            sphere_codes: [0; SPHERE_WORDS],
            cone_codes: 0,
            cone_culls: ConeCulls::default(),
        }
    }
}

impl QuantStats {
    /// The child spheres `res` encoded for `truth` (same order), all in tree level `level`,
    /// node `i`'s decoded parent sphere being `parent(i)`.
    pub(super) fn spheres(
        truth: &[TrueNode],
        res: &[Encoded],
        level: usize,
        parent: impl Fn(usize) -> (Vec3, f32) + Sync,
    ) -> Self {
        let level = level.min(LEVELS - 1);
        Self::sum_chunks(truth.len(), |i, s| {
            let (t, e) = (&truth[i], &res[i]);
            let (_, pr) = parent(i);
            let (c, r) = e.1;
            let (pr, r) = (f64::from(pr), f64::from(r));
            let d = (c.as_dvec3() - t.c.as_dvec3()).abs();
            s.spheres += 1;
            s.centre_error += (d.x + d.y + d.z) / pr;
            s.level_spheres[level] += 1;
            s.level_centre_error[level] += (d.x + d.y + d.z) / pr;
            s.sphere_codes[usize::from(e.0) / 64] |= 1 << (e.0 % 64);
            s.radius_error += (r - f64::from(t.r)) / pr;
            let grown = (f64::from(t.r) + d.x + d.y + d.z) / pr;
            s.radius_error_l1 += (grown * 13.0).ceil() / 13.0 - f64::from(t.r) / pr;
            if d.length() + f64::from(t.r) > r {
                s.not_enclosed += 1;
            }
        })
    }

    /// The stored nodes `stored` of `truth` (same order): normals and children.
    pub(super) fn nodes(truth: &[TrueNode], stored: &[QNode], has_normals: bool) -> Self {
        Self::sum_chunks(truth.len(), |i, s| {
            let (t, q) = (&truth[i], &stored[i]);
            s.children[usize::from(q.children).min(5)] += 1;
            s.cone_codes |= 1 << (q.cone & 3);
            if has_normals && t.n.length_squared() > 0.25 {
                let n = quant::decode_normal(u32::from(q.normal)).unwrap_or(Vec3::ZERO);
                let a = quant::angle(t.n.as_dvec3(), n.as_dvec3());
                s.normals += 1;
                s.cone_culls
                    .add(t.n.as_dvec3(), t.cone, n.as_dvec3(), q.cone, q.children > 0);
                s.normal_error += a;
                s.normal_error_max = s.normal_error_max.max(a);
            }
        })
    }

    /// `add(i, sums)` for `i` in `0..n`, in parallel over fixed chunks whose sums are added
    /// in order: the same `f64` sums for any thread count and schedule (a report compares
    /// them across runs).
    fn sum_chunks(n: usize, add: impl Fn(usize, &mut Self) + Sync) -> Self {
        const CHUNK: usize = 4096;
        let parts: Vec<Self> = (0..n.div_ceil(CHUNK))
            .into_par_iter()
            .map(|c| {
                let mut s = Self::default();
                for i in c * CHUNK..((c + 1) * CHUNK).min(n) {
                    add(i, &mut s);
                }
                s
            })
            .collect();
        parts.iter().fold(Self::default(), |a, b| a.merged(b))
    }

    /// Adds `o`'s sums to these.
    pub fn merge(&mut self, o: &Self) {
        self.spheres += o.spheres;
        self.centre_error += o.centre_error;
        self.radius_error += o.radius_error;
        self.radius_error_l1 += o.radius_error_l1;
        self.not_enclosed += o.not_enclosed;
        self.normals += o.normals;
        self.normal_error += o.normal_error;
        self.normal_error_max = self.normal_error_max.max(o.normal_error_max);
        for (a, b) in self.children.iter_mut().zip(o.children) {
            *a += b;
        }
        for l in 0..LEVELS {
            self.level_spheres[l] += o.level_spheres[l];
            self.level_centre_error[l] += o.level_centre_error[l];
        }
        for (a, b) in self.sphere_codes.iter_mut().zip(o.sphere_codes) {
            *a |= b;
        }
        self.cone_codes |= o.cone_codes;
        self.cone_culls.merge(&o.cone_culls);
    }

    fn merged(mut self, o: &Self) -> Self {
        self.merge(o);
        self
    }

    /// Mean centre error per coordinate, in parent radii (the paper's 0.04).
    pub fn mean_centre_error(&self) -> f64 {
        self.centre_error / (3 * self.spheres) as f64
    }

    /// Mean radius error, in parent radii (the paper's 0.15).
    pub fn mean_radius_error(&self) -> f64 {
        self.radius_error / self.spheres as f64
    }

    /// Mean radius error had the radius been grown by the L1 centre error, in parent radii.
    pub fn mean_radius_error_l1(&self) -> f64 {
        self.radius_error_l1 / self.spheres as f64
    }

    /// Mean normal error, radians (the paper's ≈ 0.01).
    pub fn mean_normal_error(&self) -> f64 {
        self.normal_error / self.normals as f64
    }

    /// The mean centre error per coordinate of level `l`'s child spheres, in parent radii.
    pub fn level_centre_error(&self, l: usize) -> f64 {
        self.level_centre_error[l] / (3 * self.level_spheres[l]) as f64
    }

    /// Largest ÷ smallest [`Self::level_centre_error`] over the levels with at least
    /// [`SPREAD_MIN_SPHERES`] child spheres, and how many such levels there are. Encoding
    /// each child relative to its *decoded* parent keeps it near 1; had the encoder used the
    /// true parent, a parent's error would carry into its children's decoded centres, and
    /// with the radius falling at each level it would grow against them level by level.
    pub fn centre_error_level_spread(&self) -> (f64, usize) {
        let means: Vec<f64> = (0..LEVELS)
            .filter(|&l| self.level_spheres[l] >= SPREAD_MIN_SPHERES)
            .map(|l| self.level_centre_error(l))
            .collect();
        let hi = means.iter().copied().fold(f64::NAN, f64::max);
        let lo = means.iter().copied().fold(f64::NAN, f64::min);
        (hi / lo, means.len())
    }

    /// Distinct sphere codes used; distinct radii (in 13ths of the parent radius) and the
    /// most distinct centre offsets on any one axis (in 13ths of its diameter) among them.
    pub fn sphere_levels_used(&self) -> (u64, usize, usize) {
        let t = quant::sphere_table();
        let mut codes = 0;
        let mut radii = std::collections::BTreeSet::new();
        let mut axes: [std::collections::BTreeSet<i32>; 3] = Default::default();
        for (code, e) in t.entries.iter().enumerate() {
            if self.sphere_codes[code / 64] & (1 << (code % 64)) == 0 {
                continue;
            }
            codes += 1;
            radii.insert((e[3] * quant::GRID as f32).round() as i32);
            for (a, set) in axes.iter_mut().enumerate() {
                set.insert((e[a] * quant::GRID as f32 / 2.0).round() as i32);
            }
        }
        let offsets = axes.iter().map(|s| s.len()).max().unwrap_or(0);
        (codes, radii.len(), offsets)
    }

    /// Nodes whose number of children the format cannot store (1, or more than 4).
    pub fn unstorable_children(&self) -> u64 {
        self.children[1] + self.children[5]
    }

    /// The build figures (`BuildStats::extra`) these give, by name.
    pub fn extras(&self) -> Vec<(&'static str, serde_json::Value)> {
        let (spread, levels) = self.centre_error_level_spread();
        let (codes, radii, offsets) = self.sphere_levels_used();
        let or_null = |x: f64| {
            if x.is_finite() {
                x.into()
            } else {
                serde_json::Value::Null
            }
        };
        vec![
            ("centre_error", or_null(self.mean_centre_error())),
            ("radius_error", or_null(self.mean_radius_error())),
            ("radius_error_l1", or_null(self.mean_radius_error_l1())),
            ("spheres_not_enclosed", self.not_enclosed.into()),
            ("normal_error", or_null(self.mean_normal_error())),
            ("normal_error_max", self.normal_error_max.into()),
            ("normal_codes", (quant::normal_table().len() as u64).into()),
            ("unstorable_children", self.unstorable_children().into()),
            ("centre_error_level_spread", or_null(spread)),
            ("centre_error_levels", (levels as u64).into()),
            ("sphere_codes_used", codes.into()),
            ("radius_levels_used", (radii as u64).into()),
            ("offset_levels_used", (offsets as u64).into()),
            ("cone_codes_used", self.cone_codes.count_ones().into()),
            ("cone_culled_exact", self.cone_culls.exact[0].into()),
            ("cone_culled_share", or_null(self.cone_culls.share(0))),
            ("cone_culled_share_inner", or_null(self.cone_culls.share(1))),
            ("cone_culled_wrong", self.cone_culls.wrong.into()),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::super::build::build_tree;
    use super::*;

    /// The figures recomputed from the debug build's true and decoded spheres, with each
    /// node's parent found from the stored child counts (children are consecutive in the
    /// next level), agree with the sums the quantisation kept.
    #[test]
    fn figures_match_a_recount_from_the_decoded_tree() {
        let cloud = scenes::generators::Generator::Statue
            .generate(3000, 2)
            .unwrap();
        let radii = crate::leaf::leaf_radii(&cloud);
        let b = build_tree(&cloud, &radii).unwrap();
        let q = b.quant;
        let levels = &b.tree.levels;
        let (mut spheres, mut centre, mut radius) = (0u64, 0f64, 0f64);
        let mut codes = std::collections::BTreeSet::new();
        for l in 1..levels.len() {
            let mut level_centre = 0.0;
            let mut parent = Vec::new();
            for (p, n) in levels[l - 1].iter().enumerate() {
                parent.extend(std::iter::repeat_n(p, n.children as usize));
            }
            assert_eq!(parent.len(), levels[l].len(), "level {l}");
            for (i, &p) in parent.iter().enumerate() {
                let (t, d) = (b.true_spheres[l][i], b.decoded_spheres[l][i]);
                let pr = f64::from(b.decoded_spheres[l - 1][p].1);
                let e = (d.0.as_dvec3() - t.0.as_dvec3()).abs();
                spheres += 1;
                centre += (e.x + e.y + e.z) / pr;
                level_centre += (e.x + e.y + e.z) / pr;
                radius += (f64::from(d.1) - f64::from(t.1)) / pr;
                codes.insert(levels[l][i].sphere);
            }
            assert_eq!(q.level_spheres[l], levels[l].len() as u64, "level {l}");
            assert!(
                (q.level_centre_error[l] - level_centre).abs() < 1e-9,
                "level {l}"
            );
        }
        assert_eq!(q.level_spheres[0], 0, "the root has no parent");
        assert_eq!(q.sphere_levels_used().0, codes.len() as u64);
        let cones: std::collections::BTreeSet<u8> =
            levels.iter().flatten().map(|n| n.cone).collect();
        assert_eq!(q.cone_codes.count_ones() as usize, cones.len());
        let nodes = b.tree.nodes();
        assert_eq!(q.spheres, nodes - 1, "every node but the root");
        assert_eq!(q.spheres, spheres);
        assert!((q.mean_centre_error() - centre / (3 * spheres) as f64).abs() < 1e-9);
        assert!((q.mean_radius_error() - radius / spheres as f64).abs() < 1e-9);
        assert_eq!(q.not_enclosed, 0, "the encoder rounds every radius up");
        assert_eq!(q.children.iter().sum::<u64>(), nodes);
        assert_eq!(q.children[0], 3000, "the leaves");
        assert_eq!(q.unstorable_children(), 0);
        // Every node of a statue has a normal; the quantiser's error is below 0.02 rad
        // (quant.rs: measured max over uniform directions < 0.02).
        assert_eq!(q.normals, nodes);
        assert!(
            q.mean_normal_error() > 0.0 && q.normal_error_max < 0.02,
            "{q:?}"
        );
        // Centre offsets are multiples of 2/13 of the parent radius per axis: rounding to
        // the nearest leaves at most 1/13 per coordinate.
        assert!(q.mean_centre_error() > 0.0 && q.mean_centre_error() <= 1.0 / 13.0 + 1e-6);
        // A radius never shrinks (rounded up to enclose).
        assert!(q.mean_radius_error() > 0.0);
        // §3.1's grid: at most 13 radii and 13 offsets per axis.
        let (_, radii, offsets) = q.sphere_levels_used();
        assert!(
            radii <= 13 && offsets <= 13,
            "{radii} radii, {offsets} offsets"
        );
        // No level's error grows from the one above: the spread is a small factor.
        let (spread, n) = q.centre_error_level_spread();
        assert!(n >= 2 && spread >= 1.0, "{spread} over {n} levels");
    }

    /// The spread is taken over the levels with enough spheres only, and a code or a cone
    /// class counts once however often it is used.
    #[test]
    fn the_level_spread_skips_thin_levels_and_codes_count_once() {
        let mut s = QuantStats::default();
        s.level_spheres[1] = 10; // too few: left out
        s.level_centre_error[1] = 10.0 * 3.0 * 0.5;
        s.level_spheres[2] = SPREAD_MIN_SPHERES;
        s.level_centre_error[2] = SPREAD_MIN_SPHERES as f64 * 3.0 * 0.02;
        s.level_spheres[3] = 2 * SPREAD_MIN_SPHERES;
        s.level_centre_error[3] = 2.0 * SPREAD_MIN_SPHERES as f64 * 3.0 * 0.05;
        let (spread, n) = s.centre_error_level_spread();
        assert_eq!(n, 2);
        assert!((spread - 2.5).abs() < 1e-12, "{spread}");
        let t = quant::sphere_table();
        // Two codes with the same radius and different x offsets, one twice.
        let code = |ix: f32, j: f32| {
            t.entries
                .iter()
                .position(|e| {
                    e[0] == ix * 2.0 / 13.0 && e[1] == 0.0 && e[2] == 0.0 && e[3] == j / 13.0
                })
                .unwrap()
        };
        for c in [code(1.0, 5.0), code(-2.0, 5.0), code(1.0, 5.0)] {
            s.sphere_codes[c / 64] |= 1 << (c % 64);
        }
        assert_eq!(s.sphere_levels_used(), (2, 1, 2));
        let o = QuantStats {
            cone_codes: 0b0101,
            ..Default::default()
        };
        s.cone_codes = 0b0011;
        s.merge(&o);
        assert_eq!(s.cone_codes.count_ones(), 3);
    }

    #[test]
    fn merging_adds_the_sums_and_keeps_the_largest_error() {
        let a = QuantStats {
            spheres: 2,
            centre_error: 0.3,
            normals: 1,
            normal_error: 0.01,
            normal_error_max: 0.01,
            children: [1, 0, 1, 0, 0, 0],
            ..Default::default()
        };
        let mut b = QuantStats {
            spheres: 1,
            centre_error: 0.3,
            not_enclosed: 1,
            normals: 1,
            normal_error: 0.03,
            normal_error_max: 0.03,
            children: [0, 1, 0, 0, 0, 2],
            ..Default::default()
        };
        b.merge(&a);
        assert_eq!(b.spheres, 3);
        assert!((b.mean_centre_error() - 0.6 / 9.0).abs() < 1e-12);
        assert!((b.mean_normal_error() - 0.02).abs() < 1e-12);
        assert_eq!(b.normal_error_max, 0.03);
        assert_eq!(b.unstorable_children(), 3);
        assert_eq!(b.not_enclosed, 1);
    }

    /// The cone test on hand-made nodes: the views are unit vectors symmetric in z (half of
    /// them below the equator), a cone around +z of half-angle 0 is back-facing from exactly
    /// those 8 with the exact cone and from the 7 below −1/16 (the class-0 sine, with the
    /// slack) with the stored one; a decoded normal outside the true cone is counted wrong.
    #[test]
    fn cone_culls_count_exact_stored_and_wrong_pairs() {
        let views = ConeCulls::views();
        for v in views {
            assert!((v.length() - 1.0).abs() < 1e-12);
        }
        assert_eq!(views.iter().filter(|v| v.z < 0.0).count(), CULL_VIEWS / 2);
        let z = glam::DVec3::Z;
        let mut c = ConeCulls::default();
        c.add(z, 0.0, z, 0, false);
        assert_eq!((c.exact, c.quantised, c.wrong), ([8, 0], [7, 0], 0));
        c.add(z, 0.2, z, 1, true);
        // sin 0.2 = 0.199 < 4/16: the stored cone culls fewer.
        let (e, q) = (
            views.iter().filter(|v| v.z < -0.2f64.sin()).count() as u64,
            views.iter().filter(|v| v.z < -0.25 - 1e-4).count() as u64,
        );
        assert_eq!((c.exact[1], c.quantised[1]), (e, q));
        assert!(q <= e && q > 0);
        // A stored class 3 never culls; an exact cone of 90° or more never does either (and
        // a stored class-0 cone for it culls what it should not).
        let mut d = ConeCulls::default();
        d.add(z, 0.0, z, 3, true);
        assert_eq!((d.exact[0], d.quantised[0], d.wrong), (8, 0, 0));
        d.add(z, 1.6, z, 0, true);
        assert_eq!((d.exact[0], d.quantised[0], d.wrong), (8, 7, 7));
        // Neither cone culls (every node of a scene without normals: cone π, class 3): the
        // node is skipped and counts nothing.
        let before = d;
        d.add(
            glam::DVec3::ZERO,
            std::f64::consts::PI,
            glam::DVec3::ZERO,
            3,
            true,
        );
        d.add(z, 1.6, z, 3, false);
        assert_eq!(d, before);
        // A stored normal pointing elsewhere than the true one culls what it should not.
        let mut w = ConeCulls::default();
        w.add(glam::DVec3::X, 0.0, z, 0, true);
        assert!(w.wrong > 0);
        assert_eq!(c.share(1), q as f64 / e as f64);
    }
}
