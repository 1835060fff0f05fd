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

/// Passes of [`radix_select`] (16 bits each, from the top of the 64-bit key).
pub const SELECT_PASSES: u32 = 4;

/// Buckets of [`select_keys`]' first pass (a histogram of 512 KiB, as one radix pass).
const BUCKET_BITS: u32 = 16;

/// Most keys [`select_keys`] collects in its second pass (32 MiB); beyond, it selects by
/// radix instead.
pub const COLLECT_MAX: u64 = 1 << 22;

/// The range of [`rank_key`]s of records whose coordinate lies in `lo..=hi`.
pub fn key_range(lo: f32, hi: f32) -> (u64, u64) {
    (
        u64::from(f32_total_order(lo)) << 32,
        (u64::from(f32_total_order(hi)) << 32) | u64::from(u32::MAX),
    )
}

/// The keys of ranks `ranks` (non-decreasing) among the keys that `scan` hands to its
/// argument, in two scans when the keys lie in `range` (inclusive; a key outside still
/// counts, in the first or last bucket): the first counts the keys per bucket of `range`
/// ([`BUCKET_BITS`] bits of buckets, each an equal slice of the range), the second collects
/// the keys of the buckets holding a wanted rank and selects among them. When those buckets
/// hold more than [`COLLECT_MAX`] keys (a range given too wide, or piles of equal
/// coordinates), the selection is [`radix_select`]'s instead. `scan` must yield the same
/// keys on every call. A rank at or beyond the number of keys is an error.
pub fn select_keys(
    ranks: &[u64],
    range: (u64, u64),
    scan: impl FnMut(&mut dyn FnMut(u64)) -> Result<(), MethodError>,
) -> Result<Vec<u64>, MethodError> {
    select_keys_capped(ranks, range, COLLECT_MAX, scan)
}

/// [`select_keys`] with the collection capped at `cap` keys.
fn select_keys_capped(
    ranks: &[u64],
    range: (u64, u64),
    cap: u64,
    mut scan: impl FnMut(&mut dyn FnMut(u64)) -> Result<(), MethodError>,
) -> Result<Vec<u64>, MethodError> {
    check_ranks(ranks)?;
    if ranks.is_empty() {
        return Ok(Vec::new());
    }
    let (lo, hi) = (range.0.min(range.1), range.0.max(range.1));
    // The smallest shift that maps the range onto at most 2^BUCKET_BITS buckets.
    let shift = (64 - (hi - lo).leading_zeros()).saturating_sub(BUCKET_BITS);
    let last = ((hi - lo) >> shift) as usize;
    let bucket = |k: u64| (k.clamp(lo, hi) - lo) >> shift;
    let mut hist = vec![0u64; last + 1];
    scan(&mut |k| hist[bucket(k) as usize] += 1)?;
    // Each rank's bucket and its rank among that bucket's keys (one sweep: ranks ascend).
    let mut wanted: Vec<(usize, u64)> = Vec::with_capacity(ranks.len());
    let (mut b, mut below) = (0usize, 0u64);
    for &r in ranks {
        while b < hist.len() && below + hist[b] <= r {
            below += hist[b];
            b += 1;
        }
        if b == hist.len() {
            return Err(beyond(ranks));
        }
        wanted.push((b, r - below));
    }
    let mut buckets: Vec<usize> = wanted.iter().map(|w| w.0).collect();
    buckets.dedup();
    if buckets.iter().map(|&b| hist[b]).sum::<u64>() > cap {
        return radix_select(ranks, scan);
    }
    let mut held: Vec<Vec<u64>> = buckets
        .iter()
        .map(|&b| Vec::with_capacity(hist[b] as usize))
        .collect();
    let (first, end) = (buckets[0] as u64, buckets[buckets.len() - 1] as u64);
    scan(&mut |k| {
        let b = bucket(k);
        if (first..=end).contains(&b)
            && let Ok(i) = buckets.binary_search(&(b as usize))
        {
            held[i].push(k);
        }
    })?;
    wanted
        .iter()
        .map(|&(b, r)| {
            let i = buckets.binary_search(&b).unwrap_or(0);
            let keys = &mut held[i];
            if keys.len() as u64 != hist[b] {
                return Err(MethodError::Limit(format!(
                    "select_keys: a second scan gave {} keys in bucket {b}, the first {}",
                    keys.len(),
                    hist[b]
                )));
            }
            let (_, k, _) = keys.select_nth_unstable(r as usize);
            Ok(*k)
        })
        .collect()
}

fn check_ranks(ranks: &[u64]) -> Result<(), MethodError> {
    if ranks.windows(2).any(|w| w[0] > w[1]) {
        return Err(MethodError::Limit(format!(
            "select_keys: ranks {ranks:?} not in order"
        )));
    }
    Ok(())
}

fn beyond(ranks: &[u64]) -> MethodError {
    MethodError::Limit(format!(
        "select_keys: rank beyond the keys scanned (ranks {ranks:?})"
    ))
}

/// The keys of ranks `ranks` (non-decreasing) by a radix selection, 16 bits per pass from
/// the top, all ranks in the same [`SELECT_PASSES`] scans (one histogram per distinct prefix
/// still in play); needs no range and no memory beyond the histograms.
pub fn radix_select(
    ranks: &[u64],
    mut scan: impl FnMut(&mut dyn FnMut(u64)) -> Result<(), MethodError>,
) -> Result<Vec<u64>, MethodError> {
    check_ranks(ranks)?;
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
                    return Err(beyond(ranks));
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

    /// The keys of `ranks` by a sort, and the number of scans `select` took.
    fn check(
        k: &[u64],
        ranks: &[u64],
        select: impl FnOnce(&mut dyn FnMut(&mut dyn FnMut(u64)) -> Result<(), MethodError>) -> Vec<u64>,
    ) -> u32 {
        let mut sorted = k.to_vec();
        sorted.sort_unstable();
        let mut calls = 0;
        let got = select(&mut |f| {
            calls += 1;
            k.iter().for_each(|&v| f(v));
            Ok(())
        });
        let want: Vec<u64> = ranks.iter().map(|&r| sorted[r as usize]).collect();
        assert_eq!(got, want, "ranks {ranks:?}");
        calls
    }

    const RANKS: [u64; 8] = [0, 1, 17, 12_500, 12_500, 25_000, 49_999, 50_002];

    #[test]
    fn select_keys_matches_a_sort_in_two_scans_for_many_ranks_at_once() {
        let k = keys(50_000);
        let tight = (*k.iter().min().unwrap(), *k.iter().max().unwrap());
        // A tight range, the whole u64 range, and one narrower than the keys (keys outside
        // count in the end buckets): all exact, in two scans.
        for range in [tight, (0, u64::MAX), (1 << 40, 1 << 44), (7, 7)] {
            let calls = check(&k, &RANKS, |scan| {
                select_keys(&RANKS, range, |f| scan(f)).unwrap()
            });
            assert_eq!(calls, 2, "range {range:?}");
        }
    }

    #[test]
    fn select_keys_selects_by_radix_when_the_wanted_buckets_exceed_the_cap() {
        let k = keys(50_000);
        // One bucket holds everything (a range of one key): 50 003 keys > a cap of 1000.
        let calls = check(&k, &RANKS, |scan| {
            select_keys_capped(&RANKS, (5, 5), 1000, |f| scan(f)).unwrap()
        });
        assert_eq!(calls, 1 + SELECT_PASSES);
        let calls = check(&k, &RANKS, |scan| {
            radix_select(&RANKS, |f| scan(f)).unwrap()
        });
        assert_eq!(calls, SELECT_PASSES);
        // Equal keys: any rank among them is that key.
        let same = vec![42u64; 3000];
        let calls = check(&same, &[0, 1500, 2999], |scan| {
            select_keys_capped(&[0, 1500, 2999], (0, u64::MAX), 100, |f| scan(f)).unwrap()
        });
        assert_eq!(calls, 1 + SELECT_PASSES);
    }

    #[test]
    fn select_keys_refuses_ranks_beyond_the_keys_and_out_of_order() {
        let k = keys(100);
        let scan = |f: &mut dyn FnMut(u64)| {
            k.iter().for_each(|&v| f(v));
            Ok(())
        };
        for cap in [COLLECT_MAX, 0] {
            let e = select_keys_capped(&[103], (0, u64::MAX), cap, scan)
                .unwrap_err()
                .to_string();
            assert!(e.contains("rank beyond"), "{e}");
            let e = select_keys_capped(&[5, 3], (0, u64::MAX), cap, scan)
                .unwrap_err()
                .to_string();
            assert!(e.contains("not in order"), "{e}");
        }
        let e = radix_select(&[103], scan).unwrap_err().to_string();
        assert!(e.contains("rank beyond"), "{e}");
        // No rank: no scan.
        let got = select_keys(&[], (0, 1), |_| panic!("scanned")).unwrap();
        assert!(got.is_empty());
    }

    #[test]
    fn a_second_scan_that_differs_is_an_error() {
        let k = keys(1000);
        let mut calls = 0;
        let e = select_keys(&[500], (0, u64::MAX), |f| {
            calls += 1;
            // The second scan drops a key.
            k.iter().skip(calls - 1).for_each(|&v| f(v));
            Ok(())
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("second scan"), "{e}");
    }

    #[test]
    fn key_range_bounds_the_rank_keys_of_its_coordinates() {
        let (lo, hi) = key_range(-2.5, 7.0);
        for x in [-2.5f32, -0.0, 0.0, 3.25, 7.0] {
            for index in [0u32, 1, u32::MAX] {
                let k = (u64::from(f32_total_order(x)) << 32) | u64::from(index);
                assert!((lo..=hi).contains(&k), "{x} {index}");
            }
        }
        let below = u64::from(f32_total_order(-2.6)) << 32 | u64::from(u32::MAX);
        let above = u64::from(f32_total_order(7.01)) << 32;
        assert!(below < lo && above > hi);
    }
}
