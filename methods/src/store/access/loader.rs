//! The loader: decoded chunks in core, filled by a loader thread from a [`ChunkSource`]
//! (see [`Loader`]).

use std::cmp::Reverse;
use std::collections::{BTreeMap, HashMap};
use std::panic::AssertUnwindSafe;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::Instant;

use super::meter::Meter;
use super::options::{DUE_WAIT, LoaderOptions, Retry};
use super::{ChunkSource, DataAccess, Decoded, Decoder, LocalSource, RepoAt, Throughput, Traffic};
use crate::MethodError;
use crate::store::{ChunkRef, Repository};

/// What the cache knows about one chunk.
enum Entry {
    /// Requested and not yet decoded (queued or in flight on the loader thread).
    Loading {
        /// First frame in which the chunk may count as available.
        ready: u64,
        /// Its place in [`State::queue`]; `None` once the loader thread has taken it.
        queued: Option<QueueKey>,
        /// The last frame that requested it.
        wanted: u64,
        /// Attempts that failed so far ([`Retry`]).
        failed: u32,
    },
    /// Decoded and held in core.
    Core {
        batch: Decoded,
        /// [`SplatBatch::byte_size`] of `batch`.
        bytes: u64,
        /// First frame in which the chunk may count as available.
        ready: u64,
        /// Position in the LRU order (key of [`State::lru`]).
        tick: u64,
        /// Frame of the last use, `None` if never used since it was loaded.
        used: Option<u64>,
    },
    /// The loader thread failed to read or decode it (the error's text), at `at`.
    Failed { error: String, at: Instant },
}

/// A place in the loader's queue: the frame of the request (newest first), then the order
/// of requests (first first).
type QueueKey = (Reverse<u64>, u64);

/// A queued request not asked for again in this frame or the one before is stale (with no
/// simulated delay): it is dropped unserved when its turn comes. One frame of grace, because
/// a method re-requests what it still wants only at the end of its frame's selection.
const STALE_AFTER: u64 = 1;

/// Everything behind the loader's mutex.
struct State {
    /// Frame counter, advanced by [`DataAccess::begin_frame`].
    frame: u64,
    entries: HashMap<u32, Entry>,
    /// Core entries by last use, oldest first (tick → id).
    lru: BTreeMap<u64, u32>,
    /// Next LRU tick.
    tick: u64,
    /// Sum of the `bytes` of core entries.
    resident: u64,
    /// Requests queued or in flight on the loader thread.
    pending: usize,
    core_bytes: u64,
    /// Requests waiting for the loader thread, best first ([`QueueKey`]).
    queue: BTreeMap<QueueKey, u32>,
    /// Failed requests waiting to be tried again, by when (then request number).
    retry_at: BTreeMap<(Instant, u64), u32>,
    /// Number of the last request (orders the requests of one frame).
    seq: u64,
    /// Counters of [`Traffic`] kept here (`bytes` is the source's).
    issued: u64,
    cancelled: u64,
    stale: u64,
    /// Fetches or decodes that failed (every try).
    failed: u64,
    /// Time spent fetching and the bytes it brought ([`Meter`]).
    meter: Meter,
}

/// Counts a fetch as in flight while alive (also if the source panics).
struct Fetching<'a> {
    shared: &'a Shared,
    stored: Option<u64>,
}

impl Drop for Fetching<'_> {
    fn drop(&mut self) {
        let now = self.shared.clock.now();
        self.shared.state().meter.end(now, self.stored);
    }
}

impl State {
    /// Marks core entry `id` as used now: newest in the LRU order, protected this frame.
    fn touch(&mut self, id: u32) {
        let frame = self.frame;
        self.tick += 1;
        let tick = self.tick;
        if let Some(Entry::Core {
            tick: t, used: u, ..
        }) = self.entries.get_mut(&id)
        {
            self.lru.remove(t);
            *t = tick;
            *u = Some(frame);
            self.lru.insert(tick, id);
        }
    }

    /// Puts `batch` in core as chunk `id` (newest in the LRU order, not yet used), then
    /// evicts down to the budget, sparing `id` itself.
    fn install(&mut self, id: u32, batch: Decoded, ready: u64) {
        self.tick += 1;
        let bytes = batch.byte_size();
        let old = self.entries.insert(
            id,
            Entry::Core {
                batch,
                bytes,
                ready,
                tick: self.tick,
                used: None,
            },
        );
        if let Some(Entry::Core { bytes: b, tick, .. }) = old {
            self.lru.remove(&tick);
            self.resident -= b;
        }
        self.lru.insert(self.tick, id);
        self.resident += bytes;
        self.evict(id);
    }

    /// Drops least recently used chunks until the resident bytes fit the budget, never a
    /// chunk used in the current frame nor `keep`.
    fn evict(&mut self, keep: u32) {
        if self.resident <= self.core_bytes {
            return;
        }
        let mut excess = self.resident - self.core_bytes;
        let mut victims = Vec::new();
        for (&tick, &id) in &self.lru {
            if excess == 0 {
                break;
            }
            if id == keep {
                continue;
            }
            if let Some(Entry::Core { bytes, used, .. }) = self.entries.get(&id)
                && *used != Some(self.frame)
            {
                victims.push((tick, id));
                excess = excess.saturating_sub(*bytes);
            }
        }
        for (tick, id) in victims {
            self.lru.remove(&tick);
            if let Some(Entry::Core { bytes, .. }) = self.entries.remove(&id) {
                self.resident -= bytes;
            }
        }
    }
}

/// State shared by the [`Loader`] handle and its thread.
struct Shared {
    source: Arc<dyn ChunkSource>,
    decode: Decoder,
    delay_frames: u32,
    retry: Retry,
    /// What the throughput meter reads ([`super::Clock`]).
    clock: super::Clock,
    state: Mutex<State>,
    /// Notified whenever the loader thread finishes a request (installed or failed).
    served: Condvar,
    /// Notified when a request is queued, and at stop.
    work: Condvar,
    /// Set by [`Loader`]'s `Drop`: the thread stops before its next request.
    stop: AtomicBool,
}

impl Shared {
    fn state(&self) -> MutexGuard<'_, State> {
        // The lock is never held across a fetch or a decode, and no code under it panics on
        // valid state; recover from poisoning rather than propagate a panic.
        self.state.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Fetches and decodes chunk `id` on the calling thread, without touching the state. A
    /// panic of the source or the decoder becomes an error.
    fn load(&self, id: u32) -> Result<Decoded, MethodError> {
        let run = || -> Result<Decoded, MethodError> {
            self.state().meter.start(self.clock.now());
            let mut fetching = Fetching {
                shared: self,
                stored: None,
            };
            let bytes = self.source.fetch(id)?;
            fetching.stored = Some(self.source.stored_bytes(id));
            drop(fetching);
            Ok(Arc::new((self.decode)(id, &bytes)?))
        };
        match std::panic::catch_unwind(AssertUnwindSafe(run)) {
            Ok(r) => r,
            Err(panic) => {
                let what = scenes::error::panic_message(&*panic).unwrap_or_default();
                Err(MethodError::Bug(format!(
                    "chunk {id}: the chunk source or decoder panicked: {what}"
                )))
            }
        }
    }

    /// Serves one request on the loader thread: installs the chunk, or schedules another
    /// attempt ([`Retry`]), or records the failure.
    fn serve(&self, id: u32) {
        {
            let mut st = self.state();
            if !matches!(st.entries.get(&id), Some(Entry::Loading { .. })) {
                // Loaded meanwhile by a synchronous `get` (or loaded, evicted and requested
                // again, then served by an earlier message).
                st.pending -= 1;
                drop(st);
                self.served.notify_all();
                return;
            }
        }
        let result = self.load(id);
        let mut st = self.state();
        let Some(&Entry::Loading {
            ready,
            wanted,
            failed,
            ..
        }) = st.entries.get(&id)
        else {
            st.pending -= 1;
            drop(st);
            self.served.notify_all();
            return;
        };
        match result {
            Ok(batch) => {
                st.pending -= 1;
                if wanted + STALE_AFTER < st.frame {
                    st.stale += 1;
                }
                st.install(id, batch, ready);
            }
            Err(e) => {
                st.failed += 1;
                let tries = failed + 1;
                if tries < self.retry.tries {
                    // Still pending: back in the queue after the backoff.
                    let wait = self.retry.backoff * 2u32.saturating_pow(tries - 1);
                    st.seq += 1;
                    let key = (Instant::now() + wait, st.seq);
                    st.retry_at.insert(key, id);
                    if let Some(Entry::Loading { failed, .. }) = st.entries.get_mut(&id) {
                        *failed = tries;
                    }
                } else {
                    st.pending -= 1;
                    let error = if tries > 1 {
                        format!("{e} (gave up after {tries} tries)")
                    } else {
                        e.to_string()
                    };
                    st.entries.insert(
                        id,
                        Entry::Failed {
                            error,
                            at: Instant::now(),
                        },
                    );
                }
            }
        }
        drop(st);
        self.served.notify_all();
    }

    /// The loader thread: takes the best queued request ([`QueueKey`]) until `stop` is set;
    /// with no simulated delay, a stale one ([`STALE_AFTER`]) is dropped unserved.
    fn run(&self) {
        let mut st = self.state();
        loop {
            if self.stop.load(Ordering::Acquire) {
                return;
            }
            // Failed requests whose backoff is over go back in the queue, with the priority of
            // the last frame that wanted them.
            let now = Instant::now();
            while let Some((&(when, _), &id)) = st.retry_at.first_key_value() {
                if when > now {
                    break;
                }
                st.retry_at.pop_first();
                let Some(&Entry::Loading { wanted, .. }) = st.entries.get(&id) else {
                    // Read meanwhile by a synchronous `get`.
                    st.pending -= 1;
                    continue;
                };
                st.seq += 1;
                let key = (Reverse(wanted), st.seq);
                st.queue.insert(key, id);
                if let Some(Entry::Loading { queued, .. }) = st.entries.get_mut(&id) {
                    *queued = Some(key);
                }
            }
            let Some((key, id)) = st.queue.pop_first() else {
                st = match st.retry_at.first_key_value() {
                    Some((&(when, _), _)) => {
                        let wait = when.saturating_duration_since(now);
                        match self.work.wait_timeout(st, wait) {
                            Ok((g, _)) => g,
                            Err(e) => e.into_inner().0,
                        }
                    }
                    None => self.work.wait(st).unwrap_or_else(|e| e.into_inner()),
                };
                continue;
            };
            let mine = matches!(
                st.entries.get(&id),
                Some(Entry::Loading { queued: Some(k), .. }) if *k == key
            );
            if !mine {
                // Read meanwhile by a synchronous `get`: nothing left to do.
                st.pending -= 1;
                self.served.notify_all();
                continue;
            }
            if self.delay_frames == 0 && key.0.0 + STALE_AFTER < st.frame {
                st.entries.remove(&id);
                st.pending -= 1;
                st.cancelled += 1;
                self.served.notify_all();
                continue;
            }
            if let Some(Entry::Loading { queued, .. }) = st.entries.get_mut(&id) {
                *queued = None;
            }
            drop(st);
            self.serve(id);
            st = self.state();
        }
    }
}

/// The data-access layer: decoded chunks in core, filled by loader threads
/// ("splatbench-loader", [`LoaderOptions::in_flight`] of them, each with one request in
/// flight) from a [`ChunkSource`].
///
/// # Design
///
/// A [`Loader`] is a handle on a mutex-protected cache shared with its thread, which holds
/// a queue of requests. [`DataAccess::request`] records the chunk as loading and queues it,
/// stamped with the frame of the request; the thread takes the newest frame's requests
/// first, each frame's in the order they were made (the caller's priority order), fetches
/// the bytes from the source, decodes them with the [`Decoder`] and puts the [`Decoded`]
/// chunk in core. A request repeated in a later frame moves up with that frame's requests
/// (re-prioritised); with no simulated delay, a request that neither this frame nor the one
/// before asked for is dropped unserved when its turn comes (cancelled: the camera has moved
/// on, as in the MWKD 100 M flythrough where most requests were stale before they were
/// served), and asked again later it is queued anew. With a delay every request is served,
/// so that the delay's frame counts stay exact. [`DataAccess::traffic`] counts requests
/// issued, cancelled, delivered stale and failed, and the source's bytes;
/// [`DataAccess::throughput`] is the rate the source delivered at over its recent
/// responses (the time during which at least one fetch was in flight: idle time does not
/// lower it, parallel fetches do not inflate it). The mutex is never
/// held while fetching or decoding, so [`DataAccess::available`] and the other queries only
/// ever wait for short bookkeeping.
///
/// # Delay
///
/// With [`LoaderOptions::delay_frames`] = d, a chunk requested during frame f (the value of
/// the frame counter, advanced by each [`DataAccess::begin_frame`]; frame 0 before the first
/// call) is [`available`](DataAccess::available) from frame f + d on, and only once decoded:
/// the loader simulates a source whose answer takes d frames. For d ≥ 1 the answer takes
/// exactly d frames: [`DataAccess::begin_frame`] waits (at most [`DUE_WAIT`]) until every
/// chunk due in the new frame is decoded or has failed, so which chunks are available in
/// which frame does not depend on how fast the machine decodes, and a run's per-frame counts
/// repeat exactly (as long as the core budget holds the working set: evictions happen when
/// the thread installs a chunk). The loader still decodes while the frame renders; a frame
/// only waits when decoding is slower than the simulated latency. With d = 0 a chunk is
/// available as soon as it is decoded: as fast as the machine allows, and timing-dependent. A chunk read by [`DataAccess::get`] without a pending request is
/// available at once; one that was pending keeps the frame of its request.
///
/// # Core budget
///
/// Decoded chunks are kept within [`LoaderOptions::core_bytes`] (sizes by
/// [`SplatBatch::byte_size`]) by dropping the least recently used first; a use is a
/// [`DataAccess::get`] or an `available` check that answers true. A chunk used in the
/// current frame is never dropped, nor is the chunk just loaded, so [`resident_bytes`]
/// may exceed the budget by one frame's working set plus one chunk; the excess is evicted by
/// later loads once the frame has passed.
///
/// # Errors
///
/// A chunk whose fetch or decode fails on the loader thread (or panics there) is tried again
/// as the loader's [`Retry`] says (not at all for a local repository; a remote one,
/// [`Loader::at`], tries 4 times with a doubling backoff), staying pending meanwhile. After
/// its last try it is remembered as failed, the error saying how many tries: it is not
/// available, requests for it are ignored until the retry's cooldown has passed (then it is
/// fetched anew: a server that came back), and
/// [`DataAccess::get`] reads it again on the caller's thread, returning the error (or the
/// chunk, if the source has recovered). The thread goes on with the next request.
/// [`DataAccess::failures`] lists the failed chunks, so that a method which renders on
/// without them (LPC stays coarse, MWKD keeps a stand-in) can report them: the runner puts
/// them in `frames.csv`, `summary.json` and on stderr, and fails the run.
///
/// Dropping the loader stops the thread before its next request and joins it.
///
/// [`resident_bytes`]: DataAccess::resident_bytes
pub struct Loader {
    shared: Arc<Shared>,
    /// False if no thread could be started (then requests are served on the caller's
    /// thread).
    threaded: bool,
    /// The loader threads ([`LoaderOptions::in_flight`]).
    workers: Vec<JoinHandle<()>>,
    /// What the chunks come from, for messages (the repository file).
    origin: String,
}

impl Loader {
    /// A loader thread over the repository file `repo` whose chunk `i` is `refs[i]` (errors
    /// name chunks "{noun} {i}"), decoding with `decode`: how LPC and MWKD open their data.
    pub fn local(
        repo: &std::path::Path,
        refs: Vec<ChunkRef>,
        noun: &'static str,
        decode: Decoder,
        options: LoaderOptions,
    ) -> Result<Self, MethodError> {
        let source = LocalSource::new(Repository::open(repo)?, refs, noun);
        let mut loader = Self::spawn(Arc::new(source), decode, options);
        loader.origin = repo.display().to_string();
        Ok(loader)
    }

    /// A loader thread over the repository at `repo`, local or remote (see [`Loader::local`]).
    pub fn at(
        repo: &RepoAt,
        refs: Vec<ChunkRef>,
        noun: &'static str,
        decode: Decoder,
        options: LoaderOptions,
    ) -> Result<Self, MethodError> {
        match repo {
            RepoAt::Local(path) => Self::local(path, refs, noun, decode, options),
            RepoAt::Remote(file) => {
                let source = crate::store::remote::RemoteSource::open(file.clone(), refs, noun)?;
                let mut loader = Self::spawn_with(Arc::new(source), decode, options, Retry::REMOTE);
                loader.origin = file.url().to_string();
                Ok(loader)
            }
        }
    }

    /// Starts a loader thread over `source`, decoding with `decode`; a failed chunk is not
    /// tried again ([`Retry::NONE`]).
    pub fn spawn(source: Arc<dyn ChunkSource>, decode: Decoder, options: LoaderOptions) -> Self {
        Self::spawn_with(source, decode, options, Retry::NONE)
    }

    /// [`Loader::spawn`] with failed chunks tried again as `retry` says.
    pub fn spawn_with(
        source: Arc<dyn ChunkSource>,
        decode: Decoder,
        options: LoaderOptions,
        retry: Retry,
    ) -> Self {
        Self::spawn_clocked(source, decode, options, retry, super::Clock::System)
    }

    /// [`Loader::spawn_with`], its throughput meter reading `clock` (a test's
    /// [`super::ManualClock`]; retries still wait in real time).
    pub fn spawn_clocked(
        source: Arc<dyn ChunkSource>,
        decode: Decoder,
        options: LoaderOptions,
        retry: Retry,
        clock: super::Clock,
    ) -> Self {
        let shared = Arc::new(Shared {
            source,
            decode,
            clock,
            delay_frames: options.delay_frames,
            retry: Retry {
                tries: retry.tries.max(1),
                ..retry
            },
            served: Condvar::new(),
            work: Condvar::new(),
            state: Mutex::new(State {
                frame: 0,
                entries: HashMap::new(),
                lru: BTreeMap::new(),
                tick: 0,
                resident: 0,
                pending: 0,
                core_bytes: options.core_bytes,
                queue: BTreeMap::new(),
                retry_at: BTreeMap::new(),
                seq: 0,
                issued: 0,
                cancelled: 0,
                stale: 0,
                failed: 0,
                meter: Meter::new(),
            }),
            stop: AtomicBool::new(false),
        });
        let workers: Vec<JoinHandle<()>> = (0..options.in_flight.max(1))
            .filter_map(|_| {
                let thread_shared = Arc::clone(&shared);
                std::thread::Builder::new()
                    .name("splatbench-loader".into())
                    .spawn(move || thread_shared.run())
                    .ok()
            })
            .collect();
        Self {
            shared,
            threaded: !workers.is_empty(),
            workers,
            origin: "the chunk source".into(),
        }
    }

    /// The error that made the loader thread give up on chunk `id`, if it did.
    pub fn error(&self, id: u32) -> Option<String> {
        match self.shared.state().entries.get(&id) {
            Some(Entry::Failed { error, .. }) => Some(error.clone()),
            _ => None,
        }
    }

    /// The current frame (number of [`DataAccess::begin_frame`] calls so far).
    pub fn frame(&self) -> u64 {
        self.shared.state().frame
    }
}

impl DataAccess for Loader {
    fn request(&self, id: u32) {
        let mut st = self.shared.state();
        let frame = st.frame;
        match st.entries.get(&id) {
            // Queued by an earlier frame: asked again, it moves up with this frame's requests.
            Some(&Entry::Loading {
                queued: Some(old), ..
            }) => {
                if old.0.0 < frame {
                    st.seq += 1;
                    let key = (Reverse(frame), st.seq);
                    st.queue.remove(&old);
                    st.queue.insert(key, id);
                    if let Some(Entry::Loading { queued, wanted, .. }) = st.entries.get_mut(&id) {
                        *queued = Some(key);
                        *wanted = frame;
                    }
                }
                return;
            }
            Some(Entry::Loading { .. }) => {
                if let Some(Entry::Loading { wanted, .. }) = st.entries.get_mut(&id) {
                    *wanted = frame;
                }
                return;
            }
            // Given up on: tried anew once the cooldown has passed (a server that came back).
            Some(Entry::Failed { at, .. }) => {
                let again = self
                    .shared
                    .retry
                    .cooldown
                    .is_some_and(|c| at.elapsed() >= c);
                if !again {
                    return;
                }
            }
            Some(_) => return,
            None => {}
        }
        let ready = frame + u64::from(self.shared.delay_frames);
        st.issued += 1;
        st.pending += 1;
        if self.threaded {
            st.seq += 1;
            let key = (Reverse(frame), st.seq);
            st.queue.insert(key, id);
            st.entries.insert(
                id,
                Entry::Loading {
                    ready,
                    queued: Some(key),
                    wanted: frame,
                    failed: 0,
                },
            );
            drop(st);
            self.shared.work.notify_one();
            return;
        }
        // No loader thread: serve the request here.
        st.entries.insert(
            id,
            Entry::Loading {
                ready,
                queued: None,
                wanted: frame,
                failed: 0,
            },
        );
        drop(st);
        self.shared.serve(id);
    }

    fn traffic(&self) -> Traffic {
        let bytes = self.shared.source.bytes_read();
        let st = self.shared.state();
        Traffic {
            issued: st.issued,
            cancelled: st.cancelled,
            stale: st.stale,
            failed: st.failed,
            bytes,
        }
    }

    fn throughput(&self) -> Option<Throughput> {
        self.shared.state().meter.throughput()
    }

    fn failures(&self) -> Vec<(u32, String)> {
        let st = self.shared.state();
        let mut out: Vec<(u32, String)> = st
            .entries
            .iter()
            .filter_map(|(&id, e)| match e {
                Entry::Failed { error, .. } => Some((id, format!("{}: {error}", self.origin))),
                _ => None,
            })
            .collect();
        out.sort();
        out
    }

    fn available(&self, id: u32) -> bool {
        let mut st = self.shared.state();
        let ready = match st.entries.get(&id) {
            Some(Entry::Core { ready, .. }) => *ready <= st.frame,
            _ => false,
        };
        if ready {
            st.touch(id);
        }
        ready
    }

    fn get(&self, id: u32) -> Result<Decoded, MethodError> {
        {
            let mut st = self.shared.state();
            if let Some(Entry::Core { batch, .. }) = st.entries.get(&id) {
                let batch = Arc::clone(batch);
                st.touch(id);
                return Ok(batch);
            }
        }
        // Not in core (or loading on the thread, or failed there): read it here. A chunk in
        // flight is read twice; the loader thread's copy is then dropped.
        let result = self.shared.load(id);
        let mut st = self.shared.state();
        match result {
            Ok(batch) => {
                let ready = match st.entries.get(&id) {
                    // Installed by the loader thread meanwhile: keep that copy.
                    Some(Entry::Core { batch, .. }) => {
                        let batch = Arc::clone(batch);
                        st.touch(id);
                        return Ok(batch);
                    }
                    Some(Entry::Loading { ready, .. }) => *ready,
                    _ => st.frame,
                };
                st.install(id, Arc::clone(&batch), ready);
                st.touch(id);
                Ok(batch)
            }
            Err(e) => {
                st.failed += 1;
                if !matches!(st.entries.get(&id), Some(Entry::Loading { .. })) {
                    st.entries.insert(
                        id,
                        Entry::Failed {
                            error: e.to_string(),
                            at: Instant::now(),
                        },
                    );
                }
                Err(e)
            }
        }
    }

    fn begin_frame(&self) {
        let mut st = self.shared.state();
        st.frame += 1;
        if self.shared.delay_frames == 0 || !self.threaded {
            return;
        }
        // A simulated latency of exactly d frames: wait for the chunks due now.
        let frame = st.frame;
        let due = |st: &State| {
            st.entries
                .values()
                .any(|e| matches!(e, Entry::Loading { ready, .. } if *ready <= frame))
        };
        let deadline = Instant::now() + DUE_WAIT;
        while due(&st) {
            let left = deadline.saturating_duration_since(Instant::now());
            if left.is_zero() {
                break;
            }
            st = match self.shared.served.wait_timeout(st, left) {
                Ok((guard, _)) => guard,
                Err(e) => e.into_inner().0,
            };
        }
    }

    fn resident_bytes(&self) -> u64 {
        self.shared.state().resident
    }

    fn pending(&self) -> usize {
        self.shared.state().pending
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        {
            // Set under the lock: the thread either sees it before waiting or is woken.
            let _st = self.shared.state();
            self.shared.stop.store(true, Ordering::Release);
        }
        self.shared.work.notify_all();
        for worker in self.workers.drain(..) {
            // The threads catch panics of the source and decoder; an error here would be a
            // bug in the loader itself, and a destructor must not panic.
            let _ = worker.join();
        }
    }
}
