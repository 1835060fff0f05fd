//! LPC's input spacing: the seeded probes' k-NN distances measured in the in-core subtrees
//! ([`probe_knn`]), the estimate of `r` and `nn_spacing` from them ([`spacing_estimates`]),
//! and the per-node spacings of eqs. (1)–(2) ([`hierarchical_spacing`]).

use glam::Vec3;
use rayon::prelude::*;
use scenes::Aabb;

use super::SpacingRule;
use super::cloud::Sample;
use super::index::NONE;
use super::layout::PROBE;
use crate::leaf::LEAF_K;

/// The spacing `r_j` of every node by eqs. (1)–(2): `r_0 = r·sqrt(N/M_0)`,
/// `M_j^tot = N_j/(N_p − M_p)·M_p^tot + M_j` (`M_0^tot = M_0`),
/// `r_j = r_p·sqrt(N_j·M_p^tot / ((N_p − M_p)·M_j^tot))`. Nodes are given parents first
/// (`parent[0] = NONE`), with their subtree sizes `N_j` and cloud sizes `M_j`.
pub fn hierarchical_spacing(r: f64, parent: &[u32], subtree: &[u64], points: &[u32]) -> Vec<f64> {
    let n = parent.len();
    let mut r_j = vec![0f64; n];
    let mut m_tot = vec![0f64; n];
    for j in 0..n {
        let (nj, mj) = (subtree[j] as f64, points[j] as f64);
        if parent[j] == NONE {
            m_tot[j] = mj;
            r_j[j] = r * (nj / mj).sqrt();
        } else {
            let p = parent[j] as usize;
            let rest = subtree[p] as f64 - points[p] as f64;
            m_tot[j] = nj / rest * m_tot[p] + mj;
            r_j[j] = r_j[p] * (nj * m_tot[p] / (rest * m_tot[j])).sqrt();
        }
    }
    r_j
}

/// Samples per parallel chunk of [`probe_knn`]'s scan.
pub const KNN_CHUNK: usize = 1 << 16;

/// Sorted squared distances of a probe's nearest samples (itself included).
type Best = [f32; LEAF_K + 1];

/// Merges the sorted `b[..k]` into the sorted `a[..k]`, keeping the `k` smallest.
fn merge_best(a: &mut Best, b: &Best, k: usize) {
    let mut out = [f32::INFINITY; LEAF_K + 1];
    let (mut i, mut j) = (0, 0);
    for o in &mut out[..k] {
        // `i + j < k`: both indices stay in range.
        if a[i] <= b[j] {
            *o = a[i];
            i += 1;
        } else {
            *o = b[j];
            j += 1;
        }
    }
    *a = out;
}

/// Bits of the probe-cell filter of [`probe_knn`].
const FILTER_BITS: usize = 1 << 20;

#[inline]
fn filter_bit(key: u64) -> usize {
    (key.wrapping_mul(0xD6E8_FEB8_6659_FD93) >> 44) as usize
}

/// `[nearest, k-th nearest]` neighbour distances of each probe sample of `s`
/// (flagged at load), measured exactly against all of `s` (the probe itself excluded once).
///
/// Linear in `s.len()`: the probes are hashed into a grid of cell size `h` (each into the
/// 27 cells around it); one scan of `s` (in parallel chunks of [`KNN_CHUNK`], whose nearest
/// lists are then merged: the same result for any split) collects, for each probe, the
/// samples within `h`.
/// A probe with fewer than `k` of them is measured again with `2h`. The first `h` is
/// `sqrt(A/n)` with `A` the surface area of the box. A 128 KiB bit filter of the cells that
/// hold probe entries spares most samples the (cache-missing) hash lookup.
pub fn probe_knn(s: &[Sample], bbox: Aabb, k: usize) -> Vec<[f32; 2]> {
    let probes: Vec<[f32; 3]> = s
        .iter()
        .filter(|x| x.flags & PROBE != 0)
        .map(|x| x.p)
        .collect();
    knn_of(&probes, s, |x| x.p, bbox, k, |_| {})
}

/// [`probe_knn`] over the whole scene, read from its position column: the probes are the
/// samples whose index `is_probe` accepts, in column order, measured against
/// every sample of `positions`, whose box is `bbox`. The same values in the same order as
/// [`probe_knn`] of the whole scene's samples in column order (the in-core root's buffer),
/// whatever part of the build is streamed: the input spacing does not depend on the memory
/// budget. `scanned` is told each range of samples a scan has finished with (a mapped
/// column's pages can be released behind it).
pub fn column_probe_knn(
    positions: &[[f32; 3]],
    is_probe: impl Fn(usize) -> bool + Sync,
    bbox: Aabb,
    k: usize,
    scanned: impl Fn(std::ops::Range<usize>) + Sync,
) -> Vec<[f32; 2]> {
    let probes: Vec<[f32; 3]> = positions
        .par_chunks(KNN_CHUNK)
        .enumerate()
        .map(|(c, chunk)| {
            let lo = c * KNN_CHUNK;
            let found = chunk
                .iter()
                .enumerate()
                .filter(|&(j, _)| is_probe(lo + j))
                .map(|(_, &p)| p)
                .collect::<Vec<_>>();
            scanned(lo..lo + chunk.len());
            found
        })
        .collect::<Vec<_>>()
        .concat();
    knn_of(&probes, positions, |p| *p, bbox, k, scanned)
}

/// The exact `[nearest, k-th nearest]` distances of `probes` (each one of `s`, excluded once)
/// against every item of `s`, whose positions `pos` gives and whose box is `bbox`
/// ([`probe_knn`]'s grid scan), telling `scanned` each range of `s` a scan is done with.
fn knn_of<T: Sync>(
    probes: &[[f32; 3]],
    s: &[T],
    pos: impl Fn(&T) -> [f32; 3] + Sync,
    bbox: Aabb,
    k: usize,
    scanned: impl Fn(std::ops::Range<usize>) + Sync,
) -> Vec<[f32; 2]> {
    if probes.is_empty() || s.len() < 2 {
        return Vec::new();
    }
    let k = k.clamp(1, s.len() - 1);
    let size = bbox.size();
    let ext = size.max_element();
    if ext <= 0.0 || !ext.is_finite() {
        // Every sample coincides: every distance is 0.
        return vec![[0.0; 2]; probes.len()];
    }
    let h0 = first_radius(bbox, s.len());
    let mut h = h0;
    let mut pending: Vec<u32> = (0..probes.len() as u32).collect();
    // Each probe's distances and its round.
    let mut done = vec![([0f32; 2], 0u32); probes.len()];
    let min = bbox.min;
    while !pending.is_empty() {
        let inv = 1.0 / h;
        let cell = |p: [f32; 3]| {
            let c = (Vec3::from(p) - min) * inv;
            [c.x as i64, c.y as i64, c.z as i64]
        };
        let key = |c: [i64; 3]| {
            ((c[0] + 1) as u64) | ((c[1] + 1) as u64) << 21 | ((c[2] + 1) as u64) << 42
        };
        let mut entries: Vec<(u64, u32)> = Vec::with_capacity(pending.len() * 27);
        for (j, &pi) in pending.iter().enumerate() {
            let c = cell(probes[pi as usize]);
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        entries.push((key([c[0] + dx, c[1] + dy, c[2] + dz]), j as u32));
                    }
                }
            }
        }
        entries.sort_unstable();
        let mut filter = vec![0u64; FILTER_BITS / 64];
        let mut map: crate::cellmap::CellMap<(u32, u32)> =
            crate::cellmap::CellMap::with_capacity_and_hasher(entries.len(), Default::default());
        let mut a = 0;
        while a < entries.len() {
            let mut b = a + 1;
            while b < entries.len() && entries[b].0 == entries[a].0 {
                b += 1;
            }
            map.insert(entries[a].0, (a as u32, b as u32));
            let f = filter_bit(entries[a].0);
            filter[f >> 6] |= 1 << (f & 63);
            a = b;
        }
        // The `k + 1` nearest of every probe, itself included (at distance 0): per chunk of
        // `s`, in parallel, then merged (the same values for any split).
        let kk = k + 1;
        let h2 = h * h;
        let fresh = || vec![[f32::INFINITY; LEAF_K + 1]; pending.len()];
        let scan = |mut best: Vec<Best>, chunk: &[T]| {
            for x in chunk {
                let p = pos(x);
                let kx = key(cell(p));
                let f = filter_bit(kx);
                if filter[f >> 6] & (1 << (f & 63)) == 0 {
                    continue;
                }
                let Some(&(a, b)) = map.get(&kx) else {
                    continue;
                };
                for &(_, j) in &entries[a as usize..b as usize] {
                    let j = j as usize;
                    let q = probes[pending[j] as usize];
                    let d2 = (Vec3::from(p) - Vec3::from(q)).length_squared();
                    let bj = &mut best[j][..kk];
                    if d2 <= h2 && d2 < bj[kk - 1] {
                        let mut i = kk - 1;
                        while i > 0 && bj[i - 1] > d2 {
                            bj[i] = bj[i - 1];
                            i -= 1;
                        }
                        bj[i] = d2;
                    }
                }
            }
            best
        };
        let best = s
            .par_chunks(KNN_CHUNK)
            .enumerate()
            .fold(fresh, |best, (c, chunk)| {
                let best = scan(best, chunk);
                scanned(c * KNN_CHUNK..c * KNN_CHUNK + chunk.len());
                best
            })
            .reduce_with(|mut x, y| {
                for (u, v) in x.iter_mut().zip(&y) {
                    merge_best(u, v, kk);
                }
                x
            })
            .unwrap_or_else(fresh);
        let mut next = Vec::new();
        for (j, &pi) in pending.iter().enumerate() {
            // `best[j][0]` is the probe itself.
            let d = best[j][k];
            if d <= h2 {
                done[pi as usize] = ([best[j][1].sqrt(), d.sqrt()], round_of(h0, d));
            } else {
                next.push(pi);
            }
        }
        pending = next;
        // A few stragglers (sparse parts of the scene) are measured with a radius growing
        // faster: a scan of every sample for each doubling costs more than the larger
        // cells' extra samples.
        h *= if pending.len() * STRAGGLERS < probes.len() {
            4.0
        } else {
            2.0
        };
    }
    // The probes in the order of the doubling schedule's rounds (then in their own order),
    // whatever schedule measured them: the mean of the distances is summed in this order.
    let mut order: Vec<u32> = (0..probes.len() as u32).collect();
    order.sort_by_key(|&i| (done[i as usize].1, i));
    order.into_iter().map(|i| done[i as usize].0).collect()
}

/// The first cell size of [`knn_of`]'s grid for `n` samples in `bbox` (positive extent):
/// `sqrt(A/n)` with `A` the surface area of the box, at least 2⁻¹⁹ of its extent.
fn first_radius(bbox: Aabb, n: usize) -> f32 {
    let size = bbox.size();
    let area = 2.0 * (size.x * size.y + size.y * size.z + size.z * size.x);
    (1.0 * (area / n as f32).sqrt()).max(size.max_element() / (1u32 << 19) as f32)
}

/// The round of the doubling schedule `h_r = h0·2^r` in which a probe whose k-th squared
/// distance is `d` is measured: the first with `d ≤ h_r²` (the order of [`knn_of`]'s output).
fn round_of(h0: f32, d: f32) -> u32 {
    let (mut r, mut hr) = (0u32, h0);
    while d > hr * hr {
        hr *= 2.0;
        r += 1;
    }
    r
}

/// Below one pending probe in this many, [`knn_of`]'s radius quadruples from scan to scan
/// instead of doubling.
const STRAGGLERS: usize = 64;

/// Quantile of the `LEAF_K`-th-neighbour distance that sets the splat spacing of
/// [`SpacingRule::Cover90`].
pub const SPACING_QUANTILE: f64 = 0.9;

/// `c_k = √π · Γ(k) / Γ(k + ½)` for `k = LEAF_K` (= 6): for samples placed uniformly at
/// random on a surface with `λ` samples per unit area, the `k`-th-neighbour distance has
/// mean `Γ(k + ½) / (Γ(k) √(πλ))`, so `c_k · mean d_k = 1/√λ = √(A/N)` exactly.
/// `Γ(6) = 120`, `Γ(6.5) = 10395 √π / 64`, so `c_6 = 120 · 64 / 10395 = 0.73882`.
pub const MEAN_SPACING_FACTOR: f64 = 120.0 * 64.0 / 10395.0;

/// `(r, r_nn)` from the probes' `[nearest, LEAF_K-th]` distances. `r` by `rule`:
/// [`SpacingRule::Mean`] `= MEAN_SPACING_FACTOR × mean d_k` (the paper's average spacing
/// `√(A/N)`), [`SpacingRule::Cover90`] `= 2 ×` the [`SPACING_QUANTILE`] of `d_k` (the splat
/// diameter that covers 90 % of the samples' own reference discs); NaN for [`SpacingRule::Area`],
/// which `build` measures on the samples. `r_nn` = the mean
/// nearest-neighbour distance (quantisation). NaN when there are no probes.
pub fn spacing_estimates(probes: &mut [[f32; 2]], rule: SpacingRule) -> (f32, f32) {
    if probes.is_empty() {
        return (f32::NAN, f32::NAN);
    }
    let mean = |i: usize| probes.iter().map(|p| p[i] as f64).sum::<f64>() / probes.len() as f64;
    let nn = mean(0);
    let r = match rule {
        SpacingRule::Mean => (MEAN_SPACING_FACTOR * mean(1)) as f32,
        SpacingRule::Cover90 => {
            probes.sort_unstable_by(|a, b| a[1].total_cmp(&b[1]));
            let at = ((probes.len() - 1) as f64 * SPACING_QUANTILE).round() as usize;
            2.0 * probes[at][1]
        }
        // Measured on the samples, not the probes (`build`).
        SpacingRule::Area => f32::NAN,
    };
    (r, nn as f32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenes::rng::Pcg32;

    #[test]
    fn probe_knn_matches_brute_force() {
        let mut rng = Pcg32::new(2);
        let s: Vec<Sample> = (0..5000)
            .map(|i| Sample {
                p: [rng.f32() * 4.0, rng.f32(), (rng.f32() * 6.0).sin() * 0.2],
                flags: if i % 97 == 0 { PROBE } else { 0 },
                ..Default::default()
            })
            .collect();
        let bbox = Aabb::from_points(&s.iter().map(|x| x.p).collect::<Vec<_>>());
        let got = probe_knn(&s, bbox, LEAF_K);
        let (sum, sum1) = got
            .iter()
            .fold((0f64, 0f64), |(a, b), d| (a + d[1] as f64, b + d[0] as f64));
        let count = got.len();
        let (mut want, mut want1) = (0f64, 0f64);
        let mut wc = 0;
        for (i, q) in s.iter().enumerate().filter(|(_, x)| x.flags & PROBE != 0) {
            let mut d: Vec<f32> = s
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, x)| (Vec3::from(x.p) - Vec3::from(q.p)).length())
                .collect();
            d.sort_by(f32::total_cmp);
            want += d[LEAF_K - 1] as f64;
            want1 += d[0] as f64;
            wc += 1;
        }
        assert_eq!(count, wc);
        assert!((sum - want).abs() < 1e-4 * want, "{sum} vs {want}");
        assert!((sum1 - want1).abs() < 1e-4 * want1, "{sum1} vs {want1}");
    }

    /// The whole-scene measure ([`column_probe_knn`], a streamed root's) gives exactly the
    /// in-core root's values in the same order, and those are the exact k-NN distances: on
    /// a scene whose density varies 1,000× (most probes measured in the first scans, the
    /// sparse corner's in the straggler scans).
    #[test]
    fn column_probe_knn_is_the_in_core_measure_exactly() {
        let mut rng = Pcg32::new(5);
        let s: Vec<Sample> = (0..30_000)
            .map(|i| {
                let sparse = i % 1000 == 0;
                let (u, v) = (rng.f32(), rng.f32());
                let p = if sparse {
                    [10.0 + u * 30.0, v * 30.0, 0.0]
                } else {
                    [u * 10.0, v * 10.0, (u * 9.0).sin() * 0.1]
                };
                Sample {
                    p,
                    flags: if i % 7 == 0 { PROBE } else { 0 },
                    ..Default::default()
                }
            })
            .collect();
        let pos: Vec<[f32; 3]> = s.iter().map(|x| x.p).collect();
        let bbox = Aabb::from_points(&pos);
        let in_core = probe_knn(&s, bbox, LEAF_K);
        let streamed = column_probe_knn(&pos, |i| i % 7 == 0, bbox, LEAF_K, |_| {});
        assert_eq!(in_core, streamed);
        // Brute force, in the doubling schedule's order: by round, then by index.
        let h0 = first_radius(bbox, s.len());
        let mut want: Vec<(u32, usize, [f32; 2])> = (0..s.len())
            .step_by(7)
            .map(|i| {
                let mut d: Vec<f32> = (0..s.len())
                    .filter(|&j| j != i)
                    .map(|j| (Vec3::from(pos[j]) - Vec3::from(pos[i])).length_squared())
                    .collect();
                d.sort_by(f32::total_cmp);
                let dk = d[LEAF_K - 1];
                (round_of(h0, dk), i, [d[0].sqrt(), dk.sqrt()])
            })
            .collect();
        want.sort_by_key(|w| (w.0, w.1));
        let rounds: std::collections::BTreeSet<u32> = want.iter().map(|w| w.0).collect();
        assert!(
            rounds.len() >= 4,
            "a scene measured in several rounds: {rounds:?}"
        );
        let want: Vec<[f32; 2]> = want.into_iter().map(|w| w.2).collect();
        assert_eq!(streamed, want);
    }

    #[test]
    fn spacing_of_a_single_child_chain() {
        // Root N=10, M=4; child N=6, M=4; grandchild N=2, M=2.
        let r = hierarchical_spacing(1.0, &[NONE, 0, 1], &[10, 6, 2], &[4, 4, 2]);
        let r0 = (10.0f64 / 4.0).sqrt();
        // M1tot = 6/6·4 + 4 = 8; r1 = r0·sqrt(6·4/(6·8)).
        let r1 = r0 * (6.0 * 4.0 / (6.0 * 8.0f64)).sqrt();
        // M2tot = 2/2·8 + 2 = 10; r2 = r1·sqrt(2·8/(2·10)).
        let r2 = r1 * (2.0 * 8.0 / (2.0 * 10.0f64)).sqrt();
        assert_eq!(r, vec![r0, r1, r2]);
    }
}
