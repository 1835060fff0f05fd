//! Scripted camera paths: the built-in paths and keyframe files.
//!
//! A path turns a frame number `i` of `frames` into a [`Camera`] for a scene with given
//! bounds. Every path is defined relative to the scene's bounding box — centre **c**, bounding
//! radius **R** = half the box diagonal, half-extents **h** — so one path serves every scene
//! size. The world convention is **+Z up** for every scene.
//!
//! # Built-in paths
//!
//! Below, `u(a, e)` is the unit vector at azimuth `a` (from +X towards +Y) and elevation `e`
//! (above the XY plane): `(cos e cos a, cos e sin a, sin e)`.
//!
//! - **`orbit`** — a full turn around the vertical axis through c: frame `i` is at
//!   `c + 2.5 R · u(2π i / frames, 20°)`, looking at c, up +Z, vertical fov 45°. Frame 0 is
//!   on the +X side of c, frame `frames/4` on the +Y side; the turn is divided evenly, so
//!   the path loops without repeating a frame.
//! - **`zoom`** — straight in towards c along `u(0°, 20°)` (the orbit's frame-0 direction),
//!   looking at c, up +Z, fov 45°. The distance falls geometrically from 100 R to 0.05 R:
//!   `d_i = 100 R · (0.05 / 100)^(i / (frames − 1))`, so every frame changes the scale by the
//!   same factor (2000^(1/(frames−1))). At 100 R the model's bounding sphere spans about
//!   `2 R · k / d` = 26 px on a 1080-pixel-high view (`k = 540 / tan 22.5°`); at 0.05 R the eye
//!   is inside the bounding box unless the box's half-extent is under 0.047 R along X or
//!   0.017 R along Z (a flat scene). With one frame the camera stays at 100 R.
//! - **`flythrough`** — a closed, smooth loop through the box at varying heights. Six
//!   control points `c + q ⊙ h'` with `h' = max(h, 0.05 R)` per axis (so a flat scene still
//!   gets some height variation) and `q` = (1.5, 0, 0.2), (0.4, 0.5, 0.5), (−0.5, 0.6, −0.3),
//!   (−0.6, −0.3, 0.4), (0, −0.6, −0.5), (0.8, −0.5, 0) are joined by a closed centripetal
//!   Catmull–Rom spline (no cusps or self-intersections within a segment), re-parameterised by
//!   arc length so the camera moves at constant speed: frame `i` is at arc length
//!   `L · i / frames` of the loop's length `L`. It starts just outside the +X face and flies
//!   in; most of the loop is inside the box. The camera looks at the point `L / 40` further
//!   along the loop, up +Z, fov 60°.
//! - **`extremes`** — nine fixed shots for numerical-stability tests, each held for an equal
//!   share of the frames (frame `i` shows shot `⌊9 i / frames⌋`; use a multiple of 9 frames to
//!   see each shot equally). Up is +Z unless stated, target c unless stated:
//!   0. *far*: `c + 10⁴ R · u(0°, 20°)`, fov 45° — the model is under a pixel;
//!   1. *telephoto*: `c + 50 R · u(0°, 20°)`, fov 1° — the model overfills the view;
//!   2. *wide*: `c + 2.5 R · u(0°, 20°)`, fov 170°;
//!   3. *top-down*: `c + 2.5 R · Z`, looking straight down, up +Y;
//!   4. *bottom-up*: `c − 2.5 R · Z`, looking straight up, up +Y;
//!   5. *grazing*: at the height of the box's top face, `2.5 R` out along +X, looking
//!      horizontally at the top face's centre — the top of the model seen edge-on, fov 45°;
//!   6. *corner*: `0.001 R` beyond the box's max corner along the diagonal, looking at c, fov 45°;
//!   7. *contact*: `c + 0.001 R · u(0°, 20°)`, looking at c, fov 45°;
//!   8. *centre*: at c, looking along +X (target `c + R · X`), fov 90°.
//!
//! # Near and far planes
//!
//! Every camera gets planes that bound the scene's bounding sphere (slightly enlarged):
//! with `d = |eye − c|`, `far = d + 1.01 R` and `near = max(d − 1.01 R, 10⁻⁴ R)` — tight when
//! the eye is outside the sphere, tiny but positive inside. Degenerate bounds are made
//! usable: empty or non-finite bounds are treated as the cube `[−1, 1]³`, and R is raised to
//! at least `max(16 ε · s, 10⁻¹⁵)`, where `ε` is `f32::EPSILON` and `s = max_k(|c_k| + h_k)`
//! the magnitude of the box's coordinates: only a box whose extent `f32` cannot resolve
//! (a single point, or a few ulps) is enlarged, so every path is the same relative to the
//! model at any scale an `f32` cloud holds (tested from 10⁻⁹ to 10⁹); `10⁻¹⁵` is the least R
//! whose shortest eye offset still normalises in `f32` (a point at the origin). Every
//! camera returned satisfies [`Camera::is_valid`]: should rounding ever make the eye equal the
//! target or the view direction parallel to up, the target is moved one R along the intended
//! direction and up is replaced by the coordinate axis least aligned with the view; should
//! near and far round to the same `f32` (an eye very far from a tiny scene), near is pulled
//! in to `far · (1 − 10⁻⁴)`.
//!
//! # Keyframe files
//!
//! Any other path is a TOML file, read with unknown fields rejected (a typo is an error):
//!
//! ```toml
//! # splatbench camera path
//! coordinates = "relative"      # required. "relative": units of R about c; "absolute": local scene coordinates
//! interpolation = "catmull-rom" # or "linear"; default "catmull-rom"
//! fov_deg = 45.0                # vertical field of view, degrees, in (0, 180); default 45
//!
//! [[key]]
//! t = 0.0                       # normalised time: first 0, last 1, strictly increasing
//! position = [2.5, 0.0, 0.8]
//! target = [0.0, 0.0, 0.0]
//! up = [0.0, 0.0, 1.0]          # optional, default +Z
//!
//! [[key]]
//! t = 1.0
//! position = [0.1, 0.0, 0.03]
//! target = [0.0, 0.0, 0.0]
//! ```
//!
//! Frame `i` is at `t = i / (frames − 1)` (`t = 0` when `frames == 1`), so the first frame is
//! the first key and the last frame the last key. In relative coordinates a position or
//! target `p` means `c + R · p`; `up` is a direction and is never scaled.
//!
//! Position, target and up are interpolated independently, each with the file's
//! interpolation; the interpolated up is normalised. Between keys `k` and `k + 1`:
//!
//! - `linear`: `a + (b − a) · s` with `s = (t − t_k) / (t_{k+1} − t_k)`.
//! - `catmull-rom`: the non-uniform Catmull–Rom spline whose knots are the key times
//!   (Barry–Goldman): a cubic Hermite segment whose tangent at an interior key is
//!   `(p_k − p_{k−1})/(t_k − t_{k−1}) − (p_{k+1} − p_{k−1})/(t_{k+1} − t_{k−1}) + (p_{k+1} − p_k)/(t_{k+1} − t_k)`.
//!   The ends are clamped: the tangent at the first (last) key is the slope of the first
//!   (last) segment, so a two-key file moves in a straight line at constant speed. Using the
//!   key times as knots (rather than centripetal knots from distances) keeps the camera on
//!   the file's timetable.
//!
//! With either interpolation the camera is exactly at a key at that key's time, and a
//! quantity that is exactly equal at two consecutive keys stays exactly constant between them,
//! with zero velocity at both keys (the camera eases in and out). So two consecutive keys with
//! the same position, target and up make a **pause**: every frame in between is the identical
//! camera, which [`PathSpec::is_still`] reports (QSplat refines progressively while still).
//!
//! Validation errors name the file, and the key (`key[i]`, counted from 0) where relevant:
//! fewer than 2 keys; a first `t` other than 0, a last `t` other than 1, or times not strictly
//! increasing; a non-finite number; position equal to target; up of zero length or parallel to
//! the view direction (`target − position`), checked at each key and at 31 evenly spaced
//! points inside each segment; `fov_deg` outside (0, 180); an unknown `coordinates` or `interpolation` value; an
//! unknown field (the TOML error names it and its line).

mod builtin;
mod keyframes;
mod spline;

pub use keyframes::{Coordinates, Interpolation, Key, Keyframes};

use std::fmt;
use std::path::Path;
use std::str::FromStr;

use glam::{DVec3, Vec3};

use crate::{Aabb, Camera, SceneError};

/// A scripted camera path: one of the built-ins or a keyframe file. See the
/// [module documentation](self) for the exact geometry of each.
///
/// ```
/// use glam::Vec3;
/// use scenes::{Aabb, paths::PathSpec};
///
/// let bounds = Aabb { min: Vec3::new(-1.0, -2.0, -3.0), max: Vec3::new(3.0, 2.0, 1.0) };
/// let path = PathSpec::parse("orbit")?;
/// let first = path.camera(0, 120, &bounds);
/// assert!(first.is_valid());
/// assert!(first.position.x > bounds.max.x, "frame 0 is on the +X side");
/// assert_eq!(first.target, bounds.center());
/// # Ok::<(), scenes::SceneError>(())
/// ```
#[derive(Debug, Clone, PartialEq)]
pub enum PathSpec {
    /// A full turn around the vertical axis at 2.5 R, 20° above the centre.
    Orbit,
    /// From 100 R straight in to 0.05 R from the centre, geometrically.
    Zoom,
    /// A closed Catmull–Rom loop through the bounding box at constant speed.
    Flythrough,
    /// Nine fixed shots at numerical extremes (sub-pixel, 1° and 170° fov, straight down and
    /// up, grazing, at a corner, touching the centre, at the centre).
    Extremes,
    /// A validated keyframe file.
    Keyframes(Keyframes),
}

impl PathSpec {
    /// The built-in paths: `(name, one-line description)`, for `splatbench list`.
    pub const BUILTIN: &'static [(&'static str, &'static str)] = &[
        (
            "orbit",
            "full turn around the vertical axis at 2.5 R, 20 deg above the centre, fov 45",
        ),
        (
            "zoom",
            "straight in from 100 R to 0.05 R (inside the box), geometric steps, fov 45",
        ),
        (
            "flythrough",
            "closed Catmull-Rom loop through the bounding box at constant speed, fov 60",
        ),
        (
            "extremes",
            "nine held shots: sub-pixel, 1 and 170 deg fov, straight down/up, grazing, corner, centre",
        ),
    ];

    /// The built-in path called `name`, if any.
    pub fn builtin(name: &str) -> Option<PathSpec> {
        match name {
            "orbit" => Some(PathSpec::Orbit),
            "zoom" => Some(PathSpec::Zoom),
            "flythrough" => Some(PathSpec::Flythrough),
            "extremes" => Some(PathSpec::Extremes),
            _ => None,
        }
    }

    /// Parses a path argument: a built-in name, or the path of a `.toml` keyframe file,
    /// which is read and validated here. An unknown name is an error listing the built-ins.
    pub fn parse(s: &str) -> Result<PathSpec, SceneError> {
        if let Some(p) = PathSpec::builtin(s) {
            return Ok(p);
        }
        let path = Path::new(s);
        let is_toml = path
            .extension()
            .is_some_and(|e| e.eq_ignore_ascii_case("toml"));
        if is_toml {
            return Keyframes::load(path).map(PathSpec::Keyframes);
        }
        let names: Vec<&str> = PathSpec::BUILTIN.iter().map(|(n, _)| *n).collect();
        Err(SceneError::Path(format!(
            "unknown camera path '{s}': expected one of {}, or a .toml keyframe file",
            names.join(", ")
        )))
    }

    /// The path's name: the built-in's name, or the keyframe file's stem.
    pub fn name(&self) -> String {
        match self {
            PathSpec::Orbit => "orbit".into(),
            PathSpec::Zoom => "zoom".into(),
            PathSpec::Flythrough => "flythrough".into(),
            PathSpec::Extremes => "extremes".into(),
            PathSpec::Keyframes(k) => k.name().into(),
        }
    }

    /// Camera for frame `i` of `frames` over a scene with `bounds`.
    ///
    /// Expects `frames ≥ 1` and `i < frames`; `frames == 0` is treated as 1 and `i` is
    /// clamped to the last frame. The camera always satisfies [`Camera::is_valid`].
    pub fn camera(&self, i: usize, frames: usize, bounds: &Aabb) -> Camera {
        let frames = frames.max(1);
        let i = i.min(frames - 1);
        let frame = Frame::new(bounds);
        match self {
            PathSpec::Orbit => builtin::orbit(i, frames, &frame),
            PathSpec::Zoom => builtin::zoom(i, frames, &frame),
            PathSpec::Flythrough => builtin::flythrough(i, frames, &frame),
            PathSpec::Extremes => builtin::extremes(i, frames, &frame),
            PathSpec::Keyframes(k) => k.camera(open_time(i, frames), &frame),
        }
    }

    /// All `frames` cameras of the path, in order.
    pub fn cameras(&self, frames: usize, bounds: &Aabb) -> Vec<Camera> {
        (0..frames)
            .map(|i| self.camera(i, frames, bounds))
            .collect()
    }

    /// True when frame `i`'s camera is identical to frame `i − 1`'s (the view is still, so a
    /// progressive method may keep refining); false for `i == 0`.
    pub fn is_still(&self, i: usize, frames: usize, bounds: &Aabb) -> bool {
        i > 0 && i < frames && self.camera(i, frames, bounds) == self.camera(i - 1, frames, bounds)
    }
}

impl FromStr for PathSpec {
    type Err = SceneError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        PathSpec::parse(s)
    }
}

impl fmt::Display for PathSpec {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.name())
    }
}

/// The camera at `eye` looking at `target` (local coordinates) over a scene with `bounds`,
/// finished as every path's cameras are (near and far planes bounding the scene, the guards
/// of [`Camera::is_valid`]): for a camera moved by hand (the viewer) that a path file must
/// reproduce exactly.
pub fn camera_at(bounds: &Aabb, eye: DVec3, target: DVec3, up: DVec3, fov_y: f64) -> Camera {
    Frame::new(bounds).camera(eye, target, up, fov_y, target - eye)
}

/// Normalised time of frame `i` on an open path: `i / (frames − 1)`, 0 for a single frame.
fn open_time(i: usize, frames: usize) -> f64 {
    if frames <= 1 {
        0.0
    } else {
        i as f64 / (frames - 1) as f64
    }
}

/// The bounding radius is raised to at least this many `f32` epsilons of the coordinates'
/// magnitude: a box whose diagonal spans fewer representable steps has no extent `f32` can
/// resolve (it is one point, or a few ulps), and its cameras still need eye offsets that do
/// not round to the centre.
const R_FLOOR_ULPS: f64 = 16.0;

/// The least bounding radius, for a box at the origin with no extent: the smallest R whose
/// shortest camera offset (the contact shot's `10⁻³ R`) still has a normal `f32` squared
/// length (`10⁻³⁶ > f32::MIN_POSITIVE`), so view directions normalise; f32 view maths cannot
/// frame a smaller model, and no reader's cloud is one.
const R_FLOOR_MIN: f64 = 1e-15;

/// The scene frame paths are defined in: centre, radius and half-extents, in `f64`,
/// sanitised so that every path can produce a valid camera.
#[derive(Debug, Clone, Copy)]
struct Frame {
    /// Centre of the bounds.
    c: DVec3,
    /// Bounding radius (half the diagonal), floored ([`R_FLOOR_ULPS`], [`R_FLOOR_MIN`]).
    r: f64,
    /// Half-extents.
    h: DVec3,
}

impl Frame {
    fn new(bounds: &Aabb) -> Frame {
        let min = bounds.min.as_dvec3();
        let max = bounds.max.as_dvec3();
        let usable = min.is_finite() && max.is_finite() && min.cmple(max).all();
        let (c, h) = if usable {
            ((min + max) * 0.5, (max - min) * 0.5)
        } else {
            (DVec3::ZERO, DVec3::ONE)
        };
        // The coordinates' magnitude: the box's farthest corner from the local origin.
        let scale = (c.abs() + h).max_element();
        let floor = (R_FLOOR_ULPS * f64::from(f32::EPSILON) * scale).max(R_FLOOR_MIN);
        Frame {
            c,
            r: h.length().max(floor),
            h,
        }
    }

    /// Finishes a camera: near/far from the bounds, `f32` conversion, and the guards that
    /// keep it valid. `fallback` is the view direction to use if `target − eye` vanishes.
    fn camera(&self, eye: DVec3, target: DVec3, up: DVec3, fov_y: f64, fallback: DVec3) -> Camera {
        let d = eye.distance(self.c);
        let far = d + 1.01 * self.r;
        let near = (d - 1.01 * self.r).max(1e-4 * self.r);
        let position = eye.as_vec3();
        let mut target_f = target.as_vec3();
        let gap = (target_f - position).length_squared();
        if gap.is_nan() || gap <= 0.0 {
            let dir = (target - eye)
                .try_normalize()
                .or_else(|| fallback.try_normalize())
                .unwrap_or(DVec3::X);
            target_f = (eye + dir * self.r).as_vec3();
        }
        let forward = (target_f - position).normalize_or_zero();
        let mut up_f = up.as_vec3();
        let sine2 = forward.cross(up_f.normalize_or_zero()).length_squared();
        if sine2.is_nan() || sine2 <= 1e-9 {
            up_f = least_aligned_axis(forward);
        }
        // Far from a tiny scene the two planes can round to the same f32; pulling near in
        // never clips the scene.
        let far_f = far as f32;
        let near_f = (near as f32).min(far_f * (1.0 - 1e-4));
        let fov_f = (fov_y as f32).clamp(f32::MIN_POSITIVE, std::f32::consts::PI.next_down());
        Camera {
            position,
            target: target_f,
            up: up_f,
            fov_y: fov_f,
            near: near_f,
            far: far_f,
        }
    }
}

/// The coordinate axis (Z preferred, then Y, then X) least aligned with `dir`.
fn least_aligned_axis(dir: Vec3) -> Vec3 {
    [Vec3::Z, Vec3::Y, Vec3::X]
        .into_iter()
        .fold((Vec3::Z, f32::INFINITY), |(best, bd), a| {
            let d = a.dot(dir).abs();
            if d < bd { (a, d) } else { (best, bd) }
        })
        .0
}

/// Unit vector at azimuth `az` (from +X towards +Y) and elevation `el`, radians.
fn dir(az: f64, el: f64) -> DVec3 {
    DVec3::new(el.cos() * az.cos(), el.cos() * az.sin(), el.sin())
}
