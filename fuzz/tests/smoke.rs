#![allow(clippy::unwrap_used)]
//! The fuzzer in CI: every target for a bounded, fixed-seed run must find nothing, and the
//! supervisor must catch a panic, an abort, a thread's panic and a hang (target `selftest`)
//! and save each input.

use std::process::Command;

const FUZZ: &str = env!("CARGO_BIN_EXE_fuzz");

/// Inputs per target: a few hundred (a debug build on two cores: about 12 s in all).
fn iters(target: &str) -> u64 {
    match target {
        "lpc" | "mwkd" => 300,
        _ => 500,
    }
}

#[test]
fn every_target_finds_nothing_on_a_fixed_seed() {
    let crashes = tempfile_dir("smoke");
    let list = Command::new(FUZZ).arg("list").output().unwrap();
    let list = String::from_utf8(list.stdout).unwrap();
    let targets: Vec<&str> = list
        .lines()
        .filter_map(|l| l.split_whitespace().next())
        .collect();
    assert_eq!(targets.len(), 18, "{list}");
    let mut failed = Vec::new();
    for t in targets {
        let out = Command::new(FUZZ)
            .args([t, "--iters", &iters(t).to_string(), "--seed", "7"])
            .args(["--crashes", crashes.to_str().unwrap()])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        if !out.status.success() {
            failed.push(format!(
                "{t}: {stdout}\n{}",
                String::from_utf8_lossy(&out.stderr)
            ));
        } else {
            let row = stdout.lines().find(|l| l.starts_with(t)).unwrap_or("");
            let execs: u64 = row
                .split_whitespace()
                .nth(1)
                .and_then(|n| n.parse().ok())
                .unwrap_or(0);
            assert_eq!(execs, iters(t), "{t}: {stdout}");
        }
    }
    let _ = std::fs::remove_dir_all(&crashes);
    assert!(failed.is_empty(), "findings:\n{}", failed.join("\n"));
}

#[test]
fn the_supervisor_catches_panics_aborts_and_hangs() {
    let crashes = tempfile_dir("selftest");
    let out = Command::new(FUZZ)
        .args(["selftest", "--iters", "10", "--timeout-s", "2"])
        .args(["--crashes", crashes.to_str().unwrap()])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        !out.status.success(),
        "findings must fail the run: {stdout}"
    );
    for needle in [
        "selftest panic (iteration 3",
        "selftest crash (iteration 5",
        "SIGABRT",
        "selftest panic (iteration 6",
        "loader thread",
        "selftest hang (iteration 7",
    ] {
        assert!(stdout.contains(needle), "'{needle}' missing: {stdout}");
    }
    // Every iteration ran, the ones after the abort and the hang included.
    let row = stdout.lines().find(|l| l.starts_with("selftest")).unwrap();
    assert_eq!(row.split_whitespace().nth(1), Some("10"), "{row}");
    // One reproducer and one note per finding; each holds the input that caused it.
    let mut bins: Vec<_> = std::fs::read_dir(&crashes)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "bin"))
        .collect();
    bins.sort();
    assert_eq!(bins.len(), 4, "{bins:?}");
    let mut its: Vec<u64> = bins
        .iter()
        .map(|b| u64::from_le_bytes(std::fs::read(b).unwrap().try_into().unwrap()))
        .collect();
    its.sort();
    assert_eq!(its, [3, 5, 6, 7]);
    assert!(bins.iter().all(|b| b.with_extension("txt").exists()));
    let _ = std::fs::remove_dir_all(&crashes);
}

fn tempfile_dir(what: &str) -> std::path::PathBuf {
    let d = std::env::temp_dir().join(format!(
        "splatbench-fuzz-test-{what}-{}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&d);
    d
}
