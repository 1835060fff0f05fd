//! Camera poses → camera-path files that `splatbench run --path FILE` reads unchanged:
//! a recorded path ([`Recorder`]: a key per keypress, its time normalised over the
//! recording) and a screenshot's sidecar ([`still`]: one pose held, so frame 0 of any run
//! is that pose). Absolute (local scene) coordinates, Catmull–Rom between keys; the camera
//! is exactly at each key at its time (the keyframe format's rule), so the recorded poses
//! come back as they were.

use std::path::Path;

use scenes::paths::{Coordinates, Interpolation, Key, Keyframes};
use scenes::{Camera, SceneError};

/// Poses recorded with their times.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Recorder {
    keys: Vec<(f64, Camera)>,
}

fn key(t: f64, c: &Camera) -> Key {
    Key {
        t,
        position: c.position.as_dvec3(),
        target: c.target.as_dvec3(),
        up: c.up.as_dvec3(),
    }
}

impl Recorder {
    /// Adds the pose `camera` at `time_s` seconds; times must increase, and every pose
    /// keeps the first one's field of view (a path has one).
    pub fn add(&mut self, time_s: f64, camera: Camera) -> Result<(), String> {
        if !time_s.is_finite() {
            return Err(format!("keyframe time {time_s} is not finite"));
        }
        if let Some((t, first)) = self.keys.last().map(|k| (k.0, self.keys[0].1)) {
            if time_s <= t {
                return Err(format!(
                    "keyframe at {time_s:.3} s is not after the last one ({t:.3} s)"
                ));
            }
            if camera.fov_y != first.fov_y {
                return Err(format!(
                    "a path has one field of view: this key has {:.2}°, the first {:.2}°",
                    camera.fov_y.to_degrees(),
                    first.fov_y.to_degrees()
                ));
            }
        }
        self.keys.push((time_s, camera));
        Ok(())
    }

    /// Keys recorded.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// True if nothing is recorded.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }

    /// The recorded path named `name`: `t` = time since the first key ÷ the recording's
    /// length. At least two keys.
    pub fn keyframes(&self, name: &str) -> Result<Keyframes, SceneError> {
        let (t0, t1) = match (self.keys.first(), self.keys.last()) {
            (Some(a), Some(b)) if self.keys.len() >= 2 => (a.0, b.0),
            _ => {
                return Err(SceneError::Path(format!(
                    "{name}: a path needs at least 2 keyframes, {} recorded",
                    self.keys.len()
                )));
            }
        };
        let keys = self
            .keys
            .iter()
            .enumerate()
            .map(|(i, (t, c))| {
                // The ends exactly 0 and 1 (the format requires them).
                let t = match i {
                    0 => 0.0,
                    _ if i + 1 == self.keys.len() => 1.0,
                    _ => (t - t0) / (t1 - t0),
                };
                key(t, c)
            })
            .collect();
        Keyframes::new(
            name,
            Coordinates::Absolute,
            Interpolation::CatmullRom,
            f64::from(self.keys[0].1.fov_y).to_degrees(),
            keys,
        )
    }

    /// Writes [`Recorder::keyframes`] to `path` (its stem names the path).
    pub fn save(&self, path: &Path) -> Result<Keyframes, SceneError> {
        let name = path
            .file_stem()
            .map_or_else(|| "recorded".into(), |s| s.to_string_lossy().into_owned());
        let kf = self.keyframes(&name)?;
        std::fs::write(path, kf.to_toml()).map_err(|e| SceneError::io(path, e))?;
        Ok(kf)
    }
}

/// The pose `camera` held still: a screenshot's sidecar, from which `run --path FILE`
/// renders the same view (every frame).
pub fn still(name: &str, camera: &Camera) -> Result<Keyframes, SceneError> {
    Keyframes::new(
        name,
        Coordinates::Absolute,
        Interpolation::Linear,
        f64::from(camera.fov_y).to_degrees(),
        vec![key(0.0, camera), key(1.0, camera)],
    )
}

/// Distance between two cameras' poses: the largest of the eye and target offsets (in
/// scene units) and the up and field-of-view differences (radians, times `scale`).
pub fn pose_distance(a: &Camera, b: &Camera, scale: f64) -> f64 {
    let d = |x: glam::Vec3, y: glam::Vec3| x.as_dvec3().distance(y.as_dvec3());
    let up =
        a.up.normalize()
            .as_dvec3()
            .distance(b.up.normalize().as_dvec3());
    d(a.position, b.position)
        .max(d(a.target, b.target))
        .max(up * scale)
        .max(f64::from((a.fov_y - b.fov_y).abs()) * scale)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::viewer::control::{Controller, Input, Key as K};
    use glam::Vec3;
    use scenes::Aabb;
    use scenes::paths::PathSpec;

    fn bounds() -> Aabb {
        Aabb {
            min: Vec3::new(10.0, -3.0, 0.0),
            max: Vec3::new(14.0, 3.0, 2.0),
        }
    }

    /// Poses recorded while flying come back from the saved file, through `PathSpec::parse`
    /// (what `run --path` does), at the frames whose times are the keys'.
    #[test]
    fn a_recorded_path_round_trips_through_its_file() {
        let b = bounds();
        let r_scene = (b.max.as_dvec3() - b.min.as_dvec3()).length() * 0.5;
        let mut c = Controller::new(&b);
        let mut rec = Recorder::default();
        let mut poses = Vec::new();
        // Keys at 0, 1, 2 and 4 s: with 5 frames, frames 0, 1, 2 and 4 are the keys.
        for (t, events) in [
            (0.0, vec![]),
            (1.0, vec![Input::Down(K::W)]),
            (2.0, vec![Input::Up(K::W), Input::Drag(120.0, 10.0)]),
            (4.0, vec![Input::Down(K::D), Input::Down(K::E)]),
        ] {
            for e in events {
                c.input(e);
            }
            c.tick(0.7);
            let cam = c.camera();
            rec.add(t, cam).unwrap();
            poses.push(cam);
        }
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("walk.toml");
        rec.save(&file).unwrap();
        let path = PathSpec::parse(file.to_str().unwrap()).unwrap();
        assert_eq!(path.name(), "walk");
        for (i, pose) in [0usize, 1, 2, 4].iter().zip(&poses) {
            let got = path.camera(*i, 5, &b);
            let err = pose_distance(&got, pose, r_scene);
            assert!(err < 1e-5 * r_scene, "frame {i}: off by {err}");
            assert!((got.near - pose.near).abs() <= 1e-5 * pose.near.max(1e-6));
        }
    }

    #[test]
    fn a_screenshot_sidecar_reproduces_its_pose() {
        let b = bounds();
        let mut c = Controller::new(&b);
        c.input(Input::Drag(-300.0, 40.0));
        let cam = c.camera();
        let kf = still("shot", &cam).unwrap();
        let back = Keyframes::from_toml(&kf.to_toml(), "shot").unwrap();
        assert_eq!(back, kf, "the TOML reads back to the same path");
        let path = PathSpec::Keyframes(back);
        for frames in [1, 3] {
            let got = path.camera(0, frames, &b);
            assert!(pose_distance(&got, &cam, 1.0) < 1e-6, "{got:?} vs {cam:?}");
        }
    }

    #[test]
    fn bad_recordings_are_refused_with_reasons() {
        let c = Controller::new(&bounds()).camera();
        let mut rec = Recorder::default();
        assert!(
            rec.keyframes("p")
                .unwrap_err()
                .to_string()
                .contains("at least 2")
        );
        rec.add(1.0, c).unwrap();
        assert!(rec.add(1.0, c).unwrap_err().contains("not after"));
        let wide = Camera { fov_y: 1.0, ..c };
        assert!(
            rec.add(2.0, wide)
                .unwrap_err()
                .contains("one field of view")
        );
        assert!(rec.add(f64::NAN, c).unwrap_err().contains("not finite"));
        // The same pose twice is a valid (still) path.
        rec.add(3.0, c).unwrap();
        assert!(rec.keyframes("p").is_ok());
    }
}
