//! The up axis of a scene.
//!
//! splatbench's world is Z-up: camera paths orbit about +Z and terrain generators grow along
//! it. Many files are not: Stanford's scans and most graphics PLY data are Y-up, so they render
//! lying on their side. [`Up`] names the file's up axis (`--up y`, `up = "y"` in a scene file)
//! and [`Up::to_z_up`] turns a point or vector of the file into splatbench's frame with a
//! proper rotation (a signed axis permutation of determinant +1), so it is exact in any
//! precision and handedness is kept.

use std::fmt;
use std::str::FromStr;

/// Which axis of the file points up.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Default)]
pub enum Up {
    /// +X.
    X,
    /// +Y (Stanford / graphics PLY data).
    Y,
    /// +Z (splatbench's own frame; LAS, E57 and most scanners). The default.
    #[default]
    Z,
    /// −X.
    NegX,
    /// −Y.
    NegY,
    /// −Z.
    NegZ,
}

impl Up {
    /// Every axis, in the order the error message lists them.
    pub const ALL: [Up; 6] = [Up::X, Up::Y, Up::Z, Up::NegX, Up::NegY, Up::NegZ];

    /// The rotation taking this axis to +Z, applied to `(x, y, z)`:
    /// `+x`: (−z, y, x) — a −90° turn about y; `+y`: (x, −z, y) — +90° about x;
    /// `−x`: (z, y, −x); `−y`: (x, z, −y); `−z`: (x, −y, −z) — 180° about x.
    pub fn to_z_up<T: Copy + std::ops::Neg<Output = T>>(self, [x, y, z]: [T; 3]) -> [T; 3] {
        match self {
            Up::X => [-z, y, x],
            Up::Y => [x, -z, y],
            Up::Z => [x, y, z],
            Up::NegX => [z, y, -x],
            Up::NegY => [x, z, -y],
            Up::NegZ => [x, -y, -z],
        }
    }
}

impl fmt::Display for Up {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Up::X => "x",
            Up::Y => "y",
            Up::Z => "z",
            Up::NegX => "-x",
            Up::NegY => "-y",
            Up::NegZ => "-z",
        })
    }
}

impl FromStr for Up {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let t = s.trim().to_ascii_lowercase();
        let t = t.strip_prefix('+').unwrap_or(&t);
        Up::ALL
            .into_iter()
            .find(|u| u.to_string() == t)
            .ok_or_else(|| {
                let all: Vec<String> = Up::ALL.iter().map(Up::to_string).collect();
                format!("'{s}' is not an axis (one of {})", all.join(" "))
            })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_axis_goes_to_plus_z_by_a_rotation() {
        for up in Up::ALL {
            let a = match up {
                Up::X => [1.0, 0.0, 0.0],
                Up::Y => [0.0, 1.0, 0.0],
                Up::Z => [0.0, 0.0, 1.0],
                Up::NegX => [-1.0, 0.0, 0.0],
                Up::NegY => [0.0, -1.0, 0.0],
                Up::NegZ => [0.0, 0.0, -1.0],
            };
            assert_eq!(up.to_z_up(a), [0.0, 0.0, 1.0], "{up}");
            // Determinant +1: the images of x, y, z form a right-handed frame.
            let [ex, ey, ez] = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]]
                .map(|v| glam::DVec3::from(up.to_z_up(v)));
            assert_eq!(ex.cross(ey).dot(ez), 1.0, "{up}");
            assert_eq!(up.to_string().parse::<Up>(), Ok(up));
        }
        assert_eq!("+Y".parse::<Up>(), Ok(Up::Y));
        let e = "w".parse::<Up>().unwrap_err();
        assert!(e.contains("'w'") && e.contains("-y"), "{e}");
    }
}
