//! Phase 1 of the LPC build: the recursive partitioning of [`super::build`]'s module docs —
//! nodes, their Russian-roulette clouds, the in-core (parallel) path and the order in which
//! nodes are processed; the streamed levels are simulated by [`super::multilevel`] over the
//! sources of [`super::source`]. Both paths give the same tree.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use glam::{DVec3, Vec3};
use scenes::rng::{Pcg32, splitmix64};
use scenes::{Aabb, PointCloud, Progress};

use super::cloud::{self, Sample};
use super::index::NONE;
use super::layout::{BLOCK, CONE_MARGIN, IN_CORE_BYTES_PER_SAMPLE, RECORD_BYTES};
use super::source::{Columns, Source, read_samples};
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
        if self.keep_or_hold(s) {
            return None;
        }
        Some(self.route(&s, d))
    }
    /// The Russian roulette and the held-back samples: true if `s` stays with the node
    /// (kept, or held back while fewer than `M` are), false if it goes to a child.
    #[inline]
    fn keep_or_hold(&mut self, s: Sample) -> bool {
        if self.leaf || self.keep_all || self.rng.f32() < self.p {
            self.res.push(s);
            return true;
        }
        if self.hold.len() < self.m {
            self.hold.push(s);
            return true;
        }
        false
    }
    /// [`Scan::step`] for a node scanned before (its sphere, cone and children known): the
    /// same draws, kept, held-back and routed samples, without the bookkeeping.
    #[inline]
    pub(super) fn step_known(&mut self, s: Sample) -> Option<usize> {
        if self.keep_or_hold(s) {
            return None;
        }
        Some((s.p[self.axis] >= self.mid) as usize)
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
    /// Whether the probes are still to be measured: by the in-core root, or (a streamed
    /// root) once over the scene's columns before the partition, after which it is false.
    pub(super) estimate: bool,
    pub(super) dir: PathBuf,
    pub(super) nodes: Vec<PNode>,
    pub(super) clouds: BufWriter<File>,
    pub(super) clouds_path: PathBuf,
    /// Samples in the cloud file so far.
    pub(super) clouds_len: u64,
    /// Scan buffers to reuse (reservoir, held back).
    pub(super) pool: Vec<(Vec<Sample>, Vec<Sample>)>,
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

impl PNode {
    /// A node whose subtree holds `n` samples, filled when it is attached.
    pub(super) fn new(parent: u32, level: u32, n: u64) -> Self {
        Self {
            parent,
            children: [NONE; 2],
            level,
            n,
            m: 0,
            cloud_off: 0,
            center: Vec3::ZERO,
            radius: 0.0,
            axis: Vec3::ZERO,
            half: 0.0,
        }
    }
}

impl<'a> Phase1<'a> {
    pub(super) fn fits(&self, n: u64) -> bool {
        n.saturating_mul(IN_CORE_BYTES_PER_SAMPLE) <= self.budget
    }

    /// Appends a cloud to the cloud file; returns its offset (samples).
    pub(super) fn append(&mut self, cloud: &[Sample]) -> Result<u64, MethodError> {
        let off = self.clouds_len;
        self.clouds
            .write_all(bytemuck::cast_slice(cloud))
            .map_err(|e| MethodError::io(&self.clouds_path, e))?;
        self.clouds_len += cloud.len() as u64;
        Ok(off)
    }

    /// Appends the node `id`'s cloud to the cloud file and attaches it ([`Phase1::attach`]).
    pub(super) fn commit(
        &mut self,
        id: u32,
        c: &Closed,
        cloud: &[Sample],
    ) -> Result<[Option<Task>; 2], MethodError> {
        let off = self.append(cloud)?;
        self.progress.inc(cloud.len() as u64);
        Ok(self.attach(id, c, off, cloud.len() as u32))
    }

    /// Fills the node `id` (its `m`-sample cloud is at `off` in the cloud file) and creates
    /// its children (the next ids, child 0 first); returns the child tasks.
    pub(super) fn attach(&mut self, id: u32, c: &Closed, off: u64, m: u32) -> [Option<Task>; 2] {
        let level = self.nodes[id as usize].level;
        let mut kids = [None, None];
        let mut ids = [NONE; 2];
        for (side, t) in c.kids(NONE).into_iter().enumerate() {
            let Some(mut t) = t else { continue };
            t.id = self.nodes.len() as u32;
            self.nodes.push(PNode::new(id, level + 1, t.n));
            ids[side] = t.id;
            kids[side] = Some(t);
        }
        let nd = &mut self.nodes[id as usize];
        nd.children = ids;
        nd.m = m;
        nd.cloud_off = off;
        nd.center = c.center;
        nd.radius = c.radius;
        nd.axis = c.axis;
        nd.half = c.half;
        kids
    }

    /// Runs phase 1: the root in memory if it fits, else streamed groups of levels
    /// ([`super::multilevel`]) down to subtrees that fit, each partitioned in memory;
    /// nodes get their ids depth first, child 0 first.
    pub(super) fn run(&mut self, cloud: &PointCloud, temps: &mut Temps) -> Result<(), MethodError> {
        let n = cloud.len() as u64;
        self.nodes.push(PNode::new(NONE, 0, n));
        let cols = Columns::new(cloud, self.cfg.seed);
        let root = |nsum: DVec3| Task {
            id: 0,
            key: self.cfg.seed,
            n,
            bbox: cloud.bounds(),
            nsum,
        };
        let mut bufs: [Vec<Sample>; 2] = [Vec::new(), Vec::new()];
        // Nodes still to process, with their ids, depth first (child 0 on top).
        let mut stack: Vec<(Item, u32)> = Vec::new();
        if self.fits(n) {
            self.progress.start("lpc: partition", n);
            let mut nsum = DVec3::ZERO;
            bufs[0].reserve_exact(n as usize);
            for lo in (0..n as usize).step_by(BLOCK) {
                let hi = (lo + BLOCK).min(n as usize);
                cols.convert(lo..hi, &mut bufs[0], Some(&mut nsum));
            }
            self.in_core(root(nsum), &mut bufs)?;
        } else {
            // The probes are measured against the whole scene, as the in-core root measures
            // them, rather than in the in-core subtrees (whose borders and number depend on
            // the memory budget): the input spacing, and so the files, do not depend on
            // `mem_mb`. The scan runs alongside the first partition passes (which wait on
            // their temporary files): at 50 M terrain samples it is hidden in them.
            let estimate = std::mem::replace(&mut self.estimate, false);
            let task = root(cols.normal_sum());
            let (probes, item) = rayon::join(
                || {
                    if estimate {
                        cols.probe_knn()
                    } else {
                        Vec::new()
                    }
                },
                || self.group(task, Source::Columns(&cols), true, "lpc: partition", temps),
            );
            self.probes = probes;
            let item = item?;
            self.progress.start("lpc: partition", n - self.clouds_len);
            stack.push((item, 0));
        }
        while let Some((item, id)) = stack.pop() {
            match item {
                Item::Node {
                    closed,
                    off,
                    m,
                    kids,
                } => {
                    let tasks = self.attach(id, &closed, off, m);
                    for (t, k) in tasks.into_iter().zip(kids).rev() {
                        debug_assert_eq!(t.is_some(), k.is_some());
                        if let (Some(t), Some(k)) = (t, k) {
                            stack.push((*k, t.id));
                        }
                    }
                }
                Item::File(FileTask { mut task, path }) => {
                    task.id = id;
                    if self.fits(task.n) {
                        bufs[0].clear();
                        bufs[0].resize(task.n as usize, Sample::default());
                        read_samples(&path, &mut bufs[0])?;
                        let _ = std::fs::remove_file(&path);
                        self.in_core(task, &mut bufs)?;
                    } else {
                        let src = Source::File {
                            path: &path,
                            n: task.n,
                        };
                        let label = format!("lpc: partition node {id}");
                        let item = self.group(task, src, false, &label, temps)?;
                        let _ = std::fs::remove_file(&path);
                        self.progress.start("lpc: partition", n - self.clouds_len);
                        stack.push((item, id));
                    }
                }
            }
        }
        Ok(())
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

/// A temporary file of samples with its task.
pub(super) struct FileTask {
    pub(super) task: Task,
    pub(super) path: PathBuf,
}

/// A node of a finished group, as phase 1 takes it (ids are given when it is attached).
pub(super) enum Item {
    /// A simulated node: its cloud (`m` samples) is at `off` in the cloud file.
    Node {
        closed: Closed,
        off: u64,
        m: u32,
        kids: [Option<Box<Item>>; 2],
    },
    /// A frontier node: its samples are in a temporary file.
    File(FileTask),
}
