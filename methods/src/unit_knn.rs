//! Leaf radii ([`crate::leaf`]) of a cloud split into units that are loaded one at a time:
//! the same values, bit for bit, as [`crate::leaf::leaf_radii`] over the whole cloud, in
//! memory bounded by the largest unit.
//!
//! Three passes over the units, with spill files between them:
//! 1. **Own.** Each unit's points are indexed ([`KnnIndex`]) and every point gets its `k`
//!    smallest squared distances within the unit. A point's true k nearest are all within
//!    its own k-th distance `r`, so only units whose bounding box lies within `r` of it can
//!    hold a nearer one: those units (found through a small tree over the units' boxes) are
//!    sent a query, and the point's own list is kept.
//! 2. **Others.** Each unit answers the queries sent to it with its own `k` smallest
//!    squared distances to the query point, sent back to the query's unit. Only the unit's
//!    points within `R` of the queries' bounding box are indexed, `R` the largest query's
//!    own k-th distance (generous by a relative 1e-5): a point farther from a query than
//!    that query's own k-th distance `r` cannot change the k-th smallest of the merged list,
//!    whose own part already holds `k` values ≤ `r`. Indexing the whole unit again had
//!    been most of this pass.
//! 3. **Merge.** Each point's k-th smallest over its own list and the answers is its k-NN
//!    distance: the union holds every one of its true k nearest, and every distance in it is
//!    a distance to another point, computed with the same `f32` arithmetic as in memory.
//!
//! **Groups.** The passes run over *groups* of consecutive units, as many as fit
//! [`KNN_BYTES_PER_SAMPLE`] per sample in the build's working memory: the k-NN needs far
//! less per sample than a method's unit build (QSplat 256, SPT 256 bytes), so its groups are
//! larger than the units, and fewer group borders mean fewer queries to other groups and
//! less spill traffic. Groups change nothing in the radii (each is exact); each unit's radii
//! are written to a file of its own, as before.
//!
//! The degenerate-distance fallback (smallest positive distance of the cloud) and the cap
//! on isolated samples (a quantile over the samples `0, s, 2s, …` by input index) need the
//! whole cloud's distances: they are gathered in pass 3 and applied when a unit's radii are
//! loaded ([`UnitRadii::load`]).

use std::ops::Range;

use glam::{DVec3, Vec3};
use scenes::spacing::{KnnIndex, fallback_spacing, is_degenerate};
use scenes::{Aabb, Progress};

use crate::MethodError;
use crate::leaf::{LEAF_K, isolation_cap, quantile_stride};
use crate::overlap::overlapped_with;
use crate::spill::samples::{f32_at, f32s, u32_at};
use crate::spill::{Spill, SpillDir, SpillWriter};

/// Bytes of a query record: home unit, position in it, the point, its own k-th squared
/// distance.
const QUERY_BYTES: usize = 24;

/// Bytes per block of the query and answer spill files (one writer per unit is open at a
/// time during passes 1 and 2, so these are small).
const SMALL_BLOCK: usize = 1 << 16;

/// Working bytes per sample of a k-NN group: while one group is searched (its indices and
/// positions 16, the index 16 over the 16-byte items of its build, the lists in tree and in
/// input order 2 · 4k) the group searched before it is being written (indices, positions and
/// lists, 16 + 4k): ≈ 120 for k = 6, rounded up.
pub const KNN_BYTES_PER_SAMPLE: u64 = 128;

/// A unit as pass 1 needs it: its sample count and the bounding box of its positions.
#[derive(Debug, Clone, Copy)]
pub struct UnitBox {
    /// Samples.
    pub n: u64,
    /// Bounding box of its positions.
    pub bbox: (Vec3, Vec3),
}

/// Loads unit `u`'s sample indices and positions, in the unit's order.
pub type LoadPositions<'a> = &'a dyn Fn(usize) -> Result<(Vec<u32>, Vec<[f32; 3]>), MethodError>;

/// Every unit's k-NN radii, before the fallback and the cap.
pub struct UnitRadii {
    files: Vec<Spill>,
    /// The spacing given to degenerate distances.
    pub fallback: f32,
    /// The cap on isolated samples' radii.
    pub cap: f32,
    /// Queries sent to other groups in pass 1 (a sample near two other groups sends two).
    pub queries: u64,
}

impl UnitRadii {
    /// Unit `u`'s leaf radii, in the unit's order, and how many were capped.
    pub fn load(&self, u: usize) -> Result<(Vec<f32>, u64), MethodError> {
        let mut r = Vec::with_capacity(self.files[u].records as usize);
        let mut capped = 0;
        self.files[u].read(|b| {
            for v in b.chunks_exact(4) {
                let mut d = f32::from_le_bytes([v[0], v[1], v[2], v[3]]);
                if is_degenerate(d) {
                    d = self.fallback;
                }
                if d > self.cap {
                    d = self.cap;
                    capped += 1;
                }
                r.push(d);
            }
            Ok(())
        })?;
        Ok((r, capped))
    }
}

/// A tree over the units' boxes, to find the groups that hold a unit near a point. The
/// units' own boxes, not the groups': a group's units need not be neighbours, and its box
/// can then span space that other groups fill, so that the points there would query it and
/// search it for neighbours far away (the 50 M QSplat build's "others" took 555 s when
/// queries went by the groups' boxes).
struct BoxTree {
    /// Per node: its box and either two children or one unit.
    nodes: Vec<((DVec3, DVec3), BoxKid)>,
    /// Each unit's group.
    group_of: Vec<usize>,
}

#[derive(Clone, Copy)]
enum BoxKid {
    Inner(usize, usize),
    Unit(usize),
}

impl BoxTree {
    fn new(units: &[UnitBox], groups: &[Range<usize>]) -> Self {
        let mut group_of = vec![0; units.len()];
        for (g, r) in groups.iter().enumerate() {
            group_of[r.clone()].fill(g);
        }
        let mut t = Self {
            nodes: Vec::new(),
            group_of,
        };
        let mut ids: Vec<usize> = (0..units.len()).collect();
        if !ids.is_empty() {
            t.add(units, &mut ids);
        }
        t
    }

    fn add(&mut self, units: &[UnitBox], ids: &mut [usize]) -> usize {
        let b = |u: usize| (units[u].bbox.0.as_dvec3(), units[u].bbox.1.as_dvec3());
        let mut lo = DVec3::INFINITY;
        let mut hi = DVec3::NEG_INFINITY;
        for &u in ids.iter() {
            lo = lo.min(b(u).0);
            hi = hi.max(b(u).1);
        }
        let me = self.nodes.len();
        if ids.len() == 1 {
            self.nodes.push(((lo, hi), BoxKid::Unit(ids[0])));
            return me;
        }
        self.nodes.push(((lo, hi), BoxKid::Unit(usize::MAX)));
        let axis = (hi - lo).max_position();
        let centre = |u: usize| (b(u).0[axis] + b(u).1[axis]) * 0.5;
        let mid = ids.len() / 2;
        ids.select_nth_unstable_by(mid, |&a, &b| {
            centre(a).total_cmp(&centre(b)).then(a.cmp(&b))
        });
        let (l, r) = ids.split_at_mut(mid);
        let a = self.add(units, l);
        let c = self.add(units, r);
        self.nodes[me].1 = BoxKid::Inner(a, c);
        me
    }

    /// Groups other than `home` with a unit whose box may hold a point within squared
    /// distance `r2` of `p` (generous by a relative 1e-5 for the `f32` rounding of `r2`),
    /// into `out`, ascending; `stack` is scratch space (called once per sample).
    fn near(
        &self,
        p: [f32; 3],
        r2: f32,
        home: usize,
        out: &mut Vec<usize>,
        stack: &mut Vec<usize>,
    ) {
        out.clear();
        if self.nodes.is_empty() {
            return;
        }
        let p = Vec3::from(p).as_dvec3();
        let reach = r2 as f64 * (1.0 + 1e-5);
        stack.clear();
        stack.push(0);
        while let Some(i) = stack.pop() {
            let ((lo, hi), kid) = self.nodes[i];
            let gap = (lo - p).max(p - hi).max(DVec3::ZERO);
            if gap.length_squared() > reach {
                continue;
            }
            match kid {
                BoxKid::Inner(a, b) => stack.extend([a, b]),
                BoxKid::Unit(u) if self.group_of[u] != home => out.push(self.group_of[u]),
                BoxKid::Unit(_) => {}
            }
        }
        out.sort_unstable();
        out.dedup();
    }
}

/// Lazily opened writers, one per unit.
struct Writers<'a> {
    dir: &'a SpillDir,
    stem: &'static str,
    record: usize,
    open: Vec<Option<SpillWriter>>,
}

impl<'a> Writers<'a> {
    fn new(dir: &'a SpillDir, stem: &'static str, record: usize, units: usize) -> Self {
        Self {
            dir,
            stem,
            record,
            open: (0..units).map(|_| None).collect(),
        }
    }
    fn get(&mut self, u: usize) -> Result<&mut SpillWriter, MethodError> {
        if self.open[u].is_none() {
            self.open[u] = Some(
                self.dir
                    .writer_with_block(self.stem, self.record, SMALL_BLOCK)?,
            );
        }
        Ok(self.open[u].as_mut().expect("just opened"))
    }
    fn finish(self) -> Result<Vec<Option<Spill>>, MethodError> {
        self.open
            .into_iter()
            .map(|w| w.map(SpillWriter::finish).transpose())
            .collect()
    }
}

/// A unit searched in pass 1 of [`unit_radii`]: its sample indices, positions and the
/// `k` smallest squared distances of each within the unit.
struct Searched {
    u: usize,
    idx: Vec<u32>,
    pos: Vec<[f32; 3]>,
    lists: Vec<f32>,
}

/// What pass 1 of [`unit_radii`] writes: the queries to other units, each unit's raw
/// radii and own lists (of the samples that sent queries), and the strided samples of the
/// cap's quantile as (unit, position in unit).
struct Pass1<'a> {
    queries: Writers<'a>,
    /// Query records written.
    sent: u64,
    raw: Vec<Spill>,
    own: Vec<Spill>,
    strided: Vec<(u32, u32)>,
}

impl Pass1<'_> {
    /// Writes a searched unit's records, in the unit's order.
    fn write(
        &mut self,
        s: Searched,
        k: usize,
        stride: usize,
        boxes: &BoxTree,
        dir: &SpillDir,
    ) -> Result<(), MethodError> {
        let list_bytes = 4 + 4 * k;
        let u = s.u;
        let (mut near, mut stack) = (Vec::new(), Vec::new());
        let mut r = dir.writer("knn-raw", 4)?;
        let mut o = dir.writer_with_block("knn-own", list_bytes, SMALL_BLOCK)?;
        let mut rec = Vec::with_capacity(list_bytes.max(QUERY_BYTES));
        for (i, (p, l)) in s.pos.iter().zip(s.lists.chunks_exact(k)).enumerate() {
            r.push(&l[k - 1].sqrt().to_le_bytes())?;
            if (s.idx[i] as usize).is_multiple_of(stride) {
                self.strided.push((u as u32, i as u32));
            }
            boxes.near(*p, l[k - 1], u, &mut near, &mut stack);
            if near.is_empty() {
                continue;
            }
            rec.clear();
            rec.extend_from_slice(&(i as u32).to_le_bytes());
            l.iter()
                .for_each(|d| rec.extend_from_slice(&d.to_le_bytes()));
            o.push(&rec)?;
            rec.clear();
            rec.extend_from_slice(&(u as u32).to_le_bytes());
            rec.extend_from_slice(&(i as u32).to_le_bytes());
            p.iter()
                .for_each(|c| rec.extend_from_slice(&c.to_le_bytes()));
            rec.extend_from_slice(&l[k - 1].to_le_bytes());
            for &v in &near {
                self.queries.get(v)?.push(&rec)?;
            }
            self.sent += near.len() as u64;
        }
        self.raw.push(r.finish()?);
        self.own.push(o.finish()?);
        Ok(())
    }
}

/// Consecutive units grouped greedily, each group at most `cap` samples (a larger unit is
/// a group of its own).
fn group_units(units: &[UnitBox], cap: u64) -> Vec<Range<usize>> {
    let mut groups: Vec<Range<usize>> = Vec::new();
    let mut n = 0u64;
    for (u, unit) in units.iter().enumerate() {
        match groups.last_mut() {
            Some(g) if n + unit.n <= cap => {
                g.end = u + 1;
                n += unit.n;
            }
            _ => {
                groups.push(u..u + 1);
                n = unit.n;
            }
        }
    }
    groups
}

/// The leaf radii of a cloud of `total` samples (bounds `bounds`) held as `units`, whose
/// positions `load` reads, searched in groups of units within `mem_bytes` (see the module
/// docs); spill files go in `dir`. Each pass is a `progress` phase of its own, named after
/// `method` ("qsplat: leaf radii 1/3, own", …).
#[allow(clippy::too_many_arguments)]
pub fn unit_radii(
    units: &[UnitBox],
    load: LoadPositions<'_>,
    total: usize,
    bounds: Aabb,
    mem_bytes: u64,
    dir: &SpillDir,
    method: &str,
    progress: &dyn Progress,
) -> Result<UnitRadii, MethodError> {
    let groups = group_units(units, (mem_bytes / KNN_BYTES_PER_SAMPLE).max(1));
    // The groups as the passes' "units": their sample counts (queries go by the units' own
    // boxes, `BoxTree`).
    let group_sizes: Vec<u64> = groups
        .iter()
        .map(|g| units[g.clone()].iter().map(|u| u.n).sum())
        .collect();
    // A group's samples: its units' in order.
    let load_group = |g: usize| -> Result<(Vec<u32>, Vec<[f32; 3]>), MethodError> {
        let mut all = (Vec::new(), Vec::new());
        for u in groups[g].clone() {
            let (idx, pos) = load(u)?;
            if idx.len() as u64 != units[u].n {
                return Err(MethodError::Bug(format!(
                    "leaf radii: unit {u} loaded {} samples, {} expected",
                    idx.len(),
                    units[u].n
                )));
            }
            if groups[g].len() == 1 {
                return Ok((idx, pos));
            }
            all.0.extend_from_slice(&idx);
            all.1.extend_from_slice(&pos);
        }
        Ok(all)
    };
    let unit_sizes: Vec<Vec<u64>> = groups
        .iter()
        .map(|g| units[g.clone()].iter().map(|u| u.n).collect())
        .collect();
    let phase = |i: usize, what: &str| {
        progress.finish();
        progress.start(&format!("{method}: leaf radii {i}/3, {what}"), total as u64);
    };
    let k = LEAF_K.clamp(1, total.saturating_sub(1).max(1));
    let passes = Passes {
        units: &group_sizes,
        unit_sizes: &unit_sizes,
        load: &load_group,
        dir,
        progress,
        k,
        list_bytes: 4 + 4 * k,
    };
    let boxes = BoxTree::new(units, &groups);
    let stride = quantile_stride(total);

    phase(1, "own");
    let Pass1 {
        queries,
        sent,
        raw,
        own,
        strided,
    } = passes.own_lists(&boxes, stride)?;
    let queries = queries.finish()?;

    phase(2, "others");
    let answers = passes.answer_queries(queries)?;

    phase(3, "merge");
    let Merged {
        files,
        smallest,
        mut sample,
    } = passes.merge(raw, own, answers, &strided)?;
    let fallback = fallback_spacing(smallest, || bounds, total);
    for d in &mut sample {
        if is_degenerate(*d) {
            *d = fallback;
        }
    }
    let cap = if total >= 2 && !sample.is_empty() {
        isolation_cap(sample)
    } else {
        f32::INFINITY
    };
    progress.finish();
    Ok(UnitRadii {
        files,
        fallback,
        cap,
        queries: sent,
    })
}

/// What the three passes of [`unit_radii`] share. Their "units" are the groups of the
/// module docs, given by their sample counts; `unit_sizes` are the sizes of each group's
/// units.
struct Passes<'a> {
    units: &'a [u64],
    unit_sizes: &'a [Vec<u64>],
    load: LoadPositions<'a>,
    dir: &'a SpillDir,
    progress: &'a dyn Progress,
    /// Neighbours per list.
    k: usize,
    /// Bytes of an own-list or answer record: position in the unit, `k` squared distances.
    list_bytes: usize,
}

/// What pass 3 of [`unit_radii`] gives: each unit's radii file (of every group, its units'
/// in order), the smallest positive radius and the strided sample of the radii (before the
/// fallback).
struct Merged {
    files: Vec<Spill>,
    smallest: f32,
    sample: Vec<f32>,
}

impl<'a> Passes<'a> {
    /// Pass 1: own lists, queries to other units. This thread loads units and searches them
    /// (in parallel); a second thread writes each searched unit's spill records, which is
    /// serial, while the next unit is searched. At most two units are held: the one written
    /// and the one searched, which waits to be handed over (`overlapped_with`, nothing
    /// waiting between them).
    fn own_lists(&self, boxes: &BoxTree, stride: usize) -> Result<Pass1<'a>, MethodError> {
        let (units, load, dir, progress, k) =
            (self.units, self.load, self.dir, self.progress, self.k);
        let pass1 = Pass1 {
            queries: Writers::new(dir, "knn-query", QUERY_BYTES, units.len()),
            raw: Vec::with_capacity(units.len()),
            own: Vec::with_capacity(units.len()),
            strided: Vec::new(),
            sent: 0,
        };
        overlapped_with(
            pass1,
            1,
            0,
            |state, searched: Vec<Searched>| {
                for unit in searched {
                    state.write(unit, k, stride, boxes, dir)?;
                }
                Ok(())
            },
            |feed| {
                for (u, &n) in units.iter().enumerate() {
                    // The loader checks each unit's count.
                    let (idx, pos) = load(u)?;
                    let lists = KnnIndex::new(&pos).self_lists(k);
                    feed.push(Searched { u, idx, pos, lists })?;
                    progress.inc(n);
                }
                Ok(())
            },
        )
    }

    /// Pass 2: answers. Each unit answers the queries sent to it (removing their file);
    /// returns the answers to each unit.
    fn answer_queries(
        &self,
        queries: Vec<Option<Spill>>,
    ) -> Result<Vec<Option<Spill>>, MethodError> {
        let units = self.units;
        let mut answers = Writers::new(self.dir, "knn-answer", self.list_bytes, units.len());
        let mut rec = Vec::with_capacity(self.list_bytes);
        for (v, q) in queries.into_iter().enumerate() {
            if let Some(q) = q {
                self.answer_unit(v, &q, &mut answers, &mut rec)?;
                q.remove();
            }
            self.progress.inc(units[v]);
        }
        answers.finish()
    }

    /// Unit `v` answers the queries `q` sent to it: their `k` nearest among its samples,
    /// written to `answers` of each query's home unit (`rec`: a record buffer).
    fn answer_unit(
        &self,
        v: usize,
        q: &Spill,
        answers: &mut Writers<'_>,
        rec: &mut Vec<u8>,
    ) -> Result<(), MethodError> {
        let (units, k) = (self.units, self.k);
        // Only unit `v`'s points within the largest query reach of the queries' box
        // can answer (see the module docs): the index holds those.
        let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
        let mut reach2 = 0.0f32;
        q.read(|b| {
            for r in b.chunks_exact(QUERY_BYTES) {
                let p = Vec3::new(f32_at(r, 8), f32_at(r, 12), f32_at(r, 16)).as_dvec3();
                (lo, hi) = (lo.min(p), hi.max(p));
                reach2 = reach2.max(f32_at(r, 20));
            }
            Ok(())
        })?;
        let reach = (reach2 as f64).sqrt() * (1.0 + 1e-5);
        let (lo, hi) = (lo - reach, hi + reach);
        let (_, mut pos) = (self.load)(v)?;
        pos.retain(|p| {
            let p = Vec3::from(*p).as_dvec3();
            p.cmpge(lo).all() && p.cmple(hi).all()
        });
        let index = KnnIndex::new(&pos);
        drop(pos);
        let mut homes: Vec<(u32, u32)> = Vec::new();
        let mut qpos: Vec<[f32; 3]> = Vec::new();
        q.read(|b| {
            homes.clear();
            qpos.clear();
            for r in b.chunks_exact(QUERY_BYTES) {
                let home = u32_at(r, 0);
                if home as usize >= units.len() || home as usize == v {
                    return Err(MethodError::corrupt(
                        &q.path,
                        format!("temporary file: query from unit {home}"),
                    ));
                }
                homes.push((home, u32_at(r, 4)));
                qpos.push([f32_at(r, 8), f32_at(r, 12), f32_at(r, 16)]);
            }
            let lists = index.query_lists(&qpos, k);
            for (&(home, i), l) in homes.iter().zip(lists.chunks_exact(k)) {
                rec.clear();
                rec.extend_from_slice(&i.to_le_bytes());
                l.iter()
                    .for_each(|d| rec.extend_from_slice(&d.to_le_bytes()));
                answers.get(home as usize)?.push(rec)?;
            }
            Ok(())
        })
    }

    /// Pass 3: merge; the smallest positive distance and the strided sample. Writes each
    /// unit's radii file and removes the files of passes 1 and 2.
    fn merge(
        &self,
        raw: Vec<Spill>,
        own: Vec<Spill>,
        answers: Vec<Option<Spill>>,
        strided: &[(u32, u32)],
    ) -> Result<Merged, MethodError> {
        let units = self.units;
        let mut files = Vec::with_capacity(units.len());
        let mut smallest = f32::INFINITY;
        let mut sample: Vec<f32> = Vec::with_capacity(strided.len());
        let mut next_strided = 0usize;
        for (u, ((raw, own), answers)) in raw.into_iter().zip(own).zip(answers).enumerate() {
            let r = self.merge_unit(u, &raw, &own, answers)?;
            smallest = r
                .iter()
                .copied()
                .filter(|&d| !is_degenerate(d))
                .fold(smallest, f32::min);
            while let Some(&(su, si)) = strided.get(next_strided)
                && su as usize == u
            {
                sample.push(r[si as usize]);
                next_strided += 1;
            }
            let mut rest = r.as_slice();
            for &n in &self.unit_sizes[u] {
                let (mine, tail) = rest.split_at(n as usize);
                rest = tail;
                let mut w = self.dir.writer("knn-radii", 4)?;
                for d in mine {
                    w.push(&d.to_le_bytes())?;
                }
                files.push(w.finish()?);
            }
            raw.remove();
            own.remove();
            self.progress.inc(units[u]);
        }
        Ok(Merged {
            files,
            smallest,
            sample,
        })
    }

    /// Unit `u`'s radii: its raw radii, with those of the samples that sent queries taken
    /// from their own lists merged with the `answers` (whose file is removed).
    fn merge_unit(
        &self,
        u: usize,
        raw: &Spill,
        own: &Spill,
        answers: Option<Spill>,
    ) -> Result<Vec<f32>, MethodError> {
        let (k, list_bytes) = (self.k, self.list_bytes);
        let mut r: Vec<f32> = Vec::with_capacity(self.units[u] as usize);
        raw.read(|b| {
            r.extend(f32s(b));
            Ok(())
        })?;
        let mut locals: Vec<u32> = Vec::new();
        let mut lists: Vec<f32> = Vec::new();
        own.read(|b| {
            for rec in b.chunks_exact(list_bytes) {
                locals.push(u32_at(rec, 0));
                lists.extend(f32s(&rec[4..]));
            }
            Ok(())
        })?;
        if let Some(a) = &answers {
            let mut merged = Vec::with_capacity(2 * k);
            a.read(|b| {
                for rec in b.chunks_exact(list_bytes) {
                    let i = u32_at(rec, 0);
                    let at = locals.binary_search(&i).map_err(|_| {
                        MethodError::corrupt(
                            &a.path,
                            format!("temporary file: an answer for sample {i}, which asked none"),
                        )
                    })?;
                    let mine = &mut lists[at * k..at * k + k];
                    merged.clear();
                    merged.extend_from_slice(mine);
                    merged.extend(f32s(&rec[4..]));
                    merged.sort_unstable_by(f32::total_cmp);
                    mine.copy_from_slice(&merged[..k]);
                }
                Ok(())
            })?;
        }
        if let Some(a) = answers {
            a.remove();
        }
        for (&i, l) in locals.iter().zip(lists.chunks_exact(k)) {
            r[i as usize] = l[k - 1].sqrt();
        }
        Ok(r)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use scenes::PointCloud;
    use scenes::progress::NoProgress;

    /// The box of `points`, as a unit of them.
    fn unit_of(points: &[[f32; 3]]) -> UnitBox {
        UnitBox {
            n: points.len() as u64,
            bbox: points
                .iter()
                .fold((Vec3::INFINITY, Vec3::NEG_INFINITY), |b, p| {
                    (b.0.min(Vec3::from(*p)), b.1.max(Vec3::from(*p)))
                }),
        }
    }

    /// [`unit_radii`] of `units` (of `pos`, loaded by `load`) within `mem`: the queries
    /// sent, every radius in unit order (each unit's count checked) and the capped count.
    fn radii_in(
        units: &[UnitBox],
        load: LoadPositions<'_>,
        pos: &[[f32; 3]],
        mem: u64,
    ) -> (u64, Vec<f32>, u64) {
        let cloud =
            PointCloud::new(glam::DVec3::ZERO, pos.to_vec().into(), None, None, None).unwrap();
        let tmp = tempfile::tempdir().unwrap();
        let dir = SpillDir::create(tmp.path(), "knn").unwrap();
        let radii = unit_radii(
            units,
            load,
            pos.len(),
            cloud.bounds(),
            mem,
            &dir,
            "test",
            &NoProgress,
        )
        .unwrap();
        let (mut all, mut capped) = (Vec::new(), 0);
        for (u, unit) in units.iter().enumerate() {
            let (r, c) = radii.load(u).unwrap();
            assert_eq!(r.len() as u64, unit.n, "unit {u}");
            all.extend(r);
            capped += c;
        }
        (radii.queries, all, capped)
    }

    #[test]
    fn units_group_greedily_in_order_within_the_cap() {
        let boxes = |ns: &[u64]| -> Vec<UnitBox> {
            ns.iter()
                .map(|&n| UnitBox {
                    n,
                    bbox: (Vec3::ZERO, Vec3::ONE),
                })
                .collect()
        };
        let u = boxes(&[3, 4, 2, 9, 1, 1]);
        assert_eq!(group_units(&u, 1), vec![0..1, 1..2, 2..3, 3..4, 4..5, 5..6]);
        assert_eq!(group_units(&u, 7), vec![0..2, 2..3, 3..4, 4..6]);
        assert_eq!(group_units(&u, 9), vec![0..3, 3..4, 4..6]);
        assert_eq!(group_units(&u, 100), vec![0..6]);
        assert!(group_units(&[], 5).is_empty());
    }

    /// Grouping never sends more queries than one group per unit, even when a group's units
    /// are not neighbours: four strips of a plane in the order 0, 2, 1, 3, grouped two by
    /// two, give groups whose boxes each span the whole plane; routed by those boxes every
    /// sample would query the other group (the 555 s of the module's `BoxTree` docs).
    #[test]
    fn groups_of_distant_units_send_no_more_queries_than_units() {
        let mut r = scenes::rng::Pcg32::new(8);
        let strip = |s: usize, r: &mut scenes::rng::Pcg32| -> Vec<[f32; 3]> {
            (0..400)
                .map(|_| [s as f32 + r.f32(), r.f32(), 0.0])
                .collect()
        };
        let strips: Vec<Vec<[f32; 3]>> = [0, 2, 1, 3].iter().map(|&s| strip(s, &mut r)).collect();
        let pos: Vec<[f32; 3]> = strips.concat();
        let units: Vec<UnitBox> = strips.iter().map(|s| unit_of(s)).collect();
        let load = |u: usize| -> Result<(Vec<u32>, Vec<[f32; 3]>), MethodError> {
            let first = 400 * u as u32;
            Ok(((first..first + 400).collect(), strips[u].clone()))
        };
        let (per_unit, want, _) = radii_in(&units, &load, &pos, 1);
        let (paired, got, _) = radii_in(&units, &load, &pos, 800 * KNN_BYTES_PER_SAMPLE);
        assert_eq!(got, want);
        assert!(per_unit > 0, "strips that touch send queries");
        assert!(
            paired <= per_unit,
            "{paired} queries by groups, {per_unit} by units"
        );
    }

    /// The radii do not depend on how the units are grouped: one unit per group, a few, or
    /// all in one give the in-memory radii (fallback and cap included), unit by unit.
    #[test]
    fn every_grouping_gives_the_in_memory_radii() {
        let mut r = scenes::rng::Pcg32::new(4);
        let mut pos: Vec<[f32; 3]> = (0..1500)
            .map(|i| {
                let s = [1.0, 0.05][i % 2];
                [r.f32() * s, r.f32() * s, r.f32() * 0.01]
            })
            .collect();
        // Duplicates (zero distances: the fallback) and a far sample (the cap).
        pos.extend_from_within(..12);
        pos.push([40.0, 40.0, 0.0]);
        let cloud =
            PointCloud::new(glam::DVec3::ZERO, pos.clone().into(), None, None, None).unwrap();
        let want = crate::leaf::leaf_radii(&cloud);
        assert!(want.capped >= 1, "the cap is exercised");
        let cuts = [0, 300, 550, 950, 1000, pos.len()];
        let units: Vec<UnitBox> = cuts.windows(2).map(|w| unit_of(&pos[w[0]..w[1]])).collect();
        let load = |u: usize| -> Result<(Vec<u32>, Vec<[f32; 3]>), MethodError> {
            let range = cuts[u]..cuts[u + 1];
            Ok((
                range.clone().map(|i| i as u32).collect(),
                pos[range].to_vec(),
            ))
        };
        for mem in [1, 700 * KNN_BYTES_PER_SAMPLE, u64::MAX / 2] {
            let (_, got, capped) = radii_in(&units, &load, &pos, mem);
            assert_eq!(got, *want.radii, "mem {mem}");
            assert_eq!(capped, want.capped, "mem {mem}");
        }
    }
}
