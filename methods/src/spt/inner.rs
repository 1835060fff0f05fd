//! §3's bound on the geometric error, counted over a build's inner nodes.

use glam::Vec3;

use super::build;

/// The inner nodes of a build, against §3's bound on the geometric error: "The maximal error
/// `e_g` has the node's bounding sphere's diameter `d` as upper bound". Our node's `r` is the
/// radius of its bounding *disk* (in the plane of its normal, [`errors::bounding_disk`]), so
/// the bound is counted against both that disk's diameter `2r` and the diameter of a bounding
/// sphere (centred on the node, around its children's spheres; a leaf's sphere is its disk's
/// radius), the paper's `d`. Counted as the nodes are made, so the in-memory and the
/// out-of-core builds report the same figures.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct InnerNodes {
    /// Inner nodes.
    pub count: u64,
    /// Inner nodes whose `e_g` exceeds the disk's diameter `2r`.
    pub eg_above_d: u64,
    /// The largest `e_g ÷ 2r` (0 with no inner node).
    pub eg_over_d_max: f64,
    /// Inner nodes whose `e_g` exceeds the bounding sphere's diameter.
    pub eg_above_sphere: u64,
    /// The largest `e_g ÷` the bounding sphere's diameter.
    pub eg_over_sphere_max: f64,
}

impl InnerNodes {
    /// Counts `node` (with bounding-sphere radius `sphere`) if it is an inner node.
    pub fn add(&mut self, node: &build::Node, sphere: f32) {
        if node.leaf {
            return;
        }
        self.count += 1;
        let e_g = f64::from(node.e_g);
        for (d, above, max) in [
            (
                2.0 * f64::from(node.r),
                &mut self.eg_above_d,
                &mut self.eg_over_d_max,
            ),
            (
                2.0 * f64::from(sphere),
                &mut self.eg_above_sphere,
                &mut self.eg_over_sphere_max,
            ),
        ] {
            if e_g > d {
                *above += 1;
            }
            if d > 0.0 {
                *max = max.max(e_g / d);
            }
        }
    }
    /// Adds the counts of another part of the same build.
    pub fn merge(&mut self, o: Self) {
        self.count += o.count;
        self.eg_above_d += o.eg_above_d;
        self.eg_over_d_max = self.eg_over_d_max.max(o.eg_over_d_max);
        self.eg_above_sphere += o.eg_above_sphere;
        self.eg_over_sphere_max = self.eg_over_sphere_max.max(o.eg_over_sphere_max);
    }
    /// The bounding-sphere radius of a node at `p` around its children: `(centre, sphere
    /// radius)` of each.
    pub fn sphere(p: Vec3, children: impl IntoIterator<Item = (Vec3, f32)>) -> f32 {
        children
            .into_iter()
            .map(|(c, r)| (c - p).length() + r)
            .fold(0.0, f32::max)
    }
    /// The inner nodes of `nodes` (post-order with parent indices into `nodes`, as a build's
    /// array or a unit's), and the bounding-sphere radius of its last node (the root).
    pub fn of(nodes: &[build::Node]) -> (Self, f32) {
        let mut sphere: Vec<f32> = nodes
            .iter()
            .map(|n| if n.leaf { n.r } else { 0.0 })
            .collect();
        let mut s = Self::default();
        for (i, n) in nodes.iter().enumerate() {
            // Every child precedes its parent: `sphere[i]` is final here.
            s.add(n, sphere[i]);
            let q = n.parent as usize;
            if n.parent != build::NO_PARENT && q > i && q < nodes.len() {
                let r = (n.p - nodes[q].p).length() + sphere[i];
                sphere[q] = sphere[q].max(r);
            }
        }
        (s, sphere.last().copied().unwrap_or(0.0))
    }
}
