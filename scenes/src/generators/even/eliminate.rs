//! One tile's sample elimination (Yuksel 2015) and the pieces it needs: the candidates'
//! local density, the neighbour lists within the elimination reach, and the split of the
//! sample count over tiles.

use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

use glam::Vec3;

/// Exponent of Yuksel's weight function.
const ALPHA: i32 = 8;
/// Neighbour rank whose mean distance gives the candidates' density.
pub(super) const DENSITY_K: usize = 6;
/// `√π · Γ(6) / Γ(6.5)`: `mean d₆ · C6 = 1/√λ` for uniformly random samples of density λ.
pub(super) const C6: f32 = 0.738_795_6;
/// Candidates per tile measured for the density.
pub(super) const DENSITY_PROBES: usize = 2048;

/// `n` split over tiles of `counts` candidates in proportion, by largest remainder (ties by
/// tile order), never more than a tile has.
pub(super) fn allocate(counts: &[u64], n: u64) -> Vec<u64> {
    let total: u64 = counts.iter().sum();
    let mut out: Vec<u64> = Vec::with_capacity(counts.len());
    let mut rem: Vec<(u128, usize)> = Vec::with_capacity(counts.len());
    for (t, &c) in counts.iter().enumerate() {
        let exact = n as u128 * c as u128;
        out.push((exact / total as u128) as u64);
        rem.push((exact % total as u128, t));
    }
    let mut left = n - out.iter().sum::<u64>();
    rem.sort_by(|a, b| b.0.cmp(&a.0).then(a.1.cmp(&b.1)));
    for &(_, t) in &rem {
        if left == 0 {
            break;
        }
        if out[t] < counts[t] {
            out[t] += 1;
            left -= 1;
        }
    }
    out
}

/// Yuksel's elimination of one tile's candidates `pts` down to `keep`: whether each is kept.
pub(super) fn eliminate(pts: &[Vec3], keep: usize) -> Vec<bool> {
    let m = pts.len();
    if keep >= m {
        return vec![true; m];
    }
    if keep == 0 {
        return vec![false; m];
    }
    // Candidates' density in the tile, from a strided probe measured against all of them.
    let stride = m.div_ceil(DENSITY_PROBES).max(1);
    let spacing = local_spacing(pts, stride);
    let c = m as f32 / keep as f32;
    let r_max = if spacing.is_finite() && spacing > 0.0 {
        // λ = 1/spacing²; r_max = √(c / (2√3 λ)).
        spacing * (c / (2.0 * 3f32.sqrt())).sqrt()
    } else {
        0.0
    };
    let reach = 2.0 * r_max;
    let mut neighbours = if reach > 0.0 {
        Neighbours::within(pts, reach)
    } else {
        Neighbours::none(m)
    };
    // Each pair's weight, computed once: the initial sums and the decrements below use the
    // same `f32` values as when each computed it from the distance (the same bytes out).
    for e in &mut neighbours.list {
        e.1 = (1.0 - e.1 / reach).powi(ALPHA);
    }
    let mut weight: Vec<f32> = (0..m)
        .map(|i| neighbours.of(i).iter().map(|&(_, w)| w).sum())
        .collect();
    let mut alive = vec![true; m];
    let mut heap = WeightHeap::new(&weight);
    for _ in keep..m {
        let Some(i) = heap.pop(&weight) else {
            break;
        };
        alive[i] = false;
        for &(j, w) in neighbours.of(i) {
            let j = j as usize;
            if alive[j] {
                weight[j] -= w;
                heap.lowered(j, &weight);
            }
        }
    }
    alive
}

/// A max-heap of candidates by weight (ties: the lower index first) whose entries can be
/// lowered in place: each candidate is in it once, so the elimination pops exactly the
/// candidates it removes (a heap of stale copies pushed per update pops ≈ 10× more).
struct WeightHeap {
    /// Candidates, heap-ordered.
    heap: Vec<u32>,
    /// Where each candidate is in `heap` (`u32::MAX` once popped).
    at: Vec<u32>,
}

impl WeightHeap {
    fn new(weight: &[f32]) -> Self {
        let m = weight.len();
        let mut h = Self {
            heap: (0..m as u32).collect(),
            at: (0..m as u32).collect(),
        };
        for i in (0..m / 2).rev() {
            h.down(i, weight);
        }
        h
    }

    /// Whether `a` is popped before `b`.
    #[inline]
    fn before(weight: &[f32], a: u32, b: u32) -> bool {
        match weight[a as usize].total_cmp(&weight[b as usize]) {
            std::cmp::Ordering::Greater => true,
            std::cmp::Ordering::Less => false,
            std::cmp::Ordering::Equal => a < b,
        }
    }

    fn pop(&mut self, weight: &[f32]) -> Option<usize> {
        let top = *self.heap.first()?;
        let last = self.heap.pop()?;
        self.at[top as usize] = u32::MAX;
        if !self.heap.is_empty() {
            self.heap[0] = last;
            self.at[last as usize] = 0;
            self.down(0, weight);
        }
        Some(top as usize)
    }

    /// Candidate `i`'s weight went down.
    fn lowered(&mut self, i: usize, weight: &[f32]) {
        let k = self.at[i];
        if k != u32::MAX {
            self.down(k as usize, weight);
        }
    }

    fn down(&mut self, mut k: usize, weight: &[f32]) {
        let n = self.heap.len();
        loop {
            let l = 2 * k + 1;
            if l >= n {
                break;
            }
            let r = l + 1;
            let c = if r < n && Self::before(weight, self.heap[r], self.heap[l]) {
                r
            } else {
                l
            };
            if !Self::before(weight, self.heap[c], self.heap[k]) {
                break;
            }
            self.heap.swap(k, c);
            self.at[self.heap[k] as usize] = k as u32;
            self.at[self.heap[c] as usize] = c as u32;
            k = c;
        }
    }
}

/// `1/√λ` of uniformly random samples from their mean 6-th-neighbour distance (NaN when
/// there are too few).
pub(super) fn mean_spacing(points: &[[f32; 3]]) -> f32 {
    if points.len() <= DENSITY_K {
        return f32::NAN;
    }
    let d = crate::spacing::knn_spacing(points, DENSITY_K);
    let mean = d.iter().map(|&x| x as f64).sum::<f64>() / d.len() as f64;
    C6 * mean as f32
}

/// `1/√λ` of a tile's candidates: the mean 6-th-neighbour distance of every `stride`-th
/// candidate, measured against all of them, times [`C6`].
fn local_spacing(pts: &[Vec3], stride: usize) -> f32 {
    if pts.len() <= DENSITY_K {
        return f32::NAN;
    }
    let all: Vec<[f32; 3]> = pts.iter().map(|p| p.to_array()).collect();
    let probes: Vec<[f32; 3]> = all.iter().step_by(stride).copied().collect();
    let index = crate::spacing::KnnIndex::new(&all);
    // The probes are among the indexed points: the nearest (distance 0) is the probe itself.
    let lists = index.query_lists(&probes, DENSITY_K + 1);
    let mut sum = 0.0f64;
    let mut n = 0usize;
    for l in lists.chunks(DENSITY_K + 1) {
        let d2 = l[DENSITY_K];
        if d2.is_finite() {
            sum += (d2 as f64).sqrt();
            n += 1;
        }
    }
    if n == 0 {
        return f32::NAN;
    }
    C6 * (sum / n as f64) as f32
}

/// A multiplicative hash for integer keys (grid cells, tiles): the standard SipHash costs
/// more than the distance tests it serves, and these keys come from our own grid, not from
/// an adversary.
#[derive(Debug, Default, Clone, Copy)]
pub(super) struct KeyHasher(u64);

impl Hasher for KeyHasher {
    fn finish(&self) -> u64 {
        self.0
    }
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(u64::from(b));
        }
    }
    fn write_u64(&mut self, x: u64) {
        self.0 = (self.0.rotate_left(5) ^ x).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    }
}

/// A `HashMap` keyed by grid cells or tiles.
pub(super) type KeyMap<V> = HashMap<u64, V, BuildHasherDefault<KeyHasher>>;

/// Every pair of a tile's candidates closer than a reach, as adjacency lists
/// (index, distance): candidates sorted into grid cells of the reach's size, each cell's
/// 27 neighbours looked up once per cell.
struct Neighbours {
    /// Per candidate: its list's first entry and length.
    span: Vec<(u32, u32)>,
    /// `(neighbour, distance)` as [`Neighbours::within`] finds them; [`eliminate`] turns
    /// each distance into the pair's weight in place.
    list: Vec<(u32, f32)>,
}

impl Neighbours {
    fn none(m: usize) -> Self {
        Self {
            span: vec![(0, 0); m],
            list: Vec::new(),
        }
    }

    fn within(pts: &[Vec3], reach: f32) -> Self {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for p in pts {
            lo = lo.min(*p);
            hi = hi.max(*p);
        }
        let dims = (((hi - lo) / reach).floor().as_uvec3() + 1).as_u64vec3();
        let coord = |p: Vec3| {
            ((p - lo) / reach)
                .floor()
                .as_uvec3()
                .as_u64vec3()
                .min(dims - 1)
        };
        let key = |c: glam::U64Vec3| (c.z * dims.y + c.y) * dims.x + c.x;
        let mut sorted: Vec<(u64, u32)> = pts
            .iter()
            .enumerate()
            .map(|(i, &p)| (key(coord(p)), i as u32))
            .collect();
        sorted.sort_unstable();
        let mut cells: KeyMap<(u32, u32)> = KeyMap::default();
        let mut a = 0;
        while a < sorted.len() {
            let k = sorted[a].0;
            let b = a + sorted[a..].partition_point(|&(kk, _)| kk == k);
            cells.insert(k, (a as u32, b as u32));
            a = b;
        }
        let r2 = reach * reach;
        let mut span = vec![(0u32, 0u32); pts.len()];
        let mut list = Vec::new();
        let mut near: Vec<(u32, u32)> = Vec::with_capacity(27);
        let mut a = 0;
        while a < sorted.len() {
            let k = sorted[a].0;
            let b = a + sorted[a..].partition_point(|&(kk, _)| kk == k);
            let c = coord(pts[sorted[a].1 as usize]).as_i64vec3();
            near.clear();
            for dz in -1..=1 {
                for dy in -1..=1 {
                    for dx in -1..=1 {
                        let q = c + glam::I64Vec3::new(dx, dy, dz);
                        if q.min_element() < 0 || q.cmpge(dims.as_i64vec3()).any() {
                            continue;
                        }
                        if let Some(&r) = cells.get(&key(q.as_u64vec3())) {
                            near.push(r);
                        }
                    }
                }
            }
            for &(_, i) in &sorted[a..b] {
                let p = pts[i as usize];
                let first = list.len();
                for &(s, e) in &near {
                    for &(_, j) in &sorted[s as usize..e as usize] {
                        if j == i {
                            continue;
                        }
                        let d2 = p.distance_squared(pts[j as usize]);
                        if d2 < r2 {
                            list.push((j, d2.sqrt()));
                        }
                    }
                }
                span[i as usize] = (first as u32, (list.len() - first) as u32);
            }
            a = b;
        }
        Self { span, list }
    }

    fn of(&self, i: usize) -> &[(u32, f32)] {
        let (s, l) = self.span[i];
        &self.list[s as usize..(s + l) as usize]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn allocation_is_exact_and_proportional() {
        let counts = [10, 0, 7, 3, 100];
        for n in [0, 1, 5, 17, 60, 120] {
            let a = allocate(&counts, n);
            assert_eq!(a.iter().sum::<u64>(), n, "n = {n}");
            let total: u64 = counts.iter().sum();
            for (t, &c) in counts.iter().enumerate() {
                let share = n as f64 * c as f64 / total as f64;
                assert!(
                    (a[t] as f64 - share).abs() < 1.0,
                    "tile {t}: {} vs {share}",
                    a[t]
                );
                assert!(a[t] <= c);
            }
        }
    }

    #[test]
    fn weight_heap_pops_the_heaviest_first_after_lowering() {
        let mut w = vec![3.0f32, 5.0, 5.0, 1.0, 4.0, 2.0];
        let mut h = WeightHeap::new(&w);
        assert_eq!(h.pop(&w), Some(1), "ties by lower index");
        w[2] = 0.5;
        h.lowered(2, &w);
        w[1] = -9.0; // popped: lowering it is ignored
        h.lowered(1, &w);
        let mut rest = Vec::new();
        while let Some(i) = h.pop(&w) {
            rest.push(i);
        }
        assert_eq!(rest, vec![4, 0, 5, 3, 2]);
    }

    #[test]
    fn neighbour_lists_hold_exactly_the_pairs_within_reach() {
        let mut rng = crate::rng::Pcg32::new(9);
        let pts: Vec<Vec3> = (0..600)
            .map(|_| Vec3::new(rng.f32(), rng.f32(), 0.3 * rng.f32()))
            .collect();
        let reach = 0.07;
        let nb = Neighbours::within(&pts, reach);
        for (i, p) in pts.iter().enumerate() {
            let mut got: Vec<u32> = nb.of(i).iter().map(|&(j, _)| j).collect();
            got.sort_unstable();
            let want: Vec<u32> = (0..pts.len() as u32)
                .filter(|&j| j as usize != i && p.distance_squared(pts[j as usize]) < reach * reach)
                .collect();
            assert_eq!(got, want, "candidate {i}");
        }
    }
}
