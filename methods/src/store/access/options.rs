//! What a [`super::Loader`] is told: its core budget, simulated delay and requests in flight,
//! how it retries a failed chunk, and how long a frame waits for chunks due.

use std::time::Duration;

/// Options of the local [`super::Loader`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LoaderOptions {
    /// Bytes of decoded chunks kept in core (least recently used dropped beyond).
    pub core_bytes: u64,
    /// Frames ([`super::DataAccess::begin_frame`] calls) between a request and the moment its
    /// chunk counts as available: simulated latency, exactly d frames for d ≥ 1 (see
    /// [`super::Loader`], "Delay"); 0 = as soon as it is decoded.
    pub delay_frames: u32,
    /// Requests fetched at once: loader threads, each with one request in flight (≥ 1).
    pub in_flight: u32,
}

impl LoaderOptions {
    /// The options a method's runtime parameters give (LPC, MWKD, Potree): `core_mb` MiB of
    /// core, `delay_frames`, and `in_flight` requests, else as many as suit the repository
    /// at `repo` ([`super::RepoAt::in_flight`]).
    pub fn new(
        core_mb: u64,
        delay_frames: u32,
        in_flight: Option<u32>,
        repo: &super::RepoAt,
    ) -> Self {
        Self {
            core_bytes: core_mb << 20,
            delay_frames,
            in_flight: repo.in_flight(in_flight),
        }
    }
}

/// How a loader retries a chunk whose fetch or decode failed: a network may fail for a
/// moment (a reset connection, a server restarting), a local file does not heal.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Retry {
    /// Attempts in all (1: none repeated).
    pub tries: u32,
    /// Wait before the second attempt, doubled before each further one.
    pub backoff: Duration,
    /// A chunk given up on is fetched again when asked for this long after (the server came
    /// back); `None`: never again.
    pub cooldown: Option<Duration>,
}

impl Retry {
    /// Local repositories: a failed read is final.
    pub const NONE: Retry = Retry {
        tries: 1,
        backoff: Duration::ZERO,
        cooldown: None,
    };
    /// Remote repositories: 4 attempts 0.25, 0.5 and 1 s apart; asked again 5 s after
    /// giving up, a chunk is tried anew.
    pub const REMOTE: Retry = Retry {
        tries: 4,
        backoff: Duration::from_millis(250),
        cooldown: Some(Duration::from_secs(5)),
    };
}

/// The longest [`super::DataAccess::begin_frame`] waits for the chunks due in its frame (delay ≥ 1)
/// before the frame goes on without them: a source that hangs must not hang the run.
pub const DUE_WAIT: Duration = Duration::from_secs(30);
