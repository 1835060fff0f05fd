//! Keyframe files: the TOML format, its validation, and interpolation between keys. The
//! format and the interpolation rules are documented in the parent module.

use std::path::Path;

use glam::DVec3;
use serde::Deserialize;

use super::Frame;
use super::spline::{catmull_rom_tangent, hermite};
use crate::{Camera, SceneError};

/// How a keyframe file's positions and targets are measured.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Coordinates {
    /// In units of the bounding radius R about the bounds' centre c: `p` means `c + R·p`.
    Relative,
    /// Local scene coordinates, used as they are.
    Absolute,
}

/// How a keyframe file interpolates between keys.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Deserialize, serde::Serialize)]
#[serde(rename_all = "kebab-case")]
pub enum Interpolation {
    /// Non-uniform Catmull–Rom with the key times as knots, clamped ends (`"catmull-rom"`).
    #[default]
    CatmullRom,
    /// Piecewise linear (`"linear"`).
    Linear,
}

/// One key of a keyframe path, in the file's coordinates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Key {
    /// Normalised time in `[0, 1]`.
    pub t: f64,
    /// Eye position.
    pub position: DVec3,
    /// Point looked at.
    pub target: DVec3,
    /// Up direction (not scaled by relative coordinates).
    pub up: DVec3,
}

/// A validated keyframe path. Build one with [`Keyframes::load`], [`Keyframes::from_toml`]
/// or [`Keyframes::new`]; all three validate.
#[derive(Debug, Clone, PartialEq)]
pub struct Keyframes {
    name: String,
    coordinates: Coordinates,
    interpolation: Interpolation,
    fov_deg: f64,
    keys: Vec<Key>,
}

/// The file as written, before validation.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct FileToml {
    coordinates: Coordinates,
    #[serde(default)]
    interpolation: Interpolation,
    #[serde(default = "default_fov_deg")]
    fov_deg: f64,
    #[serde(default)]
    key: Vec<KeyToml>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KeyToml {
    t: f64,
    position: [f64; 3],
    target: [f64; 3],
    #[serde(default = "default_up")]
    up: [f64; 3],
}

fn default_fov_deg() -> f64 {
    45.0
}

fn default_up() -> [f64; 3] {
    [0.0, 0.0, 1.0]
}

/// Validation splits each segment into this many parts and checks the inner points for a
/// degenerate view.
const SEGMENT_CHECKS: usize = 32;
/// Smallest sine of the angle between up and the view direction that validation accepts.
const MIN_UP_SINE: f64 = 1e-3;

impl Keyframes {
    /// Reads and validates a keyframe file; its name is the file stem.
    pub fn load(path: &Path) -> Result<Keyframes, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
        let name = path
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "keyframes".into());
        Keyframes::parse_toml(&text, &name, &path.display().to_string())
    }

    /// Parses and validates keyframe TOML text; `name` is the path's name and appears in
    /// error messages.
    pub fn from_toml(text: &str, name: &str) -> Result<Keyframes, SceneError> {
        Keyframes::parse_toml(text, name, name)
    }

    fn parse_toml(text: &str, name: &str, source: &str) -> Result<Keyframes, SceneError> {
        let file: FileToml = toml::from_str(text)
            .map_err(|e| SceneError::Path(format!("{source}: {}", e.to_string().trim_end())))?;
        let keys = file
            .key
            .iter()
            .map(|k| Key {
                t: k.t,
                position: DVec3::from(k.position),
                target: DVec3::from(k.target),
                up: DVec3::from(k.up),
            })
            .collect();
        Keyframes::validated(
            source,
            Keyframes {
                name: name.into(),
                coordinates: file.coordinates,
                interpolation: file.interpolation,
                fov_deg: file.fov_deg,
                keys,
            },
        )
    }

    /// Builds and validates a keyframe path from parts (errors are prefixed with `name`).
    pub fn new(
        name: &str,
        coordinates: Coordinates,
        interpolation: Interpolation,
        fov_deg: f64,
        keys: Vec<Key>,
    ) -> Result<Keyframes, SceneError> {
        Keyframes::validated(
            name,
            Keyframes {
                name: name.into(),
                coordinates,
                interpolation,
                fov_deg,
                keys,
            },
        )
    }

    /// The path's name (a file's stem).
    pub fn name(&self) -> &str {
        &self.name
    }
    /// How positions and targets are measured.
    pub fn coordinates(&self) -> Coordinates {
        self.coordinates
    }
    /// How keys are interpolated.
    pub fn interpolation(&self) -> Interpolation {
        self.interpolation
    }
    /// Vertical field of view, degrees.
    pub fn fov_deg(&self) -> f64 {
        self.fov_deg
    }
    /// The keys, in time order, in the file's coordinates.
    pub fn keys(&self) -> &[Key] {
        &self.keys
    }

    /// The path as a keyframe file that [`Keyframes::from_toml`] reads back to an equal
    /// path (numbers in Rust's shortest round-trip form).
    pub fn to_toml(&self) -> String {
        let coordinates = match self.coordinates {
            Coordinates::Relative => "relative",
            Coordinates::Absolute => "absolute",
        };
        let interpolation = match self.interpolation {
            Interpolation::CatmullRom => "catmull-rom",
            Interpolation::Linear => "linear",
        };
        let v = |d: DVec3| format!("[{:?}, {:?}, {:?}]", d.x, d.y, d.z);
        let mut out = format!(
            "# splatbench camera path\ncoordinates = \"{coordinates}\"\ninterpolation = \"{interpolation}\"\nfov_deg = {:?}\n",
            self.fov_deg
        );
        for k in &self.keys {
            out.push_str(&format!(
                "\n[[key]]\nt = {:?}\nposition = {}\ntarget = {}\nup = {}\n",
                k.t,
                v(k.position),
                v(k.target),
                v(k.up)
            ));
        }
        out
    }

    fn validated(source: &str, kf: Keyframes) -> Result<Keyframes, SceneError> {
        let err = |msg: String| SceneError::Path(format!("{source}: {msg}"));
        let keys = &kf.keys;
        if keys.len() < 2 {
            return Err(err(format!(
                "a keyframe path needs at least 2 [[key]] entries, found {}",
                keys.len()
            )));
        }
        if !(kf.fov_deg.is_finite() && kf.fov_deg > 0.0 && kf.fov_deg < 180.0) {
            return Err(err(format!("fov_deg = {} is outside (0, 180)", kf.fov_deg)));
        }
        for (i, k) in keys.iter().enumerate() {
            let field = [
                ("t", k.t.is_finite()),
                ("position", k.position.is_finite()),
                ("target", k.target.is_finite()),
                ("up", k.up.is_finite()),
            ]
            .into_iter()
            .find(|(_, ok)| !ok);
            if let Some((field, _)) = field {
                return Err(err(format!("key[{i}]: {field} has a non-finite value")));
            }
        }
        let first = keys[0].t;
        if first != 0.0 {
            return Err(err(format!(
                "key[0]: t = {first}, but the first key must have t = 0"
            )));
        }
        for (i, w) in keys.windows(2).enumerate() {
            if w[1].t <= w[0].t {
                return Err(err(format!(
                    "key[{}]: t = {} is not greater than key[{i}]'s t = {} (times must strictly increase)",
                    i + 1,
                    w[1].t,
                    w[0].t
                )));
            }
        }
        let last = keys.len() - 1;
        if keys[last].t != 1.0 {
            return Err(err(format!(
                "key[{last}]: t = {}, but the last key must have t = 1",
                keys[last].t
            )));
        }
        for (i, k) in keys.iter().enumerate() {
            if let Some(problem) = view_problem(k.position, k.target, k.up) {
                return Err(err(format!("key[{i}]: {problem}")));
            }
        }
        for (k, w) in keys.windows(2).enumerate() {
            for j in 1..SEGMENT_CHECKS {
                let t = w[0].t + (w[1].t - w[0].t) * j as f64 / SEGMENT_CHECKS as f64;
                let (p, q, up) = kf.local(t);
                if let Some(problem) = view_problem(p, q, up) {
                    return Err(err(format!(
                        "between key[{k}] and key[{}], near t = {t:.4}: {problem}",
                        k + 1
                    )));
                }
            }
        }
        Ok(kf)
    }

    /// Position, target and (unnormalised) up at time `t`, in the file's coordinates.
    fn local(&self, t: f64) -> (DVec3, DVec3, DVec3) {
        let seg = self.segment(t);
        (
            self.interpolate(seg, t, |k| k.position),
            self.interpolate(seg, t, |k| k.target),
            self.interpolate(seg, t, |k| k.up),
        )
    }

    /// Index `k` of the segment `[t_k, t_{k+1}]` holding `t` (`t_k ≤ t < t_{k+1}`, the last
    /// segment for `t ≥` the last time).
    fn segment(&self, t: f64) -> usize {
        let n = self.keys.len();
        self.keys
            .partition_point(|k| k.t <= t)
            .saturating_sub(1)
            .min(n - 2)
    }

    fn interpolate(&self, seg: usize, t: f64, get: impl Fn(&Key) -> DVec3) -> DVec3 {
        let (k0, k1) = (&self.keys[seg], &self.keys[seg + 1]);
        let (a, b) = (get(k0), get(k1));
        if a == b {
            return a;
        }
        let dt = k1.t - k0.t;
        let s = ((t - k0.t) / dt).clamp(0.0, 1.0);
        match self.interpolation {
            Interpolation::Linear => a + (b - a) * s,
            Interpolation::CatmullRom => {
                let m0 = self.tangent(seg, &get);
                let m1 = self.tangent(seg + 1, &get);
                hermite(a, m0 * dt, b, m1 * dt, s)
            }
        }
    }

    /// Time derivative of a quantity at key `j`: zero next to a hold (the quantity equal at
    /// two consecutive keys), the end chord's slope at the ends, Catmull–Rom inside.
    fn tangent(&self, j: usize, get: &impl Fn(&Key) -> DVec3) -> DVec3 {
        let keys = &self.keys;
        let n = keys.len();
        let v = get(&keys[j]);
        let held_before = j > 0 && get(&keys[j - 1]) == v;
        let held_after = j + 1 < n && get(&keys[j + 1]) == v;
        if held_before || held_after {
            return DVec3::ZERO;
        }
        let slope = |a: usize| (get(&keys[a + 1]) - get(&keys[a])) / (keys[a + 1].t - keys[a].t);
        if j == 0 {
            slope(0)
        } else if j == n - 1 {
            slope(n - 2)
        } else {
            catmull_rom_tangent(
                get(&keys[j - 1]),
                v,
                get(&keys[j + 1]),
                keys[j].t - keys[j - 1].t,
                keys[j + 1].t - keys[j].t,
            )
        }
    }

    /// The camera at normalised time `t` in the scene frame `f`.
    pub(super) fn camera(&self, t: f64, f: &Frame) -> Camera {
        let t = t.clamp(0.0, 1.0);
        let seg = self.segment(t);
        let (p, q, up) = self.local(t);
        let (k0, k1) = (&self.keys[seg], &self.keys[seg + 1]);
        let near_key = if t - k0.t <= k1.t - t { k0 } else { k1 };
        let fallback = near_key.target - near_key.position;
        let (eye, target) = match self.coordinates {
            Coordinates::Relative => (f.c + p * f.r, f.c + q * f.r),
            Coordinates::Absolute => (p, q),
        };
        let up = up.try_normalize().unwrap_or(DVec3::Z);
        f.camera(eye, target, up, self.fov_deg.to_radians(), fallback)
    }
}

/// What makes a view unusable, if anything: target at the eye (relative to the numbers'
/// magnitude, so it survives `f32`), a zero up, or up (nearly) parallel to the view direction.
fn view_problem(position: DVec3, target: DVec3, up: DVec3) -> Option<&'static str> {
    let d = target - position;
    let scale = position.abs().max(target.abs()).max_element();
    // Numbers are finite here (checked before).
    if d.length() <= 1e-6 * scale {
        return Some(
            "position is at the target, or closer to it than 1e-6 × the size of the \
             coordinates (f32 view maths cannot resolve the direction)",
        );
    }
    let Some(up) = up.try_normalize() else {
        return Some("up is the zero vector");
    };
    if d.normalize().cross(up).length() < MIN_UP_SINE {
        return Some("up is parallel to the view direction (target - position)");
    }
    None
}
