//! `potree` from the command line: a directory holding only the three Potree files (as
//! PotreeConverter writes them, no `method.json`) renders with `run --build-dir` exactly as
//! our own build of the same octree; what it cannot be is refused naming the way out.
#![allow(clippy::unwrap_used)]

mod common;

use common::{bin, fails, read_csv};

const SCENE: &str = "statue:20000:1";

fn run(build_dir: &std::path::Path, out: &std::path::Path, extra: &[&str]) {
    bin()
        .args([
            "run", "--method", "potree", "--scene", SCENE, "--frames", "3",
        ])
        .args(["--eps", "1", "--width", "128", "--height", "96"])
        .arg("--build-dir")
        .arg(build_dir)
        .arg("--out")
        .arg(out)
        .args(extra)
        .assert()
        .success();
}

#[test]
fn a_bare_potree_directory_renders_as_our_build_of_it() {
    let d = tempfile::tempdir().unwrap();
    let ours = d.path().join("ours");
    bin()
        .args(["build", "--method", "potree", "--scene", SCENE, "--out"])
        .arg(&ours)
        .assert()
        .success();
    // The converter's output: the three files and nothing of ours.
    let bare = d.path().join("bare");
    std::fs::create_dir(&bare).unwrap();
    for f in ["metadata.json", "hierarchy.bin", "octree.bin"] {
        std::fs::copy(ours.join(f), bare.join(f)).unwrap();
    }
    run(&ours, &d.path().join("a"), &[]);
    run(&bare, &d.path().join("b"), &[]);
    let a = read_csv(&d.path().join("a/frames.csv"));
    let b = read_csv(&d.path().join("b/frames.csv"));
    assert_eq!(a.len(), 3);
    for (x, y) in a.iter().zip(&b) {
        for col in [
            "points_drawn",
            "chunks_drawn",
            "visible_nodes",
            "flip_mean",
            "hole_ratio",
        ] {
            assert_eq!(x[col], y[col], "{col}");
        }
    }
    assert!(a[2]["points_drawn"].parse::<u64>().unwrap() > 0);
    let summary = std::fs::read_to_string(d.path().join("b/summary.json")).unwrap();
    assert!(summary.contains("another tool"), "{summary}");
    // A runtime parameter applies to the bare directory; a build parameter is refused.
    run(&bare, &d.path().join("c"), &["--param", "point_size=3"]);
    let c = read_csv(&d.path().join("c/frames.csv"));
    assert!(
        c.iter()
            .zip(&b)
            .all(|(x, y)| x["flip_mean"] != y["flip_mean"]),
        "point_size=3 did not change the frames"
    );
    fails(
        bin()
            .args([
                "run", "--method", "potree", "--scene", SCENE, "--frames", "1",
            ])
            .args(["--param", "max_leaf=500", "--build-dir"])
            .arg(&bare)
            .arg("--out")
            .arg(d.path().join("d")),
        "'max_leaf' changes how potree builds",
    );
    // Another method cannot read it: the missing manifest is named.
    fails(
        bin()
            .args(["run", "--method", "lpc", "--scene", SCENE, "--frames", "1"])
            .arg("--build-dir")
            .arg(&bare)
            .arg("--out")
            .arg(d.path().join("e")),
        "method.json",
    );
    // A damaged octree.bin is an error naming it, not a black frame.
    let o = bare.join("octree.bin");
    let bytes = std::fs::read(&o).unwrap();
    std::fs::write(&o, &bytes[..bytes.len() / 3]).unwrap();
    fails(
        bin()
            .args([
                "run", "--method", "potree", "--scene", SCENE, "--frames", "3",
            ])
            .args(["--eps", "0", "--build-dir"])
            .arg(&bare)
            .arg("--out")
            .arg(d.path().join("f")),
        "octree.bin",
    );
}
