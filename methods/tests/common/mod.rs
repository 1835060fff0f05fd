//! Helpers shared by the method integration tests (`mod common;` in each test file).
#![allow(dead_code, clippy::unwrap_used)]

use glam::Vec3;
use methods::{DrawList, Feedback, LodMethod, Target};
use scenes::{Camera, PointCloud, View};

/// A 320 × 240 view of `cloud` from `dist` bounding radii away, looking at its centre.
pub fn view(cloud: &PointCloud, dist: f32) -> View {
    let b = cloud.bounds();
    let c = b.center();
    View {
        camera: Camera {
            position: c + Vec3::new(0.3, -1.0, 0.4).normalize() * b.radius() * dist,
            target: c,
            up: Vec3::Z,
            fov_y: 0.8,
            near: b.radius() * 0.01,
            far: b.radius() * 100.0,
        },
        width: 320,
        height: 240,
    }
}

/// Repeats the frame (as a still camera would) until nothing is missing; panics after 5000.
pub fn settled(m: &mut dyn LodMethod, v: &View, t: Target) -> DrawList {
    settled_with(m, v, t, &Feedback::default())
}

/// [`settled`] with the given feedback every frame.
pub fn settled_with(m: &mut dyn LodMethod, v: &View, t: Target, fb: &Feedback) -> DrawList {
    for _ in 0..5000 {
        let l = m.frame(v, t, fb).unwrap();
        if l.fetch.is_empty() {
            return l;
        }
        std::thread::sleep(std::time::Duration::from_millis(1));
    }
    panic!("never settled");
}
