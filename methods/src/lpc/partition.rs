//! Phase 1 of the LPC build: the recursive partitioning of [`super::build`]'s module docs —
//! nodes, their Russian-roulette clouds, the in-core (parallel) and streamed (temporary
//! file) paths, which give the same tree.

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use scenes::rng::{Pcg32, splitmix64};
use scenes::{Aabb, PointCloud, Progress};

use super::build::{
    BLOCK, CONE_MARGIN, CONVERT_CHUNK, IN_CORE_BYTES_PER_SAMPLE, IO_BUF, PROBE, PROBES,
    RECORD_BYTES,
};
use super::cloud::{self, Sample};
use super::index::NONE;
use super::spacing::probe_knn;
use crate::MethodError;
use crate::leaf::LEAF_K;

/// Deletes the temporary files on drop (also on error).
pub(super) struct Temps(pub(super) Vec<PathBuf>);

impl Drop for Temps {
    fn drop(&mut self) {
        for p in &self.0 {
            let _ = std::fs::remove_file(p);
        }
    }
}

/// A node of phase 1 (index = processing order).
#[derive(Debug, Clone, Copy)]
pub(super) struct PNode {
    pub(super) parent: u32,
    pub(super) children: [u32; 2],
    pub(super) level: u32,
    pub(super) n: u64,
    pub(super) m: u32,
    pub(super) cloud_off: u64,
    pub(super) center: Vec3,
    pub(super) radius: f32,
    pub(super) axis: Vec3,
    pub(super) half: f32,
}

/// A node waiting to be partitioned.
#[derive(Debug, Clone, Copy)]
pub(super) struct Task {
    pub(super) id: u32,
    pub(super) key: u64,
    pub(super) n: u64,
    pub(super) bbox: Aabb,
    pub(super) nsum: DVec3,
}

/// Samples, box and normal sum gathered for a child during its parent's scan.
#[derive(Debug, Clone, Copy)]
pub(super) struct Acc {
    pub(super) n: u64,
    pub(super) bbox: Aabb,
    pub(super) nsum: DVec3,
}

impl Acc {
    const EMPTY: Acc = Acc {
        n: 0,
        bbox: Aabb::EMPTY,
        nsum: DVec3::ZERO,
    };
    /// Adds `s`, whose decoded normal is `d` (ignored without normals).
    #[inline]
    pub(super) fn add(&mut self, s: &Sample, d: [f32; 3], normals: bool) {
        self.n += 1;
        self.bbox = self.bbox.grow(Vec3::from(s.p));
        if normals {
            self.nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
        }
    }
}

/// The constants of phase 1's scans, shared by the workers.
#[derive(Debug, Clone, Copy)]
pub(super) struct Cfg {
    pub(super) m: usize,
    pub(super) k: f32,
    pub(super) seed: u64,
    pub(super) normals: bool,
}

impl Cfg {
    pub(super) fn scan_for(&self, task: &Task, spare: &mut (Vec<Sample>, Vec<Sample>)) -> Scan {
        let m = self.m;
        let p = self.k as f64 * m as f64 / task.n as f64;
        let axis = task.bbox.longest_axis();
        let naxis = if self.normals {
            let l = task.nsum.length();
            if l > 0.0 {
                (task.nsum / l).as_vec3()
            } else {
                Vec3::Z
            }
        } else {
            Vec3::ZERO
        };
        let (mut res, mut hold) = std::mem::take(spare);
        res.clear();
        hold.clear();
        Scan {
            m,
            leaf: task.n < m as u64,
            keep_all: p >= 1.0,
            p: p as f32,
            axis,
            mid: task.bbox.center()[axis],
            center: task.bbox.center(),
            naxis,
            normals: self.normals,
            max_d2: 0.0,
            min_dot: 1.0,
            rng: Pcg32::stream(self.seed, task.key),
            table: cloud::normal_table(),
            res,
            hold,
            kids: [Acc::EMPTY; 2],
        }
    }
}

/// A scanned node, before it gets its id and its place in the cloud file.
#[derive(Debug, Clone, Copy)]
pub(super) struct Closed {
    pub(super) key: u64,
    pub(super) center: Vec3,
    pub(super) radius: f32,
    pub(super) axis: Vec3,
    pub(super) half: f32,
    pub(super) acc: [Acc; 2],
}

impl Closed {
    /// The child tasks (`None`: empty child), with id `id`.
    pub(super) fn kids(&self, id: u32) -> [Option<Task>; 2] {
        std::array::from_fn(|side| {
            let acc = self.acc[side];
            (acc.n > 0).then(|| Task {
                id,
                key: child_key(self.key, side),
                n: acc.n,
                bbox: acc.bbox,
                nsum: acc.nsum,
            })
        })
    }
}

/// A node closed by [`part`]: its cloud lies in `bufs[buf][start..start + mc]`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Entry {
    pub(super) closed: Closed,
    pub(super) buf: usize,
    pub(super) start: usize,
    pub(super) mc: usize,
}

/// Subtrees smaller than this are never split between workers.
pub const PAR_MIN: u64 = 1 << 15;

/// One node partitioned in memory by [`split_node`].
#[derive(Debug, Clone, Copy)]
pub(super) struct Split {
    pub(super) closed: Closed,
    /// Child 0 is `dst[..f]`, the cloud `dst[f..bk]`, child 1 `dst[bk..]`.
    pub(super) f: usize,
    pub(super) bk: usize,
    pub(super) mc: usize,
    /// Scan-buffer capacity used (samples).
    pub(super) cap: usize,
}

/// Scans the node `task` whose samples are `src` and partitions them into `dst`: child 0
/// first, then the cloud, then child 1 (both children in scan order).
pub(super) fn split_node(
    cfg: &Cfg,
    task: &Task,
    src: &[Sample],
    dst: &mut [Sample],
    spare: &mut (Vec<Sample>, Vec<Sample>),
) -> Result<Split, MethodError> {
    let mut scan = cfg.scan_for(task, spare);
    let (mut f, mut bk) = (0usize, dst.len());
    // Child 0 fills `dst` from the front, child 1 from the back (reversed below).
    let mut place = |side: usize, s: &Sample| {
        if side == 0 {
            dst[f] = *s;
            f += 1;
        } else {
            bk -= 1;
            dst[bk] = *s;
        }
    };
    for s in src {
        if let Some(side) = scan.step(*s) {
            place(side, s);
        }
    }
    let mc = scan.select();
    scan.give_back(mc, &mut |side, s| {
        place(side, s);
        Ok(())
    })?;
    dst[bk..].reverse();
    // The children took all but the cloud: it fills the gap `f..bk`.
    dst[f..bk].copy_from_slice(&scan.res[..mc]);
    let cap = scan.res.capacity() + scan.hold.capacity();
    let closed = scan.closed(task.key);
    *spare = (scan.res, scan.hold);
    Ok(Split {
        closed,
        f,
        bk,
        mc,
        cap,
    })
}

/// Partitions, in memory, the subtree of `root` whose samples are in `bufs[buf]` (`a` is
/// buffer 0 and `b` buffer 1, both restricted to the subtree's range, which starts at
/// `base` in the full buffers). Each node's cloud is left in the gap between its
/// children's ranges in the buffer it was partitioned into; the nodes are appended to `log`
/// depth-first, child 0 first (the order of the single-threaded build). When both children
/// of a node are large (≥ [`PAR_MIN`] and ≥ 1/16 of the node: the nesting depth stays
/// logarithmic), their subtrees run in [`rayon::join`] on disjoint ranges. Returns the
/// largest scan-buffer capacity (samples) used.
#[allow(clippy::too_many_arguments)]
pub(super) fn part(
    cfg: &Cfg,
    root: Task,
    a: &mut [Sample],
    b: &mut [Sample],
    base: usize,
    buf: usize,
    log: &mut Vec<Entry>,
    mut first: Option<Split>,
) -> Result<usize, MethodError> {
    let mut spare = (Vec::new(), Vec::new());
    let mut cap = 0usize;
    // (task, buffer holding the samples, range)
    let mut stack = vec![(root, buf, 0usize, a.len())];
    while let Some((task, buf, lo, hi)) = stack.pop() {
        let (src, dst) = if buf == 1 {
            (&b[lo..hi], &mut a[lo..hi])
        } else {
            (&a[lo..hi], &mut b[lo..hi])
        };
        let Split {
            closed,
            f,
            bk,
            mc,
            cap: c,
        } = match first.take() {
            Some(sp) => sp,
            None => split_node(cfg, &task, src, dst, &mut spare)?,
        };
        cap = cap.max(c);
        log.push(Entry {
            closed,
            buf: 1 - buf,
            start: base + lo + f,
            mc,
        });
        let kids = closed.kids(NONE);
        match kids {
            [Some(t0), Some(t1)] if t0.n.min(t1.n) >= PAR_MIN.max(task.n / 16) => {
                let (a0, a1) = a[lo..hi].split_at_mut(bk);
                let (b0, b1) = b[lo..hi].split_at_mut(bk);
                let (a0, b0) = (&mut a0[..f], &mut b0[..f]);
                let (mut l0, mut l1) = (Vec::new(), Vec::new());
                let (c0, c1) = rayon::join(
                    || part(cfg, t0, a0, b0, base + lo, 1 - buf, &mut l0, None),
                    || part(cfg, t1, a1, b1, base + lo + bk, 1 - buf, &mut l1, None),
                );
                cap = cap.max(c0?).max(c1?);
                log.append(&mut l0);
                log.append(&mut l1);
            }
            _ => {
                if let Some(t) = kids[1] {
                    stack.push((t, 1 - buf, lo + bk, hi));
                }
                if let Some(t) = kids[0] {
                    stack.push((t, 1 - buf, lo, lo + f));
                }
            }
        }
    }
    Ok(cap)
}

/// The state of one node's scan.
pub(super) struct Scan {
    pub(super) m: usize,
    pub(super) leaf: bool,
    pub(super) keep_all: bool,
    pub(super) p: f32,
    pub(super) axis: usize,
    pub(super) mid: f32,
    pub(super) center: Vec3,
    pub(super) naxis: Vec3,
    pub(super) normals: bool,
    pub(super) max_d2: f32,
    pub(super) min_dot: f32,
    pub(super) rng: Pcg32,
    pub(super) table: &'static [(u32, [f32; 3])],
    pub(super) res: Vec<Sample>,
    pub(super) hold: Vec<Sample>,
    pub(super) kids: [Acc; 2],
}

impl Scan {
    #[inline]
    pub(super) fn step(&mut self, s: Sample) -> Option<usize> {
        let d2 = (Vec3::from(s.p) - self.center).length_squared();
        self.max_d2 = self.max_d2.max(d2);
        let mut d = [0.0; 3];
        if self.normals {
            d = self.table[s.normal as usize].1;
            self.min_dot = self.min_dot.min(Vec3::from(d).dot(self.naxis));
        }
        if self.leaf || self.keep_all || self.rng.f32() < self.p {
            self.res.push(s);
            return None;
        }
        if self.hold.len() < self.m {
            self.hold.push(s);
            return None;
        }
        Some(self.route(&s, d))
    }
    /// Adds `s` (decoded normal `d`) to its child; returns the side.
    #[inline]
    pub(super) fn route(&mut self, s: &Sample, d: [f32; 3]) -> usize {
        let side = (s.p[self.axis] >= self.mid) as usize;
        self.kids[side].add(s, d, self.normals);
        side
    }
    /// Arranges `res` so that `res[..returned]` is the cloud; the give-back samples are
    /// `res[returned..]` then `hold`.
    pub(super) fn select(&mut self) -> usize {
        if self.leaf {
            return self.res.len();
        }
        if self.res.len() < self.m {
            let d = self.m - self.res.len();
            self.res.extend(self.hold.drain(..d));
        }
        let len = self.res.len();
        if len > self.m {
            for i in 0..self.m {
                let j = i + self.rng.below((len - i) as u32) as usize;
                self.res.swap(i, j);
            }
        }
        self.m
    }
    /// Routes the give-back samples, calling `out(side, sample)` in a fixed order.
    pub(super) fn give_back(
        &mut self,
        mc: usize,
        out: &mut dyn FnMut(usize, &Sample) -> Result<(), MethodError>,
    ) -> Result<(), MethodError> {
        let res = std::mem::take(&mut self.res);
        let hold = std::mem::take(&mut self.hold);
        for s in res[mc..].iter().chain(&hold) {
            let side = self.route(s, self.table[s.normal as usize].1);
            out(side, s)?;
        }
        self.res = res;
        self.hold = hold;
        Ok(())
    }
    /// The node's sphere, cone and children once its scan is complete.
    pub(super) fn closed(&self, key: u64) -> Closed {
        Closed {
            key,
            center: self.center,
            radius: self.max_d2.sqrt() * (1.0 + 1e-6),
            axis: self.naxis,
            half: self.half_angle(),
            acc: self.kids,
        }
    }
    pub(super) fn half_angle(&self) -> f32 {
        if self.normals {
            (self.min_dot.clamp(-1.0, 1.0).acos() + CONE_MARGIN).min(std::f32::consts::PI)
        } else {
            std::f32::consts::PI
        }
    }
}

/// Phase 1 state.
pub(super) struct Phase1<'a> {
    pub(super) cfg: Cfg,
    pub(super) budget: u64,
    pub(super) estimate: bool,
    pub(super) dir: PathBuf,
    pub(super) nodes: Vec<PNode>,
    pub(super) clouds: BufWriter<File>,
    pub(super) clouds_path: PathBuf,
    pub(super) clouds_len: u64,
    pub(super) spare: (Vec<Sample>, Vec<Sample>),
    /// `[nearest, LEAF_K-th nearest]` distances of the measured probes.
    pub(super) probes: Vec<[f32; 2]>,
    pub(super) peak: u64,
    pub(super) temp_bytes: u64,
    pub(super) files: u64,
    pub(super) progress: &'a dyn Progress,
}

pub(super) fn child_key(key: u64, side: usize) -> u64 {
    let mut s = key
        .wrapping_mul(0x9E37_79B9_7F4A_7C15)
        .wrapping_add(side as u64 + 1);
    splitmix64(&mut s)
}

/// A temporary file of samples with its task.
pub(super) struct FileTask {
    pub(super) task: Task,
    pub(super) path: PathBuf,
}

impl<'a> Phase1<'a> {
    pub(super) fn fits(&self, n: u64) -> bool {
        n.saturating_mul(IN_CORE_BYTES_PER_SAMPLE) <= self.budget
    }

    /// Writes the cloud of a node scanned by [`Phase1::stream`], fills the node and creates
    /// its children; returns the child tasks.
    pub(super) fn close(
        &mut self,
        task: &Task,
        mut scan: Scan,
        mc: usize,
    ) -> Result<[Option<Task>; 2], MethodError> {
        self.peak = self
            .peak
            .max((scan.res.capacity() + scan.hold.capacity()) as u64 * RECORD_BYTES);
        let closed = scan.closed(task.key);
        let kids = self.commit(task.id, &closed, &scan.res[..mc])?;
        self.spare = (
            std::mem::take(&mut scan.res),
            std::mem::take(&mut scan.hold),
        );
        Ok(kids)
    }

    /// Appends the node `id`'s cloud to the cloud file, fills the node and creates its
    /// children (the next ids, child 0 first); returns the child tasks.
    pub(super) fn commit(
        &mut self,
        id: u32,
        c: &Closed,
        cloud: &[Sample],
    ) -> Result<[Option<Task>; 2], MethodError> {
        let off = self.clouds_len;
        self.clouds
            .write_all(bytemuck::cast_slice(cloud))
            .map_err(|e| MethodError::io(&self.clouds_path, e))?;
        self.clouds_len += cloud.len() as u64;
        self.progress.inc(cloud.len() as u64);
        let level = self.nodes[id as usize].level;
        let mut kids = [None, None];
        let mut ids = [NONE; 2];
        for (side, t) in c.kids(NONE).into_iter().enumerate() {
            let Some(mut t) = t else { continue };
            t.id = self.nodes.len() as u32;
            self.nodes.push(PNode {
                parent: id,
                children: [NONE; 2],
                level: level + 1,
                n: t.n,
                m: 0,
                cloud_off: 0,
                center: Vec3::ZERO,
                radius: 0.0,
                axis: Vec3::ZERO,
                half: 0.0,
            });
            ids[side] = t.id;
            kids[side] = Some(t);
        }
        let nd = &mut self.nodes[id as usize];
        nd.children = ids;
        nd.m = cloud.len() as u32;
        nd.cloud_off = off;
        nd.center = c.center;
        nd.radius = c.radius;
        nd.axis = c.axis;
        nd.half = c.half;
        Ok(kids)
    }

    pub(super) fn run(&mut self, cloud: &PointCloud, temps: &mut Temps) -> Result<(), MethodError> {
        let n = cloud.len();
        self.nodes.push(PNode {
            parent: NONE,
            children: [NONE; 2],
            level: 0,
            n: n as u64,
            m: 0,
            cloud_off: 0,
            center: Vec3::ZERO,
            radius: 0.0,
            axis: Vec3::ZERO,
            half: 0.0,
        });
        let threshold = if n as u64 <= PROBES {
            u64::MAX
        } else {
            (PROBES as f64 / n as f64 * u64::MAX as f64) as u64
        };
        let seed = self.cfg.seed;
        // Appends the samples of `range` to `out` (converted in parallel) and adds their
        // quantised normals to `nsum` (in order: the same sum for any thread count).
        let convert = |range: std::ops::Range<usize>, out: &mut Vec<Sample>, nsum: &mut DVec3| {
            let pos = &cloud.positions()[range.clone()];
            let nrm = cloud.normals().map(|v| &v[range.clone()]);
            let col = cloud.colors().map(|v| &v[range.clone()]);
            let start = out.len();
            out.resize(start + range.len(), Sample::default());
            out[start..]
                .par_chunks_mut(CONVERT_CHUNK)
                .enumerate()
                .for_each(|(c, chunk)| {
                    for (jj, s) in chunk.iter_mut().enumerate() {
                        let j = c * CONVERT_CHUNK + jj;
                        let i = range.start + j;
                        let mut h = seed ^ (i as u64).wrapping_mul(0xA24B_AED4_963E_E407);
                        let probe = splitmix64(&mut h) <= threshold;
                        *s = Sample {
                            p: pos[j],
                            normal: nrm.map_or(0, |nv| cloud::oct16_encode(Vec3::from(nv[j]))),
                            flags: if probe { PROBE } else { 0 },
                            color: col.map_or([0; 4], |c| [c[j][0], c[j][1], c[j][2], 0]),
                        };
                    }
                });
            if nrm.is_some() {
                let table = cloud::normal_table();
                for s in &out[start..] {
                    let d = table[s.normal as usize].1;
                    *nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
                }
            }
            cloud.release_pages(range);
        };
        let root = |nsum: DVec3| Task {
            id: 0,
            key: seed,
            n: n as u64,
            bbox: cloud.bounds(),
            nsum,
        };
        let mut bufs: [Vec<Sample>; 2] = [Vec::new(), Vec::new()];
        let mut stack: Vec<FileTask> = Vec::new();
        if self.fits(n as u64) {
            let mut nsum = DVec3::ZERO;
            bufs[0].reserve_exact(n);
            for lo in (0..n).step_by(BLOCK) {
                convert(lo..(lo + BLOCK).min(n), &mut bufs[0], &mut nsum);
            }
            self.in_core(root(nsum), &mut bufs)?;
        } else {
            // The root streams the scene: a first pass for the normal sum (the cone axis).
            // Blocks are encoded in parallel while the previous one is summed (in order).
            let mut nsum = DVec3::ZERO;
            if let Some(nv) = cloud.normals() {
                let table = cloud::normal_table();
                let (mut codes, mut prev) = (vec![0u16; BLOCK], vec![0u16; BLOCK]);
                let mut prev_len = 0;
                let sum = |codes: &[u16], nsum: &mut DVec3| {
                    for &c in codes {
                        let d = table[c as usize].1;
                        *nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
                    }
                };
                for lo in (0..n).step_by(BLOCK) {
                    let hi = (lo + BLOCK).min(n);
                    rayon::join(
                        || sum(&prev[..prev_len], &mut nsum),
                        || {
                            codes[..hi - lo]
                                .par_chunks_mut(CONVERT_CHUNK)
                                .zip(nv[lo..hi].par_chunks(CONVERT_CHUNK))
                                .for_each(|(c, v)| {
                                    for (c, v) in c.iter_mut().zip(v) {
                                        *c = cloud::oct16_encode(Vec3::from(*v));
                                    }
                                });
                            cloud.release_pages(lo..hi);
                        },
                    );
                    std::mem::swap(&mut codes, &mut prev);
                    prev_len = hi - lo;
                }
                sum(&prev[..prev_len], &mut nsum);
            }
            let task = root(nsum);
            let mut lo = 0;
            let kids = self.stream(&task, temps, &mut |block| {
                block.clear();
                if lo >= n {
                    return Ok(false);
                }
                let hi = (lo + BLOCK).min(n);
                let mut unused = DVec3::ZERO;
                convert(lo..hi, block, &mut unused);
                lo = hi;
                Ok(true)
            })?;
            stack.extend(kids.into_iter().rev().flatten());
        }
        while let Some(ft) = stack.pop() {
            if self.fits(ft.task.n) {
                let len = ft.task.n as usize;
                bufs[0].clear();
                bufs[0].resize(len, Sample::default());
                read_samples(&ft.path, &mut bufs[0])?;
                let _ = std::fs::remove_file(&ft.path);
                self.in_core(ft.task, &mut bufs)?;
            } else {
                let file = File::open(&ft.path).map_err(|e| MethodError::io(&ft.path, e))?;
                let mut reader = BufReader::with_capacity(IO_BUF, file);
                let mut left = ft.task.n as usize;
                let path = ft.path.clone();
                let kids = self.stream(&ft.task, temps, &mut |block| {
                    let len = left.min(BLOCK);
                    block.clear();
                    if len == 0 {
                        return Ok(false);
                    }
                    block.resize(len, Sample::default());
                    reader
                        .read_exact(bytemuck::cast_slice_mut(block))
                        .map_err(|e| MethodError::io(&path, e))?;
                    left -= len;
                    Ok(true)
                })?;
                let _ = std::fs::remove_file(&ft.path);
                stack.extend(kids.into_iter().rev().flatten());
            }
        }
        Ok(())
    }

    /// Partitions one node out of core: samples come in blocks from `next`, the children
    /// go to new temporary files.
    pub(super) fn stream(
        &mut self,
        task: &Task,
        temps: &mut Temps,
        next: &mut (dyn FnMut(&mut Vec<Sample>) -> Result<bool, MethodError> + Send),
    ) -> Result<[Option<FileTask>; 2], MethodError> {
        let mut scan = self.cfg.scan_for(task, &mut self.spare);
        let mut paths = Vec::with_capacity(2);
        let mut writers = Vec::with_capacity(2);
        for _ in 0..2 {
            let path = self.dir.join(format!("lpc-part-{}.tmp", self.files));
            self.files += 1;
            temps.0.push(path.clone());
            let f = File::create(&path).map_err(|e| MethodError::io(&path, e))?;
            writers.push(BufWriter::with_capacity(IO_BUF, f));
            paths.push(path);
        }
        let mut block = Vec::with_capacity(BLOCK);
        let mut ahead = Vec::with_capacity(BLOCK);
        self.peak = self
            .peak
            .max(2 * (BLOCK as u64) * RECORD_BYTES + 4 * IO_BUF as u64);
        let mut write = |side: usize, s: &Sample| -> Result<(), MethodError> {
            writers[side]
                .write_all(bytemuck::bytes_of(s))
                .map_err(|e| MethodError::io(&paths[side], e))
        };
        // The next block is fetched (converted / read) while this one is scanned.
        let mut more = next(&mut block)?;
        while more {
            let (scanned, fetched) = rayon::join(
                || -> Result<(), MethodError> {
                    for s in &block {
                        if let Some(side) = scan.step(*s) {
                            write(side, s)?;
                        }
                    }
                    Ok(())
                },
                || next(&mut ahead),
            );
            scanned?;
            more = fetched?;
            std::mem::swap(&mut block, &mut ahead);
        }
        let mc = scan.select();
        scan.give_back(mc, &mut write)?;
        for (w, p) in writers.into_iter().zip(&paths) {
            w.into_inner()
                .map_err(|e| MethodError::io(p, e.into_error()))?;
        }
        let kids = self.close(task, scan, mc)?;
        let mut out = [None, None];
        for side in 0..2 {
            match kids[side] {
                Some(t) => {
                    self.temp_bytes += t.n * RECORD_BYTES;
                    out[side] = Some(FileTask {
                        task: t,
                        path: paths[side].clone(),
                    });
                }
                None => {
                    let _ = std::fs::remove_file(&paths[side]);
                }
            }
        }
        Ok(out)
    }

    /// Partitions the subtree of `root`, whose samples are `bufs[0][..root.n]`, in memory
    /// ([`part`], on the current rayon pool), then commits its nodes in depth-first order.
    pub(super) fn in_core(
        &mut self,
        root: Task,
        bufs: &mut [Vec<Sample>; 2],
    ) -> Result<(), MethodError> {
        let n = root.n as usize;
        bufs[1].clear();
        bufs[1].resize(n, Sample::default());
        let mut log = Vec::new();
        let (a, b) = bufs.split_at_mut(1);
        let (a, b) = (&mut a[0][..n], &mut b[0][..n]);
        // The probe k-NN reads buffer 0 while the root is partitioned into buffer 1.
        let (probes, first) = rayon::join(
            || {
                if self.estimate {
                    probe_knn(a, root.bbox, LEAF_K)
                } else {
                    Vec::new()
                }
            },
            || split_node(&self.cfg, &root, a, b, &mut (Vec::new(), Vec::new())),
        );
        self.probes.extend(probes);
        let cap = part(&self.cfg, root, a, b, 0, 0, &mut log, Some(first?))?;
        // Each worker holds its own scan buffers.
        let workers = rayon::current_num_threads() as u64;
        self.peak = self.peak.max(
            (bufs[0].capacity() + bufs[1].capacity()) as u64 * RECORD_BYTES
                + workers * cap as u64 * RECORD_BYTES,
        );
        let mut ids = vec![root.id];
        for e in &log {
            let Some(id) = ids.pop() else { break };
            let cloud = &bufs[e.buf][e.start..e.start + e.mc];
            let kids = self.commit(id, &e.closed, cloud)?;
            ids.extend(kids.iter().rev().flatten().map(|t| t.id));
        }
        debug_assert!(ids.is_empty());
        Ok(())
    }
}

pub(super) fn read_samples(path: &Path, out: &mut [Sample]) -> Result<(), MethodError> {
    let file = File::open(path).map_err(|e| MethodError::io(path, e))?;
    let mut r = BufReader::with_capacity(IO_BUF, file);
    r.read_exact(bytemuck::cast_slice_mut(out))
        .map_err(|e| MethodError::io(path, e))
}
