//! Camera and view: matrices for wgpu (right-handed, y up, depth 0..1), frustum planes, and
//! the projection scale `k = height / (2 tan(fov_y / 2))` that turns an object-space length
//! `s` at view depth `z` into `s·k/z` pixels.
//!
//! All positions are in the cloud's local (`f32`) frame.

use glam::{Mat4, Vec3, Vec4, Vec4Swizzles};

/// A pinhole camera.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Camera {
    /// Eye position.
    pub position: Vec3,
    /// Point looked at.
    pub target: Vec3,
    /// Up hint (need not be orthogonal to the view direction, must not be parallel to it).
    pub up: Vec3,
    /// Vertical field of view, radians.
    pub fov_y: f32,
    /// Near plane distance (> 0).
    pub near: f32,
    /// Far plane distance (> near).
    pub far: f32,
}

/// A camera plus a viewport in pixels.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct View {
    /// The camera.
    pub camera: Camera,
    /// Viewport width in pixels.
    pub width: u32,
    /// Viewport height in pixels.
    pub height: u32,
}

/// Where a bounding volume lies relative to a frustum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Containment {
    /// Entirely outside one plane.
    Outside,
    /// Crosses at least one plane.
    Intersects,
    /// Entirely inside all planes.
    Inside,
}

/// Six inward-facing planes `(n, d)` with `n·p + d ≥ 0` inside; `n` normalised.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    /// Left, right, bottom, top, near, far.
    pub planes: [Vec4; 6],
}

impl Frustum {
    /// Classifies a sphere.
    #[inline]
    pub fn sphere(&self, center: Vec3, radius: f32) -> Containment {
        let mut inside = true;
        for p in &self.planes {
            let d = p.xyz().dot(center) + p.w;
            if d < -radius {
                return Containment::Outside;
            }
            if d < radius {
                inside = false;
            }
        }
        if inside {
            Containment::Inside
        } else {
            Containment::Intersects
        }
    }
    /// Classifies an axis-aligned box `[min, max]`: outside when its corner furthest along
    /// some plane's normal is behind that plane (the test Potree culls its octree nodes by;
    /// conservative: a box near a frustum edge may be called intersecting while outside).
    #[inline]
    pub fn aabb(&self, min: Vec3, max: Vec3) -> Containment {
        let mut inside = true;
        for p in &self.planes {
            let n = p.xyz();
            let far = Vec3::select(n.cmpge(Vec3::ZERO), max, min);
            let near = Vec3::select(n.cmpge(Vec3::ZERO), min, max);
            if n.dot(far) + p.w < 0.0 {
                return Containment::Outside;
            }
            if n.dot(near) + p.w < 0.0 {
                inside = false;
            }
        }
        if inside {
            Containment::Inside
        } else {
            Containment::Intersects
        }
    }
    /// True if the point is inside (or on) all six planes.
    #[inline]
    pub fn contains(&self, p: Vec3) -> bool {
        self.planes.iter().all(|pl| pl.xyz().dot(p) + pl.w >= 0.0)
    }
}

impl Camera {
    /// Unit view direction.
    pub fn forward(&self) -> Vec3 {
        (self.target - self.position).normalize()
    }
    /// True if the camera is usable: finite values, eye ≠ target, up not parallel to the
    /// view direction, 0 < fov < π, 0 < near < far.
    pub fn is_valid(&self) -> bool {
        let f = self.target - self.position;
        self.position.is_finite()
            && self.target.is_finite()
            && self.up.is_finite()
            && f.length_squared() > 0.0
            && f.normalize()
                .cross(self.up.normalize_or_zero())
                .length_squared()
                > 1e-10
            && self.fov_y > 0.0
            && self.fov_y < std::f32::consts::PI
            && self.near > 0.0
            && self.far > self.near
    }
}

impl View {
    /// World (local frame) → view space (camera at origin looking down −z).
    pub fn view_matrix(&self) -> Mat4 {
        let c = &self.camera;
        glam::camera::rh::view::look_at_mat4(c.position, c.target, c.up.normalize())
    }
    /// View → clip space, depth in 0..1 (wgpu convention).
    pub fn proj_matrix(&self) -> Mat4 {
        let c = &self.camera;
        glam::camera::rh::proj::directx::perspective(c.fov_y, self.aspect(), c.near, c.far)
    }
    /// `proj * view`.
    pub fn view_proj(&self) -> Mat4 {
        self.proj_matrix() * self.view_matrix()
    }
    /// Width / height.
    pub fn aspect(&self) -> f32 {
        self.width as f32 / self.height as f32
    }
    /// Projection scale `k = height / (2 tan(fov_y/2))`: pixels per object unit at depth 1.
    pub fn proj_scale(&self) -> f32 {
        self.height as f32 / (2.0 * (self.camera.fov_y * 0.5).tan())
    }
    /// Depth of `p` along the view direction (positive in front of the camera).
    #[inline]
    pub fn view_depth(&self, p: Vec3) -> f32 {
        (p - self.camera.position).dot(self.camera.forward())
    }
    /// Projects `p` to pixel coordinates (x right, y down, origin top-left) and NDC depth;
    /// `None` behind the camera.
    pub fn project(&self, p: Vec3) -> Option<Vec3> {
        let clip = self.view_proj() * p.extend(1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.xyz() / clip.w;
        Some(Vec3::new(
            (ndc.x * 0.5 + 0.5) * self.width as f32,
            (0.5 - ndc.y * 0.5) * self.height as f32,
            ndc.z,
        ))
    }
    /// Frustum planes extracted from `view_proj` (Gribb–Hartmann), normalised, inward.
    pub fn frustum(&self) -> Frustum {
        let m = self.view_proj();
        let r0 = m.row(0);
        let r1 = m.row(1);
        let r2 = m.row(2);
        let r3 = m.row(3);
        let raw = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2];
        let planes = raw.map(|p| p / p.xyz().length());
        Frustum { planes }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view() -> View {
        View {
            camera: Camera {
                position: Vec3::new(0.0, 0.0, 10.0),
                target: Vec3::ZERO,
                up: Vec3::Y,
                fov_y: 90f32.to_radians(),
                near: 0.1,
                far: 100.0,
            },
            width: 200,
            height: 100,
        }
    }

    #[test]
    fn projects_known_points() {
        let v = view();
        // The target lands in the centre of the image.
        let c = v.project(Vec3::ZERO).unwrap();
        assert!((c.x - 100.0).abs() < 1e-3 && (c.y - 50.0).abs() < 1e-3);
        // fov 90° ⇒ k = h/2 = 50 px per unit at depth 1; at depth 10, 1 unit = 5 px.
        assert!((v.proj_scale() - 50.0).abs() < 1e-4);
        let p = v.project(Vec3::new(1.0, 1.0, 0.0)).unwrap();
        assert!((p.x - 105.0).abs() < 1e-3, "{p}");
        assert!((p.y - 45.0).abs() < 1e-3, "y grows downwards: {p}");
        assert!(v.project(Vec3::new(0.0, 0.0, 20.0)).is_none());
        // Depth: near plane → 0, far plane → 1.
        let n = v.project(Vec3::new(0.0, 0.0, 10.0 - 0.1)).unwrap();
        let f = v.project(Vec3::new(0.0, 0.0, 10.0 - 100.0)).unwrap();
        assert!(n.z.abs() < 1e-4 && (f.z - 1.0).abs() < 1e-4);
        assert!((v.view_depth(Vec3::new(3.0, 0.0, 0.0)) - 10.0).abs() < 1e-5);
    }

    #[test]
    fn frustum_classifies_boxes() {
        let f = view().frustum();
        let b = |lo: [f32; 3], hi: [f32; 3]| f.aabb(Vec3::from(lo), Vec3::from(hi));
        assert_eq!(b([-1.0; 3], [1.0; 3]), Containment::Inside);
        // Straddles the right plane (x = z' at depth z' = 10 - z with fov 90°, aspect 2).
        assert_eq!(
            b([15.0, -1.0, -1.0], [25.0, 1.0, 1.0]),
            Containment::Intersects
        );
        assert_eq!(
            b([30.0, -1.0, -1.0], [31.0, 1.0, 1.0]),
            Containment::Outside
        );
        // Behind the eye.
        assert_eq!(
            b([-1.0, -1.0, 11.0], [1.0, 1.0, 12.0]),
            Containment::Outside
        );
        // A box enclosing the whole frustum intersects it.
        assert_eq!(b([-500.0; 3], [500.0; 3]), Containment::Intersects);
    }

    #[test]
    fn frustum_classifies_spheres() {
        let v = view();
        let f = v.frustum();
        assert_eq!(f.sphere(Vec3::ZERO, 1.0), Containment::Inside);
        assert_eq!(
            f.sphere(Vec3::new(0.0, 0.0, 20.0), 1.0),
            Containment::Outside
        );
        // Half-width at depth 10 is 20 (aspect 2, fov 90°): a sphere at x = 20 straddles.
        assert_eq!(
            f.sphere(Vec3::new(20.0, 0.0, 0.0), 1.0),
            Containment::Intersects
        );
        assert_eq!(
            f.sphere(Vec3::new(23.0, 0.0, 0.0), 1.0),
            Containment::Outside
        );
        assert!(f.contains(Vec3::new(19.0, 9.0, 0.0)));
        assert!(!f.contains(Vec3::new(0.0, 11.0, 0.0)));
    }

    #[test]
    fn camera_validation() {
        let mut c = view().camera;
        assert!(c.is_valid());
        c.up = Vec3::Z;
        assert!(!c.is_valid(), "up parallel to view direction");
        c.up = Vec3::Y;
        c.near = 0.0;
        assert!(!c.is_valid());
    }
}
