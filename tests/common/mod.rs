//! What the CLI test files share: the binary, and the check for a clean failure.
#![allow(clippy::unwrap_used, dead_code)]

use assert_cmd::Command;

/// The `splatbench` binary.
pub fn bin() -> Command {
    Command::cargo_bin("splatbench").unwrap()
}

/// Runs `cmd`, which must fail cleanly: a non-zero exit, no panic, and `needle` in its stderr.
pub fn fails(cmd: &mut Command, needle: &str) {
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{cmd:?} should fail: {err}");
    assert!(!err.contains("panicked"), "{cmd:?} panicked: {err}");
    assert!(
        err.contains(needle),
        "{cmd:?}: expected '{needle}' in: {err}"
    );
}
