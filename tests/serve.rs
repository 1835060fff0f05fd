//! `splatbench serve` as a user starts it: it prints where it listens, answers ranges, logs,
//! and refuses bad arguments with an error naming them.
#![allow(clippy::unwrap_used)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::process::{Child, Stdio};
use std::time::Duration;

mod common;

use common::bin;

/// Kills the server when the test ends, however it ends.
struct Running(Child);

impl Drop for Running {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

#[test]
fn serve_prints_its_address_answers_a_range_and_logs_it() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("build");
    std::fs::create_dir(&root).unwrap();
    let bytes: Vec<u8> = (0..10_000u32).map(|i| (i % 256) as u8).collect();
    std::fs::write(root.join("repo.bin"), &bytes).unwrap();
    let log = dir.path().join("access.log");
    let cmd = std::process::Command::new(env!("CARGO_BIN_EXE_splatbench"))
        .args(["serve", root.to_str().unwrap(), "--addr", "127.0.0.1:0"])
        .args(["--log", log.to_str().unwrap()])
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let mut server = Running(cmd);
    let mut first = String::new();
    BufReader::new(server.0.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    let url = first
        .trim()
        .split(" at ")
        .nth(1)
        .unwrap_or_else(|| panic!("first line {first:?}"));
    let addr = url
        .strip_prefix("http://")
        .and_then(|u| u.strip_suffix('/'))
        .unwrap();
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    write!(
        s,
        "GET /repo.bin HTTP/1.1\r\nHost: x\r\nRange: bytes=100-199\r\nConnection: close\r\n\r\n"
    )
    .unwrap();
    let mut reply = Vec::new();
    s.read_to_end(&mut reply).unwrap();
    let split = reply.windows(4).position(|w| w == b"\r\n\r\n").unwrap();
    let head = String::from_utf8_lossy(&reply[..split]).to_string();
    assert!(head.starts_with("HTTP/1.1 206"), "{head}");
    assert!(
        head.contains("Content-Range: bytes 100-199/10000"),
        "{head}"
    );
    assert_eq!(reply[split + 4..], bytes[100..200]);
    // The log line is written once the response is sent; give the server a moment.
    let mut logged = String::new();
    for _ in 0..100 {
        logged = std::fs::read_to_string(&log).unwrap_or_default();
        if !logged.is_empty() {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    assert!(
        logged
            .trim_end()
            .ends_with("GET /repo.bin bytes=100-199 206 100"),
        "{logged}"
    );
}

#[test]
fn serve_refuses_a_missing_directory_and_bad_flags() {
    let dir = tempfile::tempdir().unwrap();
    let missing = dir.path().join("no-such-build");
    common::fails(
        bin().args(["serve", missing.to_str().unwrap(), "--addr", "127.0.0.1:0"]),
        "no-such-build",
    );
    let d = dir.path().to_str().unwrap();
    common::fails(
        bin().args(["serve", d, "--addr", "127.0.0.1:0", "--bandwidth", "0"]),
        "--bandwidth",
    );
    common::fails(
        bin().args(["serve", d, "--addr", "127.0.0.1:0", "--threads", "0"]),
        "--threads",
    );
}
