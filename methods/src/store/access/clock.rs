//! Where a [`super::Loader`] reads the time for its throughput meter: the system's monotonic
//! clock, or a clock that moves only when told, so that a test of the meter measures an exact
//! rate instead of one that depends on how busy the machine is (a sleeping source overshoots
//! by whatever the scheduler adds; a source that advances a [`ManualClock`] takes exactly the
//! time it says).

use std::sync::Arc;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{Duration, Instant};

/// The loader's clock.
#[derive(Debug, Clone, Default)]
pub enum Clock {
    /// [`Instant::now`].
    #[default]
    System,
    /// A clock that a test drives.
    Manual(Arc<ManualClock>),
}

impl Clock {
    /// The time now.
    pub fn now(&self) -> Instant {
        match self {
            Clock::System => Instant::now(),
            Clock::Manual(m) => m.now(),
        }
    }
}

/// A clock that stands still until [`ManualClock::advance`] moves it (from any thread).
#[derive(Debug)]
pub struct ManualClock {
    origin: Instant,
    nanos: AtomicU64,
}

impl ManualClock {
    /// A clock at an arbitrary origin, for [`Clock::Manual`].
    pub fn new() -> Arc<Self> {
        Arc::new(Self {
            origin: Instant::now(),
            nanos: AtomicU64::new(0),
        })
    }

    /// The time now: the origin plus every advance so far.
    pub fn now(&self) -> Instant {
        self.origin + Duration::from_nanos(self.nanos.load(Ordering::SeqCst))
    }

    /// Moves the clock forward by `d`.
    pub fn advance(&self, d: Duration) {
        let ns = u64::try_from(d.as_nanos()).unwrap_or(u64::MAX);
        self.nanos.fetch_add(ns, Ordering::SeqCst);
    }

    /// Moves the clock forward to `t` (no change if it is already there or later): what a
    /// sleep until `t` does on this clock.
    pub fn advance_to(&self, t: Instant) {
        let ns =
            u64::try_from(t.saturating_duration_since(self.origin).as_nanos()).unwrap_or(u64::MAX);
        self.nanos.fetch_max(ns, Ordering::SeqCst);
    }
}

impl Clock {
    /// Waits until `t`: a real sleep on the system clock; on a manual clock, the clock moves
    /// to `t` at once (the wait takes no real time).
    pub fn sleep_until(&self, t: Instant) {
        match self {
            Clock::System => {
                let now = Instant::now();
                if t > now {
                    std::thread::sleep(t - now);
                }
            }
            Clock::Manual(m) => m.advance_to(t),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_manual_clock_moves_only_when_told() {
        let m = ManualClock::new();
        let c = Clock::Manual(m.clone());
        let t0 = c.now();
        assert_eq!(c.now(), t0);
        m.advance(Duration::from_millis(50));
        m.advance(Duration::from_millis(25));
        assert_eq!(c.now() - t0, Duration::from_millis(75));
        // Sleeping to a time past is no change; to a time ahead moves the clock there.
        c.sleep_until(t0 + Duration::from_millis(10));
        assert_eq!(c.now() - t0, Duration::from_millis(75));
        c.sleep_until(t0 + Duration::from_millis(100));
        assert_eq!(c.now() - t0, Duration::from_millis(100));
        assert!(Clock::System.now() >= t0);
    }
}
