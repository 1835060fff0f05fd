//! `splatbench` end to end: list, build, run (with its own reference ⇒ no error), reuse of a
//! build, shading, demo, and a corrupted repository failing the run. Bad input of every kind
//! is in `cli_errors.rs`; plan, export, sweep, cache and scene formats in `cli_tools.rs`.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use predicates::prelude::*;

mod common;

use common::{bin, csv_table, fails_with, have_gpu};

#[test]
fn list_names_methods_generators_paths() {
    bin()
        .arg("list")
        .assert()
        .success()
        .stdout(predicate::str::contains("full"))
        .stdout(predicate::str::contains("statue"))
        .stdout(predicate::str::contains("isosurface"))
        .stdout(predicate::str::contains("terrain"))
        .stdout(predicate::str::contains("orbit"))
        .stdout(predicate::str::contains("flythrough"));
}

#[test]
fn build_writes_build_json() {
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("b");
    bin()
        .args([
            "build",
            "--method",
            "full",
            "--scene",
            "statue:5000",
            "--out",
        ])
        .arg(&out)
        .assert()
        .success();
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("build.json")).unwrap()).unwrap();
    for k in [
        "points_in",
        "nodes",
        "levels",
        "bytes_in",
        "bytes_out",
        "bits_per_sample",
        "seconds",
        "points_per_s",
    ] {
        assert!(v.get(k).is_some(), "build.json lacks {k}: {v}");
    }
    assert_eq!(v["points_in"], 5000);
    assert!(out.join("method.json").exists());
}

#[test]
fn run_full_against_its_own_reference_is_exact() {
    if !have_gpu("run_full_against_its_own_reference_is_exact") {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    // `full` on an 8 K statue, 8 frames at 160 × 120 (lag 7 reached once), into `out`, one
    // cache for both runs.
    let run = |out: &std::path::Path| {
        bin()
            .args([
                "run",
                "--method",
                "full",
                "--scene",
                "statue:8000",
                "--frames",
                "8",
            ])
            .args(["--width", "160", "--height", "120", "--out"])
            .arg(out)
            .arg("--cache")
            .arg(d.path().join("cache"))
            .assert()
            .success();
    };
    let out = d.path().join("run");
    run(&out);
    let (h, rows) = csv_table(&out.join("frames.csv"));
    assert_eq!(
        h.join(","),
        "frame,method,scene,path,target,eps_px,budget,points_drawn,chunks_drawn,gpu_ms,wall_ms,\
         cpu_select_ms,upload_bytes,splats_per_s,rss_bytes,gpu_cache_bytes,psnr_db,ssim,\
         flip_mean,hole_ratio,extra_coverage,popping_flip,warped_flip_l1,warped_ref_flip_l1,\
         popping_warped_l1,pop_events_l1,warp_valid_l1,warped_flip_l7,warped_ref_flip_l7,\
         popping_warped_l7,pop_events_l7,warp_valid_l7,metrics_ms"
    );
    assert_eq!(rows.len(), 8);
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    for r in &rows {
        assert_eq!(&r[col("method")], "full");
        assert_eq!(&r[col("points_drawn")], "8000");
        assert_eq!(r[col("hole_ratio")].parse::<f64>().unwrap(), 0.0);
        assert_eq!(r[col("flip_mean")].parse::<f64>().unwrap(), 0.0);
        assert_eq!(r[col("extra_coverage")].parse::<f64>().unwrap(), 0.0);
        // `full` draws the reference's pixels, so it changes between frames exactly as the
        // reference does: no popping. Frame 0 has no previous frame.
        match &r[col("frame")][..] {
            "0" => assert_eq!(&r[col("popping_flip")], ""),
            _ => assert_eq!(r[col("popping_flip")].parse::<f64>().unwrap(), 0.0),
        }
        // Warped at lags 1 and 7 (issue 38): the method's and the reference's terms are one
        // image each, so their difference and the pop events are exactly 0; empty before the
        // path has a frame that far back.
        let frame: usize = r[col("frame")].parse().unwrap();
        for lag in [1, 7] {
            let cell = |c: &str| r[col(&format!("{c}_l{lag}"))].to_string();
            if frame < lag {
                assert_eq!(cell("popping_warped"), "", "frame {frame}, lag {lag}");
                continue;
            }
            assert_eq!(cell("popping_warped").parse::<f64>().unwrap(), 0.0);
            assert_eq!(cell("warped_flip"), cell("warped_ref_flip"));
            assert_eq!(cell("pop_events"), "0");
            let valid: f64 = cell("warp_valid").parse().unwrap();
            assert!(
                valid > 0.0 && valid < 1.0,
                "frame {frame}, lag {lag}: {valid}"
            );
        }
        assert!(r[col("wall_ms")].parse::<f64>().unwrap() > 0.0);
        assert!(r[col("metrics_ms")].parse::<f64>().unwrap() > 0.0);
        assert!(r[col("rss_bytes")].parse::<u64>().unwrap() > 0);
    }
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(s["complete"], true);
    assert!(s["adapter"]["name"].as_str().is_some_and(|n| !n.is_empty()));
    assert_eq!(s["width"], 160);
    assert_eq!(s["scene"]["points"], 8000);
    for f in ["timeline.png", "timeline.svg"] {
        assert!(out.join(f).exists(), "{f} missing");
    }
    // One cached reference (image and depth) per distinct view; the same run again reads
    // them (none is made
    // again: the files and their modification times stay as they were) and still agrees.
    let refs = || {
        let mut v: Vec<_> = std::fs::read_dir(d.path().join("cache/refs"))
            .unwrap()
            .map(|e| {
                let e = e.unwrap();
                (e.file_name(), e.metadata().unwrap().modified().unwrap())
            })
            .collect();
        v.sort();
        v
    };
    let before = refs();
    assert_eq!(
        before.len(),
        16,
        "one cached reference image and depth per distinct view"
    );
    let again = d.path().join("again");
    run(&again);
    assert_eq!(refs(), before, "the second run made references again");
    let (h2, rows2) = csv_table(&again.join("frames.csv"));
    assert_eq!(h2, h);
    for r in &rows2 {
        for c in ["points_drawn", "hole_ratio", "flip_mean", "extra_coverage"] {
            assert_eq!(r[col(c)], rows[0][col(c)], "{c}");
        }
    }
}

#[test]
fn demo_runs_every_method_and_plots() {
    if !have_gpu("demo_runs_every_method_and_plots") {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    // 12 frames: LPC refines over the first 3–4 (as fast as the loader delivers), so the
    // median frame is a refined one (24 frames: median holes 3.8 %, the first frame 0.8 %).
    let out = bin()
        .args(["demo", "--frames", "12", "--out"])
        .arg(d.path())
        .assert()
        .success()
        .stdout(predicate::str::contains("demo done"));
    for m in methods::MethodKind::ALL {
        assert!(d.path().join(m.name()).join("frames.csv").exists(), "{m}");
    }
    // LPC's holes on the randomly sampled statue are its spacing rule's Boolean-model gaps
    // (above lpc::SPACING_HOLES): the summary line and summary.json say so and name the
    // departure, which the demo runs beside the paper's row (issue 37, item 2).
    let stdout = String::from_utf8_lossy(&out.get_output().stdout).to_string();
    assert!(
        stdout.contains("known effect: holes")
            && stdout.contains("`--param spacing_rule=cover90` changes it"),
        "{stdout}"
    );
    let summary = |dir: &str| -> serde_json::Value {
        serde_json::from_str(
            &std::fs::read_to_string(d.path().join(dir).join("summary.json")).unwrap(),
        )
        .unwrap()
    };
    let effect = |dir: &str| summary(dir)["known_effect"].clone();
    // What the departure buys: its holes are under the threshold the paper's rule passed.
    let holes = |dir: &str| summary(dir)["medians"]["hole_ratio"].as_f64().unwrap();
    assert!(holes("lpc") > methods::lpc::SPACING_HOLES);
    assert!(holes("lpc-spacing_rule-cover90") < methods::lpc::SPACING_HOLES);
    assert_eq!(effect("lpc")["param"], "spacing_rule=cover90");
    assert!(
        stdout.contains("\nlpc spacing_rule=cover90 statue:60000:1"),
        "{stdout}"
    );
    assert_eq!(effect("lpc-spacing_rule-cover90"), serde_json::Value::Null);
    assert_eq!(effect("qsplat"), serde_json::Value::Null);
    assert!(d.path().join("comparison.png").exists());
    // `plot --out` creates the directory it is given.
    let out = d.path().join("new/plots");
    bin()
        .arg("plot")
        .arg(d.path().join("full"))
        .arg(d.path().join("mwkd"))
        .arg("--out")
        .arg(&out)
        .assert()
        .success();
    assert!(out.join("comparison.png").exists() && out.join("comparison.svg").exists());
}

#[test]
fn spt_refuses_a_model_larger_than_the_gpu_budget() {
    if !have_gpu("spt_refuses_a_model_larger_than_the_gpu_budget") {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("o");
    let out = out.to_str().unwrap();
    // 60 k samples → ≈ 96 k nodes × 36 bytes ≈ 3.3 MiB > 1 MiB.
    fails_with(
        &[
            "run",
            "--method",
            "spt",
            "--scene",
            "statue:60000",
            "--gpu-cache-mb",
            "1",
            "--frames",
            "1",
            "--no-metrics",
            "--out",
            out,
        ],
        "more than the GPU cache budget",
    );
    // The method's own limit, at open.
    fails_with(
        &[
            "run",
            "--method",
            "spt",
            "--scene",
            "statue:60000",
            "--param",
            "gpu_limit_mb=1",
            "--frames",
            "1",
            "--no-metrics",
            "--out",
            out,
        ],
        "gpu_limit_mb = 1 MiB",
    );
}

/// `run --build-dir` opens an existing build instead of building; a build of another
/// method or scene, or a `--param` that would change the build, is refused naming the flag
/// or key; runtime parameters (`occlusion=true`) may change.
#[test]
fn run_reuses_an_existing_build() {
    if !have_gpu("run_reuses_an_existing_build") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let build = tmp.path().join("b");
    let scene = "statue:20000:3";
    bin()
        .args([
            "build", "--method", "lpc", "--param", "m=512", "--scene", scene, "--out",
        ])
        .arg(&build)
        .arg("--cache")
        .arg(&cache)
        .assert()
        .success();
    let out = tmp.path().join("r");
    let common = |m: &str, s: &str, out: &Path| {
        let mut v: Vec<String> = ["run", "--method", m, "--scene", s, "--frames", "2"]
            .iter()
            .map(|x| x.to_string())
            .collect();
        v.extend(["--width", "64", "--height", "64", "--no-metrics"].map(String::from));
        v.extend(["--build-dir".into(), build.display().to_string()]);
        v.extend(["--cache".into(), cache.display().to_string()]);
        v.extend(["--out".into(), out.display().to_string()]);
        v
    };
    let args = common("lpc", scene, &out);
    bin().args(&args).assert().success();
    assert!(!out.join("build").exists(), "nothing built");
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["complete"], true);
    assert_eq!(summary["params"]["m"], "512");
    let args = common("qsplat", scene, &tmp.path().join("x"));
    fails_with(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        "--build-dir",
    );
    let args = common("lpc", "statue:20000:4", &tmp.path().join("y"));
    fails_with(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        "--build-dir",
    );
    let mut args = common("lpc", scene, &tmp.path().join("z"));
    args.extend(["--param".into(), "m=256".into()]);
    fails_with(
        &args.iter().map(String::as_str).collect::<Vec<_>>(),
        "'m' changes how lpc builds",
    );
    // A runtime parameter may change: the summary records the merged parameters.
    let out = tmp.path().join("occ");
    let mut args = common("lpc", scene, &out);
    args.extend(["--param".into(), "occlusion=true".into()]);
    bin().args(&args).assert().success();
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(summary["params"]["m"], "512");
    assert_eq!(summary["params"]["occlusion"], "true");
    let csv = std::fs::read_to_string(out.join("frames.csv")).unwrap();
    assert!(csv.lines().next().unwrap().ends_with(
        "clouds_queried,clouds_occluded,chunks_failed,bytes_fetched,requests_issued,\
                 requests_cancelled,requests_failed,stale_deliveries,bandwidth_est_bytes_per_s"
    ));
}

/// `--shading`: `auto` resolves to EDL for a bare LAS tile and is recorded; shading by a
/// scalar the file lacks, or one that is constant, fails before anything is built.
#[test]
fn shading_is_resolved_recorded_and_checked() {
    let tmp = tempfile::tempdir().unwrap();
    let las = tmp.path().join("bare.las");
    // A bare tile: positions only (format 0 has intensity and class fields, all zero here).
    let cloud = scenes::SceneSpec::parse("terrain:3000:2", None, 1)
        .unwrap()
        .load(None, &scenes::NoProgress)
        .unwrap()
        .cloud
        .without_colors();
    scenes::las::write(&las, &cloud).unwrap();
    for (shading, needle) in [
        (
            "intensity",
            "every point has the intensity 0: nothing to shade by",
        ),
        ("classification", "every point has the class"),
    ] {
        let out = tmp.path().join(shading);
        common::fails(
            bin()
                .args(["run", "--method", "full", "--frames", "1", "--scene"])
                .arg(&las)
                .args(["--shading", shading, "--out"])
                .arg(&out),
            needle,
        );
        assert!(!out.join("summary.json").exists());
    }
    common::fails(
        bin()
            .args([
                "run",
                "--method",
                "full",
                "--scene",
                "statue:1000",
                "--shading",
                "intensity",
                "--out",
            ])
            .arg(tmp.path().join("g")),
        "a generated scene has no intensity",
    );
    fails_with(
        &["run", "--shading", "phong"],
        "invalid value 'phong' for '--shading",
    );
    if !have_gpu("shading_is_resolved_recorded_and_checked") {
        return;
    }
    for (flag, want) in [(None, "edl"), (Some("elevation"), "elevation")] {
        let out = tmp.path().join(want);
        let mut cmd = bin();
        cmd.args([
            "run", "--method", "lpc", "--frames", "2", "--width", "64", "--height", "64", "--cache",
        ])
        .arg(tmp.path().join("cache"))
        .arg("--scene")
        .arg(&las)
        .arg("--out")
        .arg(&out);
        if let Some(f) = flag {
            cmd.args(["--shading", f]);
        }
        let o = cmd.output().unwrap();
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s: serde_json::Value =
            serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap();
        assert_eq!(s["shading"], want);
    }
}

/// A corrupted repository (issue 13, item 3): a flipped payload byte in LPC's or MWKD's
/// repo.bin used to run to the end with exit 0 and `"complete": true`, the chunk never
/// arriving. Now the failed chunk is on stderr (file and chunk), in frames.csv
/// (`chunks_failed`) and summary.json (`failed_chunks`), and the run fails unless
/// `--allow-missing-chunks`, which finishes with exit 0 and still lists it.
#[test]
fn a_corrupted_repository_is_reported_and_fails_the_run() {
    if !have_gpu("a_corrupted_repository_is_reported_and_fails_the_run") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let scene = "statue:20000:3";
    for (method, param) in [("lpc", "m=512"), ("mwkd", "vbo=512")] {
        let build = tmp.path().join(format!("b-{method}"));
        bin()
            .args([
                "build", "--method", method, "--param", param, "--scene", scene,
            ])
            .arg("--out")
            .arg(&build)
            .arg("--cache")
            .arg(&cache)
            .assert()
            .success();
        // Flip one byte in the middle of some of the finest chunks (LPC stores its clouds
        // by level, so those are the second half of repo.bin; MWKD's index says where each
        // leaf is). The root, read at open, stays intact: a broken root is an error there.
        let repo = build.join("repo.bin");
        let mut bytes = std::fs::read(&repo).unwrap();
        let n = bytes.len();
        let spots: Vec<usize> = if method == "mwkd" {
            let nodes = methods::mwkd::index::read(&build.join("index.bin")).unwrap();
            let deepest = nodes.iter().map(|x| x.level).max().unwrap();
            nodes
                .iter()
                .filter(|x| x.level == deepest)
                .step_by(3)
                .map(|x| (x.chunk.offset + u64::from(x.chunk.stored) / 2) as usize)
                .collect()
        } else {
            (n / 2..n).step_by(1 << 12).collect()
        };
        for at in spots {
            bytes[at] ^= 0x5a;
        }
        std::fs::write(&repo, bytes).unwrap();
        let run = |out: &Path, allow: bool, delay: bool| {
            let mut c = bin();
            c.args([
                "run", "--method", method, "--scene", scene, "--path", "zoom",
            ])
            .args([
                "--frames",
                "6",
                "--width",
                "96",
                "--height",
                "96",
                "--no-metrics",
            ])
            .arg("--build-dir")
            .arg(&build)
            .arg("--cache")
            .arg(&cache)
            .arg("--out")
            .arg(out);
            // A simulated latency of one frame: which chunks arrive in which frame no
            // longer depends on how fast this machine decodes, so the corrupted chunks are
            // reached in every run (with d = 0, under a loaded machine, the allowed run once
            // ended before any broken chunk had arrived).
            if delay {
                c.args(["--param", "delay_frames=1"]);
            }
            if allow {
                c.arg("--allow-missing-chunks");
            }
            c.output().unwrap()
        };
        let summary = |out: &Path| -> serde_json::Value {
            serde_json::from_slice(&std::fs::read(out.join("summary.json")).unwrap()).unwrap()
        };
        let out = tmp.path().join(format!("r-{method}"));
        let o = run(&out, false, true);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success(), "{method}: the run should fail: {err}");
        assert!(!err.contains("panicked"), "{err}");
        assert!(
            err.contains("failed to load")
                && err.contains("repo.bin")
                && err.contains("not a faithful"),
            "{method}: {err}"
        );
        let s = summary(&out);
        assert_eq!(s["complete"], false, "{method}");
        let failed = s["failed_chunks"].as_array().unwrap();
        assert!(!failed.is_empty(), "{method}");
        assert!(failed[0]["error"].as_str().unwrap().contains("repo.bin"));
        let (h, rows) = csv_table(&out.join("frames.csv"));
        let col = h.iter().position(|c| c == "chunks_failed").unwrap();
        let last: f64 = rows.last().unwrap()[col].parse().unwrap();
        assert_eq!(
            last as usize,
            failed.len(),
            "{method}: the CSV counts what summary lists"
        );
        let out = tmp.path().join(format!("a-{method}"));
        let o = run(&out, true, true);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        let s = summary(&out);
        assert_eq!(s["complete"], true);
        assert!(!s["failed_chunks"].as_array().unwrap().is_empty());
        // A broken index fails at open; with no --param given, the message says none
        // (issue 13, item 7: it read "--build-dir … with --param").
        std::fs::write(build.join("index.bin"), b"garbage").unwrap();
        let o = run(&tmp.path().join(format!("i-{method}")), false, false);
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(!o.status.success() && err.contains("--build-dir"), "{err}");
        assert!(!err.contains("with --param"), "{err}");
    }
}

/// A headless run prints only splatbench's own lines (issue 37, item 3): Mesa's
/// device-select layer connected to a Wayland display while listing devices, and libwayland
/// printed "error: XDG_RUNTIME_DIR is invalid or not set in the environment." twice on every
/// run; `main` turns the layer off for commands that open no window. Run with the variables
/// a plain shell on a headless machine has (no XDG_RUNTIME_DIR, no WAYLAND_DISPLAY, none of
/// the layer's switches).
#[test]
fn a_headless_run_prints_no_window_system_noise() {
    if !have_gpu("a_headless_run_prints_no_window_system_noise") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let out = bin()
        .args([
            "run",
            "--method",
            "full",
            "--scene",
            "statue:1000",
            "--frames",
            "1",
        ])
        .args(["--width", "32", "--height", "32", "--out"])
        .arg(tmp.path().join("run"))
        .arg("--cache")
        .arg(tmp.path().join("cache"))
        .env_remove("XDG_RUNTIME_DIR")
        .env_remove("WAYLAND_DISPLAY")
        .env_remove("NODEVICE_SELECT")
        .env_remove("MESA_VK_DEVICE_SELECT")
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{stderr}");
    assert!(!stderr.contains("XDG_RUNTIME_DIR"), "{stderr}");
    assert!(stderr.contains("adapter: "), "{stderr}");
    // The summary line (issue 37, item 7): integers as integers, thousands grouped, each
    // unit once.
    let stdout = String::from_utf8_lossy(&out.stdout);
    let line = stdout.lines().find(|l| l.starts_with("full ")).unwrap();
    assert!(line.contains("points       1,000  "), "{line}");
    assert!(
        line.contains(" ms  splats/s ") && !line.contains("ms ms"),
        "{line}"
    );
    // `full` is the reference: no error, no hole.
    assert!(line.ends_with("flip 0.0000  holes  0.00 %"), "{line}");
}
