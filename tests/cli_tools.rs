//! `splatbench plan`, `export`, `sweep` / `plot-sweep`, `cache` and the scene formats through
//! the CLI, each with its errors.
#![allow(clippy::unwrap_used)]

use std::path::Path;

use predicates::prelude::*;

mod common;

use common::{bin, csv_table, fails_with, have_gpu};

/// Table II of the multi-way kd-tree paper (St. Matthew, n = 186,850,683):
/// (fan-out, VBO size, levels, nodes).
const TABLE_II: [(u32, u32, u64, u64); 5] = [
    (6, 4009, 7, 55_987),
    (6, 24029, 6, 9_331),
    (7, 77822, 5, 2_801),
    (3, 85437, 8, 3_280),
    (8, 364943, 4, 585),
];

#[test]
fn plan_reproduces_table_ii_rows() {
    for (fanout, vbo, levels, nodes) in TABLE_II {
        let out = bin()
            .args([
                "plan",
                "--method",
                "mwkd",
                "--points",
                "186850683",
                "--json",
            ])
            .arg(format!("--param=fanout={fanout}"))
            .arg(format!("--param=vbo={vbo}"))
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        assert_eq!(v["levels"], levels, "N={fanout} s={vbo}: {v}");
        assert_eq!(v["nodes"], nodes, "N={fanout} s={vbo}");
        let leaves = u64::from(fanout).pow(levels as u32 - 1);
        assert_eq!(v["leaves"], leaves);
        let (lo, hi) = (
            v["leaf_points_min"].as_u64().unwrap(),
            v["leaf_points_max"].as_u64().unwrap(),
        );
        assert!(hi - lo <= 1 && hi <= u64::from(vbo) + 1);
        assert_eq!(v["inner_held_min"], vbo);
        assert_eq!(v["inner_held_max"], vbo);
    }
    // The human table: two rows, totals line.
    bin()
        .args(["plan", "--method", "mwkd", "--points", "186_850_683"])
        .args(["--param", "fanout=6", "--param", "vbo=24029"])
        .assert()
        .success()
        .stdout(predicate::str::contains(
            "levels 6, nodes 9331, leaves 7776, samples per leaf 24029–24030",
        ));
    bin()
        .args(["plan", "--method", "mwkd", "--points", "186850683"])
        .args(["--param", "fanout=3", "--param", "vbo=85437"])
        .assert()
        .success()
        .stdout(predicate::str::contains(
            "levels 8, nodes 3280, leaves 2187",
        ));
}

#[test]
fn plan_errors_are_clear() {
    fails_with(
        &["plan", "--method", "spt", "--points", "1000"],
        "'spt' cannot plan without data",
    );
    for m in ["full", "qsplat", "lpc"] {
        fails_with(
            &["plan", "--method", m, "--points", "1000"],
            "cannot plan without data",
        );
    }
    fails_with(
        &["plan", "--method", "nope", "--points", "10"],
        "unknown method 'nope'",
    );
    fails_with(&["plan", "--method", "nope", "--points", "10"], "mwkd");
    fails_with(&["plan", "--points", "10"], "--method");
    fails_with(&["plan", "--method", "mwkd"], "--points");
    fails_with(
        &["plan", "--method", "mwkd", "--points", "lots"],
        "--points",
    );
    fails_with(&["plan", "--method", "mwkd", "--points", "0"], "--points");
    fails_with(
        &[
            "plan", "--method", "mwkd", "--points", "100", "--param", "fanout=1",
        ],
        "fanout",
    );
    fails_with(
        &[
            "plan", "--method", "mwkd", "--points", "100", "--param", "vbo=0",
        ],
        "vbo",
    );
    fails_with(
        &[
            "plan", "--method", "mwkd", "--points", "100", "--param", "leaves=3",
        ],
        "unknown field `leaves`",
    );
    fails_with(
        &[
            "plan", "--method", "mwkd", "--points", "100", "--param", "fanout",
        ],
        "key=value",
    );
}

/// `export` writes a scene as LAS that reads back with the same count, and `build --method
/// lpc` takes that LAS file; a wrong extension is an error and writes nothing.
#[test]
fn export_las_then_build_lpc_from_it() {
    let tmp = tempfile::tempdir().unwrap();
    let las = tmp.path().join("terrain.las");
    let cache = tmp.path().join("cache");
    bin()
        .args(["export", "--scene", "terrain:30000:2", "--out"])
        .arg(&las)
        .arg("--cache")
        .arg(&cache)
        .assert()
        .success()
        .stdout(predicate::str::contains("30000 points"));
    let cloud = scenes::las::read(&las).unwrap();
    assert_eq!(cloud.len(), 30_000);
    let out = tmp.path().join("lpc");
    bin()
        .args(["build", "--method", "lpc", "--param", "m=1024", "--scene"])
        .arg(&las)
        .arg("--out")
        .arg(&out)
        .arg("--cache")
        .arg(&cache)
        .assert()
        .success();
    let stats = methods::BuildStats::read(&out).unwrap();
    assert_eq!(stats.points_in, 30_000);
    assert!(out.join("index.bin").exists() && out.join("repo.bin").exists());
    let bad = tmp.path().join("terrain.xyz");
    fails_with(
        &[
            "export",
            "--scene",
            "terrain:100",
            "--out",
            bad.to_str().unwrap(),
        ],
        "must be .las",
    );
    assert!(!bad.exists());
}

/// `sweep` builds once and runs the path at every budget (`sweep.csv`: one row per target,
/// budgets kept, more budget ⇒ more points, FLIP in [0, 1]) and plots it; a second sweep, at
/// tolerances on an existing build (`--build-dir`), and `plot-sweep` overlays both.
#[test]
fn sweep_budgets_and_tolerances_then_plot_sweep() {
    if !have_gpu("sweep_budgets_and_tolerances_then_plot_sweep") {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let scene = "statue:5000:1";
    let sweep = |args: &[&str], out: &Path| {
        bin()
            .args([
                "sweep", "--scene", scene, "--path", "orbit", "--frames", "2",
            ])
            .args(["--width", "96", "--height", "96"])
            .args(args)
            .arg("--out")
            .arg(out)
            .arg("--cache")
            .arg(&cache)
            .assert()
            .success()
            .stdout(predicate::str::contains("sweep.csv (2 targets)"));
    };
    let mwkd = tmp.path().join("mwkd");
    sweep(
        &[
            "--method",
            "mwkd",
            "--param",
            "vbo=400",
            "--budgets",
            "500,2000",
        ],
        &mwkd,
    );
    let (h, rows) = csv_table(&mwkd.join("sweep.csv"));
    assert_eq!(
        h.join(","),
        "method,params,scene,path,target,value,frames,points_drawn_median,splats_per_s_median,\
         gpu_ms_median,cpu_select_ms_median,flip_mean_median,flip_mean_max,hole_ratio_median,\
         hole_ratio_max,psnr_db_median,popping_flip_median,popping_warped_l1_median,\
         popping_warped_l1_p95,popping_warped_l7_median,popping_warped_l7_p95,rss_bytes_max"
    );
    assert_eq!(rows.len(), 2);
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let num = |r: &csv::StringRecord, name: &str| r[col(name)].parse::<f64>().unwrap();
    for (r, budget) in rows.iter().zip([500.0, 2000.0]) {
        assert_eq!(&r[col("method")], "mwkd");
        assert_eq!(&r[col("params")], "vbo=400");
        assert_eq!(&r[col("scene")], scene);
        assert_eq!(&r[col("path")], "orbit");
        assert_eq!(&r[col("target")], "budget");
        assert_eq!(num(r, "value"), budget);
        assert_eq!(num(r, "frames"), 2.0);
        let drawn = num(r, "points_drawn_median");
        assert!(drawn > 0.0 && drawn <= budget, "{budget}: {drawn} points");
        for c in ["flip_mean_median", "flip_mean_max"] {
            let v = num(r, c);
            assert!((0.0..=1.0).contains(&v), "{c} = {v}");
        }
        assert!(num(r, "flip_mean_median") <= num(r, "flip_mean_max"));
        assert!(num(r, "rss_bytes_max") > 0.0);
    }
    assert!(
        num(&rows[1], "points_drawn_median") > num(&rows[0], "points_drawn_median"),
        "a larger budget draws more"
    );
    assert!(mwkd.join("build/method.json").exists(), "one build");
    for run in ["budget-500", "budget-2000"] {
        let dir = mwkd.join(run);
        for f in ["frames.csv", "summary.json", "timeline.png", "timeline.svg"] {
            assert!(dir.join(f).exists(), "{run}/{f} missing");
        }
        assert!(
            !dir.join("build").exists(),
            "{run} reused the sweep's build"
        );
        let s: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("summary.json")).unwrap())
                .unwrap();
        assert_eq!(s["complete"], true);
        assert_eq!(s["params"]["vbo"], "400");
    }
    for f in ["sweep.png", "sweep.svg"] {
        assert!(mwkd.join(f).exists(), "{f} missing");
    }

    let build = tmp.path().join("lpc-build");
    bin()
        .args([
            "build", "--method", "lpc", "--param", "m=256", "--scene", scene,
        ])
        .arg("--out")
        .arg(&build)
        .arg("--cache")
        .arg(&cache)
        .assert()
        .success();
    let lpc = tmp.path().join("lpc");
    let build_arg = build.to_str().unwrap();
    sweep(
        &["--method", "lpc", "--build-dir", build_arg, "--eps", "4,1"],
        &lpc,
    );
    let (_, rows) = csv_table(&lpc.join("sweep.csv"));
    let targets: Vec<(&str, &str, &str)> = rows
        .iter()
        .map(|r| (&r[col("params")], &r[col("target")], &r[col("value")]))
        .collect();
    assert_eq!(
        targets,
        [("m=256", "eps", "4"), ("m=256", "eps", "1")],
        "the build's parameters"
    );
    assert!(num(&rows[1], "points_drawn_median") >= num(&rows[0], "points_drawn_median"));
    assert!(lpc.join("eps-4/frames.csv").exists() && lpc.join("eps-1/frames.csv").exists());
    assert!(!lpc.join("build").exists(), "--build-dir: nothing built");

    let cmp = tmp.path().join("cmp");
    bin()
        .arg("plot-sweep")
        .arg(&mwkd)
        .arg(&lpc)
        .arg("--out")
        .arg(&cmp)
        .assert()
        .success();
    let svg = std::fs::read_to_string(cmp.join("sweep-comparison.svg")).unwrap();
    assert!(svg.contains("mwkd vbo=400") && svg.contains("lpc m=256"));
    assert!(cmp.join("sweep-comparison.png").exists());
}

/// Bad sweep targets fail before anything is built or rendered (no GPU needed), naming the
/// flag; `plot-sweep` of a folder without `sweep.csv` says so.
#[test]
fn sweep_errors_are_clear() {
    let tmp = tempfile::tempdir().unwrap();
    let out = tmp.path().join("sweep");
    let out = out.to_str().unwrap();
    let sweep = |extra: &[&str], needle: &str| {
        let mut args = vec![
            "sweep",
            "--method",
            "mwkd",
            "--scene",
            "statue:100",
            "--out",
            out,
        ];
        args.extend(extra);
        fails_with(&args, needle);
    };
    sweep(&[], "--budgets");
    sweep(&[], "--eps");
    sweep(&["--budgets", "500", "--eps", "1"], "exclusive");
    sweep(&["--budgets", ""], "--budgets: the list is empty");
    sweep(&["--eps", " "], "--eps: the list is empty");
    sweep(&["--budgets", "500,,2000"], "value 2 is empty");
    sweep(&["--budgets", "500,lots"], "--budgets: budget 'lots'");
    sweep(
        &["--budgets", "500,0"],
        "--budgets: budget '0': must be at least 1",
    );
    sweep(&["--budgets", "-5"], "--budgets");
    sweep(&["--eps", "2,wide"], "--eps: 'wide' is not a number");
    sweep(&["--eps", "-1"], "--eps: '-1'");
    sweep(&["--eps", "2,NaN"], "--eps: 'NaN'");
    sweep(&["--eps", "inf"], "--eps: 'inf'");
    sweep(&["--eps", "2,1,2.0"], "--eps: 2 is given twice");
    sweep(&["--budgets", "1k,1000"], "--budgets: 1000 is given twice");
    sweep(&["--eps", "1", "--param", "vbo=0"], "vbo");
    sweep(&["--eps", "1", "--frames", "0"], "--frames");
    sweep(&["--eps", "1", "--path", "spiral"], "orbit");
    assert!(!Path::new(out).exists(), "nothing written");
    let empty = tmp.path().join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    fails_with(
        &[
            "plot-sweep",
            empty.to_str().unwrap(),
            "--out",
            tmp.path().join("cmp").to_str().unwrap(),
        ],
        "no sweep.csv",
    );
}

/// `splatbench cache`: the directory comes from `--cache`, else `$SPLATBENCH_CACHE`; the sizes
/// of what splatbench put there are reported; `--clear` removes exactly those folders and
/// nothing else a mistyped `--cache` might point at.
#[test]
fn cache_reports_its_size_and_clears_only_its_own_folders() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("c");
    std::fs::create_dir_all(cache.join("scenes")).unwrap();
    std::fs::create_dir_all(cache.join("refs/x")).unwrap();
    std::fs::write(cache.join("scenes/a.sbc"), vec![0u8; 3 << 20]).unwrap();
    std::fs::write(cache.join("refs/x/b.png"), vec![0u8; 1 << 20]).unwrap();
    std::fs::write(cache.join("mine.txt"), b"not splatbench's").unwrap();
    let out = bin()
        .arg("cache")
        .env("SPLATBENCH_CACHE", &cache)
        .output()
        .unwrap();
    assert!(out.status.success());
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(text.contains(&cache.display().to_string()), "{text}");
    assert!(
        text.contains("3.0 MiB") && text.contains("1.0 MiB"),
        "{text}"
    );
    assert!(text.contains("total") && text.contains("4.0 MiB"), "{text}");
    let out = bin()
        .args(["cache", "--clear", "--cache"])
        .arg(&cache)
        .output()
        .unwrap();
    assert!(out.status.success());
    assert!(!cache.join("scenes").exists() && !cache.join("refs").exists());
    assert!(
        cache.join("mine.txt").exists(),
        "only splatbench's folders are removed"
    );
}

/// Scene files the readers do not know are named with the supported list; a PCD scene goes
/// through `export` like any other, with the reader's warnings on stderr.
#[test]
fn scene_formats_through_the_cli() {
    let tmp = tempfile::tempdir().unwrap();
    fails_with(
        &["export", "--scene", "scan.xyz", "--out", "x.ply"],
        "'.xyz' files are not read (supported: .ply .las .laz .e57 .pcd",
    );
    let pcd = tmp.path().join("grid.pcd");
    std::fs::write(
        &pcd,
        "FIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nWIDTH 2\nHEIGHT 2\nPOINTS 4\nDATA ascii\n\
         0 0 0\nnan nan nan\n1 0 0\n0 1 0\n",
    )
    .unwrap();
    let out_file = tmp.path().join("grid.ply");
    let out = bin()
        .args(["export", "--scene"])
        .arg(&pcd)
        .arg("--out")
        .arg(&out_file)
        .output()
        .unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{err}");
    assert!(
        err.contains("warning:") && err.contains("points dropped: 1 of 4"),
        "{err}"
    );
    assert!(String::from_utf8_lossy(&out.stdout).contains("3 points"));
    let cloud = scenes::ply::read(&out_file, &Default::default()).unwrap();
    assert_eq!(cloud.len(), 3);
}

/// `export` says what the file holds: LAS has no normals, and the help names the LAS version
/// the writer uses (issue 13, item 7).
#[test]
fn export_reports_what_the_file_holds() {
    let tmp = tempfile::tempdir().unwrap();
    let las = tmp.path().join("s.las");
    let o = bin()
        .args(["export", "--scene", "statue:500", "--out"])
        .arg(&las)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let text = String::from_utf8_lossy(&o.stdout);
    assert!(
        text.contains("500 points, position,") && !text.contains("normal"),
        "{text}"
    );
    let ply = tmp.path().join("s.ply");
    let o = bin()
        .args(["export", "--scene", "statue:500", "--out"])
        .arg(&ply)
        .output()
        .unwrap();
    assert!(String::from_utf8_lossy(&o.stdout).contains("position+normal"));
    let help = bin().args(["help", "export"]).output().unwrap();
    let help = String::from_utf8_lossy(&help.stdout);
    assert!(
        help.contains("LAS 1.2") && !help.contains("(LAS 1.4)"),
        "{help}"
    );
}

/// Every subcommand's `--help` reads as text: no rustdoc link syntax (``[`Shading::resolve`]``)
/// leaks from the doc comments clap takes its help from (issue 37, item 7).
#[test]
fn help_texts_carry_no_rustdoc_links() {
    let help = |command: &str| {
        let mut cmd = bin();
        if !command.is_empty() {
            cmd.arg(command);
        }
        let out = cmd
            .arg("--help")
            .assert()
            .success()
            .get_output()
            .stdout
            .clone();
        String::from_utf8(out).unwrap()
    };
    let top = help("");
    // The subcommands, as the top-level help lists them.
    let commands: Vec<String> = top
        .lines()
        .skip_while(|l| !l.starts_with("Commands:"))
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .filter_map(|l| l.split_whitespace().next().map(str::to_string))
        .filter(|c| c != "help")
        .collect();
    assert!(commands.len() >= 10, "{commands:?}");
    for c in std::iter::once(String::new()).chain(commands) {
        let text = help(&c);
        for bad in ["[`", "`]"] {
            assert!(
                !text.contains(bad),
                "splatbench {c} --help: '{bad}' in\n{}",
                text.lines()
                    .filter(|l| l.contains(bad))
                    .collect::<Vec<_>>()
                    .join("\n")
            );
        }
    }
}

/// `--version` names the commit the binary was built from (the one run results carry), so a
/// figure measured with it can say which code made it.
#[test]
fn version_names_the_build_commit() {
    let out = bin()
        .arg("--version")
        .assert()
        .success()
        .get_output()
        .stdout
        .clone();
    let text = String::from_utf8(out).unwrap();
    let want = format!(
        "splatbench {} ({})",
        env!("CARGO_PKG_VERSION"),
        harness::runner::GIT_COMMIT
    );
    assert_eq!(text.trim(), want);
    assert_ne!(harness::runner::GIT_COMMIT, "", "{text}");
}
