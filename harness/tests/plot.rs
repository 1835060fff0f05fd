//! Tests of `harness::plot`: plots drawn from synthetic `frames.csv` files, and the errors a
//! malformed file must give (naming the file, the column, the row).
#![allow(clippy::unwrap_used)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use harness::plot::{self, COMPARISON_SIZE, FRAME_COLUMNS, TIMELINE_SIZE};

/// Header of a synthetic run: the standard columns plus one method-specific column.
fn header() -> String {
    format!("{},nodes_visited", FRAME_COLUMNS.join(","))
}

/// CSV text of a synthetic run of `frames` frames. `with_metrics: false` leaves the image
/// metric columns empty, as a run without reference does.
fn run_csv(method: &str, target: &str, frames: u32, scale: f64, with_metrics: bool) -> String {
    let mut csv = header();
    csv.push('\n');
    for f in 0..frames {
        let t = f64::from(f);
        let points = (scale * (1.0 + t * t)).round() as u64;
        let (eps, budget) = match target {
            "eps" => ("1.5".to_owned(), String::new()),
            _ => (String::new(), format!("{}", (scale * 50.0) as u64)),
        };
        let wall = 2.0 + 0.3 * t + scale * 1e-5;
        let metrics = if with_metrics {
            let flip = 0.3 / (1.0 + t);
            // No popping for frame 0 (no previous frame), no lag-7 popping before frame 7.
            let popping = if f == 0 {
                String::new()
            } else {
                format!("{:.4}", 0.02 * scale.log10())
            };
            let warped = |lag: u32| {
                if f < lag {
                    String::new()
                } else {
                    format!("{:.4}", 0.01 * scale.log10() * f64::from(lag))
                }
            };
            format!(
                "{:.3},{:.4},{flip:.5},{:.4},{:.4},{popping},{},{}",
                20.0 + t,
                0.8 + 0.01 * t,
                flip * 0.5,
                0.01,
                warped(1),
                warped(7)
            )
        } else {
            ",,,,,,,".to_owned()
        };
        writeln!(
            csv,
            "{f},{method},statue,orbit,{target},{eps},{budget},{points},{},{:.3},{wall:.3},0.5,\
             {},{:.1},123456789,4096,{metrics},{}",
            points / 100 + 1,
            wall * 0.8,
            points * 16,
            points as f64 / (wall * 1e-3),
            points * 3,
        )
        .unwrap();
    }
    csv
}

/// Writes `csv` as `dir/name/frames.csv`; returns the run folder.
fn write_run(dir: &Path, name: &str, csv: &str) -> PathBuf {
    let run = dir.join(name);
    std::fs::create_dir_all(&run).unwrap();
    std::fs::write(run.join("frames.csv"), csv).unwrap();
    run
}

/// Decodes a PNG and checks its size and that it is not a single colour.
fn check_png(path: &Path, size: (u32, u32)) {
    let img = image::open(path).unwrap().into_rgb8();
    assert_eq!(img.dimensions(), size, "{}", path.display());
    let first = *img.get_pixel(0, 0);
    assert!(
        img.pixels().any(|p| *p != first),
        "{} is a single colour",
        path.display()
    );
}

#[test]
fn timeline_and_comparison_plots_are_written() {
    let dir = tempfile::tempdir().unwrap();
    let a = write_run(
        dir.path(),
        "qsplat-eps",
        &run_csv("qsplat", "eps", 10, 1000.0, true),
    );
    let b = write_run(
        dir.path(),
        "lpc-budget",
        &run_csv("lpc", "budget", 10, 30000.0, true),
    );

    for run in [&a, &b] {
        let written = plot::plot_run(run).unwrap();
        assert_eq!(
            written,
            vec![run.join("timeline.png"), run.join("timeline.svg")]
        );
        check_png(&written[0], TIMELINE_SIZE);
        let svg = std::fs::read_to_string(&written[1]).unwrap();
        assert!(svg.starts_with("<svg"), "{}", &svg[..svg.len().min(80)]);
        assert!(svg.contains("statue · orbit"));
        assert!(svg.contains("flip_mean") && svg.contains("hole_ratio") && svg.contains("gpu_ms"));
    }

    let out = dir.path().join("compare");
    std::fs::create_dir_all(&out).unwrap();
    let written = plot::plot_comparison(&[a, b], &out).unwrap();
    assert_eq!(
        written,
        vec![out.join("comparison.png"), out.join("comparison.svg")]
    );
    check_png(&written[0], COMPARISON_SIZE);
    let svg = std::fs::read_to_string(&written[1]).unwrap();
    // Targets differ, so the labels carry them.
    assert!(
        svg.contains("qsplat · eps") && svg.contains("lpc · budget"),
        "labels missing"
    );
    // Only the plots and the CSVs are left: temporary files were renamed away.
    let names: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .map(|e| e.unwrap().file_name())
        .collect();
    assert_eq!(names.len(), 2, "{names:?}");
}

#[test]
fn runs_without_reference_still_plot() {
    let dir = tempfile::tempdir().unwrap();
    let a = write_run(dir.path(), "a", &run_csv("mwkd", "eps", 3, 10.0, false));
    let b = write_run(dir.path(), "b", &run_csv("mwkd", "eps", 1, 10.0, false));
    check_png(&plot::plot_run(&a).unwrap()[0], TIMELINE_SIZE);
    check_png(&plot::plot_run(&b).unwrap()[0], TIMELINE_SIZE);
    let written = plot::plot_comparison(&[a, b], dir.path()).unwrap();
    check_png(&written[0], COMPARISON_SIZE);
    // Same method and target: the folder names tell the runs apart.
    let svg = std::fs::read_to_string(&written[1]).unwrap();
    assert!(svg.contains("mwkd (a)") && svg.contains("mwkd (b)"));
}

#[test]
fn frames_are_read_by_header_name() {
    let dir = tempfile::tempdir().unwrap();
    // Reverse the column order: values must still land in the right fields.
    let csv = run_csv("spt", "budget", 2, 100.0, false);
    let reversed: String = csv
        .lines()
        .map(|line| {
            let mut fields: Vec<&str> = line.split(',').collect();
            fields.reverse();
            fields.join(",") + "\n"
        })
        .collect();
    let run = write_run(dir.path(), "spt", &reversed);
    let frames = plot::read_frames(&run.join("frames.csv")).unwrap();
    assert_eq!(frames.len(), 2);
    let f = &frames[1];
    assert_eq!(
        (f.frame, f.method.as_str(), f.target.as_str()),
        (1, "spt", "budget")
    );
    assert_eq!(
        (f.points_drawn, f.budget, f.eps_px),
        (200, Some(5000), None)
    );
    assert_eq!((f.flip_mean, f.ssim, f.rss_bytes), (None, None, 123456789));
}

#[test]
fn missing_column_is_named() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run_csv("qsplat", "eps", 4, 10.0, true);
    let without: String = csv
        .lines()
        .map(|line| {
            let mut fields: Vec<&str> = line.split(',').collect();
            fields.remove(7); // points_drawn
            fields.join(",") + "\n"
        })
        .collect();
    let run = write_run(dir.path(), "r", &without);
    let err = format!("{:#}", plot::plot_run(&run).unwrap_err());
    assert!(
        err.contains("points_drawn") && err.contains("frames.csv"),
        "{err}"
    );
}

#[test]
fn bad_number_names_file_column_and_row() {
    let dir = tempfile::tempdir().unwrap();
    let csv = run_csv("qsplat", "eps", 4, 10.0, true).replacen(",0.5,", ",fast,", 3);
    let run = write_run(dir.path(), "r", &csv);
    let err = format!("{:#}", plot::plot_run(&run).unwrap_err());
    assert!(
        err.contains("frames.csv") && err.contains("cpu_select_ms"),
        "{err}"
    );
    assert!(err.contains("row 1") && err.contains("\"fast\""), "{err}");
    let bad_target = run_csv("qsplat", "eps", 2, 10.0, true).replace(",eps,", ",speed,");
    let run = write_run(dir.path(), "t", &bad_target);
    let err = format!("{:#}", plot::plot_run(&run).unwrap_err());
    assert!(err.contains("target") && err.contains("speed"), "{err}");
}

#[test]
fn empty_csv_is_an_error() {
    let dir = tempfile::tempdir().unwrap();
    for (name, text) in [("empty", String::new()), ("header-only", header() + "\n")] {
        let run = write_run(dir.path(), name, &text);
        let err = format!("{:#}", plot::plot_run(&run).unwrap_err());
        assert!(
            err.contains("no frames in") && err.contains("frames.csv"),
            "{err}"
        );
        assert!(!run.join("timeline.png").exists());
        let err = plot::plot_comparison(&[run], dir.path()).unwrap_err();
        assert!(format!("{err:#}").contains("no frames in"), "{err:#}");
    }
    let missing = dir.path().join("nowhere");
    let err = format!("{:#}", plot::plot_run(&missing).unwrap_err());
    assert!(err.contains("nowhere"), "{err}");
    assert!(plot::plot_comparison(&[], dir.path()).is_err());
}
