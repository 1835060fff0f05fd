//! CI regression tracking: the committed suite (`results/baselines/quick.toml`: every method
//! on statue, terrain and isosurface, a short orbit, a tolerance and a budget) is run and
//! checked against its committed baseline (`quick.json`) with `splatbench check`. A change
//! that alters any method's selection, image or file size fails here, printing the check's
//! table (figure, method, scene, frame/target, old, new, allowed, verdict).
//!
//! After an intended change, re-bless and commit the new baseline with the change:
//!
//! ```sh
//! cargo run --release -- check --suite results/baselines/quick.toml --out /tmp/quick --bless
//! ```

#[test]
fn the_quick_suite_matches_its_committed_baseline() {
    if harness::gpu::gpu_for_test("the_quick_suite_matches_its_committed_baseline").is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let suite = concat!(env!("CARGO_MANIFEST_DIR"), "/results/baselines/quick.toml");
    let t = std::time::Instant::now();
    let out = crate::common::bin()
        .args(["check", "--suite", suite, "--out"])
        .arg(tmp.path().join("out"))
        .arg("--cache")
        .arg(tmp.path().join("cache"))
        .output()
        .unwrap();
    let (stdout, stderr) = (
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr),
    );
    assert!(
        out.status.success(),
        "the quick suite does not match results/baselines/quick.json (exit {:?}):\n{stdout}\n\
         {stderr}\nIf the change is intended, re-bless: cargo run --release -- check --suite \
         results/baselines/quick.toml --out /tmp/quick --bless",
        out.status.code()
    );
    // Every registered method is in the suite, and every run it makes is checked: the count
    // comes from the suite file, not a number pinned here.
    let loaded = harness::check::suite::Suite::load(std::path::Path::new(suite)).unwrap();
    let names: Vec<&str> = loaded.methods.iter().map(|m| m.kind.name()).collect();
    let registry: Vec<&str> = methods::MethodKind::ALL.iter().map(|m| m.name()).collect();
    assert_eq!(names, registry, "results/baselines/quick.toml: methods");
    let runs = format!("holds: {} runs", loaded.runs());
    assert!(stdout.contains(&runs), "expected '{runs}':\n{stdout}");
    eprintln!(
        "quick suite: {:.1} s\n{}",
        t.elapsed().as_secs_f64(),
        stdout.lines().last().unwrap_or_default()
    );
}
