//! `splatbench tune` and `merge` end to end: a tune of LPC's `m` × two budgets (rows, front,
//! recommendation, plots, figures equal to the runs'), a runtime grid that builds once, the
//! `--emit-jobs` + `xargs -P 2` + `merge` round trip equal to the local tune, and bad input.

use std::path::Path;

use crate::common::{bin, fails, read_csv, run_jobs};

/// The flags every tune here shares (a small scene, few frames, a small image).
fn tune_args(out: &Path, cache: &Path) -> Vec<String> {
    let mut a: Vec<String> = [
        "tune",
        "--method",
        "lpc",
        "--scene",
        "statue:5000:1",
        "--path",
        "orbit",
        "--frames",
        "2",
        "--width",
        "64",
        "--height",
        "64",
        "--param",
        "delay_frames=1",
        "--cost",
        "points",
    ]
    .iter()
    .map(|s| s.to_string())
    .collect();
    a.extend(["--out".into(), out.display().to_string()]);
    a.extend(["--cache".into(), cache.display().to_string()]);
    a
}

/// Columns of `tune.csv` that are times or memory: they differ between any two runs.
const MACHINE_COLUMNS: [&str; 6] = [
    "gpu_ms_median",
    "wall_ms_median",
    "cpu_select_ms_median",
    "build_seconds",
    "build_peak_rss_bytes",
    "peak_rss_bytes",
];

#[test]
fn a_tune_of_lpc_m_over_two_budgets_and_its_jobs_merged() {
    if harness::gpu::gpu_for_test("a_tune_of_lpc_m_over_two_budgets_and_its_jobs_merged").is_none()
    {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (local, cache) = (tmp.path().join("local"), tmp.path().join("cache"));
    let mut args = tune_args(&local, &cache);
    args.extend(["--grid", "m=512,1024", "--budgets", "2000,4000"].map(String::from));
    let out = bin().args(&args).output().unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // One build per value of m, one run and one repeat per setting and budget.
    let builds: Vec<_> = std::fs::read_dir(local.join("builds")).unwrap().collect();
    assert_eq!(builds.len(), 2);
    let rows = read_csv(&local.join("tune.csv"));
    assert_eq!(rows.len(), 4);
    let order: Vec<(String, String)> = rows
        .iter()
        .map(|r| (r["m"].clone(), r["target"].clone()))
        .collect();
    assert_eq!(
        order,
        [
            ("512", "budget-2000"),
            ("512", "budget-4000"),
            ("1024", "budget-2000"),
            ("1024", "budget-4000")
        ]
        .map(|(a, b)| (a.to_string(), b.to_string()))
    );
    assert!(rows.iter().any(|r| r["pareto"] == "true"));
    for r in &rows {
        // The row's figures are its run's: the run's own summary medians.
        let run = local
            .join("runs")
            .join(format!("m-{}", r["m"]))
            .join(&r["target"]);
        let summary: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(run.join("summary.json")).unwrap())
                .unwrap();
        let med = &summary["medians"];
        assert_eq!(
            r["points_drawn_median"].parse::<f64>().unwrap(),
            med["points_drawn"].as_f64().unwrap()
        );
        assert_eq!(
            r["flip_mean_median"].parse::<f64>().unwrap(),
            med["flip_mean"].as_f64().unwrap()
        );
        assert_eq!(r["cost"], r["points_drawn_median"], "--cost points");
        let budget: f64 = r["value"].parse().unwrap();
        assert!(r["points_drawn_median"].parse::<f64>().unwrap() <= budget);
        // The repeat draws the same points and image (delay_frames=1: deterministic).
        assert_eq!(
            (r["flip_noise"].as_str(), r["cost_noise"].as_str()),
            ("0", "0")
        );
        assert!(r["build_peak_rss_bytes"].parse::<f64>().unwrap() > 0.0);
    }
    let rec = std::fs::read_to_string(local.join("recommendation.md")).unwrap();
    for needle in [
        "## budget 2000",
        "## budget 4000",
        "**Recommended: m=",
        "Pareto front",
    ] {
        assert!(rec.contains(needle), "'{needle}' in {rec}");
    }
    assert!(
        stdout.contains("**Recommended: m="),
        "printed too: {stdout}"
    );
    for f in ["tune.png", "tune.svg", "tune.json"] {
        assert!(local.join(f).is_file(), "{f}");
    }

    // The same tune as jobs, run two at a time by xargs, then merged.
    let jobs = tmp.path().join("jobs.txt");
    let emitted = tmp.path().join("emitted");
    let mut args = tune_args(&emitted, &cache);
    args.extend(["--grid", "m=512,1024", "--budgets", "2000,4000"].map(String::from));
    args.extend(["--emit-jobs".to_string(), jobs.display().to_string()]);
    bin().args(&args).assert().success();
    let lines = std::fs::read_to_string(&jobs).unwrap();
    assert_eq!(lines.lines().count(), 2, "one job per build: {lines}");
    assert!(!emitted.join("tune.csv").exists(), "emitting runs nothing");
    let parts = run_jobs(&jobs, &emitted);
    // A merge without one part names it, and writes no tune.csv.
    fails(
        bin().arg("merge").arg(&parts[0]).arg("--out").arg(&emitted),
        "part(s) build 1 missing",
    );
    assert!(!emitted.join("tune.csv").exists());
    bin()
        .arg("merge")
        .args(&parts)
        .arg("--out")
        .arg(&emitted)
        .assert()
        .success();
    let merged = read_csv(&emitted.join("tune.csv"));
    assert_eq!(merged.len(), rows.len());
    for (a, b) in rows.iter().zip(&merged) {
        for (k, v) in a {
            if !MACHINE_COLUMNS.contains(&k.as_str()) {
                assert_eq!((k, v), (k, &b[k]), "merged tune.csv equals the local one");
            }
        }
    }
    assert_eq!(
        std::fs::read_to_string(emitted.join("recommendation.md")).unwrap(),
        rec,
        "merged recommendation equals the local one byte for byte"
    );
    // Parts of another tune are refused, naming what differs.
    let other = tmp.path().join("other");
    let mut args = tune_args(&other, &cache);
    args.extend(["--grid", "m=512,1024", "--budgets", "3000"].map(String::from));
    args.extend(["--part", "1"].map(String::from));
    bin().args(&args).assert().success();
    fails(
        bin()
            .arg("merge")
            .arg(&parts[0])
            .arg(&other)
            .arg("--out")
            .arg(tmp.path().join("mixed")),
        "'targets'",
    );
}

#[test]
fn a_grid_over_a_runtime_parameter_builds_once() {
    if harness::gpu::gpu_for_test("a_grid_over_a_runtime_parameter_builds_once").is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("t");
    let mut args = tune_args(&out, &tmp.path().join("cache"));
    args.extend(
        [
            "--grid",
            "fetch_per_frame=1,32",
            "--budgets",
            "3000",
            "--repeats",
            "1",
        ]
        .map(String::from),
    );
    bin().args(&args).assert().success();
    let builds: Vec<String> = std::fs::read_dir(out.join("builds"))
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    assert_eq!(builds, ["default"]);
    let rows = read_csv(&out.join("tune.csv"));
    assert_eq!(rows.len(), 2);
    assert!(
        rows.iter().all(|r| r["flip_noise"].is_empty()),
        "--repeats 1"
    );
    let rec = std::fs::read_to_string(out.join("recommendation.md")).unwrap();
    assert!(rec.contains("noise not measured (--repeats 1)"), "{rec}");
    assert!(!out.join("repeats").exists());
}

#[test]
fn bad_tune_flags_are_refused_before_anything_runs() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("t");
    let base = tune_args(&out, &tmp.path().join("cache"));
    let with = |extra: &[&str]| {
        let mut c = bin();
        c.args(&base).args(extra);
        c
    };
    for (extra, needle) in [
        (&["--budgets", "3000"][..], "at least one --grid"),
        (
            &["--grid", "mm=1,2", "--budgets", "3000"][..],
            "unknown field `mm`",
        ),
        (&["--grid", "m=512,x", "--budgets", "3000"][..], "m=x"),
        (&["--grid", "m=", "--budgets", "3000"][..], "no values"),
        (&["--grid", "m=512"][..], "needs its targets"),
        (
            &["--grid", "m=512", "--budgets", "3000", "--repeats", "0"][..],
            "--repeats 0",
        ),
        (
            &["--grid", "m=512", "--budgets", "3000", "--part", "5"][..],
            "this tune has 1 parts",
        ),
        (
            &["--grid", "delay_frames=1,2", "--budgets", "3000"][..],
            "also fixed by --param",
        ),
    ] {
        fails(&mut with(extra), needle);
        assert!(!out.join("runs").exists(), "{extra:?} ran something");
    }
    // A build key over an existing build.
    fails(
        &mut with(&[
            "--grid",
            "m=512,1024",
            "--budgets",
            "3000",
            "--build-dir",
            "x",
        ]),
        "changes how lpc builds",
    );
    // A directory that is not a tune's output is not emptied.
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("mine.txt"), "keep").unwrap();
    fails(
        &mut with(&["--grid", "m=512", "--budgets", "3000"]),
        "not this command's output",
    );
    assert!(out.join("mine.txt").exists());
    fails(
        bin()
            .arg("merge")
            .arg(&out)
            .arg("--out")
            .arg(tmp.path().join("m")),
        "not a part written by an emitted job",
    );
}
