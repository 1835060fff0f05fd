//! `splatbench check` end to end: a real run blessed and checked (exit 0), a changed count
//! (exit 1, the row naming it), another resolution, a missing baseline and bad flags (exit
//! 2, each named), and a suite file with a typo.

use std::path::Path;

use crate::common::bin;

/// `splatbench check …`: (exit status, stdout, stderr); never a panic.
fn check(args: &[&str]) -> (i32, String, String) {
    let out = bin().arg("check").args(args).output().unwrap();
    let (o, e) = (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    );
    assert!(!e.contains("panicked"), "{e}");
    (out.status.code().unwrap_or(-1), o, e)
}

fn run(dir: &Path, cache: &Path, width: &str) {
    bin()
        .args(["run", "--method", "lpc", "--scene", "statue:5000:1"])
        .args([
            "--param",
            "delay_frames=1",
            "--path",
            "orbit",
            "--frames",
            "2",
        ])
        .args(["--width", width, "--height", "64", "--eps", "2"])
        .arg("--out")
        .arg(dir)
        .arg("--cache")
        .arg(cache)
        .assert()
        .success();
}

#[test]
fn check_exits_0_on_a_match_1_on_a_regression_2_on_unusable_input() {
    if harness::gpu::gpu_for_test("check_exits_0_on_a_match_1_on_a_regression_2_on_unusable_input")
        .is_none()
    {
        return;
    }
    let tmp = tempfile::tempdir().unwrap();
    let (runs, cache) = (tmp.path().join("run"), tmp.path().join("cache"));
    run(&runs, &cache, "64");
    let base = tmp.path().join("base.json");
    let p = |x: &Path| x.to_str().unwrap().to_string();
    let (code, out, _) = check(&[&p(&runs), "--baseline", &p(&base), "--bless"]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("blessed") && out.contains("1 runs"), "{out}");
    let text = std::fs::read_to_string(&base).unwrap();
    assert!(
        text.contains("splatbench run --method lpc"),
        "the command: {text}"
    );

    let (code, out, _) = check(&[&p(&runs), "--baseline", &p(&base)]);
    assert_eq!(code, 0, "{out}");
    assert!(out.contains("holds: 1 runs"), "{out}");

    // One point more in frame 1: exit 1, and the row names the figure, method and frame.
    let csv = runs.join("frames.csv");
    let original = std::fs::read_to_string(&csv).unwrap();
    let mut rd = csv::Reader::from_reader(original.as_bytes());
    let header = rd.headers().unwrap().clone();
    let col = header.iter().position(|h| h == "points_drawn").unwrap();
    let mut w = csv::Writer::from_writer(Vec::new());
    w.write_record(&header).unwrap();
    let mut old_points = String::new();
    for rec in rd.records() {
        let mut rec: Vec<String> = rec.unwrap().iter().map(String::from).collect();
        if rec[0] == "1" {
            old_points = rec[col].clone();
            rec[col] = (rec[col].parse::<u64>().unwrap() + 1).to_string();
        }
        w.write_record(&rec).unwrap();
    }
    std::fs::write(&csv, w.into_inner().unwrap()).unwrap();
    let (code, out, _) = check(&[&p(&runs), "--baseline", &p(&base)]);
    assert_eq!(code, 1, "{out}");
    let row = out
        .lines()
        .find(|l| l.starts_with("points_drawn"))
        .unwrap_or_else(|| panic!("no points_drawn row in {out}"));
    for needle in [
        "lpc delay_frames=1",
        "statue:5000:1",
        "eps 2 · frame 1",
        &old_points,
        "FAILS",
    ] {
        assert!(row.contains(needle), "'{needle}' in {row}");
    }
    assert!(out.contains("REGRESSION"), "{out}");
    std::fs::write(&csv, original).unwrap();

    // Another resolution: not the same experiment.
    let wide = tmp.path().join("wide");
    run(&wide, &cache, "96");
    let (code, _, err) = check(&[&p(&wide), "--baseline", &p(&base)]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(&format!(
            "{}: the run: resolution 96×64, the baseline's 64×64: the two are not the same \
             experiment (--compare-across compares them anyway)",
            p(&wide)
        )),
        "{err}"
    );
    // --compare-across compares them: the images differ in size, so figures fail (exit 1),
    // and the output says how the runs differ.
    let (code, out, err) = check(&[&p(&wide), "--baseline", &p(&base), "--compare-across"]);
    assert_eq!(code, 1, "{out}{err}");
    assert!(
        out.contains(
            "compared across experiments: the run: resolution 96×64, the baseline's 64×64"
        ),
        "{out}"
    );

    // Missing baseline, missing directory, a bad gate, a directory and a suite at once.
    let (code, _, err) = check(&[&p(&runs), "--baseline", "nope.json"]);
    assert_eq!(code, 2);
    assert!(err.contains("nope.json"), "{err}");
    let (code, _, err) = check(&["no/such/dir", "--baseline", &p(&base)]);
    assert_eq!(code, 2);
    assert!(err.contains("no/such/dir"), "{err}");
    let (code, _, err) = check(&[&p(&runs), "--baseline", &p(&base), "--timing-gate", "0.5"]);
    assert_eq!(code, 2);
    assert!(err.contains("--timing-gate 0.5"), "{err}");
    let (code, _, err) = check(&[&p(&runs), "--suite", "x.toml", "--out", "y"]);
    assert_eq!(code, 2);
    assert!(err.contains("not both"), "{err}");
}

#[test]
fn a_suite_file_with_a_typo_is_refused_naming_file_and_field() {
    let tmp = tempfile::tempdir().unwrap();
    let suite = tmp.path().join("s.toml");
    let good = "baseline = \"s.json\"\nwidth = 64\nheight = 64\nframes = 2\npaths = [\"orbit\"]\n\
                methods = [\"lpc\"]\nscenes = [\"statue:5000:1\"]\neps = [2.0]\n";
    let out = tmp.path().join("out");
    let cases = [
        (format!("{good}framez = 3\n"), "unknown field `framez`"),
        (
            good.replace("\"lpc\"", "\"lcp\""),
            "methods: unknown method 'lcp'",
        ),
        (format!("{good}[params]\nlpc = [\"mm=3\"]\n"), "params.lpc"),
        (
            format!("{good}[params]\nmwkd = [\"vbo=3\"]\n"),
            "params.mwkd",
        ),
        (
            good.replace("eps = [2.0]\n", ""),
            "give at least one target",
        ),
        (good.replace("frames = 2", "frames = 0"), "frames"),
        (
            format!("{good}[method.mwkd]\nbudgets = [1000]\n"),
            "method.mwkd: is not one of the suite's methods",
        ),
        (
            format!("{good}[method.lpc]\nbudgets = [0]\n"),
            "method.lpc.budgets",
        ),
        (
            format!("{good}[method.lpc]\nscenes = []\n"),
            "method.lpc.scenes: the list is empty",
        ),
        (
            format!("{good}[method.lpc]\nscenez = [\"statue:5000:1\"]\n"),
            "unknown field `scenez`",
        ),
    ];
    for (text, needle) in cases {
        std::fs::write(&suite, &text).unwrap();
        let (code, _, err) = check(&[
            "--suite",
            suite.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        assert_eq!(code, 2, "{text}: {err}");
        assert!(
            err.contains("s.toml") && err.contains(needle),
            "'{needle}' in {err}"
        );
        assert!(!out.exists(), "nothing is run for a bad suite");
    }
}

/// `[method.NAME]` replaces the suite's scenes and targets for that method only, and the
/// counts `check` prints (and `tests/experiments/baselines.rs` expects) follow it.
#[test]
fn a_method_table_replaces_the_suites_lists_for_that_method() {
    let tmp = tempfile::tempdir().unwrap();
    let file = tmp.path().join("s.toml");
    std::fs::write(
        &file,
        "baseline = \"s.json\"\nwidth = 64\nheight = 64\nframes = 2\npaths = [\"orbit\"]\n\
         methods = [\"lpc\", \"potree\", \"mwkd\"]\nscenes = [\"statue:5000:1\", \"terrain:5000:1\"]\n\
         eps = [2.0]\nbudgets = [1000, 2000]\n\
         [method.potree]\nscenes = [\"statue:50000:1\", \"statue:5000:1\"]\nbudgets = [9000]\neps = []\n",
    )
    .unwrap();
    let suite = harness::check::suite::Suite::load(&file).unwrap();
    let labels: Vec<(String, Vec<&str>)> = suite
        .scenes
        .iter()
        .map(|(s, users)| {
            let names = users
                .iter()
                .map(|&i| suite.methods[i].kind.name())
                .collect();
            (s.label(), names)
        })
        .collect();
    assert_eq!(
        labels,
        vec![
            ("statue:5000:1".to_string(), vec!["lpc", "potree", "mwkd"]),
            ("terrain:5000:1".to_string(), vec!["lpc", "mwkd"]),
            ("statue:50000:1".to_string(), vec!["potree"]),
        ]
    );
    let potree = &suite.methods[1];
    assert_eq!(potree.targets.len(), 1, "potree: budgets only");
    assert_eq!(potree.targets[0].0, "budget");
    // lpc and mwkd: 2 scenes × (eps, budget) sweeps of 1 + 2 runs; potree: 2 scenes × 1 run.
    assert_eq!(suite.sweeps(), 2 * 2 * 2 + 2);
    assert_eq!(suite.runs(), 2 * 2 * 3 + 2);
}
