//! The loader's measured throughput (`DataAccess::throughput`, the paper's "estimated
//! bandwidth") and its requests in flight (`LoaderOptions::in_flight`), with a source whose
//! every fetch takes a known time on a clock the test drives (`ManualClock`): the measured
//! rates are exact, whatever the machine's load (no sleep, no wall-clock bound).
#![allow(clippy::unwrap_used)]

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Barrier};
use std::time::{Duration, Instant};

use methods::store::access::{
    ChunkSource, Clock, DataAccess, Decoder, Loader, LoaderOptions, ManualClock, Retry,
};
use methods::{MethodError, SplatBatch};

/// Stored bytes of every chunk of [`Timed`].
const STORED: u64 = 10_000;

/// A source whose fetches take `per_fetch` on `clock`, `batch` at a time: the fetches of a
/// batch wait for each other, one of them moves the clock by `per_fetch`, and all return at
/// once (so `batch` fetches in flight overlap exactly). It records how many fetches were in
/// flight at once.
struct Timed {
    chunks: usize,
    per_fetch: Duration,
    clock: Arc<ManualClock>,
    batch: Barrier,
    now: AtomicUsize,
    most: AtomicUsize,
}

impl Timed {
    fn new(chunks: usize, per_fetch: Duration, batch: usize) -> Arc<Self> {
        Arc::new(Self {
            chunks,
            per_fetch,
            clock: ManualClock::new(),
            batch: Barrier::new(batch),
            now: AtomicUsize::new(0),
            most: AtomicUsize::new(0),
        })
    }
}

impl ChunkSource for Timed {
    fn len(&self) -> usize {
        self.chunks
    }
    fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError> {
        let n = self.now.fetch_add(1, Ordering::SeqCst) + 1;
        self.most.fetch_max(n, Ordering::SeqCst);
        if self.batch.wait().is_leader() {
            self.clock.advance(self.per_fetch);
        }
        self.now.fetch_sub(1, Ordering::SeqCst);
        self.batch.wait();
        Ok(vec![id as u8; 4])
    }
    fn stored_bytes(&self, _id: u32) -> u64 {
        STORED
    }
}

fn decoder() -> Decoder {
    Arc::new(|_, bytes: &[u8]| {
        Ok(SplatBatch {
            positions: bytes.iter().map(|&b| [b as f32, 0.0, 0.0]).collect(),
            normals: None,
            colors: None,
            radii: None,
            lod: None,
        })
    })
}

fn loader(source: Arc<dyn ChunkSource>, clock: &Arc<ManualClock>, in_flight: u32) -> Loader {
    Loader::spawn_clocked(
        source,
        decoder(),
        LoaderOptions {
            core_bytes: 1 << 30,
            delay_frames: 0,
            in_flight,
        },
        Retry::NONE,
        Clock::Manual(clock.clone()),
    )
}

/// Waits until every request is served; the deadline only keeps a hung loader from hanging
/// the test (nothing is measured in real time).
fn drain(l: &Loader) {
    let deadline = Instant::now() + Duration::from_secs(60);
    while l.pending() > 0 {
        assert!(Instant::now() < deadline, "the loader never drained");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// `a` equals `b` up to float rounding.
fn exact(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-9 * b.abs()
}

/// Bytes over busy time: 20 fetches of 50 ms and 10 kB each, in two bursts with a second of
/// idleness between them, measure exactly 200 kB/s. Had the idle second counted, the rate
/// would be 1/2 of that.
#[test]
fn the_rate_is_bytes_over_the_time_spent_fetching() {
    let source = Timed::new(64, Duration::from_millis(50), 1);
    let clock = source.clock.clone();
    let l = loader(source.clone(), &clock, 1);
    assert_eq!(l.throughput(), None, "no response, no estimate");
    for burst in 0..2u32 {
        for id in burst * 10..burst * 10 + 10 {
            l.request(id);
        }
        drain(&l);
        if burst == 0 {
            clock.advance(Duration::from_secs(1));
        }
    }
    let t = l.throughput().unwrap();
    assert_eq!(t.responses, 20);
    let want = STORED as f64 / 0.050;
    assert!(
        exact(t.bytes_per_s, want),
        "measured {:.3} B/s, fetches deliver {want:.3} B/s",
        t.bytes_per_s
    );
    assert!(exact(t.chunks_per_s * STORED as f64, t.bytes_per_s));
    assert_eq!(l.traffic().failed, 0);
}

/// Four in flight: never more than four fetches at once, four reached, and the busy time
/// counts overlapping fetches once, so the rate is exactly four times one fetch's (16 fetches
/// of 50 ms, four at a time, keep the loader busy for 200 ms).
#[test]
fn requests_in_flight_overlap_and_their_rate_adds_up() {
    let source = Timed::new(64, Duration::from_millis(50), 4);
    let clock = source.clock.clone();
    let l = loader(source.clone(), &clock, 4);
    for id in 0..16 {
        l.request(id);
    }
    drain(&l);
    assert_eq!(source.most.load(Ordering::SeqCst), 4);
    let t = l.throughput().unwrap();
    let want = 4.0 * STORED as f64 / 0.050;
    assert!(
        exact(t.bytes_per_s, want),
        "measured {:.3} B/s, four at a time deliver {want:.3} B/s",
        t.bytes_per_s
    );
    for id in 0..16 {
        assert!(l.available(id), "chunk {id} was delivered");
    }
}

/// Only the last `METER_WINDOW` responses count: after a slow phase and a fast one, the rate
/// is the fast one's.
#[test]
fn the_rate_follows_the_recent_responses() {
    struct Phased {
        slow_until: u32,
        clock: Arc<ManualClock>,
    }
    impl ChunkSource for Phased {
        fn len(&self) -> usize {
            1000
        }
        fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError> {
            let ms = if id < self.slow_until { 100 } else { 25 };
            self.clock.advance(Duration::from_millis(ms));
            Ok(vec![0; 4])
        }
        fn stored_bytes(&self, _id: u32) -> u64 {
            STORED
        }
    }
    let w = methods::store::access::METER_WINDOW as u32;
    let clock = ManualClock::new();
    let l = loader(
        Arc::new(Phased {
            slow_until: 8,
            clock: clock.clone(),
        }),
        &clock,
        1,
    );
    for id in 0..8 + w {
        l.request(id);
    }
    drain(&l);
    let t = l.throughput().unwrap();
    assert_eq!(t.responses, w as usize);
    let fast = STORED as f64 / 0.025;
    assert!(
        exact(t.bytes_per_s, fast),
        "measured {:.3} B/s, the last {w} fetches deliver {fast:.3} B/s",
        t.bytes_per_s
    );
}
