//! Input → camera. Two modes:
//!
//! - **fly**: WASD moves along the view direction and sideways, Q/E down and up (world Z),
//!   at `speed` scene radii per second (Shift ×4); dragging the mouse turns the view (yaw
//!   about world Z, pitch clamped to ±89°), `TURN_DEG_PER_PX` per pixel; the scroll wheel
//!   scales the speed by `SPEED_STEP` per notch.
//! - **orbit**: dragging turns the eye about the pivot (azimuth about world Z, elevation
//!   clamped to ±89°); the wheel moves the eye towards or away from the pivot by
//!   `SPEED_STEP` per notch; W/S do the same continuously.
//!
//! Speeds are in units of the scene's bounding radius R, so the same keys serve a statue and
//! a 10 km terrain. [`Controller::reset`] returns to the scene's default view (the orbit
//! path's first frame); every camera comes out of [`scenes::paths::camera_at`], finished as
//! the paths' cameras are.

use glam::DVec3;
use scenes::paths::{PathSpec, camera_at};
use scenes::{Aabb, Camera};

/// Degrees the view turns per pixel of mouse drag.
pub const TURN_DEG_PER_PX: f64 = 0.25;
/// Factor per scroll notch (fly: speed; orbit: distance).
pub const SPEED_STEP: f64 = 1.25;
/// Fly speed at reset, scene radii per second.
pub const DEFAULT_SPEED: f64 = 0.5;
/// Multiplier while Shift is held.
pub const FAST: f64 = 4.0;
/// The furthest the pitch / elevation goes from the horizon, degrees.
pub const MAX_PITCH_DEG: f64 = 89.0;

/// A key the controller knows.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Key {
    /// Forward (fly) / closer (orbit).
    W,
    /// Left.
    A,
    /// Back (fly) / further (orbit).
    S,
    /// Right.
    D,
    /// Down (world Z).
    Q,
    /// Up (world Z).
    E,
    /// Faster while held.
    Shift,
}

/// One input event.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Input {
    /// A key pressed.
    Down(Key),
    /// A key released.
    Up(Key),
    /// The mouse dragged by (dx, dy) pixels (x right, y down).
    Drag(f64, f64),
    /// The wheel turned by this many notches (positive: away from the user).
    Scroll(f64),
}

/// Fly or orbit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Mode {
    /// Free flight.
    Fly,
    /// Turning about a pivot.
    Orbit,
}

/// The camera state the viewer moves.
#[derive(Debug, Clone, PartialEq)]
pub struct Controller {
    bounds: Aabb,
    /// Scene centre and radius (the paths' frame).
    center: DVec3,
    radius: f64,
    /// Eye position, local coordinates.
    pub eye: DVec3,
    /// Heading about world Z, radians (0 looks along +X).
    pub yaw: f64,
    /// Angle above the horizon, radians.
    pub pitch: f64,
    /// Orbit pivot.
    pub pivot: DVec3,
    /// Fly speed, scene radii per second.
    pub speed: f64,
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// Fly or orbit.
    pub mode: Mode,
    held: std::collections::HashSet<Key>,
}

impl Controller {
    /// At the scene's default view (the orbit path's first frame), flying.
    pub fn new(bounds: &Aabb) -> Self {
        let b = *bounds;
        let center = (b.min.as_dvec3() + b.max.as_dvec3()) * 0.5;
        let radius = (b.max.as_dvec3() - b.min.as_dvec3()).length() * 0.5;
        let mut c = Controller {
            bounds: b,
            center,
            radius: if radius > 0.0 { radius } else { 1.0 },
            eye: DVec3::ZERO,
            yaw: 0.0,
            pitch: 0.0,
            pivot: center,
            speed: DEFAULT_SPEED,
            fov_y: 45f64.to_radians(),
            mode: Mode::Fly,
            held: Default::default(),
        };
        c.reset();
        c
    }

    /// Back to the default view (the orbit path's frame 0), default speed.
    pub fn reset(&mut self) {
        let cam = PathSpec::Orbit.camera(0, 8, &self.bounds);
        self.look_from(cam.position.as_dvec3(), cam.target.as_dvec3());
        self.fov_y = f64::from(cam.fov_y);
        self.pivot = self.center;
        self.speed = DEFAULT_SPEED;
    }

    /// Puts the eye at `eye` looking at `target`.
    pub fn look_from(&mut self, eye: DVec3, target: DVec3) {
        let d = (target - eye).try_normalize().unwrap_or(DVec3::X);
        self.eye = eye;
        self.yaw = d.y.atan2(d.x);
        self.pitch = d.z.clamp(-1.0, 1.0).asin();
    }

    /// Unit view direction.
    pub fn forward(&self) -> DVec3 {
        DVec3::new(
            self.pitch.cos() * self.yaw.cos(),
            self.pitch.cos() * self.yaw.sin(),
            self.pitch.sin(),
        )
    }

    /// Switches between fly and orbit; orbiting turns about the point the view aims at, at
    /// the distance to the scene's centre (at least 0.1 R).
    pub fn toggle_mode(&mut self) {
        self.mode = match self.mode {
            Mode::Fly => {
                let d = self.eye.distance(self.center).max(0.1 * self.radius);
                self.pivot = self.eye + self.forward() * d;
                Mode::Orbit
            }
            Mode::Orbit => Mode::Fly,
        };
    }

    /// Applies one event.
    pub fn input(&mut self, ev: Input) {
        let turn = TURN_DEG_PER_PX.to_radians();
        let max_pitch = MAX_PITCH_DEG.to_radians();
        match ev {
            Input::Down(k) => {
                self.held.insert(k);
            }
            Input::Up(k) => {
                self.held.remove(&k);
            }
            Input::Drag(dx, dy) => match self.mode {
                Mode::Fly => {
                    self.yaw -= dx * turn;
                    self.pitch = (self.pitch - dy * turn).clamp(-max_pitch, max_pitch);
                }
                Mode::Orbit => {
                    // The eye moves on the sphere about the pivot; the view keeps aiming at it.
                    let back = self.eye - self.pivot;
                    let dist = back.length();
                    let az = back.y.atan2(back.x) - dx * turn;
                    let el = ((back.z / dist.max(f64::MIN_POSITIVE))
                        .clamp(-1.0, 1.0)
                        .asin()
                        + dy * turn)
                        .clamp(-max_pitch, max_pitch);
                    let eye = self.pivot
                        + DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin()) * dist;
                    self.look_from(eye, self.pivot);
                }
            },
            Input::Scroll(n) => match self.mode {
                Mode::Fly => self.speed *= SPEED_STEP.powf(n),
                Mode::Orbit => self.dolly(SPEED_STEP.powf(-n)),
            },
        }
    }

    fn dolly(&mut self, factor: f64) {
        let eye = self.pivot + (self.eye - self.pivot) * factor;
        self.look_from(eye, self.pivot);
    }

    /// Advances by `dt` seconds with the keys held.
    pub fn tick(&mut self, dt: f64) {
        let fast = if self.held.contains(&Key::Shift) {
            FAST
        } else {
            1.0
        };
        let step = self.speed * self.radius * dt * fast;
        let axis = |pos: Key, neg: Key| {
            f64::from(u8::from(self.held.contains(&pos)))
                - f64::from(u8::from(self.held.contains(&neg)))
        };
        match self.mode {
            Mode::Fly => {
                let f = self.forward();
                let right = f.cross(DVec3::Z).try_normalize().unwrap_or(DVec3::Y);
                self.eye += (f * axis(Key::W, Key::S)
                    + right * axis(Key::D, Key::A)
                    + DVec3::Z * axis(Key::E, Key::Q))
                    * step;
            }
            Mode::Orbit => {
                let w = axis(Key::W, Key::S);
                if w != 0.0 {
                    self.dolly((1.0 - 0.5 * w * dt * fast).max(0.01));
                }
            }
        }
    }

    /// The camera now.
    pub fn camera(&self) -> Camera {
        camera_at(
            &self.bounds,
            self.eye,
            self.eye + self.forward() * self.radius,
            DVec3::Z,
            self.fov_y,
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn bounds(scale: f32) -> Aabb {
        Aabb {
            min: Vec3::new(-1.0, -2.0, 0.0) * scale,
            max: Vec3::new(1.0, 2.0, 1.0) * scale,
        }
    }

    #[test]
    fn reset_is_the_orbits_first_frame() {
        let b = bounds(1.0);
        let c = Controller::new(&b);
        let want = PathSpec::Orbit.camera(0, 8, &b);
        let got = c.camera();
        assert!(
            got.position.distance(want.position) < 1e-5,
            "{got:?} {want:?}"
        );
        assert!(got.forward().dot(want.forward()) > 1.0 - 1e-6);
        assert_eq!(got.fov_y, want.fov_y);
        assert!(got.is_valid());
    }

    #[test]
    fn keys_move_in_scene_radii_per_second_at_any_scale() {
        for scale in [1e-6f32, 1.0, 1e4] {
            let b = bounds(scale);
            let r = (b.max.as_dvec3() - b.min.as_dvec3()).length() * 0.5;
            let mut c = Controller::new(&b);
            let (e0, f) = (c.eye, c.forward());
            c.input(Input::Down(Key::W));
            c.tick(2.0);
            let moved = c.eye - e0;
            assert!((moved.length() - 2.0 * DEFAULT_SPEED * r).abs() < 1e-9 * r);
            assert!(
                moved.normalize().dot(f) > 1.0 - 1e-12,
                "W moves along the view"
            );
            c.input(Input::Up(Key::W));
            c.input(Input::Down(Key::E));
            c.input(Input::Down(Key::Shift));
            let z = c.eye.z;
            c.tick(1.0);
            assert!((c.eye.z - z - FAST * DEFAULT_SPEED * r).abs() < 1e-9 * r);
        }
    }

    #[test]
    fn dragging_turns_and_pitch_stops_short_of_the_poles() {
        let mut c = Controller::new(&bounds(1.0));
        let yaw = c.yaw;
        c.input(Input::Drag(40.0, 0.0));
        assert!(
            (c.yaw - (yaw - 10f64.to_radians())).abs() < 1e-12,
            "40 px = 10°"
        );
        c.input(Input::Drag(0.0, -1e6));
        assert!((c.pitch - MAX_PITCH_DEG.to_radians()).abs() < 1e-12);
        assert!(
            c.camera().is_valid(),
            "looking almost straight up is still a valid view"
        );
        c.input(Input::Scroll(2.0));
        assert!((c.speed - DEFAULT_SPEED * SPEED_STEP * SPEED_STEP).abs() < 1e-12);
        c.reset();
        assert_eq!(c.speed, DEFAULT_SPEED);
    }

    #[test]
    fn orbiting_keeps_the_pivot_in_view_at_its_distance() {
        let mut c = Controller::new(&bounds(1.0));
        c.toggle_mode();
        assert_eq!(c.mode, Mode::Orbit);
        let pivot = c.pivot;
        let d = c.eye.distance(pivot);
        for ev in [
            Input::Drag(100.0, 30.0),
            Input::Drag(-20.0, -500.0),
            Input::Drag(333.0, 0.0),
        ] {
            c.input(ev);
            assert!((c.eye.distance(pivot) - d).abs() < 1e-9 * d);
            let to_pivot = (pivot - c.eye).normalize();
            assert!(
                c.forward().dot(to_pivot) > 1.0 - 1e-9,
                "{ev:?}: the view leaves the pivot"
            );
        }
        c.input(Input::Scroll(1.0));
        assert!(
            (c.eye.distance(pivot) - d / SPEED_STEP).abs() < 1e-9 * d,
            "a notch moves closer"
        );
    }
}
