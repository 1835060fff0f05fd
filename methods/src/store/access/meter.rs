//! The loader's throughput meter: bytes and chunks over the time a fetch was in flight.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

use super::Throughput;

/// Responses over which [`Throughput`] is measured.
pub const METER_WINDOW: usize = 32;

/// The loader's fetch time: the time during which at least one fetch was in flight ("busy"),
/// and after each response the totals so far, for the last [`METER_WINDOW`] responses. Idle
/// time (nothing asked) does not count, and parallel fetches count once, so bytes over busy
/// time is the rate the source delivers at, whatever the number in flight.
pub(super) struct Meter {
    /// Fetches in flight.
    active: u32,
    /// Start of the current busy stretch (while `active > 0`).
    busy_since: Option<Instant>,
    /// Busy time of the finished stretches.
    busy: Duration,
    /// Stored bytes and chunks received so far.
    bytes: u64,
    chunks: u64,
    /// (bytes, chunks, busy seconds) after each of the last responses, and one before them.
    recent: VecDeque<(u64, u64, f64)>,
}

impl Meter {
    pub(super) fn new() -> Self {
        Self {
            active: 0,
            busy_since: None,
            busy: Duration::ZERO,
            bytes: 0,
            chunks: 0,
            recent: VecDeque::from([(0, 0, 0.0)]),
        }
    }

    pub(super) fn start(&mut self, now: Instant) {
        if self.active == 0 {
            self.busy_since = Some(now);
        }
        self.active += 1;
    }

    /// A fetch ended at `now`, bringing `stored` bytes (`None`: it failed).
    pub(super) fn end(&mut self, now: Instant, stored: Option<u64>) {
        let since = self.busy_since.unwrap_or(now);
        let busy = self.busy + now.saturating_duration_since(since);
        if let Some(b) = stored {
            self.bytes += b;
            self.chunks += 1;
        }
        self.recent
            .push_back((self.bytes, self.chunks, busy.as_secs_f64()));
        if self.recent.len() > METER_WINDOW + 1 {
            self.recent.pop_front();
        }
        self.active = self.active.saturating_sub(1);
        if self.active == 0 {
            self.busy = busy;
            self.busy_since = None;
        }
    }

    pub(super) fn throughput(&self) -> Option<Throughput> {
        let (&(b0, c0, t0), &(b1, c1, t1)) = (self.recent.front()?, self.recent.back()?);
        let dt = t1 - t0;
        (self.recent.len() > 1 && dt > 0.0).then(|| Throughput {
            bytes_per_s: (b1 - b0) as f64 / dt,
            chunks_per_s: (c1 - c0) as f64 / dt,
            responses: self.recent.len() - 1,
        })
    }
}
