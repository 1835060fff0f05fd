//! Streamed levels of phase 1 simulated in read-only passes, so that each sample is written
//! to a temporary file once per *group* of streamed levels instead of once per level.
//!
//! A streamed node's scan ([`Scan::step`], [`Scan::select`], [`Scan::give_back`]) is
//! deterministic given the node's task (count, tight box, normal sum, key → random stream)
//! and its samples in scan order. A child's scan order is: the samples its parent routed
//! straight during its scan (in the parent's scan order), then the samples the parent gave
//! back after the scan (kept extras, then held-back ones). So the levels below a node that
//! does not fit the budget can be computed by re-reading the node's source (the scene's
//! columns for the root, else the node's temporary file), never writing the levels between:
//!
//! - **A group** starts at a node that does not fit (its root). Its nodes are *simulated*
//!   (scanned in every pass, they do not fit) or *frontier* nodes (they get a file).
//! - **Pass 1** scans the root and learns its children's tasks (count, box, normal sum: the
//!   scan's [`super::partition::Acc`]s); the root is closed (its cloud appended). A child
//!   that does not fit is simulated too (within the limits below). **Pass p** re-reads the
//!   source, re-runs the known scans (same draws; [`Scan::step_known`] skips the bookkeeping
//!   already done) with each sample routed down as far as a scan passes it, and learns and
//!   closes the nodes simulated since pass p − 1. At the end of a pass the nodes are
//!   finished in depth order: a node selects its cloud and gives back its extras, which go
//!   on into its child's scan (and, routed straight there, further down) before the child
//!   selects in turn. Only nodes on a path to one with work in the pass are scanned.
//! - **The last pass** is the one after which every simulated node's children are known. It
//!   writes each sample that reaches a frontier node without a file to that node's file, in
//!   the order the file of the level-by-level build would have had (the parent's straight
//!   samples, then its give-back).
//! - **Speculation** (the root's group only). A node learned in a pass whose even split
//!   would fit (`⌈(n − M)/2⌉` samples fit) writes its children to files in that same pass:
//!   they are frontier nodes from the start. When every node learned in a pass is
//!   speculated, that pass is the last, which saves the group one pass over its source (a
//!   root whose children fit is then streamed in one pass, as the level-by-level build did).
//!   A speculated child that does not fit (an uneven split) starts a new group from its file:
//!   its samples are written twice. Groups started from files do not speculate, so that
//!   cannot cascade (a chain of uneven splits would otherwise be written once per level).
//! - **Output.** The group returns an [`Item`] tree; phase 1 walks it depth first, child 0
//!   first, as it walked streamed nodes before: a simulated node gets its id and its
//!   children's ids (`Phase1::attach`), a frontier node that fits is partitioned in memory
//!   from its file, one that does not starts a new group from its file. So the node ids,
//!   the clouds and the tree are those of the level-by-level build (only the order of the
//!   clouds in the temporary cloud file changes; they are read back by offset).
//!
//! **Limits** (memory bounded whatever the input). A group simulates at most
//! [`MAX_SIMULATED`] nodes (each holds a scan's reservoir and held-back samples, ≈ (K+1)·M
//! records), at most [`MAX_LEVELS`] levels, and has at most [`MAX_FILES`] frontier files
//! (buffered with [`WRITE_BUF`] bytes each): a node that does not fit is simulated only
//! while that keeps all three (a simulated node replaces one frontier node by at most two).
//! A frontier node that does not fit starts a new group, whose samples are written once
//! more. With a split near the midpoint (a balanced tree), a group of up to 6 levels writes
//! every sample once: with the default 768 MiB budget (in-core subtrees of ≤ 20 M samples),
//! inputs up to ≈ 1.3 G samples are written to temporary files once, larger ones once per 6
//! streamed levels; uneven splits under speculation add at most one more write of the
//! samples below them. Degenerate inputs (a chain of nodes) are written once per
//! [`MAX_LEVELS`] levels. The price is reads and scans: a group of `L` levels reads its
//! source up to `L + 1` times (`L` with speculation), and a sample passes through up to `L`
//! scans per pass.
//!
//! **Measured** (`terrain` LAS, 2 cores, shared machine; commands in the lpc README):
//! 50 M samples, 91.5 → 46.5 bytes of temporary files per sample; the build time moved by
//! −6 % to +15 % over three back-to-back pairs (noise of a shared machine): where the page
//! cache holds the temporary files, writing a sample costs about what re-scanning it does.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::PathBuf;

use super::cloud::Sample;
use super::index::NONE;
use super::layout::{BLOCK, IO_BUF, RECORD_BYTES};
use super::partition::{Closed, FileTask, Item, Phase1, Scan, Task, Temps};
use super::source::Source;
use crate::MethodError;

/// Most frontier files of one group (open at once in its last pass).
pub const MAX_FILES: usize = 64;
/// Most simulated nodes of one group (scans held at once).
pub const MAX_SIMULATED: usize = 64;
/// Most levels simulated in one group.
pub const MAX_LEVELS: u32 = 8;
/// Capacity of the buffered writer of each frontier file.
pub const WRITE_BUF: usize = 1 << 17;

/// A simulated node's result of the last pass.
struct Done {
    closed: Closed,
    off: u64,
    m: u32,
}

/// A node of a group (index 0: the group's root; children after their parents).
struct GNode {
    task: Task,
    depth: u32,
    parent: usize,
    /// Scanned in the passes (it does not fit); else a frontier node.
    sim: bool,
    /// Whether the children (`kids`) are known.
    learned: bool,
    /// Children written to files in the pass that learns them (speculation).
    spec: bool,
    /// The children's indices; `None`: empty, or not known yet.
    kids: [Option<usize>; 2],
    /// The scan of this pass (simulated nodes being scanned).
    scan: Option<Scan>,
    /// Files being written in this pass: a frontier node's own, a speculated node's
    /// children's (by side).
    out: Option<usize>,
    spec_out: [Option<usize>; 2],
    /// A frontier node's file, once it is being written.
    path: Option<PathBuf>,
    done: Option<Done>,
}

impl GNode {
    fn new(task: Task, depth: u32, parent: usize) -> Self {
        Self {
            task,
            depth,
            parent,
            sim: false,
            learned: false,
            spec: false,
            kids: [None; 2],
            scan: None,
            out: None,
            spec_out: [None; 2],
            path: None,
            done: None,
        }
    }
}

/// A frontier file being written.
struct Out {
    w: BufWriter<File>,
    path: PathBuf,
    n: u64,
    /// A speculated child that turned out empty (the file is removed).
    empty: bool,
}

/// Hands `s` to node `j`: its scan and, routed straight, on down the group, to the file of
/// the frontier node (or speculated child) it reaches when that file is written in this
/// pass. Samples reaching a node with nothing to do in this pass are dropped (its parent's
/// scan has counted them).
#[inline]
fn deliver(
    nodes: &mut [GNode],
    outs: &mut [Out],
    mut j: usize,
    s: &Sample,
) -> Result<(), MethodError> {
    loop {
        let node = &mut nodes[j];
        let mut out = node.out;
        if let Some(scan) = node.scan.as_mut() {
            let step = if node.learned {
                scan.step_known(*s)
            } else {
                scan.step(*s)
            };
            let Some(side) = step else {
                return Ok(());
            };
            if let Some(k) = node.kids[side] {
                j = k;
                continue;
            }
            out = node.spec_out[side];
        }
        if let Some(o) = out {
            outs[o].write(s)?;
        }
        return Ok(());
    }
}

impl Out {
    #[inline]
    fn write(&mut self, s: &Sample) -> Result<(), MethodError> {
        self.n += 1;
        self.w
            .write_all(bytemuck::bytes_of(s))
            .map_err(|e| MethodError::io(&self.path, e))
    }
}

impl Phase1<'_> {
    /// Partitions the node `root` (it does not fit the budget) from `src` and the levels
    /// below it that do not fit either, in read-only passes over `src` (module docs), with
    /// speculation when `speculate`; `label` names the passes on the progress bar. Returns
    /// the group's tree.
    pub(super) fn group(
        &mut self,
        root: Task,
        src: Source<'_>,
        speculate: bool,
        label: &str,
        temps: &mut Temps,
    ) -> Result<Item, MethodError> {
        let mut nodes = vec![GNode::new(root, 0, usize::MAX)];
        nodes[0].sim = true;
        let m = self.cfg.m as u64;
        let mut pass = 1;
        loop {
            // The pass is the last when every node it learns is speculated (none: it only
            // writes the frontier files).
            let mut last = true;
            for x in nodes.iter_mut().filter(|x| x.sim && !x.learned) {
                x.spec = speculate && self.fits(x.task.n.saturating_sub(m).div_ceil(2));
                last &= x.spec;
            }
            let work = |x: &GNode| if x.sim { !x.learned } else { x.path.is_none() };
            if last && !nodes.iter().any(work) {
                break; // nothing left to learn or write (streamed nodes without children)
            }
            self.pass(
                &mut nodes,
                src,
                last,
                &format!("{label} pass {pass}"),
                temps,
            )?;
            if last {
                break;
            }
            self.expand(&mut nodes);
            pass += 1;
        }
        item(&mut nodes, 0)
    }

    /// Simulates the frontier nodes that do not fit, within the limits (module docs).
    fn expand(&self, nodes: &mut [GNode]) {
        let mut files = nodes.iter().filter(|x| !x.sim).count();
        let mut sims = nodes.len() - files;
        for x in nodes.iter_mut() {
            if x.sim
                || x.path.is_some()
                || self.fits(x.task.n)
                || x.depth >= MAX_LEVELS
                || sims >= MAX_SIMULATED
                || files >= MAX_FILES
            {
                continue;
            }
            x.sim = true;
            sims += 1;
            files += 1; // one frontier node less, at most two more
        }
    }

    /// One pass over `src`: it learns the children of the simulated nodes whose children are
    /// unknown (and closes them: clouds appended), writing the speculated ones' children to
    /// files; the last pass also writes the frontier files not written yet.
    fn pass(
        &mut self,
        nodes: &mut Vec<GNode>,
        src: Source<'_>,
        last: bool,
        label: &str,
        temps: &mut Temps,
    ) -> Result<(), MethodError> {
        // Scanned: the simulated nodes on a path to a node whose children are unknown or,
        // in the last pass, to a frontier node without a file (children come after their
        // parents).
        let mut live = vec![false; nodes.len()];
        for i in (0..nodes.len()).rev() {
            let x = &nodes[i];
            let need = if x.sim {
                !x.learned
            } else {
                last && x.path.is_none()
            };
            live[i] |= x.sim && need;
            if (need || live[i]) && i > 0 {
                live[x.parent] = true;
            }
        }
        for (x, _) in nodes.iter_mut().zip(&live).filter(|(_, l)| **l) {
            let mut spare = self.pool.pop().unwrap_or_default();
            x.scan = Some(self.cfg.scan_for(&x.task, &mut spare));
        }
        let mut outs = Vec::new();
        for x in nodes.iter_mut() {
            if x.sim && !x.learned && x.spec {
                for side in 0..2 {
                    x.spec_out[side] = Some(outs.len());
                    outs.push(self.temp_file(temps)?);
                }
            } else if !x.sim && last && x.path.is_none() {
                x.out = Some(outs.len());
                let o = self.temp_file(temps)?;
                x.path = Some(o.path.clone());
                outs.push(o);
            }
        }

        // The next block is fetched (converted / read) while this one is scanned.
        self.progress.start(label, src.len());
        let mut reader = src.reader()?;
        let mut block = Vec::with_capacity(BLOCK);
        let mut ahead = Vec::with_capacity(BLOCK);
        let mut more = reader.next(&mut block)?;
        while more {
            let (scanned, fetched) = rayon::join(
                || -> Result<(), MethodError> {
                    for s in &block {
                        deliver(nodes, &mut outs, 0, s)?;
                    }
                    Ok(())
                },
                || reader.next(&mut ahead),
            );
            scanned?;
            more = fetched?;
            self.progress.inc(block.len() as u64);
            std::mem::swap(&mut block, &mut ahead);
        }
        self.progress.finish();

        // Finish the scans in depth order: a node's give-back goes on into its children's
        // scans before they select.
        let mut held = 0usize;
        for i in 0..nodes.len() {
            let Some(mut scan) = nodes[i].scan.take() else {
                continue;
            };
            let mc = scan.select();
            let kids = nodes[i].kids;
            let spec_out = nodes[i].spec_out;
            scan.give_back(mc, &mut |side, s| match (kids[side], spec_out[side]) {
                (Some(j), _) => deliver(nodes, &mut outs, j, s),
                (None, Some(o)) => outs[o].write(s),
                (None, None) => Ok(()),
            })?;
            held += scan.res.capacity() + scan.hold.capacity();
            if !nodes[i].learned {
                // Its first scan: close it, learn its children.
                let closed = scan.closed(nodes[i].task.key);
                let off = self.append(&scan.res[..mc])?;
                let depth = nodes[i].depth + 1;
                for (side, t) in closed.kids(NONE).into_iter().enumerate() {
                    let spec = nodes[i].spec_out[side].take();
                    match (t, spec) {
                        (Some(t), spec) => {
                            nodes[i].kids[side] = Some(nodes.len());
                            let mut kid = GNode::new(t, depth, i);
                            kid.path = spec.map(|o| outs[o].path.clone());
                            nodes.push(kid);
                        }
                        (None, Some(o)) => outs[o].empty = true,
                        (None, None) => {}
                    }
                }
                nodes[i].learned = true;
                nodes[i].done = Some(Done {
                    closed,
                    off,
                    m: mc as u32,
                });
            }
            self.pool.push((scan.res, scan.hold));
        }
        for x in nodes.iter_mut() {
            x.out = None;
        }
        self.peak = self.peak.max(
            (2 * BLOCK + held) as u64 * RECORD_BYTES + (IO_BUF + outs.len() * WRITE_BUF) as u64,
        );
        for o in outs {
            o.w.into_inner()
                .map_err(|e| MethodError::io(&o.path, e.into_error()))?;
            if o.empty {
                let _ = std::fs::remove_file(&o.path);
            }
            self.temp_bytes += o.n * RECORD_BYTES;
        }
        Ok(())
    }

    /// A new temporary file (deleted at the end of the build if still there).
    fn temp_file(&mut self, temps: &mut Temps) -> Result<Out, MethodError> {
        let path = self.dir.join(format!("lpc-part-{}.tmp", self.files));
        self.files += 1;
        temps.0.push(path.clone());
        let f = File::create(&path).map_err(|e| MethodError::io(&path, e))?;
        Ok(Out {
            w: BufWriter::with_capacity(WRITE_BUF, f),
            path,
            n: 0,
            empty: false,
        })
    }
}

/// The tree of node `i` once the last pass is over (depth ≤ [`MAX_LEVELS`]).
fn item(nodes: &mut [GNode], i: usize) -> Result<Item, MethodError> {
    let x = &mut nodes[i];
    let lost = || MethodError::Bug(format!("lpc: node {} of a group left unfinished", i));
    if !x.sim {
        let path = x.path.take().ok_or_else(lost)?;
        return Ok(Item::File(FileTask { task: x.task, path }));
    }
    let Done { closed, off, m } = x.done.take().ok_or_else(lost)?;
    let ids = x.kids;
    let mut kids = [None, None];
    for (k, j) in kids.iter_mut().zip(ids) {
        if let Some(j) = j {
            *k = Some(Box::new(item(nodes, j)?));
        }
    }
    Ok(Item::Node {
        closed,
        off,
        m,
        kids,
    })
}
