//! `harness::check` on hand-made run directories: what holds, what fails (and the row that
//! names it), what cannot be compared, and the baseline file's round trip. No GPU: the runs
//! are written by the test, in the runner's file formats.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use harness::check::{self, Baseline, Options, Unusable, Verdict};

/// A run of `frames` rows, as the runner writes `summary.json` and `frames.csv`.
struct Run {
    method: &'static str,
    params: serde_json::Value,
    scene: &'static str,
    width: u32,
    backend: &'static str,
    complete: bool,
    points: Vec<u64>,
    flip: Vec<f64>,
    gpu_ms: Vec<f64>,
    /// An SPT-like run: `prefix_points` (chosen on the CPU) and `gpu_passed` columns, and
    /// `points_drawn` counted on the GPU.
    interval: bool,
    prefix: Vec<u64>,
}

impl Run {
    fn new(method: &'static str) -> Self {
        Self {
            method,
            params: serde_json::json!({}),
            scene: "statue:5000:1",
            width: 64,
            backend: "Vulkan",
            complete: true,
            points: vec![1000, 2000, 3000],
            flip: vec![0.1, 0.2, 0.3],
            gpu_ms: vec![1.0, 2.0, 3.0],
            interval: false,
            prefix: vec![5000; 3],
        }
    }

    fn write(&self, dir: &Path) {
        std::fs::create_dir_all(dir).unwrap();
        let summary = serde_json::json!({
            "complete": self.complete,
            "adapter": {"name": "llvmpipe (LLVM 15.0.6, 256 bits)", "backend": self.backend,
                        "device_type": "Cpu", "driver": "llvmpipe", "driver_info": "Mesa"},
            "git_commit": "abc",
            "command": "splatbench run --method x",
            "width": self.width,
            "height": 64,
            "method": self.method,
            "params": self.params,
            "target": {"Tolerance": 2.0},
            "kernel": "square",
            "shading": "lambert",
            "path": "orbit",
            "frames": 3,
            "scene": {"label": self.scene, "points": 5000, "content_hash": "00ff"},
            "build": {"nodes": 15, "bytes_out": 7000, "seconds": 0.5, "points_per_s": 1e4,
                      "extra": {"leaves": 9, "tree_seconds": 0.1}},
            "peak_rss_bytes": 1e8,
            "run_seconds": 2.0,
        });
        std::fs::write(dir.join("summary.json"), summary.to_string()).unwrap();
        let mut csv = String::from(
            "frame,method,scene,path,target,eps_px,budget,points_drawn,chunks_drawn,gpu_ms,\
             wall_ms,rss_bytes,flip_mean,hole_ratio",
        );
        if self.interval {
            csv.push_str(",prefix_points,gpu_passed");
        }
        csv.push('\n');
        for i in 0..self.points.len() {
            csv.push_str(&format!(
                "{i},{},{},orbit,eps,2,,{},3,{},{},{},{},0.05",
                self.method,
                self.scene,
                self.points[i],
                self.gpu_ms[i],
                self.gpu_ms[i] + 1.0,
                1e8 + i as f64,
                self.flip[i]
            ));
            if self.interval {
                csv.push_str(&format!(",{},{}", self.prefix[i], self.points[i]));
            }
            csv.push('\n');
        }
        std::fs::write(dir.join("frames.csv"), csv).unwrap();
    }
}

fn snap(dir: &Path) -> Baseline {
    check::snapshot(dir, None).unwrap()
}

fn compare(old: &Baseline, new: &Baseline) -> check::Report {
    check::compare(old, new, Options::default()).unwrap()
}

fn unusable(old: &Baseline, new: &Baseline) -> String {
    let e = check::compare(old, new, Options::default()).unwrap_err();
    assert!(e.is::<Unusable>(), "{e:#}");
    format!("{e:#}")
}

/// The failing rows as `figure @ at: verdict`.
fn failing(r: &check::Report) -> Vec<String> {
    r.rows
        .iter()
        .filter(|r| r.verdict.fails())
        .map(|r| format!("{} {} @ {}: {}", r.method, r.figure, r.at, r.verdict.word()))
        .collect()
}

#[test]
fn identical_inputs_hold_and_every_figure_is_counted() {
    let d = tempfile::tempdir().unwrap();
    Run::new("lpc").write(d.path());
    let b = snap(d.path());
    assert_eq!(b.what, "run");
    assert_eq!(b.runs.keys().collect::<Vec<_>>(), ["."]);
    assert_eq!(b.commands, ["splatbench run --method x"]);
    let r = compare(&b, &b);
    assert!(r.holds(), "{}", check::render_table(&r, None));
    // complete, scene points and hash; nodes, bytes_out, leaves; 3 frames × (points,
    // chunks, flip, holes); the medians of gpu_ms and wall_ms, build seconds, points/s,
    // tree_seconds, run_seconds.
    assert_eq!(r.compared, 3 + 3 + 3 * 4 + 6);
    assert!(
        r.rows.iter().all(|r| r.verdict == Verdict::Ratio),
        "only times are listed when nothing changed"
    );
}

#[test]
fn a_changed_point_count_fails_naming_method_figure_and_frame() {
    let d = tempfile::tempdir().unwrap();
    let mut run = Run::new("mwkd");
    run.write(d.path());
    let old = snap(d.path());
    run.points[1] += 1;
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert_eq!(failing(&r), ["mwkd points_drawn @ eps 2 · frame 1: FAILS"]);
    let table = check::render_table(&r, Some(60));
    assert!(table.contains("2000") && table.contains("2001"), "{table}");
    assert!(table.contains("REGRESSION: 1 runs"), "{table}");
}

#[test]
fn flip_within_tolerance_holds_beyond_it_fails() {
    let d = tempfile::tempdir().unwrap();
    let mut run = Run::new("qsplat");
    run.write(d.path());
    let old = snap(d.path());
    let tol = old.tolerances.same_adapter.flip_mean.unwrap();
    run.flip[0] += tol / 2.0;
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert!(r.holds());
    assert_eq!(
        r.rows
            .iter()
            .filter(|r| r.verdict == Verdict::Within)
            .count(),
        1
    );
    run.flip[2] += 10.0 * tol;
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert_eq!(failing(&r), ["qsplat flip_mean @ eps 2 · frame 2: FAILS"]);
}

#[test]
fn a_missing_frame_and_a_missing_method_fail() {
    let d = tempfile::tempdir().unwrap();
    let mut lpc = Run::new("lpc");
    lpc.write(&d.path().join("lpc/eps-2"));
    Run::new("mwkd").write(&d.path().join("mwkd/eps-2"));
    let old = snap(d.path());
    assert_eq!(old.what, "runs");
    lpc.points.pop();
    lpc.flip.pop();
    lpc.gpu_ms.pop();
    lpc.write(&d.path().join("lpc/eps-2"));
    std::fs::remove_dir_all(d.path().join("mwkd")).unwrap();
    let r = compare(&old, &snap(d.path()));
    assert_eq!(
        failing(&r),
        [
            "lpc frame @ eps 2 · frame 2: MISSING",
            "mwkd run @ eps 2: MISSING"
        ]
    );
    // A run that is new is shown, and does not fail.
    Run::new("spt").write(&d.path().join("spt/eps-2"));
    let r = compare(&old, &snap(d.path()));
    assert_eq!(failing(&r).len(), 2);
    assert!(
        r.rows
            .iter()
            .any(|r| r.verdict == Verdict::New && r.run == "spt/eps-2")
    );
}

#[test]
fn a_run_that_did_not_complete_fails() {
    let d = tempfile::tempdir().unwrap();
    let mut run = Run::new("lpc");
    run.write(d.path());
    let old = snap(d.path());
    run.complete = false;
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert_eq!(failing(&r), ["lpc complete @ eps 2: FAILS"]);
}

#[test]
fn another_resolution_scene_or_experiment_is_unusable() {
    let d = tempfile::tempdir().unwrap();
    let mut run = Run::new("lpc");
    run.write(d.path());
    let old = snap(d.path());
    run.width = 128;
    run.write(d.path());
    let e = unusable(&old, &snap(d.path()));
    assert!(
        e.contains(
            "the run: resolution 128×64, the baseline's 64×64: the two are not the same \
             experiment (--compare-across compares them anyway)"
        ),
        "{e}"
    );
    run.width = 64;
    run.scene = "terrain:5000:1";
    run.write(d.path());
    let e = unusable(&old, &snap(d.path()));
    assert!(
        e.contains("scene terrain:5000:1, the baseline's statue:5000:1"),
        "{e}"
    );
    run.scene = "statue:5000:1";
    run.params = serde_json::json!({"m": "512"});
    run.write(d.path());
    let e = unusable(&old, &snap(d.path()));
    assert!(
        e.contains("parameters lpc m=512, the baseline's lpc"),
        "{e}"
    );
    // --compare-across compares them anyway, saying how they differ.
    let across = check::compare(
        &old,
        &snap(d.path()),
        Options {
            compare_across: true,
            ..Options::default()
        },
    )
    .unwrap();
    assert_eq!(
        across.across,
        ["the run: parameters lpc m=512, the baseline's lpc"]
    );
    // No run in common: a baseline of another experiment altogether.
    let other = tempfile::tempdir().unwrap();
    Run::new("lpc").write(&other.path().join("budget-5000"));
    let e = unusable(&old, &snap(other.path()));
    assert!(e.contains("no run in common"), "{e}");
    // A directory without runs, a missing one.
    let empty = tempfile::tempdir().unwrap();
    let e = check::snapshot(empty.path(), None).unwrap_err();
    assert!(
        e.is::<Unusable>() && format!("{e}").contains("no run directory"),
        "{e}"
    );
    let e = check::snapshot(&empty.path().join("nope"), None).unwrap_err();
    assert!(format!("{e}").contains("no such directory"), "{e}");
}

#[test]
fn bless_round_trip_and_bad_baseline_files() {
    let d = tempfile::tempdir().unwrap();
    Run::new("spt").write(&d.path().join("run"));
    let b = snap(&d.path().join("run"));
    let file = d.path().join("base/quick.json");
    b.write(&file).unwrap();
    let text = std::fs::read_to_string(&file).unwrap();
    assert!(
        text.contains("\"points_drawn\": [1000, 2000, 3000]"),
        "{text}"
    );
    for field in ["\"adapter\"", "\"commit\"", "\"date\"", "\"commands\""] {
        assert!(text.contains(field), "{field} in {text}");
    }
    let back = Baseline::read(&file).unwrap();
    assert_eq!(back, b);
    assert!(compare(&back, &b).holds());
    let leftovers: Vec<_> = std::fs::read_dir(d.path().join("base")).unwrap().collect();
    assert_eq!(leftovers.len(), 1, "no temporary file left");

    std::fs::write(&file, text.replace("\"format\": 1", "\"format\": 9")).unwrap();
    let e = Baseline::read(&file).unwrap_err();
    assert!(
        e.is::<Unusable>() && format!("{e}").contains("format 9"),
        "{e}"
    );
    std::fs::write(&file, text.replace("\"what\"", "\"whatt\"")).unwrap();
    let e = format!("{}", Baseline::read(&file).unwrap_err());
    assert!(e.contains("quick.json") && e.contains("whatt"), "{e}");
    let e = Baseline::read(&d.path().join("none.json")).unwrap_err();
    assert!(
        e.is::<Unusable>() && format!("{e}").contains("none.json"),
        "{e}"
    );
}

#[test]
fn times_never_fail_without_a_gate() {
    let d = tempfile::tempdir().unwrap();
    let mut run = Run::new("full");
    run.write(d.path());
    let old = snap(d.path());
    run.gpu_ms = vec![10.0, 20.0, 30.0];
    run.write(d.path());
    let new = snap(d.path());
    let r = compare(&old, &new);
    assert!(r.holds());
    let gpu = r
        .rows
        .iter()
        .find(|r| r.figure == "gpu_ms (median)")
        .unwrap();
    assert_eq!((gpu.verdict, gpu.ratio), (Verdict::Ratio, Some(10.0)));
    // One line of geometric means when every time holds; each figure's line with --all.
    let table = check::render_table(&r, Some(60));
    assert!(
        table.contains("times, new/old (geometric mean of 1 runs; --all lists each): ")
            && table.contains("gpu_ms (median) ×10.000"),
        "{table}"
    );
    assert!(!table.contains("time gpu_ms"), "{table}");
    // Figures that follow the machine are named once, never compared.
    assert!(
        table.contains("recorded, not compared (they follow the machine or thread timing")
            && table.contains("): rss_bytes\n"),
        "{table}"
    );
    let all = check::render_table(&r, None);
    assert!(
        all.contains("time gpu_ms (median): new/old ×10.000"),
        "{all}"
    );
    let gated = |g| {
        check::compare(
            &old,
            &new,
            Options {
                timing_gate: Some(g),
                ..Options::default()
            },
        )
        .unwrap()
    };
    assert_eq!(failing(&gated(20.0)), Vec::<String>::new());
    assert_eq!(
        failing(&gated(1.5)),
        [
            "full gpu_ms (median) @ eps 2: SLOWER",
            "full wall_ms (median) @ eps 2: SLOWER"
        ]
    );
}

#[test]
fn on_another_adapter_gpu_counts_are_shown_and_images_use_its_tolerance() {
    let d = tempfile::tempdir().unwrap();
    let mut run = Run::new("spt");
    run.interval = true;
    run.write(d.path());
    let old = snap(d.path());
    // The GPU's interval test passes one splat more; FLIP moves by 0.01.
    run.backend = "Gl";
    run.points[0] += 1;
    run.flip[0] += 0.01;
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert!(r.holds(), "{}", check::render_table(&r, None));
    let verdict = |fig: &str| {
        r.rows
            .iter()
            .find(|r| r.figure == fig && r.at.ends_with("frame 0"))
            .map(|r| r.verdict)
    };
    assert_eq!(verdict("points_drawn"), Some(Verdict::OtherAdapter));
    assert_eq!(verdict("gpu_passed"), Some(Verdict::OtherAdapter));
    assert_eq!(verdict("flip_mean"), Some(Verdict::Within));
    // The CPU's prefix is exact on any adapter.
    run.prefix[1] += 1;
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert_eq!(failing(&r), ["spt prefix_points @ eps 2 · frame 1: FAILS"]);
    // On the same adapter the GPU's counts are exact and FLIP's allowance is tight.
    run.backend = "Vulkan";
    run.write(d.path());
    let r = compare(&old, &snap(d.path()));
    assert_eq!(
        failing(&r),
        [
            "spt flip_mean @ eps 2 · frame 0: FAILS",
            "spt gpu_passed @ eps 2 · frame 0: FAILS",
            "spt points_drawn @ eps 2 · frame 0: FAILS",
            "spt prefix_points @ eps 2 · frame 1: FAILS"
        ]
    );
}

#[test]
fn runs_are_found_by_path_but_not_in_builds_images_or_parts() {
    let d = tempfile::tempdir().unwrap();
    for dir in ["runs/m-512/budget-1", "repeats/m-512/budget-1/rep-1"] {
        Run::new("lpc").write(&d.path().join(dir));
    }
    for skipped in [
        "builds/x",
        "runs/m-512/budget-1/images",
        "parts/part-000/runs/a",
    ] {
        Run::new("lpc").write(&d.path().join(skipped));
    }
    let keys: Vec<String> = check::find_runs(d.path()).unwrap().into_keys().collect();
    assert_eq!(
        keys,
        ["repeats/m-512/budget-1/rep-1", "runs/m-512/budget-1"]
    );
}

/// With enough frames the timing gate judges the 95 % interval of the ratio, not one median:
/// a run three times slower on every frame fails a ×1.5 gate, a run whose median doubled but
/// whose frames scatter from 0.2× to 4× does not (its interval reaches below the gate).
#[test]
fn a_timing_gate_with_enough_frames_fails_only_a_slowdown_the_frames_show() {
    let d = tempfile::tempdir().unwrap();
    let n = 12;
    let mut run = Run::new("full");
    run.points = vec![1000; n];
    run.flip = vec![0.1; n];
    run.prefix = vec![5000; n];
    run.gpu_ms = (0..n).map(|i| 10.0 + (i % 3) as f64).collect();
    run.write(d.path());
    let old = snap(d.path());
    let gate = Options {
        timing_gate: Some(1.5),
        ..Options::default()
    };
    let gpu_row = |r: &check::Report| {
        r.rows
            .iter()
            .find(|r| r.figure == "gpu_ms (median)")
            .cloned()
            .unwrap()
    };
    run.gpu_ms = run.gpu_ms.iter().map(|x| 3.0 * x).collect();
    run.write(d.path());
    let slower = check::compare(&old, &snap(d.path()), gate).unwrap();
    let row = gpu_row(&slower);
    assert_eq!(row.verdict, Verdict::Slower, "{row:?}");
    assert!(
        row.new.contains("[95 % ×") && row.allowed == "slowdown ≤ ×1.5 (95 % interval)",
        "{row:?}"
    );
    // Median ×2 (21 against 10.5…), frames from 2 to 45 ms: not shown to be slower.
    run.gpu_ms = vec![
        2.0, 45.0, 21.0, 3.0, 40.0, 21.0, 2.5, 44.0, 22.0, 3.5, 42.0, 20.0,
    ];
    run.write(d.path());
    let scattered = check::compare(&old, &snap(d.path()), gate).unwrap();
    let row = gpu_row(&scattered);
    assert_eq!(row.verdict, Verdict::Ratio, "{row:?}");
    // Three frames (the other tests): no interval, the medians are gated as before.
    let few = tempfile::tempdir().unwrap();
    Run::new("full").write(few.path());
    let three = snap(few.path());
    assert!(
        !gpu_row(&check::compare(&three, &three, gate).unwrap())
            .new
            .contains("95 %")
    );
}
