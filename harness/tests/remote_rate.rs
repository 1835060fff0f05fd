//! The loader's bandwidth estimate over HTTP (issue 17: "bandwidth estimate within 20 % of
//! a throttled server's rate"): a served repository behind `--bandwidth`, read with one and
//! with four requests in flight; the link is shared, so four in flight measure the same rate.
//! The server paces its link on a manual clock that the loader's meter also reads: the
//! throttle moves the clock by exactly each slice's time on the link, nothing else does, so
//! the estimate is exact whatever the machine's load (no sleep, no wall-clock bound).
#![allow(clippy::unwrap_used)]

use std::sync::Arc;
use std::time::{Duration, Instant};

use harness::remote::HttpFile;
use harness::serve::{ServeOptions, Server};
use methods::SplatBatch;
use methods::store::RepoWriter;
use methods::store::access::{Clock, DataAccess, Loader, LoaderOptions, ManualClock, Retry};
use methods::store::remote::RemoteSource;

/// Chunks of the repository, each [`CHUNK`] bytes that LZO cannot shrink.
const CHUNKS: u32 = 24;
const CHUNK: usize = 64 * 1024;
/// The served link, bytes/s.
const RATE: f64 = 2.0e6;

/// Bytes of a xorshift generator: incompressible, so the stored chunk is about as large as
/// the raw one and the transfer takes a known time.
fn noise(seed: u64, n: usize) -> Vec<u8> {
    let mut x = seed.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1;
    (0..n)
        .map(|_| {
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            x as u8
        })
        .collect()
}

#[test]
fn the_estimate_is_a_throttled_servers_rate() {
    let dir = tempfile::tempdir().unwrap();
    let mut w = RepoWriter::create(&dir.path().join("repo.bin")).unwrap();
    let refs: Vec<_> = (0..CHUNKS)
        .map(|c| w.append(&noise(u64::from(c), CHUNK)).unwrap())
        .collect();
    w.finish().unwrap();
    assert!(refs.iter().all(|r| r.stored as usize >= CHUNK));
    let clock = ManualClock::new();
    let mut opt = ServeOptions::new(dir.path(), "127.0.0.1:0".parse().unwrap());
    opt.bandwidth = Some(RATE);
    opt.clock = Clock::Manual(clock.clone());
    let server = Server::start(&opt, Box::new(std::io::sink())).unwrap();
    for in_flight in [1, 4] {
        let file = HttpFile::new(format!("{}repo.bin", server.url()), Duration::from_secs(10));
        let source = RemoteSource::open(std::sync::Arc::new(file), refs.clone(), "cloud").unwrap();
        let l = Loader::spawn_clocked(
            Arc::new(source),
            Arc::new(|_, b: &[u8]| {
                Ok(SplatBatch {
                    positions: vec![[b.len() as f32, 0.0, 0.0]],
                    normals: None,
                    colors: None,
                    radii: None,
                    lod: None,
                })
            }),
            LoaderOptions {
                core_bytes: u64::MAX,
                delay_frames: 0,
                in_flight,
            },
            Retry::NONE,
            Clock::Manual(clock.clone()),
        );
        // The deadline only keeps a hung loader from hanging the test.
        let deadline = Instant::now() + Duration::from_secs(60);
        for id in 0..CHUNKS {
            l.request(id);
        }
        while l.pending() > 0 {
            assert!(Instant::now() < deadline, "never drained");
            std::thread::sleep(Duration::from_millis(2));
        }
        assert!(l.failures().is_empty(), "{:?}", l.failures());
        let t = l.throughput().unwrap();
        assert_eq!(t.responses, CHUNKS as usize);
        // Exact up to the clock's nanosecond steps: the link's time is the only time that
        // passes, and every stored byte crosses it.
        assert!(
            (t.bytes_per_s / RATE - 1.0).abs() <= 1e-6,
            "{in_flight} in flight: estimated {:.3} B/s on a {RATE:.0} B/s link",
            t.bytes_per_s
        );
        assert_eq!(
            l.traffic().bytes,
            refs.iter().map(|r| u64::from(r.stored)).sum::<u64>()
        );
    }
}
