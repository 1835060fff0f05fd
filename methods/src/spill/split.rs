//! Streamed splits of sample records ([`super::samples`]), shared by the builds in units
//! (QSplat's binary partition, MWKD's N-way split): read a range's records in order
//! ([`scan`]), find exact order statistics of their keys ([`select_keys`]), and route
//! every record into one of several child files ([`route`]), stably, so each child file
//! keeps input order.
//!
//! The order is that of the in-memory builds' `select_nth_unstable_by`: coordinate in
//! [`f32_total_order`], ties by input index ([`rank_key`]). A key is unique per sample, so
//! the samples of rank `< k` are exactly those whose key is `<` the key of rank `k`.

use glam::Vec3;
use scenes::PointCloud;

use super::samples::{EMPTY_BOX, SampleLayout, f32_at, grow, index_of, pos_of};
use super::{BLOCK_BYTES, Spill, SpillDir};
use crate::MethodError;
use crate::overlap::overlapped;
use crate::sortkey::f32_total_order;

/// Calls `f` with every record of `src`, or, for `None`, of the whole cloud in input order
/// (encoded on the fly in blocks; the cloud's mapped pages are released behind the cursor,
/// so the scan does not make the scene file resident).
pub fn scan(
    src: Option<&Spill>,
    cloud: &PointCloud,
    layout: SampleLayout,
    mut f: impl FnMut(&[u8]) -> Result<(), MethodError>,
) -> Result<(), MethodError> {
    let rb = layout.bytes();
    match src {
        Some(s) => s.read(|block| {
            for r in block.chunks_exact(rb) {
                f(r)?;
            }
            Ok(())
        }),
        None => {
            const BLOCK: usize = 1 << 16;
            let mut buf = Vec::with_capacity(BLOCK * rb);
            let n = cloud.len();
            for start in (0..n).step_by(BLOCK) {
                let end = (start + BLOCK).min(n);
                buf.clear();
                for i in start..end {
                    layout.encode(cloud, i, &mut buf);
                }
                for r in buf.chunks_exact(rb) {
                    f(r)?;
                }
                cloud.release_pages(start..end);
            }
            Ok(())
        }
    }
}

/// The selection key of record `r` along `axis`: coordinate in total order, then index.
pub fn rank_key(r: &[u8], axis: usize) -> u64 {
    ((f32_total_order(f32_at(r, 4 + 4 * axis)) as u64) << 32) | index_of(r) as u64
}

/// Passes of [`select_keys`] (16 bits each, from the top of the 64-bit key).
pub const SELECT_PASSES: u32 = 4;

/// The keys of ranks `ranks` (non-decreasing) among the keys that `scan` hands to its
/// argument: a radix selection, 16 bits per pass from the top, all ranks in the same
/// [`SELECT_PASSES`] scans (one histogram per distinct prefix still in play). `scan` must
/// yield the same keys on every call. A rank at or beyond the number of keys is an error.
pub fn select_keys(
    ranks: &[u64],
    mut scan: impl FnMut(&mut dyn FnMut(u64)) -> Result<(), MethodError>,
) -> Result<Vec<u64>, MethodError> {
    if ranks.windows(2).any(|w| w[0] > w[1]) {
        return Err(MethodError::Limit(format!(
            "select_keys: ranks {ranks:?} not in order"
        )));
    }
    let mut prefix = vec![0u64; ranks.len()];
    let mut rest = ranks.to_vec();
    for pass in 0..SELECT_PASSES {
        let shift = 48 - 16 * pass;
        // The bits fixed so far (none in the first pass).
        let high = |k: u64| k.checked_shr(shift + 16).unwrap_or(0);
        let mut groups: Vec<u64> = prefix.iter().map(|&p| high(p)).collect();
        groups.dedup();
        let mut hist = vec![0u64; groups.len() << 16];
        scan(&mut |k| {
            let at = if groups.len() == 1 {
                (high(k) == groups[0]).then_some(0)
            } else {
                groups.binary_search(&high(k)).ok()
            };
            if let Some(g) = at {
                hist[(g << 16) | ((k >> shift) & 0xFFFF) as usize] += 1;
            }
        })?;
        for (p, r) in prefix.iter_mut().zip(&mut rest) {
            let g = groups.binary_search(&high(*p)).unwrap_or(0);
            let h = &hist[g << 16..(g + 1) << 16];
            let mut digit = 0usize;
            while *r >= h[digit] {
                *r -= h[digit];
                digit += 1;
                if digit == h.len() {
                    return Err(MethodError::Limit(format!(
                        "select_keys: rank beyond the keys scanned (ranks {ranks:?})"
                    )));
                }
            }
            *p |= (digit as u64) << shift;
        }
    }
    Ok(prefix)
}

/// One part of a [`route`]: its record count, file and bounding box.
pub type Part = (u64, Spill, (Vec3, Vec3));

/// Streams the records of `src` (the cloud for `None`) into `parts` new files of `spill`,
/// record `r` into part `which(r)` (< `parts`), in order; returns each part's count, file
/// and the bounding box of its positions. Reading and routing run on this thread, writing
/// on a second one ([`crate::overlap`]): the same files as one loop.
pub fn route(
    src: Option<&Spill>,
    cloud: &PointCloud,
    layout: SampleLayout,
    spill: &SpillDir,
    parts: usize,
    which: impl Fn(&[u8]) -> usize,
) -> Result<Vec<Part>, MethodError> {
    let rb = layout.bytes();
    // Many parts share a bounded amount of buffer.
    let block = (BLOCK_BYTES * 2 / parts.max(1)).clamp(1 << 16, BLOCK_BYTES);
    let w = (0..parts)
        .map(|_| spill.writer_with_block("samples", rb, block))
        .collect::<Result<Vec<_>, _>>()?;
    let state = (w, vec![0u64; parts], vec![EMPTY_BOX; parts]);
    let (w, n, b) = overlapped(
        state,
        1,
        |(w, n, b), routed: Vec<Routed>| {
            for r in routed {
                for (rec, &k) in r.records.chunks_exact(rb).zip(&r.parts) {
                    let k = k as usize;
                    n[k] += 1;
                    grow(&mut b[k], pos_of(rec));
                    w[k].push(rec)?;
                }
            }
            Ok::<(), MethodError>(())
        },
        |feed| {
            let mut cur = Routed::with_capacity(rb);
            scan(src, cloud, layout, |rec| {
                let k = which(rec);
                if k >= parts {
                    return Err(MethodError::Limit(format!(
                        "split: a record routed to part {k} of {parts}"
                    )));
                }
                cur.parts.push(k as u32);
                cur.records.extend_from_slice(rec);
                if cur.parts.len() == ROUTE_BATCH {
                    feed.push(std::mem::replace(&mut cur, Routed::with_capacity(rb)))?;
                }
                Ok(())
            })?;
            if !cur.parts.is_empty() {
                feed.push(cur)?;
            }
            Ok(())
        },
    )?;
    w.into_iter()
        .zip(n.into_iter().zip(b))
        .map(|(w, (n, b))| Ok((n, w.finish()?, b)))
        .collect()
}

/// Records per batch handed from [`route`]'s reader to its writer.
const ROUTE_BATCH: usize = 1 << 14;

/// A batch of [`route`]: records and the part of each.
struct Routed {
    records: Vec<u8>,
    parts: Vec<u32>,
}

impl Routed {
    fn with_capacity(record_bytes: usize) -> Self {
        Routed {
            records: Vec::with_capacity(ROUTE_BATCH * record_bytes),
            parts: Vec::with_capacity(ROUTE_BATCH),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn keys(n: u64) -> Vec<u64> {
        // Many equal high parts, spread low parts, and a few extremes.
        let mut k: Vec<u64> = (0..n)
            .map(|i| ((i * 7919 % 13) << 40) | (i * 104_729 % 65_537) << 8 | i)
            .collect();
        k.extend([0, u64::MAX, 1 << 63]);
        k
    }

    #[test]
    fn select_keys_matches_a_sort_for_many_ranks_at_once() {
        let k = keys(50_000);
        let mut sorted = k.clone();
        sorted.sort_unstable();
        let ranks = [
            0,
            1,
            17,
            12_500,
            12_500,
            25_000,
            49_999,
            sorted.len() as u64 - 1,
        ];
        let mut calls = 0;
        let got = select_keys(&ranks, |f| {
            calls += 1;
            k.iter().for_each(|&v| f(v));
            Ok(())
        })
        .unwrap();
        let want: Vec<u64> = ranks.iter().map(|&r| sorted[r as usize]).collect();
        assert_eq!(got, want);
        assert_eq!(calls, SELECT_PASSES);
    }

    #[test]
    fn select_keys_refuses_ranks_beyond_the_keys_and_out_of_order() {
        let k = keys(100);
        let scan = |f: &mut dyn FnMut(u64)| {
            k.iter().for_each(|&v| f(v));
            Ok(())
        };
        let e = select_keys(&[103], scan).unwrap_err().to_string();
        assert!(e.contains("rank beyond"), "{e}");
        let e = select_keys(&[5, 3], scan).unwrap_err().to_string();
        assert!(e.contains("not in order"), "{e}");
    }
}
