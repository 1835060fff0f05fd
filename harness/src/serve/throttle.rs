//! Bandwidth and latency of the served link, for experiments: one rate shared by every
//! connection (as one network link would be), paced in small slices.

use std::io::Read;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use methods::store::access::Clock;

/// Bytes sent per slice of a throttled body: small enough that the pacing is smooth at a few
/// MB/s (3.3 ms per slice at 5 MB/s), large enough that the pacing costs nothing measurable.
pub const SLICE: usize = 16 * 1024;

/// A link of `rate` bytes/s shared by all responses: each slice is given the next free
/// interval of the link, so `n` bytes sent through it take at least `n / rate` seconds in
/// total, whatever the number of connections.
#[derive(Debug)]
pub struct Link {
    rate: f64,
    /// When the link is free again.
    free_at: Mutex<Instant>,
    /// The time the pacing reads and waits on (a test's manual clock: no real waiting).
    clock: Clock,
}

impl Link {
    /// A link of `rate` bytes/s (finite, `> 0`).
    pub fn new(rate: f64) -> Self {
        Self::with_clock(rate, Clock::System)
    }

    /// [`Link::new`], paced on `clock`.
    pub fn with_clock(rate: f64, clock: Clock) -> Self {
        Self {
            rate,
            free_at: Mutex::new(clock.now()),
            clock,
        }
    }

    /// Reserves the link for `bytes` and sleeps until the end of that reservation.
    pub fn pace(&self, bytes: usize) {
        let done = {
            // A poisoned lock only means another response panicked mid-slice: the time in
            // it is still right.
            let mut free = self.free_at.lock().unwrap_or_else(|p| p.into_inner());
            let start = (*free).max(self.clock.now());
            *free = start + Duration::from_secs_f64(bytes as f64 / self.rate);
            *free
        };
        self.clock.sleep_until(done);
    }
}

/// A body read through a [`Link`]: at most [`SLICE`] bytes per read, each read paced.
pub struct Paced<R> {
    inner: R,
    link: Arc<Link>,
}

impl<R> Paced<R> {
    /// `inner` read through `link`.
    pub fn new(inner: R, link: Arc<Link>) -> Self {
        Self { inner, link }
    }
}

impl<R: Read> Read for Paced<R> {
    fn read(&mut self, buf: &mut [u8]) -> std::io::Result<usize> {
        let want = buf.len().min(SLICE);
        let n = self.inner.read(&mut buf[..want])?;
        if n > 0 {
            self.link.pace(n);
        }
        Ok(n)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_paced_body_takes_its_bytes_over_the_rate_and_arrives_whole() {
        // 256 KiB at 2 MiB/s: 125 ms at least (the pacing sleeps to the end of each slice's
        // interval), and not much more on an idle machine; the upper bound is loose because a
        // loaded CI machine may oversleep.
        let data: Vec<u8> = (0..256 * 1024).map(|i| (i % 251) as u8).collect();
        let link = Arc::new(Link::new(2.0 * 1024.0 * 1024.0));
        let t = Instant::now();
        let mut out = Vec::new();
        Paced::new(&data[..], link).read_to_end(&mut out).unwrap();
        let s = t.elapsed().as_secs_f64();
        assert_eq!(out, data);
        assert!(s >= 0.125, "{s} s");
        assert!(s < 2.0, "{s} s");
    }

    #[test]
    fn connections_share_one_link() {
        // Two readers of 128 KiB each over one 2 MiB/s link: 256 KiB in all, ≥ 125 ms.
        let link = Arc::new(Link::new(2.0 * 1024.0 * 1024.0));
        let t = Instant::now();
        std::thread::scope(|s| {
            for _ in 0..2 {
                let link = link.clone();
                s.spawn(move || {
                    let data = vec![7u8; 128 * 1024];
                    let mut out = Vec::new();
                    Paced::new(&data[..], link).read_to_end(&mut out).unwrap();
                    assert_eq!(out.len(), data.len());
                });
            }
        });
        let s = t.elapsed().as_secs_f64();
        assert!(s >= 0.125, "{s} s");
    }
}
