//! The loader over HTTP when the server goes away: failed fetches are tried again with
//! backoff and succeed once the server is back; after the last try the chunk is failed
//! with the error naming the URL, and asked for again after the cooldown it is fetched
//! anew. Each case is bounded in time.
#![allow(clippy::unwrap_used)]

use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};

use harness::remote::HttpFile;
use harness::serve::{ServeOptions, Server};
use methods::SplatBatch;
use methods::store::RepoWriter;
use methods::store::access::{DataAccess, Decoder, Loader, LoaderOptions, Retry};
use methods::store::remote::RemoteSource;

/// A repository of 6 chunks; chunk `c` holds `(c + 1) · 1000` bytes.
fn repository(dir: &Path) -> Vec<methods::store::ChunkRef> {
    let mut w = RepoWriter::create(&dir.join("repo.bin")).unwrap();
    let refs = (0..6u32)
        .map(|c| w.append(&vec![c as u8; (c as usize + 1) * 1000]).unwrap())
        .collect();
    w.finish().unwrap();
    refs
}

/// One point per chunk, at x = its length in bytes.
fn length_decoder() -> Decoder {
    Arc::new(|_, bytes: &[u8]| {
        Ok(SplatBatch {
            positions: vec![[bytes.len() as f32, 0.0, 0.0]],
            normals: None,
            colors: None,
            radii: None,
            lod: None,
        })
    })
}

fn start(dir: &Path, addr: SocketAddr) -> Server {
    Server::start(&ServeOptions::new(dir, addr), Box::new(std::io::sink())).unwrap()
}

fn wait_until(what: &str, limit: Duration, cond: impl Fn() -> bool) {
    let deadline = Instant::now() + limit;
    while !cond() {
        assert!(Instant::now() < deadline, "timed out waiting for {what}");
        std::thread::sleep(Duration::from_millis(5));
    }
}

/// A loader over the repository served by `server`, retrying as `retry` says. Requests
/// time out after 1 s: the connection kept alive from `RemoteSource::open` outlives a stopped
/// server (`Server::stop`), so the first attempt after a stop waits for its timeout, as on a
/// half-open connection; later attempts connect anew and are refused at once.
fn loader(server: &Server, refs: Vec<methods::store::ChunkRef>, retry: Retry) -> Loader {
    let file = HttpFile::new(format!("{}repo.bin", server.url()), Duration::from_secs(1));
    let source = RemoteSource::open(std::sync::Arc::new(file), refs, "node").unwrap();
    Loader::spawn_with(
        Arc::new(source),
        length_decoder(),
        LoaderOptions {
            core_bytes: u64::MAX,
            delay_frames: 0,
            in_flight: 1,
        },
        retry,
    )
}

#[test]
fn a_fetch_is_tried_again_until_the_server_is_back() {
    let dir = tempfile::tempdir().unwrap();
    let refs = repository(dir.path());
    let server = start(dir.path(), "127.0.0.1:0".parse().unwrap());
    let addr = server.addr();
    let l = loader(
        &server,
        refs,
        Retry {
            tries: 8,
            backoff: Duration::from_millis(50),
            cooldown: None,
        },
    );
    server.stop();
    l.begin_frame();
    l.request(3);
    // The first attempt times out (1 s), the next are refused at once, 50, 100, 200 … ms
    // apart; the server is back after 1.2 s.
    std::thread::sleep(Duration::from_millis(1200));
    assert!(!l.available(3));
    let _back = start(dir.path(), addr);
    // The remaining tries span 0.4 + 0.8 + … + 3.2 s: one of them finds the server.
    wait_until(
        "chunk 3 over the restarted server",
        Duration::from_secs(10),
        || l.available(3),
    );
    assert_eq!(l.get(3).unwrap().positions[0][0], 4000.0);
    assert!(l.failures().is_empty());
    let t = l.traffic();
    assert_eq!(t.issued, 1);
    // Every try that failed counts: at least the one while the server was down, and fewer
    // than all 8 since the chunk came.
    assert!((1..8).contains(&t.failed), "{} failed tries", t.failed);
}

#[test]
fn after_its_last_try_a_chunk_is_failed_and_fetched_anew_after_the_cooldown() {
    let dir = tempfile::tempdir().unwrap();
    let refs = repository(dir.path());
    let server = start(dir.path(), "127.0.0.1:0".parse().unwrap());
    let addr = server.addr();
    let url = server.url();
    let l = loader(
        &server,
        refs,
        Retry {
            tries: 3,
            backoff: Duration::from_millis(20),
            cooldown: Some(Duration::from_millis(300)),
        },
    );
    server.stop();
    l.begin_frame();
    l.request(2);
    wait_until("chunk 2 to fail", Duration::from_secs(5), || {
        !l.failures().is_empty()
    });
    let failures = l.failures();
    assert_eq!(failures.len(), 1);
    let (id, error) = &failures[0];
    assert_eq!(*id, 2);
    assert!(
        error.contains(&url) && error.contains("after 3 tries"),
        "{error}"
    );
    assert_eq!((l.pending(), l.traffic().failed), (0, 3));
    // Asked again at once: still failed, nothing queued.
    l.request(2);
    assert_eq!((l.pending(), l.traffic().issued), (0, 1));
    let _back = start(dir.path(), addr);
    std::thread::sleep(Duration::from_millis(320));
    l.request(2);
    wait_until("chunk 2 after the cooldown", Duration::from_secs(5), || {
        l.available(2)
    });
    assert!(l.failures().is_empty());
    assert_eq!(l.traffic().issued, 2);
}
