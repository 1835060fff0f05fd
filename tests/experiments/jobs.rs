//! `--emit-jobs` and `merge` for `sweep` and `reproduce` (the tune's round trip is in
//! tests/experiments/tune.rs): the job lines run two at a time by `xargs -P 2`, merged, equal the local
//! command's output wherever it does not depend on timing; merging parts of different
//! commands or kinds is refused.

use std::path::Path;

use crate::common::{bin, fails, read_csv, run_jobs};

#[test]
fn a_sweep_as_jobs_merges_into_the_local_sweep() {
    if harness::gpu::gpu_for_test("a_sweep_as_jobs_merges_into_the_local_sweep").is_none() {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let sweep = |out: &Path| {
        let mut c = bin();
        c.args(["sweep", "--method", "mwkd", "--scene", "statue:5000:1"])
            .args(["--param", "vbo=1000", "--param", "delay_frames=1"])
            .args(["--frames", "2", "--width", "64", "--height", "64"])
            .args(["--budgets", "1500,3000,6000", "--out"])
            .arg(out)
            .arg("--cache")
            .arg(&cache);
        c
    };
    let (local, emitted) = (tmp.path().join("local"), tmp.path().join("emitted"));
    sweep(&local).assert().success();
    let jobs = tmp.path().join("jobs.txt");
    sweep(&emitted)
        .arg("--emit-jobs")
        .arg(&jobs)
        .assert()
        .success();
    assert_eq!(std::fs::read_to_string(&jobs).unwrap().lines().count(), 3);
    let parts = run_jobs(&jobs, &emitted);
    assert_eq!(parts.len(), 3);
    fails(
        bin()
            .arg("merge")
            .args(&parts[..2])
            .arg("--out")
            .arg(&emitted),
        "part(s) target budget-6000 missing",
    );
    bin()
        .arg("merge")
        .args(&parts)
        .arg("--out")
        .arg(&emitted)
        .assert()
        .success();
    let (a, b) = (
        read_csv(&local.join("sweep.csv")),
        read_csv(&emitted.join("sweep.csv")),
    );
    assert_eq!(a.len(), 3);
    let timing = [
        "splats_per_s_median",
        "gpu_ms_median",
        "cpu_select_ms_median",
        "rss_bytes_max",
    ];
    for (ra, rb) in a.iter().zip(&b) {
        for (x, y) in ra.iter().zip(rb) {
            if !timing.contains(&x.0.as_str()) {
                assert_eq!(x, y, "merged sweep.csv equals the local one");
            }
        }
    }
    for f in [
        "sweep.png",
        "sweep.svg",
        "build/method.json",
        "budget-3000/frames.csv",
    ] {
        assert!(emitted.join(f).is_file(), "{f}");
    }
    // Parts of a tune and of a sweep do not merge.
    let tune = tmp.path().join("tune");
    bin()
        .args(["tune", "--method", "mwkd", "--scene", "statue:5000:1"])
        .args(["--grid", "vbo=1000", "--budgets", "1500", "--frames", "1"])
        .args(["--width", "32", "--height", "32", "--part", "0", "--out"])
        .arg(&tune)
        .arg("--cache")
        .arg(&cache)
        .assert()
        .success();
    fails(
        bin()
            .arg("merge")
            .arg(&parts[0])
            .arg(&tune)
            .arg("--out")
            .arg(tmp.path().join("x")),
        "merge the parts of one command",
    );
}

#[test]
fn a_reproduction_as_jobs_merges_into_the_local_report() {
    let tmp = tempfile::tempdir().unwrap();
    let cache = tmp.path().join("cache");
    let reproduce = |out: &Path| {
        let mut c = bin();
        c.args(["reproduce", "--only", "mwkd-table2,qsplat-fig6", "--out"])
            .arg(out)
            .arg("--cache")
            .arg(&cache);
        c
    };
    let (local, emitted) = (tmp.path().join("local"), tmp.path().join("emitted"));
    reproduce(&local).assert().success();
    let jobs = tmp.path().join("jobs.txt");
    reproduce(&emitted)
        .arg("--emit-jobs")
        .arg(&jobs)
        .assert()
        .success();
    let parts = run_jobs(&jobs, &emitted);
    assert_eq!(parts.len(), 2, "one job per spec");
    bin()
        .arg("merge")
        .args(&parts)
        .arg("--out")
        .arg(&emitted)
        .assert()
        .success();
    let tables = |dir: &Path| -> Vec<serde_json::Value> {
        let v: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(dir.join("results.json")).unwrap())
                .unwrap();
        v["tables"]
            .as_array()
            .unwrap()
            .iter()
            .map(|t| {
                // What the tables say; their seconds are the machine's, and so are the rows
                // made of them (qsplat-fig6's build rates, from each run's own builds).
                let rows: Vec<&serde_json::Value> = t["rows"]
                    .as_array()
                    .unwrap()
                    .iter()
                    .filter(|r| !r["what"].as_str().unwrap().starts_with("build rate"))
                    .collect();
                serde_json::json!({"id": t["id"], "rows": rows, "verdict": t["verdict"]})
            })
            .collect()
    };
    assert_eq!(tables(&local), tables(&emitted));
    let report = std::fs::read_to_string(emitted.join("report.md")).unwrap();
    assert!(
        report.contains("| N = 6, VBO 4,009: nodes | 55,987 | 55,987 | 1.00 | exact | holds |"),
        "{report}"
    );
    assert!(
        report.contains("Generated by `splatbench reproduce --only mwkd-table2,qsplat-fig6"),
        "the reproduction's command, not a part's: {report}"
    );
    // A part run twice is named.
    fails(
        bin()
            .arg("merge")
            .arg(&parts[0])
            .arg(&parts[0])
            .arg(&parts[1])
            .arg("--out")
            .arg(tmp.path().join("twice")),
        "part 0 (qsplat-fig6) is in both",
    );
}

#[test]
fn a_part_whose_table_failed_stays_pending_and_merge_refuses_it() {
    // A spec whose one measure fails when it runs (its scene file is there, but not a PLY):
    // the part returns an error, its record keeps "complete": false — so that a driver which
    // skips finished parts runs it again — and merge names it instead of merging a failure.
    let tmp = tempfile::tempdir().unwrap();
    let specs = tmp.path().join("specs");
    std::fs::create_dir_all(&specs).unwrap();
    let broken = tmp.path().join("broken.ply");
    std::fs::write(&broken, "not a ply\n").unwrap();
    std::fs::write(
        specs.join("bad.toml"),
        format!(
            "id = \"bad\"\npaper = \"Multi-way kd-tree (Goswami et al. 2010)\"\n\
             title = \"a build that fails\"\nsource = \"test\"\nnotes = \"test\"\n\n\
             [scenes.s]\nfile = {:?}\n\n\
             [[measure]]\nid = \"b\"\nkind = \"build\"\nmethod = \"mwkd\"\nscene = \"s\"\n\n\
             [[row]]\nwhat = \"nodes\"\nours = \"b.build.nodes\"\nrule = \"report\"\n",
            broken.display().to_string()
        ),
    )
    .unwrap();
    let part = tmp.path().join("part-000");
    fails(
        bin()
            .args(["reproduce", "--part", "0", "--specs"])
            .arg(&specs)
            .arg("--out")
            .arg(&part)
            .arg("--cache")
            .arg(tmp.path().join("cache")),
        "1 of 1 tables failed",
    );
    let record: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(part.join("reproduce-part.json")).unwrap())
            .unwrap();
    assert_eq!(record["complete"], false, "{record}");
    fails(
        bin()
            .arg("merge")
            .arg(&part)
            .arg("--out")
            .arg(tmp.path().join("merged")),
        "this part did not finish",
    );
}
