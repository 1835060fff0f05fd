//! `splatbench reproduce` end to end (the specs themselves: `reproduce_specs.rs`): a quick
//! reproduction of small tables writes a report holding their rows with numbers, and a tiny
//! spec of our own exercises builds shared across measures, runs, sweeps, an isolated run and
//! a figure.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use assert_cmd::Command;

mod common;
use common::{SPEC_GOOD as GOOD, root};

fn bin() -> Command {
    let mut c = common::bin();
    c.current_dir(root()).env("NODEVICE_SELECT", "1");
    c
}

/// Runs a CLI command that must fail cleanly, naming `needle`.
fn fails_with(cmd: &mut Command, needle: &str) {
    common::fails(cmd, needle);
}

#[test]
fn quick_reproduction_of_small_tables_writes_their_rows() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("out");
    bin()
        .args([
            "reproduce",
            "--profile",
            "quick",
            "--only",
            "mwkd-table2,qsplat-fig6",
            "--out",
        ])
        .arg(&out)
        .arg("--cache")
        .arg(d.path().join("cache"))
        .assert()
        .success();
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("## Multi-way kd-tree (Goswami et al. 2010) — Table II"),
        "{report}"
    );
    // Table II is exact: every row holds, with the paper's numbers on both sides.
    for row in [
        "| N = 6, VBO 4,009: nodes | 55,987 | 55,987 | 1.00 | exact | holds |",
        "| N = 8, VBO 364,943: levels | 4 | 4 | 1.00 | exact | holds |",
    ] {
        assert!(report.contains(row), "missing '{row}' in {report}");
    }
    // QSplat Fig. 6 on the quick statue: 4 bytes per node, true by construction (shown, not
    // counted as a verdict); the verdicts are words.
    assert!(
        report.contains(
            "| bytes per node (no colour) | 4 | 4 | 1.00 | by construction | by construction |"
        ),
        "{report}"
    );
    // The spec hashes are recorded (issue 35: reports that cannot go stale).
    assert!(report.contains("- spec `qsplat-fig6`: `"), "{report}");
    assert!(report.contains("| interior nodes / leaves |"), "{report}");
    assert!(report.contains("commit: `"), "{report}");
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let tables = results["tables"].as_array().unwrap();
    // Papers in order of publication: QSplat's table before MWKD's.
    let ids: Vec<&str> = tables.iter().map(|t| t["id"].as_str().unwrap()).collect();
    assert_eq!(ids, ["qsplat-fig6", "mwkd-table2"]);
    assert_eq!(tables[1]["verdict"]["verdict"], "holds");
    // A partial run cannot publish, and an unknown id is named.
    fails_with(
        bin()
            .args(["reproduce", "--only", "mwkd-table2", "--publish"])
            .arg(d.path()),
        "--publish regenerates the whole report",
    );
    fails_with(
        bin()
            .args(["reproduce", "--only", "mwkd-tabel2", "--out"])
            .arg(&out),
        "--only: no spec 'mwkd-tabel2'",
    );
}

const TINY: &str = r#"
id = "tiny"
paper = "Test"
title = "A tiny spec exercising every kind of measure"
source = "tests/reproduce.rs"

[scenes.s]
generator = "statue"
points = 6000
seed = 3

[[measure]]
id = "b"
kind = "build"
method = "lpc"
scene = "s"
params = { m = 512 }

[[measure]]
id = "r"
kind = "run"
method = "lpc"
scene = "s"
params = { m = 512, fetch_per_frame = 100000 }
frames = 3
skip = 2
eps = 2
width = 96
height = 96

[[measure]]
id = "iso"
kind = "run"
method = "lpc"
scene = "s"
params = { m = 512 }
frames = 2
eps = 2
width = 96
height = 96
metrics = false
isolate = true

[[measure]]
id = "sw"
kind = "sweep"
method = "qsplat"
scene = "s"
frames = 1
eps = [8, 1]
width = 96
height = 96

[[figure]]
name = "f"
title = "FLIP against points"
sweeps = ["sw"]

[[row]]
what = "the run and the build count the same input"
paper = 6000
ours = "r.build.points_in"
rule = "exact"

[[row]]
what = "clouds built"
ours = "b.clouds"
rule = "report"

[[row]]
what = "a build rate is a rate"
paper = 1
ours = "b.points_per_s * b.seconds / b.points_in"
rule = "within"
tolerance = 0.01

[[row]]
what = "frames take time"
paper = [0, 1e9]
ours = "r.median.wall_ms"
rule = "inside"

[[row]]
what = "a finer tolerance draws more"
paper = [1, 2]
ours = ["sw.eps_8.median.points_drawn", "sw.eps_1.median.points_drawn"]
rule = "order"

[[row]]
what = "isolated run has its own memory figure"
paper = 1
ours = "iso.peak_rss_bytes / iso.peak_rss_bytes"
rule = "exact"

[[row]]
what = "an impossible rate"
paper = 1e15
ours = "r.median.splats_per_s"
rule = "at_least"
needs_gpu = true

[[measure]]
id = "slow"
kind = "build"
method = "qsplat"
scene = "s"
profiles = ["full", "paper"]

[[row]]
what = "a figure only the larger profiles measure"
ours = "slow.bytes_per_node"
rule = "report"
"#;

/// A temporary directory with `specs/tiny.toml` ([`TINY`]); `(dir, specs, out)`.
fn tiny_spec_dir() -> (tempfile::TempDir, std::path::PathBuf, std::path::PathBuf) {
    let d = tempfile::tempdir().unwrap();
    let specs = d.path().join("specs");
    std::fs::create_dir_all(&specs).unwrap();
    std::fs::write(specs.join("tiny.toml"), TINY).unwrap();
    let out = d.path().join("out");
    (d, specs, out)
}

#[test]
fn a_tiny_spec_runs_every_kind_of_measure() {
    let Some(_gpu) = harness::gpu::gpu_for_test("a_tiny_spec_runs_every_kind_of_measure") else {
        return;
    };
    let (d, specs, out) = tiny_spec_dir();
    let run = |out: &Path| {
        bin()
            .args(["reproduce", "--specs"])
            .arg(&specs)
            .arg("--out")
            .arg(out)
            .arg("--cache")
            .arg(d.path().join("cache"))
            .arg("--publish")
            .arg(d.path().join("paper"))
            .assert()
            .success();
    };
    run(&out);
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains(
            "| the run and the build count the same input | 6,000 | 6,000 | 1.00 | exact | holds |"
        ),
        "{report}"
    );
    assert!(
        report.contains("| a finer tolerance draws more |"),
        "{report}"
    );
    assert!(report.contains("| same ordering | holds |"), "{report}");
    assert!(
        report
            .contains("| isolated run has its own memory figure | 1 | 1 | 1.00 | exact | holds |"),
        "{report}"
    );
    // lavapipe is a CPU: the GPU row is listed, not measured.
    assert!(
        report.contains("| an impossible rate |") && report.contains("| needs a GPU |"),
        "{report}"
    );
    assert!(report.contains("Sweep `sw`"), "{report}");
    // Times a verdict reads are medians of three: the build's (b's rate), the run's frames.
    assert!(
        report.contains("build time: the median of 3 builds ("),
        "{report}"
    );
    assert!(report.contains("times: the median of 3 runs ("), "{report}");
    // Its value prints as 1 or 1.00 (rate × time / points, rounded either side of 1).
    assert!(
        report
            .lines()
            .any(|l| l.starts_with("| a build rate is a rate | 1 |")
                && l.ends_with("| ratio within ±1 % | holds |")),
        "{report}"
    );
    let build_json = std::fs::read_dir(out.join("builds"))
        .unwrap()
        .map(|e| e.unwrap().path().join("build.json"))
        .find(|p| std::fs::read_to_string(p).is_ok_and(|t| t.contains("timing_builds")));
    assert!(build_json.is_some(), "the timed build's build.json says so");
    // The measure limited to the larger profiles did not run; its row is named.
    assert!(
        report.contains(
            "Rows this profile leaves out (measured in the profiles named): \
             *a figure only the larger profiles measure* (full, paper)."
        ),
        "{report}"
    );
    assert!(!report.contains("`slow`"), "{report}");
    assert!(
        report.contains("![FLIP against points](figures/tiny-f.png)"),
        "{report}"
    );
    for f in [
        "figures/tiny-f.png",
        "figures/tiny-f.svg",
        "results.json",
        "runs/tiny/r/frames.csv",
        "runs/tiny/sw/sweep.csv",
    ] {
        assert!(out.join(f).is_file(), "{f}");
    }
    // One build per (method, build parameters, scene): `b` and `r` share theirs (m = 512;
    // fetch_per_frame is a runtime parameter), the isolated run too; the sweep has its own.
    let builds: Vec<_> = std::fs::read_dir(out.join("builds")).unwrap().collect();
    assert_eq!(builds.len(), 2, "{builds:?}");
    // Published: the report, results and figures under the profile's names.
    let paper = d.path().join("paper");
    for f in [
        "report-quick.md",
        "results-quick.json",
        "figures-quick/tiny-f.png",
        "figures-quick/tiny-f.svg",
    ] {
        assert!(paper.join(f).is_file(), "published {f}");
    }
    let published = std::fs::read_to_string(paper.join("report-quick.md")).unwrap();
    assert!(
        published.contains("](figures-quick/tiny-f.png)"),
        "{published}"
    );
    // A bad expression at evaluation (a metric that does not exist) fails the table and the
    // command, and nothing is published.
    std::fs::write(
        specs.join("tiny.toml"),
        TINY.replace("ours = \"b.clouds\"", "ours = \"b.cloudz\""),
    )
    .unwrap();
    std::fs::remove_dir_all(&paper).unwrap();
    let o = bin()
        .args(["reproduce", "--specs"])
        .arg(&specs)
        .arg("--out")
        .arg(&out)
        .arg("--cache")
        .arg(d.path().join("cache"))
        .arg("--publish")
        .arg(&paper)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!o.status.success());
    assert!(
        err.contains("1 table(s) failed: nothing published"),
        "{err}"
    );
    assert!(!paper.join("report-quick.md").exists());
    let report = std::fs::read_to_string(out.join("report.md")).unwrap();
    assert!(
        report.contains("measure 'b' has no metric 'cloudz'"),
        "{report}"
    );
}

/// `--resume` (issue 35: a paper-profile part outlives a session): a second run takes every
/// measure the first one finished from its checkpoint, same numbers, runs untouched; an
/// edited spec runs everything again. A binary built from a dirty tree writes no
/// checkpoints (its commit does not name what ran), so there it resumes nothing.
#[test]
fn a_resumed_reproduction_takes_finished_measures_from_their_checkpoints() {
    let Some(_gpu) = harness::gpu::gpu_for_test(
        "a_resumed_reproduction_takes_finished_measures_from_their_checkpoints",
    ) else {
        return;
    };
    let (d, specs, out) = tiny_spec_dir();
    let run = |resume: bool| {
        let mut c = bin();
        c.args(["reproduce", "--specs"])
            .arg(&specs)
            .arg("--out")
            .arg(&out)
            .arg("--cache")
            .arg(d.path().join("cache"));
        if resume {
            c.arg("--resume");
        }
        let output = c.assert().success().get_output().clone();
        let results: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap())
                .unwrap();
        let report = std::fs::read_to_string(out.join("report.md")).unwrap();
        let stderr = String::from_utf8_lossy(&output.stderr).into_owned();
        (results, report, stderr)
    };
    let rows = |v: &serde_json::Value| v["tables"][0]["rows"].to_string();
    let (first, report, _) = run(false);
    assert!(!report.contains("resumed"), "{report}");
    let frames = out.join("runs/tiny/r/frames.csv");
    let before = std::fs::read(&frames).unwrap();
    let modified = std::fs::metadata(&frames).unwrap().modified().unwrap();
    let commit = first["meta"]["commit"].as_str().unwrap().to_string();
    if commit.ends_with("-dirty") {
        eprintln!(
            "note: {commit} is a dirty build: checking that it neither writes nor reads checkpoints"
        );
        assert!(!out.join("measures").exists());
        let (_, report, _) = run(true);
        assert!(!report.contains("resumed"), "{report}");
        return;
    }
    // The four measures that ran (the GPU row's measure is the sweep's, which ran too).
    for m in ["b", "r", "iso", "sw"] {
        assert!(out.join(format!("measures/tiny/{m}.json")).is_file(), "{m}");
    }
    let (second, report, stderr) = run(true);
    assert!(!stderr.contains("not resumed"), "{stderr}");
    assert_eq!(
        report.matches("resumed: measured").count(),
        4,
        "every measure resumed: {report}"
    );
    assert_eq!(rows(&second), rows(&first));
    assert_eq!(std::fs::read(&frames).unwrap(), before);
    assert_eq!(
        std::fs::metadata(&frames).unwrap().modified().unwrap(),
        modified
    );
    // A resumed measure's time is the one first measured (bit for bit), and the report's
    // total counts it: at least the first run's measures together.
    let measure_secs = |v: &serde_json::Value| -> Vec<f64> {
        v["tables"][0]["measures"]
            .as_array()
            .unwrap()
            .iter()
            .map(|m| m["seconds"].as_f64().unwrap())
            .collect()
    };
    assert_eq!(measure_secs(&second), measure_secs(&first));
    let total: f64 = measure_secs(&first).iter().sum();
    assert!(second["meta"]["seconds"].as_f64().unwrap() >= total);
    // A run whose directory is gone runs again; the others stay resumed.
    std::fs::remove_dir_all(out.join("runs/tiny/iso")).unwrap();
    let (_, report, stderr) = run(true);
    assert_eq!(report.matches("resumed: measured").count(), 3, "{report}");
    // ... and says why, naming the measure.
    assert!(
        stderr.contains("tiny.iso: not resumed, measuring again: its runs")
            && stderr.contains("are gone"),
        "{stderr}"
    );
    assert_eq!(stderr.matches("not resumed").count(), 1, "{stderr}");
    // An edited spec is another experiment: nothing resumes.
    std::fs::write(specs.join("tiny.toml"), format!("{TINY}\n# edited\n")).unwrap();
    let (_, report, stderr) = run(true);
    assert!(!report.contains("resumed"), "{report}");
    assert_eq!(
        stderr
            .matches("not resumed, measuring again: it was measured with the spec as it was (edited since)")
            .count(),
        4,
        "{stderr}"
    );
    // Without --resume nothing resumes, and the checkpoints are rewritten.
    let (_, report, _) = run(false);
    assert!(!report.contains("resumed"), "{report}");
}

/// A relative-speed row end to end through the CLI (issue 35): LPC and QSplat on one view
/// and ε, points drawn ÷ (selection + upload + draw), a one-sided band. On a CPU rasteriser
/// the ratio is measured and shown, and the verdict is "CPU rasteriser: no verdict".
const SPEED: &str = r#"
id = "speed"
paper = "LPC"
title = "relative speed"
source = "§6"

[scenes.s]
generator = "statue"
points = 20000
sampling = "even"

[[measure]]
id = "qs"
kind = "run"
method = "qsplat"
scene = "s"
path = "paper/paths/still-mid.toml"
frames = 2
eps = 2
width = 96
height = 96
metrics = false

[[measure]]
id = "lpc"
kind = "run"
method = "lpc"
scene = "s"
params = { m = 512, fetch_per_frame = 100000 }
path = "paper/paths/still-mid.toml"
frames = 6
skip = 5
eps = 2
width = 96
height = 96
metrics = false

[[row]]
what = "relative speed"
paper = 11.1
ours = "(lpc.median.points_drawn / (lpc.median.cpu_select_ms + lpc.median.wall_ms)) / (qs.median.points_drawn / (qs.median.cpu_select_ms + qs.median.wall_ms))"
rule = "band"
band = [8.9, inf]
band_reason = "at least 11.1, less 20 % noise"
judge_on_gpu = true
"#;

#[test]
fn a_relative_speed_row_is_measured_and_judged_only_on_a_gpu() {
    let Some(gpu) =
        harness::gpu::gpu_for_test("a_relative_speed_row_is_measured_and_judged_only_on_a_gpu")
    else {
        return;
    };
    let d = tempfile::tempdir().unwrap();
    let specs = d.path().join("specs");
    std::fs::create_dir_all(&specs).unwrap();
    std::fs::write(specs.join("speed.toml"), SPEED).unwrap();
    let out = d.path().join("out");
    bin()
        .args([
            "reproduce",
            "--profile",
            "quick",
            "--only",
            "speed",
            "--specs",
        ])
        .arg(&specs)
        .arg("--out")
        .arg(&out)
        .arg("--cache")
        .arg(d.path().join("cache"))
        .assert()
        .success();
    let results: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("results.json")).unwrap()).unwrap();
    let row = &results["tables"][0]["rows"][0];
    let ratio = row["ours"][0]
        .as_f64()
        .expect("the ratio is measured on every adapter");
    assert!(ratio.is_finite() && ratio > 0.0, "{row}");
    let verdict = row["verdict"]["verdict"].as_str().unwrap();
    let cpu = gpu.adapter.device_type.eq_ignore_ascii_case("cpu");
    if cpu {
        assert_eq!(verdict, "no_verdict_cpu", "{row}");
        let report = std::fs::read_to_string(out.join("report.md")).unwrap();
        assert!(report.contains("CPU rasteriser: no verdict"), "{report}");
        assert!(report.contains("band ≥ 8.9"), "{report}");
    } else {
        assert!(verdict == "holds" || verdict == "differs", "{row}");
    }
}

/// The paper profile deletes what it made once no later measure needs it: two specs share a
/// scene and a build; the first also builds SPT between two measures on the shared build.
/// The SPT build goes right after its measure, the shared one after the second spec's; after
/// the whole run neither the builds nor the cached scene are left, and the report says what
/// each measure had to make and what it deleted. A run of some specs (`--only`) keeps the
/// cached scene for the others.
#[test]
fn the_paper_profile_prunes_builds_and_scenes_as_it_goes() {
    let d = tempfile::tempdir().unwrap();
    let specs = d.path().join("specs");
    std::fs::create_dir_all(&specs).unwrap();
    for id in ["a", "b"] {
        let mut text = GOOD
            .replace("id = \"t\"", &format!("id = \"{id}\""))
            .replace(
                "points = { quick = 2000, full = 3000 }",
                "points = { quick = 2000, full = 3000, paper = 4000 }",
            );
        if id == "a" {
            for (m, method) in [("c", "spt"), ("d", "qsplat")] {
                text.push_str(&format!(
                    "\n[[measure]]\nid = \"{m}\"\nkind = \"build\"\nmethod = \"{method}\"\nscene = \"s\"\n\n\
                     [[row]]\nwhat = \"{m}\"\nours = \"{m}.bytes_in\"\nrule = \"report\"\n"
                ));
            }
        }
        std::fs::write(specs.join(format!("{id}.toml")), text).unwrap();
    }
    let (out, cache) = (d.path().join("out"), d.path().join("cache"));
    let run = |only: Option<&str>| {
        let mut c = bin();
        c.args(["reproduce", "--profile", "paper", "--specs"])
            .arg(&specs)
            .arg("--out")
            .arg(&out)
            .arg("--cache")
            .arg(&cache);
        if let Some(o) = only {
            c.args(["--only", o]);
        }
        c.assert().success();
        std::fs::read_to_string(out.join("report.md")).unwrap()
    };
    let report = run(None);
    assert!(report.contains("on statue:4000:1"), "{report}");
    // The first spec made the scene and both builds (its third measure reused the first's
    // build, kept for it); the second spec reused the scene and the shared build.
    assert_eq!(report.matches("ok; scene made: ").count(), 1, "{report}");
    assert_eq!(report.matches("build made: ").count(), 2, "{report}");
    // Deleted twice: SPT's after its measure, the shared build after the second spec's.
    assert_eq!(
        report.matches("; build deleted after: ").count(),
        2,
        "{report}"
    );
    let spt_line = report
        .lines()
        .find(|l| l.contains("spt") && l.contains("build made: "))
        .unwrap_or_else(|| panic!("no line for the SPT build: {report}"));
    assert!(spt_line.contains("build deleted after: "), "{spt_line}");
    let builds: Vec<_> = std::fs::read_dir(out.join("builds")).unwrap().collect();
    assert!(builds.is_empty(), "builds left: {builds:?}");
    let scene = cache.join("scenes/statue-4000-1-even2-v1.sbc");
    assert!(!scene.exists(), "the cached scene is pruned");
    run(Some("a"));
    assert!(scene.is_file(), "--only keeps the cached scene");
    assert!(
        std::fs::read_dir(out.join("builds"))
            .unwrap()
            .next()
            .is_none()
    );
}
