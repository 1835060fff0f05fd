//! The data-access layer's local loader (`methods::store::access::Loader`) through its public
//! API: delivery by the loader thread, request order, exact delay semantics, deduplication,
//! the LRU core budget, a corrupt chunk in a real repository file, panics in the decoder, and
//! that dropping the loader stops and joins its thread.
#![allow(clippy::unwrap_used)]

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::{Duration, Instant};

use methods::store::access::{
    ChunkSource, DataAccess, Decoder, Loader, LoaderOptions, LocalSource,
};
use methods::store::{ChunkRef, RepoWriter, Repository};
use methods::{MethodError, SplatBatch};

/// Bytes per decoded point of [`byte_decoder`] (positions only).
const POINT: u64 = 12;

/// Polls `cond` until it holds; fails the test after 5 s.
fn wait_until(what: &str, cond: impl Fn() -> bool) {
    let deadline = Instant::now() + Duration::from_secs(5);
    while !cond() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Waits until the loader has served every request.
fn drain(l: &Loader) {
    wait_until("the loader queue to drain", || l.pending() == 0);
}

/// An in-memory source: chunk `id` is `sizes[id]` bytes; counts and logs fetches, and can
/// hold every fetch until its gate opens.
struct MemSource {
    sizes: Vec<usize>,
    log: Mutex<Vec<u32>>,
    fetches: AtomicUsize,
    gate: Mutex<bool>,
    opened: Condvar,
    /// Sleep of every fetch after the first (simulated transfer time).
    slow: Duration,
}

impl MemSource {
    fn new(sizes: Vec<usize>) -> Self {
        Self {
            sizes,
            log: Mutex::new(Vec::new()),
            fetches: AtomicUsize::new(0),
            gate: Mutex::new(true),
            opened: Condvar::new(),
            slow: Duration::ZERO,
        }
    }
    fn uniform(chunks: usize, bytes: usize) -> Self {
        Self::new(vec![bytes; chunks])
    }
    fn closed(mut self) -> Self {
        self.gate = Mutex::new(false);
        self
    }
    fn open(&self) {
        *self.gate.lock().unwrap() = true;
        self.opened.notify_all();
    }
    fn fetches(&self) -> usize {
        self.fetches.load(Ordering::SeqCst)
    }
    fn log(&self) -> Vec<u32> {
        self.log.lock().unwrap().clone()
    }
}

impl ChunkSource for MemSource {
    fn len(&self) -> usize {
        self.sizes.len()
    }
    fn fetch(&self, id: u32) -> Result<Vec<u8>, MethodError> {
        let n = self.fetches.fetch_add(1, Ordering::SeqCst);
        self.log.lock().unwrap().push(id);
        let gate = self.gate.lock().unwrap();
        let (gate, timeout) = self
            .opened
            .wait_timeout_while(gate, Duration::from_secs(5), |open| !*open)
            .unwrap();
        assert!(
            !timeout.timed_out() && *gate,
            "the test never opened the gate"
        );
        drop(gate);
        if n > 0 {
            std::thread::sleep(self.slow);
        }
        let size = *self
            .sizes
            .get(id as usize)
            .ok_or(MethodError::NoChunk(id.into()))?;
        Ok((0..size).map(|i| (i as u32 ^ id) as u8).collect())
    }
}

/// One point per byte, `[byte, id, 0]`; records the name of the decoding thread.
fn byte_decoder(threads: Arc<Mutex<Vec<(u32, String)>>>) -> Decoder {
    Arc::new(move |id, bytes: &[u8]| {
        let name = std::thread::current().name().unwrap_or("").to_owned();
        threads.lock().unwrap().push((id, name));
        Ok(SplatBatch {
            positions: bytes.iter().map(|&b| [b as f32, id as f32, 0.0]).collect(),
            normals: None,
            colors: None,
            radii: None,
            lod: None,
        })
    })
}

fn loader(source: &Arc<MemSource>, core_bytes: u64, delay_frames: u32) -> Loader {
    Loader::spawn(
        source.clone(),
        byte_decoder(Arc::default()),
        LoaderOptions {
            core_bytes,
            delay_frames,
            in_flight: 1,
        },
    )
}

#[test]
fn delivers_through_the_loader_thread() {
    let src = Arc::new(MemSource::uniform(10, 50));
    let threads = Arc::new(Mutex::new(Vec::new()));
    let l = Loader::spawn(
        src.clone(),
        byte_decoder(threads.clone()),
        LoaderOptions {
            core_bytes: u64::MAX,
            delay_frames: 0,
            in_flight: 1,
        },
    );
    l.begin_frame();
    for id in 0..8 {
        l.request(id);
    }
    wait_until("chunks 0..8", || (0..8).all(|id| l.available(id)));
    assert_eq!(l.pending(), 0);
    assert_eq!(l.resident_bytes(), 8 * 50 * POINT);
    for id in 0..8u32 {
        let b = l.get(id).unwrap();
        assert_eq!(b.len(), 50);
        assert_eq!(b.positions[3], [(3 ^ id) as u8 as f32, id as f32, 0.0]);
    }
    assert_eq!(src.fetches(), 8, "get served from core");
    assert!(
        threads
            .lock()
            .unwrap()
            .iter()
            .all(|(_, name)| name == "splatbench-loader"),
        "{:?}",
        threads.lock().unwrap()
    );
    // A chunk never requested is read and decoded on the caller's thread, and is then in
    // core and available.
    assert!(!l.available(9));
    let b = l.get(9).unwrap();
    assert_eq!(b.positions[0][1], 9.0);
    let last = threads.lock().unwrap().last().cloned().unwrap();
    assert_eq!(last.0, 9);
    assert_ne!(last.1, "splatbench-loader");
    assert!(l.available(9));
    assert_eq!(src.fetches(), 9);
    // An unknown chunk is an error, not a panic.
    assert!(matches!(l.get(99), Err(MethodError::NoChunk(99))));
}

#[test]
fn requests_return_at_once_and_are_served_in_order() {
    let src = Arc::new(MemSource::uniform(10, 20).closed());
    let l = loader(&src, u64::MAX, 0);
    l.begin_frame();
    let order = [5, 3, 9, 1, 0];
    for id in order {
        l.request(id); // Returns although the source is stuck.
    }
    assert_eq!(l.pending(), 5, "queued + in flight");
    wait_until("the first fetch", || src.fetches() == 1);
    // `available` answers while the thread is blocked in a fetch.
    assert!(order.iter().all(|&id| !l.available(id)));
    assert_eq!(l.resident_bytes(), 0);
    src.open();
    drain(&l);
    assert_eq!(src.log(), order);
    assert!(order.iter().all(|&id| l.available(id)));
}

#[test]
fn a_newer_frames_requests_go_first() {
    let src = Arc::new(MemSource::uniform(10, 20).closed());
    let l = loader(&src, u64::MAX, 0);
    l.begin_frame();
    l.request(0);
    wait_until("the first fetch", || src.fetches() == 1);
    for id in [1, 2, 3] {
        l.request(id);
    }
    // The next frame still wants 3 and 2, in that order: they move ahead of 1.
    l.begin_frame();
    l.request(3);
    l.request(2);
    l.request(3); // twice in one frame: keeps its place
    src.open();
    drain(&l);
    assert_eq!(src.log(), [0, 3, 2, 1]);
    let t = l.traffic();
    assert_eq!((t.issued, t.cancelled, t.stale, t.failed), (4, 0, 0, 0));
}

#[test]
fn requests_no_frame_wants_any_more_are_cancelled() {
    let src = Arc::new(MemSource::uniform(10, 20).closed());
    let l = loader(&src, u64::MAX, 0);
    l.begin_frame(); // frame 1
    l.request(0);
    wait_until("the first fetch", || src.fetches() == 1);
    l.request(1);
    l.request(2);
    l.begin_frame(); // frame 2: only 2 is still wanted
    l.request(2);
    l.begin_frame(); // frame 3: 1 was last wanted in frame 1, two frames ago
    src.open();
    drain(&l);
    assert_eq!(src.log(), [0, 2], "1 was dropped unserved");
    assert!(!l.available(1) && l.available(2));
    let t = l.traffic();
    assert_eq!(t.cancelled, 1);
    // 0 arrived in frame 3, wanted last in frame 1: stale (and kept, it may be used).
    assert_eq!(t.stale, 1);
    assert!(l.available(0));
    // Wanted again, 1 is fetched.
    l.request(1);
    drain(&l);
    assert_eq!(src.log(), [0, 2, 1]);
    assert!(l.available(1));
    assert_eq!(l.traffic().issued, 4);
}

#[test]
fn with_a_simulated_delay_nothing_is_cancelled() {
    // A delay of d frames serves every request (so a run's counts repeat exactly): 1 would
    // be stale in frame 2 without it.
    let src = Arc::new(MemSource::uniform(4, 10).closed());
    let l = loader(&src, u64::MAX, 3);
    l.request(0);
    wait_until("the first fetch", || src.fetches() == 1);
    l.request(1);
    l.begin_frame();
    l.begin_frame();
    src.open();
    l.begin_frame(); // frame 3: both due, waited for
    assert!(l.available(0) && l.available(1));
    assert_eq!(src.log(), [0, 1]);
    assert_eq!(l.traffic().cancelled, 0);
}

#[test]
fn delay_counts_frames_from_the_request() {
    let src = Arc::new(MemSource::uniform(4, 10));
    let l = loader(&src, u64::MAX, 3);
    l.begin_frame(); // Frame f = 1.
    assert_eq!(l.frame(), 1);
    l.request(0);
    drain(&l); // Decoded now: only the delay holds it back.
    assert_eq!(l.resident_bytes(), 10 * POINT);
    assert!(!l.available(0), "frame f");
    l.begin_frame();
    l.request(1); // Requested in frame f + 1: due at f + 4.
    drain(&l);
    assert!(!l.available(0), "frame f + 1");
    l.begin_frame();
    assert!(!l.available(0), "frame f + 2");
    // `get` hands over the decoded chunk (the renderer's upload) without making it
    // available early and without a second fetch.
    assert_eq!(l.get(0).unwrap().len(), 10);
    assert!(!l.available(0), "frame f + 2 after get");
    assert_eq!(src.fetches(), 2);
    l.begin_frame();
    assert_eq!(l.frame(), 4);
    assert!(l.available(0), "frame f + 3");
    assert!(!l.available(1), "chunk 1 at frame f + 3");
    l.begin_frame();
    assert!(l.available(0) && l.available(1));

    // Delay 0: available as soon as decoded, within the frame of the request.
    let l0 = loader(&src, u64::MAX, 0);
    l0.begin_frame();
    l0.request(2);
    drain(&l0);
    assert!(l0.available(2));
}

/// With a delay of d ≥ 1 frames a chunk arrives in exactly d frames however slow the source
/// is: `begin_frame` waits for the chunks due in the new frame, so a run's counts repeat.
#[test]
fn a_delay_is_exact_even_when_the_source_is_slow() {
    let src = Arc::new(MemSource::uniform(4, 10).closed());
    let l = loader(&src, u64::MAX, 1);
    l.begin_frame(); // Frame f = 1.
    l.request(0);
    l.request(1);
    assert!(
        !l.available(0),
        "frame f: nothing arrives in the frame of the request"
    );
    let opener = {
        let src = Arc::clone(&src);
        std::thread::spawn(move || {
            // The source answers long after the frame would have ended.
            std::thread::sleep(std::time::Duration::from_millis(200));
            src.open();
        })
    };
    let t = std::time::Instant::now();
    l.begin_frame(); // Frame f + 1: both are due, so it waits for them.
    assert!(t.elapsed() >= std::time::Duration::from_millis(150));
    assert!(
        l.available(0) && l.available(1),
        "frame f + 1: both arrived"
    );
    assert_eq!(l.pending(), 0);
    opener.join().unwrap();
    // A chunk requested later is not waited for before its own frame.
    l.request(2);
    assert!(!l.available(2));
    l.begin_frame();
    assert!(l.available(2));
}

#[test]
fn repeated_requests_fetch_once() {
    let src = Arc::new(MemSource::uniform(4, 10).closed());
    let l = loader(&src, u64::MAX, 1);
    l.begin_frame();
    for _ in 0..10 {
        l.request(2); // Queued or in flight.
    }
    assert_eq!(l.pending(), 1);
    src.open();
    drain(&l);
    for _ in 0..3 {
        l.begin_frame();
        l.request(2); // In core.
        assert!(l.available(2));
        l.get(2).unwrap();
    }
    assert_eq!(l.pending(), 0);
    assert_eq!(src.fetches(), 1);
    assert_eq!(src.log(), [2]);
}

#[test]
fn core_budget_evicts_least_recently_used() {
    // Chunks of 100 points = 1200 bytes; the core holds three.
    let chunk = 100 * POINT;
    let src = Arc::new(MemSource::uniform(10, 100));
    let l = loader(&src, 3 * chunk, 0);
    let load = |ids: &[u32]| {
        for &id in ids {
            l.request(id);
        }
        drain(&l);
    };

    l.begin_frame(); // 1
    load(&[0, 1, 2]);
    assert!((0..3).all(|id| l.available(id)));
    assert_eq!(l.resident_bytes(), 3 * chunk);

    l.begin_frame(); // 2: uses 0 then 2; 1 is the least recently used.
    assert!(l.available(0) && l.available(2));
    load(&[3]);
    assert_eq!(l.resident_bytes(), 3 * chunk);
    assert!(!l.available(1), "1 evicted");
    assert!(l.available(3));

    l.begin_frame(); // 3: uses 3; of 0 and 2 (both last used in frame 2), 0 is older.
    assert!(l.available(3));
    load(&[4]);
    assert_eq!(l.resident_bytes(), 3 * chunk);
    assert!(!l.available(0), "0 evicted");
    assert!(l.available(2) && l.available(4));

    // An evicted chunk can be requested again (a second fetch).
    assert_eq!(src.fetches(), 5);

    l.begin_frame(); // 4: a working set of four: the budget overshoots, nothing in use goes.
    assert!(l.available(2) && l.available(3) && l.available(4));
    l.get(5).unwrap();
    assert_eq!(l.resident_bytes(), 4 * chunk);
    assert!((2..6).all(|id| l.available(id)));

    l.begin_frame(); // 5: only 5 in use; loading 6 trims back to the budget (2, 3 go).
    assert!(l.available(5));
    load(&[6]);
    assert_eq!(l.resident_bytes(), 3 * chunk);
    assert!(!l.available(2) && !l.available(3));
    assert!(l.available(4) && l.available(5) && l.available(6));

    l.begin_frame(); // 6: re-request 0 (evicted in frame 3).
    load(&[0]);
    assert!(l.available(0));
    assert_eq!(src.fetches(), 8);
    assert_eq!(l.resident_bytes(), 3 * chunk);
}

#[test]
fn chunk_larger_than_the_budget_is_kept_until_used() {
    let src = Arc::new(MemSource::new(vec![10, 10, 500]));
    let l = loader(&src, 20 * POINT, 0);
    l.begin_frame();
    l.request(0);
    l.request(1);
    drain(&l);
    l.begin_frame();
    l.request(2);
    drain(&l);
    // The loaded chunk stays (the others go), so the request was not wasted.
    assert!(l.available(2));
    assert!(!l.available(0) && !l.available(1));
    assert_eq!(l.resident_bytes(), 500 * POINT);
}

/// Positions of chunk `c` of the repository test, as stored bytes.
fn positions(c: u32) -> Vec<[f32; 3]> {
    (0..(c * 300 + 40))
        .map(|i| [i as f32, c as f32, (i % 7) as f32 * 0.5])
        .collect()
}

fn position_decoder() -> Decoder {
    Arc::new(|id, bytes: &[u8]| {
        if !bytes.len().is_multiple_of(12) {
            return Err(MethodError::Limit(format!(
                "cloud {id}: {} bytes are not whole points",
                bytes.len()
            )));
        }
        Ok(SplatBatch {
            positions: bytes
                .chunks_exact(12)
                .map(bytemuck::pod_read_unaligned)
                .collect(),
            normals: None,
            colors: None,
            radii: None,
            lod: None,
        })
    })
}

#[test]
fn an_unfinished_repository_leaves_no_file() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("repo.bin");
    let mut w = RepoWriter::create(&path).unwrap();
    w.append(bytemuck::cast_slice(&positions(0))).unwrap();
    assert_eq!(
        std::fs::read_dir(dir.path()).unwrap().count(),
        1,
        "the temporary file"
    );
    drop(w); // a build that failed
    assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 0);
    let mut w = RepoWriter::create(&path).unwrap();
    w.append(bytemuck::cast_slice(&positions(0))).unwrap();
    w.finish().unwrap();
    let left: Vec<_> = std::fs::read_dir(dir.path())
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(left, ["repo.bin"]);
}

#[test]
fn corrupt_chunk_in_a_repository_is_an_error_naming_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("repo.bin");
    let mut w = RepoWriter::create(&path).unwrap();
    let refs: Vec<ChunkRef> = (0..5)
        .map(|c| w.append(bytemuck::cast_slice(&positions(c))).unwrap())
        .collect();
    w.finish().unwrap();
    // Flip one stored byte of chunk 2.
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[refs[2].offset as usize + refs[2].stored as usize / 2] ^= 0x04;
    std::fs::write(&path, &bytes).unwrap();

    let repo = Repository::open(&path).unwrap();
    let source = Arc::new(LocalSource::new(repo, refs, "cloud"));
    assert_eq!(source.len(), 5);
    let l = Loader::spawn(
        source,
        position_decoder(),
        LoaderOptions {
            core_bytes: 1 << 20,
            delay_frames: 0,
            in_flight: 1,
        },
    );
    l.begin_frame();
    for id in [2, 0, 1, 3] {
        l.request(id); // The failure of 2 must not stop the others.
    }
    drain(&l);
    assert!(!l.available(2));
    let remembered = l.error(2).unwrap();
    assert!(
        remembered.contains("cloud 2") && remembered.contains("checksum"),
        "{remembered}"
    );
    for id in [0, 1, 3] {
        assert!(l.available(id), "cloud {id}");
        assert_eq!(l.get(id).unwrap().positions, positions(id));
        assert_eq!(l.error(id), None);
    }
    // A further request is ignored; `get` reads again and returns the error.
    l.request(2);
    assert_eq!(l.pending(), 0);
    for _ in 0..2 {
        let e = l.get(2).unwrap_err();
        assert!(matches!(e, MethodError::Corrupt { .. }), "{e:?}");
        let msg = e.to_string();
        assert!(
            msg.contains("cloud 2") && msg.contains("checksum") && msg.contains("repo.bin"),
            "{msg}"
        );
    }
    l.begin_frame();
    assert!(!l.available(2));
    // The thread is still serving.
    l.request(4);
    drain(&l);
    assert!(l.available(4));
    assert_eq!(l.get(4).unwrap().positions, positions(4));
    assert_eq!(
        l.resident_bytes(),
        [0, 1, 3, 4]
            .map(|c| positions(c).len() as u64 * POINT)
            .iter()
            .sum::<u64>()
    );
}

#[test]
fn panicking_decoder_is_an_error_and_the_thread_survives() {
    let src = Arc::new(MemSource::uniform(4, 10));
    let inner = byte_decoder(Arc::default());
    let decode: Decoder = Arc::new(move |id, bytes: &[u8]| {
        assert_ne!(id, 1, "decoder bug on chunk 1");
        inner(id, bytes)
    });
    let l = Loader::spawn(
        src.clone(),
        decode,
        LoaderOptions {
            core_bytes: u64::MAX,
            delay_frames: 0,
            in_flight: 1,
        },
    );
    l.begin_frame();
    l.request(1);
    l.request(2);
    drain(&l);
    assert!(!l.available(1));
    assert!(l.available(2));
    assert!(l.error(1).unwrap().contains("decoder bug on chunk 1"));
    // A panic is a bug, reported as one (not as a limit of the data), naming the chunk.
    let e = l.get(1).unwrap_err();
    assert!(matches!(e, MethodError::Bug(_)), "{e:?}");
    let e = e.to_string();
    assert!(
        e.contains("chunk 1") && e.contains("panicked") && e.contains("a bug in splatbench"),
        "{e}"
    );
}

#[test]
fn drop_stops_and_joins_the_thread() {
    // Idle thread: dropping joins it (its share of the source is released on return).
    let src = Arc::new(MemSource::uniform(4, 10));
    let l = loader(&src, u64::MAX, 0);
    l.begin_frame();
    l.request(0);
    drain(&l);
    assert_eq!(Arc::strong_count(&src), 2);
    drop(l);
    assert_eq!(Arc::strong_count(&src), 1, "the loader thread has exited");

    // Busy thread with a long queue: dropping waits for the fetch in flight only. The first
    // fetch is held until shortly after the drop began; every later fetch takes 5 ms, so
    // draining the queue would take 250 ms.
    let mut slow = MemSource::uniform(60, 10).closed();
    slow.slow = Duration::from_millis(5);
    let src = Arc::new(slow);
    let l = loader(&src, u64::MAX, 0);
    l.begin_frame();
    for id in 0..50 {
        l.request(id);
    }
    wait_until("the first fetch", || src.fetches() == 1);
    std::thread::scope(|s| {
        s.spawn(|| {
            std::thread::sleep(Duration::from_millis(20));
            src.open();
        });
        let start = Instant::now();
        drop(l);
        let waited = start.elapsed();
        assert!(waited < Duration::from_secs(5), "{waited:?}");
    });
    assert_eq!(Arc::strong_count(&src), 1, "the loader thread has exited");
    assert!(
        src.fetches() < 50,
        "the queue was drained instead of dropped: {} fetches",
        src.fetches()
    );
}
