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

/// A flat end of a cloud: the samples that lie in the slab of depth [`BASE_SLAB`] of the
/// box's extent at one end of one axis, where a scanned object stands on its base or a room
/// on its floor (scanners rarely see the underside, so the opposite end holds few).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FlatBase {
    /// The up axis the base implies: `+a` for a base at the low end of axis `a`, `−a` at
    /// its high end.
    pub up: Up,
    /// Share of the samples in the base's slab.
    pub share: f64,
    /// The largest share of any other end's slab.
    pub next: f64,
}

/// Depth of an end's slab, as a fraction of the box's extent along the axis. Evenly
/// spread samples put this share in every slab.
pub const BASE_SLAB: f64 = 0.03;
/// A base holds at least this share of the samples (5 / 3 of an even spread's) …
pub const BASE_SHARE: f64 = 0.05;
/// … and this many times the share of every other end, so that a box whose ends are all
/// alike (a room's floor and ceiling, a terrain's sides, a flat tile's two faces) names
/// none. Measured: the Stanford bunny (`scenes/tests/data/real/bunny.ply`, Y-up) holds
/// 10.3 % at its low y end, the next end 2.1 % (4.9×).
pub const BASE_DOMINANCE: f64 = 3.0;

/// The flat base of the samples `positions` within `bounds` (samples outside are not
/// counted), if one end's slab holds at least [`BASE_SHARE`] of them and
/// [`BASE_DOMINANCE`] times any other end's share. An axis of zero extent has no ends.
/// A hint, not a proof: a file whose base is not its lowest flat end is not recognised.
pub fn flat_base<'a>(
    positions: impl Iterator<Item = &'a [f32; 3]>,
    bounds: (glam::Vec3, glam::Vec3),
) -> Option<FlatBase> {
    let (lo, hi) = bounds;
    let ext = hi - lo;
    // [low x, low y, low z, high x, high y, high z].
    let mut ends = [0u64; 6];
    let mut total = 0u64;
    for p in positions {
        let v = glam::Vec3::from(*p);
        if !(v.cmpge(lo).all() && v.cmple(hi).all()) {
            continue;
        }
        total += 1;
        for a in 0..3 {
            if ext[a] <= 0.0 {
                continue;
            }
            let t = f64::from((v[a] - lo[a]) / ext[a]);
            ends[a] += u64::from(t < BASE_SLAB);
            ends[a + 3] += u64::from(t > 1.0 - BASE_SLAB);
        }
    }
    if total == 0 {
        return None;
    }
    let share = ends.map(|n| n as f64 / total as f64);
    let best = (0..6).max_by(|&i, &j| share[i].total_cmp(&share[j]))?;
    let next = (0..6)
        .filter(|&i| i != best)
        .map(|i| share[i])
        .fold(0.0, f64::max);
    let up = [Up::X, Up::Y, Up::Z, Up::NegX, Up::NegY, Up::NegZ][best];
    (share[best] >= BASE_SHARE && share[best] >= BASE_DOMINANCE * next).then_some(FlatBase {
        up,
        share: share[best],
        next,
    })
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

    /// `n³` samples on a regular grid filling the unit cube, plus `copies` times the
    /// grid's `n²` columns in the plane y = 0 (a floor scanned `copies` times).
    fn cube_with_floor(n: usize, copies: usize) -> Vec<[f32; 3]> {
        let g = |i: usize| (i as f32 + 0.5) / n as f32;
        let grid = |d: usize| (0..n.pow(d as u32)).map(move |i| [i % n, i / n % n, i / n / n]);
        let mut v: Vec<[f32; 3]> = grid(3).map(|[i, j, k]| [g(i), g(j), g(k)]).collect();
        for _ in 0..copies {
            v.extend(grid(2).map(|[i, k, _]| [g(i), 0.0, g(k)]));
        }
        v
    }

    fn bounds(v: &[[f32; 3]]) -> (glam::Vec3, glam::Vec3) {
        v.iter().fold(
            (glam::Vec3::splat(f32::MAX), glam::Vec3::splat(f32::MIN)),
            |(lo, hi), p| (lo.min((*p).into()), hi.max((*p).into())),
        )
    }

    #[test]
    fn a_floor_names_the_axis_it_stands_on_in_every_orientation() {
        // 15,625 in the cube (the slab of 3 % holds one layer in 25: 625) and 5 × 625 on
        // the floor: 3,750 / 18,750 = 20 % at the low y end; the next, a low or high x or z
        // end, holds a layer and the floor's first row (625 + 5 × 25) = 4 %.
        let v = cube_with_floor(25, 5);
        let b = flat_base(v.iter(), bounds(&v));
        let b = b.unwrap_or_else(|| panic!("no base: {:?} {}", bounds(&v), v.len()));
        assert_eq!(b.up, Up::Y);
        assert_eq!(b.share, 3750.0 / 18750.0);
        assert_eq!(b.next, 750.0 / 18750.0);
        // The same cloud turned to each up axis: the base names that axis, and turned with
        // `to_z_up` (as a file read with the right `--up`) it names +z.
        for up in Up::ALL {
            let turned: Vec<[f32; 3]> = v
                .iter()
                .map(|&p| Up::Y.to_z_up(p))
                .map(|p| {
                    // From +z (where the base now is) to `up`: the inverse of `up.to_z_up`.
                    let e =
                        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]].map(|a| up.to_z_up(a));
                    // to_z_up is a signed permutation R; its inverse is the transpose.
                    [0, 1, 2].map(|i| e[i][0] * p[0] + e[i][1] * p[1] + e[i][2] * p[2])
                })
                .collect();
            let b = flat_base(turned.iter(), bounds(&turned)).expect("a base");
            assert_eq!(b.up, up);
            let back: Vec<[f32; 3]> = turned.iter().map(|&p| up.to_z_up(p)).collect();
            assert_eq!(
                flat_base(back.iter(), bounds(&back)).map(|b| b.up),
                Some(Up::Z)
            );
        }
    }

    #[test]
    fn alike_ends_a_thin_base_and_a_flat_tile_name_none() {
        // No floor: every end holds one layer in 25, 4 %.
        let v = cube_with_floor(25, 0);
        assert_eq!(flat_base(v.iter(), bounds(&v)), None);
        // A floor and a ceiling alike: the dominance fails.
        let mut v = cube_with_floor(25, 5);
        let ceiling: Vec<[f32; 3]> = v[15_625..].iter().map(|p| [p[0], 1.0, p[2]]).collect();
        v.extend(ceiling);
        assert_eq!(flat_base(v.iter(), bounds(&v)), None);
        // One copy of the floor: 1,250 / 16,250 = 7.7 %, but only 1.9 × the next end's 4 %.
        let v = cube_with_floor(25, 1);
        assert_eq!(flat_base(v.iter(), bounds(&v)), None);
        // Every end empty but for the unit cube's 8 corners, 13³ samples inside, and a floor
        // of k samples at y = 0 in the middle: (k + 4) / (2,205 + k) at the low y end, 4 /
        // (2,205 + k) at every other, so only BASE_SHARE decides.
        let floor = |k: usize| {
            let inner = |i: usize| 0.2 + 0.05 * i as f32;
            let mut v: Vec<[f32; 3]> = (0..13usize.pow(3))
                .map(|i| [inner(i % 13), inner(i / 13 % 13), inner(i / 169)])
                .collect();
            v.extend((0..8).map(|c| [c & 1, c >> 1 & 1, c >> 2].map(|b| b as f32)));
            v.extend((0..k).map(|i| [inner(i % 13), 0.0, inner(i / 13 % 13)]));
            v
        };
        let v = floor(100); // 104 / 2,305 = 4.5 %
        assert_eq!(flat_base(v.iter(), bounds(&v)), None);
        let v = floor(130); // 134 / 2,335 = 5.7 %
        assert_eq!(flat_base(v.iter(), bounds(&v)).map(|b| b.up), Some(Up::Y));
        // A flat tile (zero z extent): its ends are not counted, x and y are alike.
        let v: Vec<[f32; 3]> = cube_with_floor(25, 0)
            .iter()
            .map(|p| [p[0], p[1], 0.0])
            .collect();
        assert_eq!(flat_base(v.iter(), bounds(&v)), None);
        // Samples outside the bounds are not counted; no sample inside: none.
        assert_eq!(
            flat_base(v.iter(), (glam::Vec3::splat(2.0), glam::Vec3::splat(3.0))),
            None
        );
    }
}
