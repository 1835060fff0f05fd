//! Where phase 1 reads a node's samples from, in blocks of [`BLOCK`] samples, in scan order:
//! the scene's columns (the root: converted to [`Sample`] records, probes flagged, pages
//! released behind the cursor) or a temporary file of records. A source can be read any
//! number of times ([`Source::reader`]), always in the same order: the multi-level passes
//! of [`super::multilevel`] re-read it.

use std::fs::File;
use std::io::{BufReader, Read};
use std::ops::Range;
use std::path::Path;

use glam::{DVec3, Vec3};
use rayon::prelude::*;
use scenes::PointCloud;
use scenes::rng::splitmix64;

use super::cloud::{self, Sample};
use super::layout::{BLOCK, CONVERT_CHUNK, IO_BUF, PROBE, PROBES};
use crate::MethodError;

/// The scene's columns as sample records.
pub(super) struct Columns<'c> {
    cloud: &'c PointCloud,
    seed: u64,
    /// A sample is a probe when its hash is at most this.
    threshold: u64,
}

impl<'c> Columns<'c> {
    pub(super) fn new(cloud: &'c PointCloud, seed: u64) -> Self {
        let n = cloud.len() as u64;
        let threshold = if n <= PROBES {
            u64::MAX
        } else {
            (PROBES as f64 / n as f64 * u64::MAX as f64) as u64
        };
        Self {
            cloud,
            seed,
            threshold,
        }
    }

    pub(super) fn len(&self) -> u64 {
        self.cloud.len() as u64
    }

    /// Whether sample `i` of the scene is a spacing probe (a seeded hash of its index).
    #[inline]
    pub(super) fn is_probe(&self, i: usize) -> bool {
        let mut h = self.seed ^ (i as u64).wrapping_mul(0xA24B_AED4_963E_E407);
        splitmix64(&mut h) <= self.threshold
    }

    /// `[nearest, LEAF_K-th nearest]` distances of every probe, measured against the whole
    /// scene ([`super::spacing::column_probe_knn`]): what the in-core root measures, for a
    /// root that is streamed.
    pub(super) fn probe_knn(&self) -> Vec<[f32; 2]> {
        super::spacing::column_probe_knn(
            self.cloud.positions(),
            |i| self.is_probe(i),
            self.cloud.bounds(),
            crate::leaf::LEAF_K,
            |range| self.cloud.release_pages(range),
        )
    }

    /// The sum of the quantised normals, in order (the root's cone axis before its scan; zero
    /// without normals): one pass over the normal column, blocks encoded in parallel while
    /// the previous one is summed.
    pub(super) fn normal_sum(&self) -> DVec3 {
        let mut nsum = DVec3::ZERO;
        let Some(nv) = self.cloud.normals() else {
            return nsum;
        };
        let n = nv.len();
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
                    self.cloud.release_pages(lo..hi);
                },
            );
            std::mem::swap(&mut codes, &mut prev);
            prev_len = hi - lo;
        }
        sum(&prev[..prev_len], &mut nsum);
        nsum
    }

    /// Appends the samples of `range` to `out` (converted in parallel), adds their quantised
    /// normals to `nsum` when given (in order: the same sum for any thread count) and
    /// releases the columns' pages of `range`.
    pub(super) fn convert(
        &self,
        range: Range<usize>,
        out: &mut Vec<Sample>,
        nsum: Option<&mut DVec3>,
    ) {
        let cloud = self.cloud;
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
                    *s = Sample {
                        p: pos[j],
                        normal: nrm.map_or(0, |nv| cloud::oct16_encode(Vec3::from(nv[j]))),
                        flags: if self.is_probe(i) { PROBE } else { 0 },
                        color: col.map_or([0; 4], |c| [c[j][0], c[j][1], c[j][2], 0]),
                    };
                }
            });
        if let (Some(nsum), true) = (nsum, nrm.is_some()) {
            let table = cloud::normal_table();
            for s in &out[start..] {
                let d = table[s.normal as usize].1;
                *nsum += DVec3::new(d[0] as f64, d[1] as f64, d[2] as f64);
            }
        }
        cloud.release_pages(range);
    }
}

/// The samples of one node, readable again and again in the same order.
#[derive(Clone, Copy)]
pub(super) enum Source<'a> {
    /// The whole scene (the root).
    Columns(&'a Columns<'a>),
    /// The first `n` records of a temporary file.
    File { path: &'a Path, n: u64 },
}

impl<'a> Source<'a> {
    /// Samples in the source.
    pub(super) fn len(&self) -> u64 {
        match self {
            Source::Columns(c) => c.len(),
            Source::File { n, .. } => *n,
        }
    }

    /// Opens one read of the source.
    pub(super) fn reader(&self) -> Result<Reader<'a>, MethodError> {
        Ok(match *self {
            Source::Columns(cols) => Reader::Columns { cols, next: 0 },
            Source::File { path, n } => {
                let file = File::open(path).map_err(|e| MethodError::io(path, e))?;
                Reader::File {
                    path,
                    r: BufReader::with_capacity(IO_BUF, file),
                    left: n,
                }
            }
        })
    }
}

/// One read of a [`Source`].
pub(super) enum Reader<'a> {
    Columns {
        cols: &'a Columns<'a>,
        next: usize,
    },
    File {
        path: &'a Path,
        r: BufReader<File>,
        left: u64,
    },
}

impl Reader<'_> {
    /// Replaces `block` with the next samples (at most [`BLOCK`]); false at the end. A file
    /// shorter than its node is an error naming it.
    pub(super) fn next(&mut self, block: &mut Vec<Sample>) -> Result<bool, MethodError> {
        block.clear();
        match self {
            Reader::Columns { cols, next } => {
                let n = cols.len() as usize;
                if *next >= n {
                    return Ok(false);
                }
                let hi = (*next + BLOCK).min(n);
                cols.convert(*next..hi, block, None);
                *next = hi;
            }
            Reader::File { path, r, left } => {
                let len = (*left).min(BLOCK as u64) as usize;
                if len == 0 {
                    return Ok(false);
                }
                block.resize(len, Sample::default());
                r.read_exact(bytemuck::cast_slice_mut(block))
                    .map_err(|e| MethodError::io(*path, e))?;
                *left -= len as u64;
            }
        }
        Ok(true)
    }
}

/// Reads `out.len()` records from the start of `path`.
pub(super) fn read_samples(path: &Path, out: &mut [Sample]) -> Result<(), MethodError> {
    let file = File::open(path).map_err(|e| MethodError::io(path, e))?;
    let mut r = BufReader::with_capacity(IO_BUF, file);
    r.read_exact(bytemuck::cast_slice_mut(out))
        .map_err(|e| MethodError::io(path, e))
}
