//! `harness::remote` and `methods::store::remote` against `harness::serve` over loopback: chunks read over HTTP
//! ranges equal the local reads, over one kept-alive connection, and every fault is an
//! error naming the URL (and the chunk), within the timeout.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::time::{Duration, Instant};

use harness::remote::HttpFile;
use harness::serve::Server;
use methods::MethodError;
use methods::store::access::{ChunkSource, LocalSource};
use methods::store::remote::RemoteSource;
use methods::store::{ChunkRef, RepoWriter, Repository};
use serving::serve;

mod serving;

/// A repository of 12 chunks of different sizes and contents in `dir/repo.bin`.
fn repository(dir: &Path) -> Vec<ChunkRef> {
    let mut w = RepoWriter::create(&dir.join("repo.bin")).unwrap();
    let refs = (0..12u32)
        .map(|c| {
            let raw: Vec<u8> = (0..(c as usize + 1) * 3000)
                .map(|i| ((i as u32 * (c + 3)) % 97) as u8)
                .collect();
            w.append(&raw).unwrap()
        })
        .collect();
    w.finish().unwrap();
    refs
}

fn remote(server: &Server, name: &str) -> HttpFile {
    HttpFile::new(format!("{}{name}", server.url()), Duration::from_secs(10))
}

#[test]
fn chunks_over_http_equal_the_local_reads_over_one_connection() {
    let dir = tempfile::tempdir().unwrap();
    let refs = repository(dir.path());
    let local_refs = refs.clone();
    let local = LocalSource::new(
        Repository::open(&dir.path().join("repo.bin")).unwrap(),
        refs.clone(),
        "node",
    );
    let (server, log) = serve(dir.path(), |_| {});
    let source = RemoteSource::open(
        std::sync::Arc::new(remote(&server, "repo.bin")),
        refs,
        "node",
    )
    .unwrap();
    assert_eq!(source.len(), 12);
    for id in (0..12).rev() {
        assert_eq!(
            source.fetch(id).unwrap(),
            local.fetch(id).unwrap(),
            "chunk {id}"
        );
    }
    assert!(matches!(source.fetch(12), Err(MethodError::NoChunk(12))));
    // Both count the stored bytes of the chunks they read.
    let stored: u64 = (0..12).map(|i| u64::from(local_refs[i].stored)).sum();
    assert_eq!(source.bytes_read(), stored);
    assert_eq!(local.bytes_read(), stored);
    drop(server);
    // The magic and the 12 chunks: 13 range requests from one client port (kept alive).
    let log = log.text();
    let peers: std::collections::BTreeSet<&str> =
        log.lines().filter_map(|l| l.split(' ').nth(1)).collect();
    assert_eq!(log.lines().count(), 13, "{log}");
    assert_eq!(peers.len(), 1, "{log}");
    assert!(log.lines().all(|l| l.contains(" 206 ")), "{log}");
}

#[test]
fn whole_files_and_missing_ones() {
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("index.json"), b"{\"nodes\": 3}").unwrap();
    let (server, _) = serve(dir.path(), |_| {});
    assert_eq!(
        remote(&server, "index.json").get().unwrap(),
        b"{\"nodes\": 3}"
    );
    let err = remote(&server, "nope.json").get().unwrap_err().to_string();
    assert!(
        err.contains("/nope.json") && err.contains("HTTP 404"),
        "{err}"
    );
    let err = RemoteSource::open(
        std::sync::Arc::new(remote(&server, "nope.bin")),
        Vec::new(),
        "node",
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("/nope.bin") && err.contains("HTTP 404"),
        "{err}"
    );
    let err = RemoteSource::open(
        std::sync::Arc::new(remote(&server, "index.json")),
        Vec::new(),
        "node",
    )
    .err()
    .unwrap()
    .to_string();
    assert!(err.contains("bad magic"), "{err}");
}

#[test]
fn a_corrupted_chunk_is_an_error_naming_the_url_and_the_chunk() {
    let dir = tempfile::tempdir().unwrap();
    let refs = repository(dir.path());
    let path = dir.path().join("repo.bin");
    let mut bytes = std::fs::read(&path).unwrap();
    bytes[refs[5].offset as usize + 10] ^= 0x40;
    std::fs::write(&path, &bytes).unwrap();
    let (server, _) = serve(dir.path(), |_| {});
    let source = RemoteSource::open(
        std::sync::Arc::new(remote(&server, "repo.bin")),
        refs,
        "node",
    )
    .unwrap();
    assert!(source.fetch(4).is_ok());
    let err = source.fetch(5).unwrap_err();
    assert!(matches!(err, MethodError::Corrupt { .. }), "{err}");
    let err = err.to_string();
    assert!(
        err.contains("/repo.bin") && err.contains("node 5") && err.contains("checksum"),
        "{err}"
    );
}

#[test]
fn a_truncated_repository_and_server_errors_are_named() {
    let dir = tempfile::tempdir().unwrap();
    let refs = repository(dir.path());
    let path = dir.path().join("repo.bin");
    let (server, _) = serve(dir.path(), |o| o.fail_after = Some(3));
    let source = RemoteSource::open(
        std::sync::Arc::new(remote(&server, "repo.bin")),
        refs.clone(),
        "node",
    )
    .unwrap();
    assert!(source.fetch(0).is_ok());
    // Cut the file inside chunk 11: its range now runs past the end.
    let len = std::fs::metadata(&path).unwrap().len();
    std::fs::OpenOptions::new()
        .write(true)
        .open(&path)
        .unwrap()
        .set_len(len - 100)
        .unwrap();
    let err = source.fetch(11).unwrap_err().to_string();
    assert!(
        err.contains("/repo.bin") && err.contains("Content-Range"),
        "{err}"
    );
    // The server now fails every request (--fail-after 3: magic, chunk 0, chunk 11).
    let err = source.fetch(1).unwrap_err().to_string();
    assert!(err.contains("HTTP 500"), "{err}");
    // And when it is gone, the connection is refused.
    let url = source.url().to_string();
    server.stop();
    let err = source.fetch(1).unwrap_err().to_string();
    assert!(err.starts_with(&url) && err.contains("failed"), "{err}");
}

#[test]
fn a_server_that_does_not_answer_is_an_error_within_the_timeout() {
    let dir = tempfile::tempdir().unwrap();
    let refs = repository(dir.path());
    let (server, _) = serve(dir.path(), |o| o.latency = Duration::from_secs(2));
    let file = HttpFile::new(
        format!("{}repo.bin", server.url()),
        Duration::from_millis(300),
    );
    let t = Instant::now();
    let err = RemoteSource::open(std::sync::Arc::new(file), refs, "node")
        .err()
        .unwrap()
        .to_string();
    // The 300 ms timeout, with margin for a loaded machine; far below the server's 2 s.
    assert!(t.elapsed() < Duration::from_secs(3), "{:?}", t.elapsed());
    assert!(err.contains("/repo.bin"), "{err}");
}

/// A one-connection server that answers the first request on it with `reply` (raw bytes)
/// and closes; with `reply` = `None` it closes without reading the request, which resets
/// the connection (unread data on a closed socket makes the kernel send RST).
fn scripted(reply: Option<Vec<u8>>) -> String {
    use std::io::{Read, Write};
    let listener = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
    let url = format!("http://{}/repo.bin", listener.local_addr().unwrap());
    std::thread::spawn(move || {
        let (mut s, _) = listener.accept().unwrap();
        let Some(reply) = reply else {
            std::thread::sleep(Duration::from_millis(100));
            return;
        };
        let mut req = Vec::new();
        let mut b = [0u8; 1];
        while !req.ends_with(b"\r\n\r\n") && s.read(&mut b).unwrap_or(0) == 1 {
            req.push(b[0]);
        }
        let _ = s.write_all(&reply);
    });
    url
}

/// Faults a real server does not make, from a scripted one: a reset connection, a body cut
/// short of its `Content-Length`, a server that ignores `Range` (200 with the whole file),
/// a `Content-Range` for other bytes, a 416 and a status line that is not HTTP. Each is an
/// error naming the URL, within the request's timeout.
#[test]
fn a_reset_a_short_body_and_wrong_answers_are_errors_naming_the_url() {
    let head = |status: &str, range: &str, len: usize| {
        format!("HTTP/1.1 {status}\r\nContent-Range: {range}\r\nContent-Length: {len}\r\n\r\n")
            .into_bytes()
    };
    let with_body = |mut h: Vec<u8>, body: usize| {
        h.extend(std::iter::repeat_n(7u8, body));
        h
    };
    let cases: Vec<(&str, Option<Vec<u8>>, &str)> = vec![
        ("reset", None, "failed"),
        (
            "short body",
            Some(with_body(
                head("206 Partial Content", "bytes 100-199/1000", 100),
                40,
            )),
            "reading bytes 100-199",
        ),
        (
            "range ignored",
            Some(with_body(head("200 OK", "bytes 0-999/1000", 1000), 1000)),
            "HTTP 200 for bytes 100-199, expected 206",
        ),
        (
            "other bytes",
            Some(with_body(
                head("206 Partial Content", "bytes 0-99/1000", 100),
                100,
            )),
            "Content-Range \"bytes 0-99/1000\"",
        ),
        (
            "416",
            Some(head("416 Range Not Satisfiable", "bytes */50", 0)),
            "HTTP 416",
        ),
        (
            "not HTTP",
            Some(b"SSH-2.0-OpenSSH\r\n\r\n".to_vec()),
            "failed",
        ),
    ];
    for (what, reply, needle) in cases {
        let url = scripted(reply);
        let file = HttpFile::new(url.clone(), Duration::from_secs(5));
        let t = Instant::now();
        let err = file.get_range(100, 100).unwrap_err().to_string();
        assert!(
            t.elapsed() < Duration::from_secs(5),
            "{what}: {:?}",
            t.elapsed()
        );
        assert!(
            err.starts_with(&url) && err.contains(needle),
            "{what}: expected '{needle}' in: {err}"
        );
    }
}

/// A host name that cannot resolve (RFC 6761 reserves `.invalid`) is an error naming the
/// URL within the request's timeout: ureq resolves on a thread it stops waiting for at the
/// timeout (2 s here; 4 s of margin for a loaded machine).
#[test]
fn a_name_that_does_not_resolve_is_an_error_within_the_timeout() {
    let url = "http://splatbench-test.invalid:8080/repo.bin";
    let file = HttpFile::new(url, Duration::from_secs(2));
    let t = Instant::now();
    let err = file.get().unwrap_err().to_string();
    assert!(t.elapsed() < Duration::from_secs(6), "{:?}", t.elapsed());
    assert!(err.starts_with(url) && err.contains("failed"), "{err}");
}
