//! The built-in paths: orbit, zoom, flythrough, extremes. The geometry is documented in the
//! parent module; the constants here are those numbers.

use std::f64::consts::TAU;

use glam::DVec3;

use super::spline::ClosedLoop;
use super::{Frame, dir};
use crate::Camera;

/// Orbit: distance in units of R.
const ORBIT_DISTANCE: f64 = 2.5;
/// Orbit and zoom: elevation above the centre, degrees.
const ELEVATION_DEG: f64 = 20.0;
/// Orbit, zoom and most extremes: vertical field of view, degrees.
const FOV_DEG: f64 = 45.0;
/// Zoom: first and last distance, units of R.
const ZOOM_FROM: f64 = 100.0;
const ZOOM_TO: f64 = 0.05;
/// Flythrough: control points in units of the (floored) half-extents about the centre.
const FLY_POINTS: [[f64; 3]; 6] = [
    [1.5, 0.0, 0.2],
    [0.4, 0.5, 0.5],
    [-0.5, 0.6, -0.3],
    [-0.6, -0.3, 0.4],
    [0.0, -0.6, -0.5],
    [0.8, -0.5, 0.0],
];
/// Flythrough: half-extents are floored to this many R.
const FLY_MIN_HALF_EXTENT: f64 = 0.05;
/// Flythrough: the target is this fraction of the loop's length ahead of the eye.
const FLY_LOOK_AHEAD: f64 = 1.0 / 40.0;
/// Flythrough: vertical field of view, degrees.
const FLY_FOV_DEG: f64 = 60.0;
/// Extremes: number of shots.
const EXTREME_SHOTS: usize = 9;

/// Orbit's (and zoom's) unit direction from the centre at azimuth `az` radians.
fn orbit_dir(az: f64) -> DVec3 {
    dir(az, ELEVATION_DEG.to_radians())
}

pub(super) fn orbit(i: usize, frames: usize, f: &Frame) -> Camera {
    let az = TAU * i as f64 / frames as f64;
    let eye = f.c + orbit_dir(az) * (ORBIT_DISTANCE * f.r);
    f.camera(eye, f.c, DVec3::Z, FOV_DEG.to_radians(), -orbit_dir(az))
}

pub(super) fn zoom(i: usize, frames: usize, f: &Frame) -> Camera {
    let t = super::open_time(i, frames);
    let d = ZOOM_FROM * (ZOOM_TO / ZOOM_FROM).powf(t) * f.r;
    let eye = f.c + orbit_dir(0.0) * d;
    f.camera(eye, f.c, DVec3::Z, FOV_DEG.to_radians(), -orbit_dir(0.0))
}

pub(super) fn flythrough(i: usize, frames: usize, f: &Frame) -> Camera {
    let h = f.h.max(DVec3::splat(FLY_MIN_HALF_EXTENT * f.r));
    let points = FLY_POINTS
        .iter()
        .map(|q| f.c + DVec3::from(*q) * h)
        .collect();
    let lp = ClosedLoop::new(points);
    let len = lp.length();
    let s = len * i as f64 / frames as f64;
    let eye = lp.at_length(s);
    let ahead = lp.at_length(s + FLY_LOOK_AHEAD * len);
    f.camera(eye, ahead, DVec3::Z, FLY_FOV_DEG.to_radians(), ahead - eye)
}

pub(super) fn extremes(i: usize, frames: usize, f: &Frame) -> Camera {
    let shot = (i * EXTREME_SHOTS / frames).min(EXTREME_SHOTS - 1);
    let (c, r) = (f.c, f.r);
    let side = orbit_dir(0.0);
    let fov = FOV_DEG.to_radians();
    let (eye, target, up, fov) = match shot {
        0 => (c + side * (1e4 * r), c, DVec3::Z, fov),
        1 => (c + side * (50.0 * r), c, DVec3::Z, 1f64.to_radians()),
        2 => (c + side * (2.5 * r), c, DVec3::Z, 170f64.to_radians()),
        3 => (c + DVec3::Z * (2.5 * r), c, DVec3::Y, fov),
        4 => (c - DVec3::Z * (2.5 * r), c, DVec3::Y, fov),
        5 => {
            let top = DVec3::new(c.x, c.y, c.z + f.h.z);
            (top + DVec3::X * (2.5 * r), top, DVec3::Z, fov)
        }
        6 => {
            let corner = c + f.h;
            let diag = f.h.try_normalize().unwrap_or(DVec3::ONE.normalize());
            (corner + diag * (1e-3 * r), c, DVec3::Z, fov)
        }
        7 => (c + side * (1e-3 * r), c, DVec3::Z, fov),
        _ => (c, c + DVec3::X * r, DVec3::Z, 90f64.to_radians()),
    };
    f.camera(eye, target, up, fov, target - eye)
}
