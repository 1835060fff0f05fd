//! Geometry and bookkeeping of three-phase occlusion culling (Layered Point Clouds, Gobbetti
//! & Marton 2004, §4), shared by the GPU renderer and its CPU mirror so both query exactly
//! the same triangles.
//!
//! A candidate's bounding sphere is stood in for by a regular icosahedron that
//! circumscribes it: the unit icosahedron (vertices on the unit sphere) is scaled by
//! `radius / inradius · (1 + 1e-4)`, so every face plane lies at least `radius` from the
//! centre (the `1e-4` absorbs float rounding). [`Icosahedron::vertices`] gives the 12
//! world-space vertices; the GPU draws them from a vertex buffer with
//! [`Icosahedron::INDICES`] (20 triangles, counter-clockwise seen from outside, back faces
//! culled), the CPU mirror rasterises the same triangles.
//!
//! A candidate is **visible without a query** when its icosahedron reaches the near plane
//! (some vertex has clip `w ≤ 0` or clip `z < 0`), which covers a sphere containing the eye:
//! the query geometry would be clipped and its count would understate what the cloud covers.

use glam::Vec3;
use methods::{ChunkId, OcclusionCandidate};
use scenes::View;

/// Vertices and faces of the query icosahedron.
pub struct Icosahedron;

/// Golden ratio.
const PHI: f32 = 1.618_034;

/// Unit-circumradius icosahedron vertices (before normalisation).
const RAW: [[f32; 3]; 12] = [
    [-1.0, PHI, 0.0],
    [1.0, PHI, 0.0],
    [-1.0, -PHI, 0.0],
    [1.0, -PHI, 0.0],
    [0.0, -1.0, PHI],
    [0.0, 1.0, PHI],
    [0.0, -1.0, -PHI],
    [0.0, 1.0, -PHI],
    [PHI, 0.0, -1.0],
    [PHI, 0.0, 1.0],
    [-PHI, 0.0, -1.0],
    [-PHI, 0.0, 1.0],
];

impl Icosahedron {
    /// Triangles, counter-clockwise seen from outside (tested).
    pub const INDICES: [[u16; 3]; 20] = [
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    /// Vertices of the icosahedron with circumradius 1.
    pub fn unit() -> [Vec3; 12] {
        RAW.map(|v| Vec3::from(v).normalize())
    }
    /// Inradius of the unit-circumradius icosahedron: `√((5 + 2√5)/15)·…` = the distance
    /// from the centre to a face plane of [`Icosahedron::unit`].
    pub fn unit_inradius() -> f32 {
        let u = Self::unit();
        Self::INDICES
            .iter()
            .map(|t| {
                let (a, b, c) = (u[t[0] as usize], u[t[1] as usize], u[t[2] as usize]);
                (b - a).cross(c - a).normalize().dot(a).abs()
            })
            .fold(f32::INFINITY, f32::min)
    }
    /// Circumradius of the icosahedron whose inradius is `radius` (plus the rounding margin).
    pub fn circumradius(radius: f32) -> f32 {
        radius / Self::unit_inradius() * (1.0 + 1e-4)
    }
    /// The 12 world-space vertices of the icosahedron circumscribing the sphere
    /// (`center`, `radius`): `center + unit · circumradius(radius)`.
    pub fn vertices(center: [f32; 3], radius: f32) -> [Vec3; 12] {
        let c = Vec3::from(center);
        let s = Self::circumradius(radius.max(0.0));
        Self::unit().map(|u| c + u * s)
    }
}

/// True when the candidate needs an occlusion query; false when it is visible without one
/// (its sphere contains the eye, or its icosahedron `verts` reaches the near plane).
pub fn needs_query(view: &View, c: &OcclusionCandidate, verts: &[Vec3; 12]) -> bool {
    if (view.camera.position - Vec3::from(c.center)).length() <= c.radius {
        return false;
    }
    let vp = view.view_proj();
    verts.iter().all(|p| {
        let clip = vp * p.extend(1.0);
        clip.w > 0.0 && clip.z >= 0.0
    })
}

/// What the occlusion pass found (in [`super::FrameStats::occlusion`] and the CPU mirror's
/// [`super::cpu::CpuFrame`]).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct OcclusionStats {
    /// Occlusion queries issued (candidates minus those visible without a query).
    pub clouds_queried: u64,
    /// Candidates whose query passed no more than the threshold's fragments.
    pub clouds_occluded: u64,
    /// Ids of the visible candidates (queried above the threshold, or visible without a
    /// query), in candidate order: next frame's occluders.
    pub visible: Vec<ChunkId>,
    /// Ids of the occluded candidates, in candidate order.
    pub occluded: Vec<ChunkId>,
    /// Per candidate, in candidate order: fragments of its icosahedron that passed the depth
    /// test against phase 1 (exact: counted in the query's fragment stage), `None` when it
    /// was visible without a query. The visibility decision uses these.
    pub samples: Vec<Option<u64>>,
    /// Per candidate: the hardware occlusion query's result (GPU only; empty in the CPU
    /// mirror). Zero exactly when `samples` is zero; otherwise the sample count or, where the
    /// driver answers non-precise queries with a boolean (lavapipe), 1.
    pub query_results: Vec<Option<u64>>,
    /// Splats drawn in phase 3 (included in [`super::FrameStats::points`]).
    pub phase3_points: u64,
    /// GPU time of the query pass(es) alone (timestamps), ms; included in
    /// [`super::FrameStats::gpu_ms`]. `None` without timestamps or when nothing was queried.
    pub query_gpu_ms: Option<f64>,
}

impl OcclusionStats {
    /// Classifies candidates from their sample counts (`None` = visible without a query):
    /// visible when the count is above `threshold`.
    pub fn classify(
        candidates: &[OcclusionCandidate],
        samples: Vec<Option<u64>>,
        threshold: u64,
    ) -> Self {
        let mut s = Self {
            samples,
            ..Default::default()
        };
        for (c, n) in candidates.iter().zip(&s.samples) {
            s.clouds_queried += n.is_some() as u64;
            if n.is_none_or(|n| n > threshold) {
                s.visible.push(c.id);
            } else {
                s.occluded.push(c.id);
            }
        }
        s.clouds_occluded = s.occluded.len() as u64;
        s
    }
    /// True when candidate `i` (candidate order) was found visible.
    pub fn is_visible(&self, i: usize, threshold: u64) -> bool {
        self.samples
            .get(i)
            .is_some_and(|n| n.is_none_or(|n| n > threshold))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn faces_are_ccw_from_outside_and_circumscribe_the_sphere() {
        let u = Icosahedron::unit();
        for t in Icosahedron::INDICES {
            let (a, b, c) = (u[t[0] as usize], u[t[1] as usize], u[t[2] as usize]);
            let n = (b - a).cross(c - a);
            assert!(n.dot(a + b + c) > 0.0, "face {t:?} winds inwards");
            // Edges of a regular icosahedron are all equal.
            assert!(((b - a).length() - (c - b).length()).abs() < 1e-5);
        }
        let r = Icosahedron::unit_inradius();
        assert!((r - 0.794_654_5).abs() < 1e-5, "{r}");
        let v = Icosahedron::vertices([1.0, 2.0, 3.0], 2.0);
        for t in Icosahedron::INDICES {
            let (a, b, c) = (v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]);
            let n = (b - a).cross(c - a).normalize();
            let d = n.dot(a - Vec3::new(1.0, 2.0, 3.0));
            assert!(d >= 2.0, "face plane at {d} < radius");
        }
        // Every edge appears twice, once each way: a closed, consistently wound surface.
        let mut edges = std::collections::HashMap::new();
        for t in Icosahedron::INDICES {
            for k in 0..3 {
                *edges.entry((t[k], t[(k + 1) % 3])).or_insert(0) += 1;
            }
        }
        assert_eq!(edges.len(), 60);
        assert!(edges.keys().all(|&(a, b)| edges.contains_key(&(b, a))));
    }
}
