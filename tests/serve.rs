//! `splatbench serve` as a user starts it: it prints where it listens, answers ranges, logs,
//! and refuses bad arguments with an error naming them.
#![allow(clippy::unwrap_used)]

use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

mod common;

use common::bin;

#[test]
fn serve_prints_its_address_answers_a_range_and_logs_it() {
    let dir = tempfile::tempdir().unwrap();
    let root = dir.path().join("build");
    std::fs::create_dir(&root).unwrap();
    let bytes: Vec<u8> = (0..10_000u32).map(|i| (i % 256) as u8).collect();
    std::fs::write(root.join("repo.bin"), &bytes).unwrap();
    let log = dir.path().join("access.log");
    let (_server, url) = common::serve(&root, "127.0.0.1:0", &["--log", log.to_str().unwrap()]);
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

/// Builds `method` with `param` on `scene` into `build`, and serves it on a loopback port.
fn build_and_serve(
    method: &str,
    param: &str,
    scene: &str,
    build: &std::path::Path,
    cache: &std::path::Path,
) -> harness::serve::Server {
    bin()
        .args([
            "build", "--method", method, "--param", param, "--scene", scene,
        ])
        .arg("--out")
        .arg(build)
        .arg("--cache")
        .arg(cache)
        .assert()
        .success();
    harness::serve::Server::start(
        &harness::serve::ServeOptions::new(build, "127.0.0.1:0".parse().unwrap()),
        Box::new(std::io::sink()),
    )
    .unwrap()
}

fn have_gpu(test: &str) -> bool {
    harness::gpu::gpu_for_test(test).is_some()
}

/// `run --build-url` runs an LPC build served over HTTP: complete, nothing built, the small
/// files copied and the repository not; a served build of another method, or nothing
/// served, is refused naming the flag. (That the frames equal the local build's is checked
/// at the method level in `harness/tests/remote_build.rs`, without a GPU.)
#[test]
fn run_opens_a_build_served_over_http() {
    if !have_gpu("run_opens_a_build_served_over_http") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let build = tmp.path().join("b");
    let scene = "statue:20000:3";
    let server = build_and_serve("lpc", "m=512", scene, &build, &cache);
    let run = |method: &str, url: &str, out: &std::path::Path| {
        let mut c = bin();
        c.args(["run", "--method", method, "--scene", scene, "--frames", "3"])
            .args(["--width", "64", "--height", "64", "--no-metrics"])
            .args(["--build-url", url])
            .arg("--cache")
            .arg(&cache)
            .arg("--out")
            .arg(out);
        c
    };
    let out = tmp.path().join("r");
    run("lpc", &server.url(), &out).assert().success();
    assert!(!out.join("build").exists(), "nothing built");
    assert!(out.join("remote-build/index.bin").is_file());
    assert!(!out.join("remote-build/repo.bin").exists());
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["complete"], true);
    assert_eq!(summary["params"]["m"], "512");
    // The chunks travelled over HTTP: frames.csv counts their bytes and requests.
    let mut csv = csv::Reader::from_path(out.join("frames.csv")).unwrap();
    let header = csv.headers().unwrap().clone();
    let col = |name: &str| header.iter().position(|c| c == name).unwrap();
    let (bytes, issued) = (col("bytes_fetched"), col("requests_issued"));
    let (mut total_bytes, mut total_issued) = (0.0, 0.0);
    for row in csv.records() {
        let row = row.unwrap();
        total_bytes += row[bytes].parse::<f64>().unwrap();
        total_issued += row[issued].parse::<f64>().unwrap();
    }
    assert!(
        total_bytes > 0.0 && total_issued > 0.0,
        "{total_bytes} {total_issued}"
    );
    // summary.json's totals are the columns' sums; the bandwidth was measured.
    let traffic = &summary["traffic"];
    assert_eq!(traffic["bytes_fetched"].as_f64(), Some(total_bytes));
    assert_eq!(traffic["requests_issued"].as_f64(), Some(total_issued));
    assert_eq!(traffic["requests_failed"].as_f64(), Some(0.0));
    assert!(traffic["bandwidth_est_bytes_per_s"].as_f64().unwrap() > 0.0);
    let repo = std::fs::metadata(build.join("repo.bin")).unwrap().len() as f64;
    // Nothing is evicted (20 K points fit the default core budget many times), so a chunk
    // is read at most twice: by the loader thread, and once more by a synchronous `get`
    // racing it (`Loader::get`). The root read at open counts in frame 0.
    assert!(total_bytes <= 2.0 * repo, "{total_bytes} > 2 × {repo}");
    // A sweep over the same served build: one run per budget, nothing built.
    let sweep = tmp.path().join("sweep");
    bin()
        .args([
            "sweep", "--method", "lpc", "--scene", scene, "--path", "orbit",
        ])
        .args(["--frames", "2", "--width", "64", "--height", "64"])
        .args(["--budgets", "4000,8000", "--build-url", &server.url()])
        .arg("--cache")
        .arg(&cache)
        .arg("--out")
        .arg(&sweep)
        .assert()
        .success();
    let rows = std::fs::read_to_string(sweep.join("sweep.csv")).unwrap();
    assert_eq!(rows.lines().count(), 3, "{rows}");
    assert!(!sweep.join("build").exists(), "nothing built");
    assert!(sweep.join("budget-4000/remote-build/index.bin").is_file());
    // A tune over the same served build: a runtime parameter varies, nothing is built, and
    // every run reads the served build.
    let tune = tmp.path().join("tune");
    bin()
        .args([
            "tune", "--method", "lpc", "--scene", scene, "--path", "orbit",
        ])
        .args([
            "--frames",
            "2",
            "--width",
            "64",
            "--height",
            "64",
            "--repeats",
            "1",
        ])
        .args(["--budgets", "6000", "--grid", "in_flight=1,4"])
        .args(["--build-url", &server.url(), "--remote-timeout", "5"])
        .arg("--cache")
        .arg(&cache)
        .arg("--out")
        .arg(&tune)
        .assert()
        .success();
    assert_eq!(common::read_csv(&tune.join("tune.csv")).len(), 2);
    assert!(!tune.join("builds").exists(), "nothing built");
    let runs: Vec<_> = walk(&tune.join("runs"))
        .into_iter()
        .filter(|p| p.ends_with("remote-build/index.bin"))
        .collect();
    assert_eq!(runs.len(), 2, "{runs:?}");
    common::fails(
        bin()
            .args([
                "tune",
                "--method",
                "lpc",
                "--scene",
                scene,
                "--budgets",
                "6000",
            ])
            .args(["--grid", "m=256,512", "--build-url", &server.url()])
            .arg("--out")
            .arg(tmp.path().join("t2")),
        "--build-url",
    );
    common::fails(
        &mut run("qsplat", &server.url(), &tmp.path().join("x")),
        "--build-url",
    );
    common::fails(
        &mut run(
            "lpc",
            &format!("{}nothing/", server.url()),
            &tmp.path().join("y"),
        ),
        "404",
    );
    common::fails(
        bin()
            .args([
                "run",
                "--method",
                "lpc",
                "--scene",
                scene,
                "--build-url",
                "http://x/",
            ])
            .arg("--build-dir")
            .arg(&build),
        "--build-dir",
    );
}

/// Every file under `dir`, recursively.
fn walk(dir: &std::path::Path) -> Vec<std::path::PathBuf> {
    let mut out = Vec::new();
    for e in std::fs::read_dir(dir).unwrap() {
        let p = e.unwrap().path();
        if p.is_dir() {
            out.extend(walk(&p));
        } else {
            out.push(p);
        }
    }
    out
}

/// Once converged, a run over HTTP draws the local run's image, pixel for pixel: LPC, MWKD
/// and Potree on a still camera (`paper/paths/still-near.toml`), 24 frames, the last frame's PNG
/// of each run compared byte for byte (the same renderer and encoder), after checking in
/// `frames.csv` that both had converged (no coarse cloud or stand-in, nothing pending).
#[test]
fn a_remote_run_draws_the_local_runs_image_once_converged() {
    if !have_gpu("a_remote_run_draws_the_local_runs_image_once_converged") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let scene = "statue:20000:3";
    let still = format!("{}/paper/paths/still-near.toml", env!("CARGO_MANIFEST_DIR"));
    let frames = 24;
    for (method, param, coarse) in [
        ("lpc", "m=512", "clouds_coarse"),
        ("mwkd", "vbo=1024", "stand_ins"),
        ("potree", "max_leaf=1000", "nodes_waiting"),
    ] {
        let build = tmp.path().join(format!("b-{method}"));
        let server = build_and_serve(method, param, scene, &build, &cache);
        let run = |flag: &str, from: &str, out: &std::path::Path| {
            bin()
                .args([
                    "run", "--method", method, "--scene", scene, "--path", &still,
                ])
                .args([
                    "--frames",
                    &frames.to_string(),
                    "--width",
                    "96",
                    "--height",
                    "96",
                ])
                .args(["--no-metrics", "--save-images", flag, from])
                .arg("--cache")
                .arg(&cache)
                .arg("--out")
                .arg(out)
                .assert()
                .success();
            let rows = common::read_csv(&out.join("frames.csv"));
            let last = rows.last().unwrap();
            assert_eq!(
                (last[coarse].as_str(), last["loader_pending"].as_str()),
                ("0", "0"),
                "{method} {flag}: not converged after {frames} frames"
            );
            std::fs::read(out.join(format!("images/frame_{:04}.png", frames - 1))).unwrap()
        };
        let local = run(
            "--build-dir",
            build.to_str().unwrap(),
            &tmp.path().join(format!("l-{method}")),
        );
        let remote = run(
            "--build-url",
            &server.url(),
            &tmp.path().join(format!("r-{method}")),
        );
        assert!(local == remote, "{method}: the converged images differ");
    }
}
