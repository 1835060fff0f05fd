//! Records the git commit the harness was built from (results files cite it).
//!
//! It is rerun when HEAD moves: when `HEAD` itself changes (a checkout), when the branch it
//! names moves (a commit, an amend, a reset: the ref's file, or `packed-refs` once git packs
//! it), and when the index changes (what `-dirty` depends on). Watching `HEAD` and the index
//! alone misses a commit that leaves the index file as it was — an amend of the message
//! only, `commit --allow-empty`, `reset --soft` (checked: none of them rewrites the index) —
//! after which a build would keep the old id.
use std::path::PathBuf;
use std::process::Command;

fn git(args: &[&str]) -> Option<String> {
    Command::new("git")
        .args(args)
        .output()
        .ok()
        .filter(|o| o.status.success())
        .map(|o| String::from_utf8_lossy(&o.stdout).trim().to_string())
}

fn main() {
    let commit = git(&["rev-parse", "--short=12", "HEAD"]).unwrap_or_else(|| "unknown".into());
    let dirty = Command::new("git")
        .args(["status", "--porcelain", "--untracked-files=no"])
        .output()
        .ok()
        .is_some_and(|o| !o.stdout.is_empty());
    println!(
        "cargo:rustc-env=SPLATBENCH_GIT_COMMIT={commit}{}",
        if dirty { "-dirty" } else { "" }
    );
    // Absolute paths, right in a worktree too (its HEAD and index are its own, the refs the
    // repository's). A path that does not exist (no such ref file while the ref is packed)
    // makes cargo rerun this script every build: harmless, it is quick.
    let abs = |p: String| {
        let p = PathBuf::from(p);
        if p.is_absolute() {
            p
        } else {
            std::env::current_dir().unwrap_or_default().join(p)
        }
    };
    let (Some(git_dir), Some(common)) = (
        git(&["rev-parse", "--git-dir"]).map(abs),
        git(&["rev-parse", "--git-common-dir"]).map(abs),
    ) else {
        return;
    };
    let mut watch = vec![
        git_dir.join("HEAD"),
        git_dir.join("index"),
        common.join("packed-refs"),
    ];
    if let Some(r) = git(&["symbolic-ref", "-q", "HEAD"]) {
        watch.push(common.join(r));
    }
    for p in watch {
        println!("cargo:rerun-if-changed={}", p.display());
    }
}
