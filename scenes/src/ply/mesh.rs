//! Mesh-derived attributes (vertex normals, radii) and surface resampling.

use std::path::Path;

use glam::DVec3;
use rayon::prelude::*;

use super::vertices::Vertices;
use super::{cloud_err, ferr};
use crate::rng::Pcg32;
use crate::{PointCloud, SceneError};

/// Samples per independently seeded block when resampling.
const SAMPLE_BLOCK: usize = 1 << 16;

// ---------------------------------------------------------------------------------------------
// Mesh-derived attributes
// ---------------------------------------------------------------------------------------------

#[inline(always)]
fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}
#[inline(always)]
fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}
#[inline(always)]
fn dot(a: [f64; 3], b: [f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}
/// `v / |v|` as `f32`, or `None` for a zero / non-finite vector.
#[inline(always)]
fn unit_f32(v: [f64; 3]) -> Option<[f32; 3]> {
    let l = dot(v, v).sqrt();
    if !(l.is_finite() && l > 0.0) {
        return None;
    }
    let n = v.map(|c| (c / l) as f32);
    let l2 = n[0] * n[0] + n[1] * n[1] + n[2] * n[2];
    (l2.is_finite() && l2 > 0.5).then_some(n)
}

/// Twice the area vector of triangle `t` (winding order `a → b → c`).
#[inline(always)]
fn tri_cross(pos: &[[f64; 3]], t: [u32; 3]) -> [f64; 3] {
    let a = pos[t[0] as usize];
    cross(sub(pos[t[1] as usize], a), sub(pos[t[2] as usize], a))
}

/// Area-weighted vertex normals (see the module docs for the fallbacks).
pub(super) fn mesh_normals(pos: &[[f64; 3]], tris: &[[u32; 3]]) -> Vec<[f32; 3]> {
    let mut sum = vec![[0.0f64; 3]; pos.len()];
    for &t in tris {
        let c = tri_cross(pos, t);
        for &v in &t {
            let s = &mut sum[v as usize];
            s[0] += c[0];
            s[1] += c[1];
            s[2] += c[2];
        }
    }
    let mut normals: Vec<Option<[f32; 3]>> = sum.par_iter().map(|s| unit_f32(*s)).collect();
    drop(sum);
    if normals.iter().any(Option::is_none) {
        // Faces that cancel: take the largest incident face's normal.
        let mut best = vec![0.0f64; pos.len()];
        let mut best_n: Vec<Option<[f32; 3]>> = vec![None; pos.len()];
        for &t in tris {
            if t.iter().all(|&v| normals[v as usize].is_some()) {
                continue;
            }
            let c = tri_cross(pos, t);
            let a = dot(c, c);
            for &v in &t {
                let v = v as usize;
                if normals[v].is_none()
                    && a > best[v]
                    && let Some(n) = unit_f32(c)
                {
                    best[v] = a;
                    best_n[v] = Some(n);
                }
            }
        }
        for (n, b) in normals.iter_mut().zip(best_n) {
            if n.is_none() {
                *n = b;
            }
        }
    }
    normals
        .into_iter()
        .map(|n| n.unwrap_or([0.0, 0.0, 1.0]))
        .collect()
}

/// Radius of the smallest sphere enclosing triangle `t`.
#[inline(always)]
fn tri_sphere_radius(pos: &[[f64; 3]], t: [u32; 3]) -> f64 {
    let (a, b, c) = (pos[t[0] as usize], pos[t[1] as usize], pos[t[2] as usize]);
    let (ab, bc, ca) = (sub(b, a), sub(c, b), sub(a, c));
    let mut e = [dot(bc, bc), dot(ca, ca), dot(ab, ab)];
    e.sort_by(f64::total_cmp);
    if e[2] >= e[0] + e[1] {
        // Right, obtuse or degenerate: the longest edge is a diameter.
        return 0.5 * e[2].sqrt();
    }
    // Acute: circumradius = |ab||bc||ca| / (2 |ab × ac|).
    let cr = cross(ab, sub(c, a));
    let denom = 2.0 * dot(cr, cr).sqrt();
    let r = (e[0] * e[1] * e[2]).sqrt() / denom;
    if r.is_finite() { r } else { 0.5 * e[2].sqrt() }
}

/// QSplat leaf radii: the largest bounding-sphere radius of the incident triangles.
pub(super) fn mesh_radii(
    pos: &[[f64; 3]],
    tris: &[[u32; 3]],
    local: &[[f32; 3]],
    diag: f64,
) -> Vec<f32> {
    let mut r = vec![0.0f64; pos.len()];
    for &t in tris {
        let s = tri_sphere_radius(pos, t);
        for &v in &t {
            let v = v as usize;
            if s > r[v] {
                r[v] = s;
            }
        }
    }
    let ok = |x: f32| x.is_finite() && x > 0.0;
    let mut radii: Vec<f32> = r.par_iter().map(|&x| x as f32).collect();
    drop(r);
    if radii.iter().all(|&x| ok(x)) {
        return radii;
    }
    let mut good: Vec<f32> = radii.iter().copied().filter(|&x| ok(x)).collect();
    if !good.is_empty() {
        let mid = good.len() / 2;
        let (_, m, _) = good.select_nth_unstable_by(mid, f32::total_cmp);
        let median = *m;
        for x in &mut radii {
            if !ok(*x) {
                *x = median;
            }
        }
        return radii;
    }
    // Every triangle is degenerate: nearest-neighbour spacing, then a fraction of the extent.
    let knn = crate::spacing::knn_spacing(local, 1);
    let last = if diag.is_finite() && diag > 0.0 {
        (diag * 1e-3) as f32
    } else {
        1.0
    };
    let last = if ok(last) { last } else { 1.0 };
    for (i, x) in radii.iter_mut().enumerate() {
        if !ok(*x) {
            *x = knn.get(i).copied().filter(|&k| ok(k)).unwrap_or(last);
        }
    }
    radii
}

// ---------------------------------------------------------------------------------------------
// Surface resampling
// ---------------------------------------------------------------------------------------------

#[derive(Clone, Copy, Default)]
struct Sample {
    p: [f32; 3],
    n: [f32; 3],
    c: [u8; 3],
}

pub(super) fn sample_surface(
    path: &Path,
    v: &Vertices,
    tris: &[[u32; 3]],
    origin: DVec3,
    count: usize,
    seed: u64,
) -> Result<PointCloud, SceneError> {
    if tris.is_empty() {
        return Err(ferr(
            path,
            "cannot resample the surface: the faces hold no triangle (every face has fewer than 3 vertices)",
        ));
    }
    let o = origin.to_array();
    // Positions relative to the origin keep the area sums well conditioned.
    let rel: Vec<[f64; 3]> = v.pos.par_iter().map(|p| sub(*p, o)).collect();
    let mut cdf = Vec::with_capacity(tris.len());
    let mut total = 0.0f64;
    let mut last_positive = None;
    for (i, &t) in tris.iter().enumerate() {
        let c = tri_cross(&rel, t);
        let area = 0.5 * dot(c, c).sqrt();
        if area > 0.0 && area.is_finite() {
            total += area;
            last_positive = Some(i);
        }
        cdf.push(total);
    }
    let Some(last_positive) = last_positive.filter(|_| total.is_finite() && total > 0.0) else {
        return Err(ferr(
            path,
            "cannot resample the surface: every triangle has zero area",
        ));
    };
    let mut out = vec![Sample::default(); count];
    out.par_chunks_mut(SAMPLE_BLOCK)
        .enumerate()
        .for_each(|(b, chunk)| {
            let mut rng = Pcg32::stream(seed, b as u64);
            for s in chunk {
                let u = rng.f64() * total;
                let ti = cdf.partition_point(|&c| c <= u).min(last_positive);
                let t = tris[ti];
                let r1 = rng.f64();
                let r2 = rng.f64();
                let sq = r1.sqrt();
                let w = [1.0 - sq, sq * (1.0 - r2), sq * r2];
                let (a, bb, c) = (rel[t[0] as usize], rel[t[1] as usize], rel[t[2] as usize]);
                let p: [f64; 3] = std::array::from_fn(|k| w[0] * a[k] + w[1] * bb[k] + w[2] * c[k]);
                s.p = p.map(|x| x as f32);
                let face_n = || unit_f32(tri_cross(&rel, t)).unwrap_or([0.0, 0.0, 1.0]);
                s.n = match &v.normals {
                    Some(n) => {
                        let (na, nb, nc) = (n[t[0] as usize], n[t[1] as usize], n[t[2] as usize]);
                        let m: [f64; 3] = std::array::from_fn(|k| {
                            w[0] * f64::from(na[k])
                                + w[1] * f64::from(nb[k])
                                + w[2] * f64::from(nc[k])
                        });
                        unit_f32(m).unwrap_or_else(face_n)
                    }
                    None => face_n(),
                };
                if let Some(col) = &v.colors {
                    let (ca, cb, cc) = (col[t[0] as usize], col[t[1] as usize], col[t[2] as usize]);
                    s.c = std::array::from_fn(|k| {
                        (w[0] * f64::from(ca[k])
                            + w[1] * f64::from(cb[k])
                            + w[2] * f64::from(cc[k]))
                        .round()
                        .clamp(0.0, 255.0) as u8
                    });
                }
            }
        });
    let positions: Vec<[f32; 3]> = out.par_iter().map(|s| s.p).collect();
    let normals: Vec<[f32; 3]> = out.par_iter().map(|s| s.n).collect();
    let colors: Option<Vec<[u8; 3]>> = v
        .colors
        .as_ref()
        .map(|_| out.par_iter().map(|s| s.c).collect());
    drop(out);
    PointCloud::new(
        origin,
        positions.into(),
        Some(normals.into()),
        colors.map(Into::into),
        None,
    )
    .map_err(|e| cloud_err(path, e))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn sphere_radius_of_right_and_equilateral_triangles() {
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [1.0, 1.0, 0.0]];
        let r = tri_sphere_radius(&pos, [0, 1, 2]);
        assert!((r - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        let h = 3.0f64.sqrt() / 2.0;
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.5, h, 0.0]];
        let r = tri_sphere_radius(&pos, [0, 1, 2]);
        assert!((r - 1.0 / 3.0f64.sqrt()).abs() < 1e-12, "{r}");
        let pos = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]];
        assert!((tri_sphere_radius(&pos, [0, 1, 2]) - 1.0).abs() < 1e-12);
    }
}
