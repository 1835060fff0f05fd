//! `scripts/gpu-bench.sh` at its reduced `ci` size on whatever adapter exists (lavapipe in
//! CI), so that the GPU benchmark's one command cannot rot between the sessions that have a
//! GPU: every method measured with both rasterisers, paired, the adapter recorded.
#![allow(clippy::unwrap_used)]

use std::process::Command;

#[test]
fn gpu_bench_runs_every_method_on_both_rasterisers() {
    if harness::gpu::gpu_for_test("gpu_bench_runs_every_method_on_both_rasterisers").is_none() {
        return;
    }
    let d = tempfile::tempdir().unwrap();
    let out = d.path().join("bench");
    let script = concat!(env!("CARGO_MANIFEST_DIR"), "/scripts/gpu-bench.sh");
    let o = Command::new("bash")
        .arg(script)
        .arg(env!("CARGO_BIN_EXE_splatbench"))
        .arg(&out)
        .arg("ci")
        .arg(d.path().join("cache"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(o.status.success(), "gpu-bench.sh failed: {stderr}");
    let report = std::fs::read_to_string(out.join("gpu-bench.md")).unwrap();
    assert!(report.contains("Adapter: **"), "{report}");
    let mut r = csv::Reader::from_path(out.join("gpu-bench.csv")).unwrap();
    let h: Vec<String> = r.headers().unwrap().iter().map(String::from).collect();
    let col = |name: &str| h.iter().position(|c| c == name).unwrap();
    let rows: Vec<csv::StringRecord> = r.records().map(|r| r.unwrap()).collect();
    let methods: Vec<&str> = rows.iter().map(|r| &r[col("method")]).collect();
    assert_eq!(methods, ["full", "qsplat", "spt", "lpc", "mwkd"]);
    let num = |r: &csv::StringRecord, c: &str| r[col(c)].parse::<f64>().unwrap();
    for r in &rows {
        assert!(num(r, "points_drawn") > 0.0, "{r:?}");
        assert!(num(r, "quads_splats_per_s") > 0.0, "{r:?}");
        // lavapipe has 64-bit atomics: the compute rasteriser must have run too.
        assert!(num(r, "compute_splats_per_s") > 0.0, "{r:?}");
        let ratio = num(r, "compute_over_quads");
        let expect = num(r, "compute_splats_per_s") / num(r, "quads_splats_per_s");
        assert!((ratio - expect).abs() <= 1e-9 * expect, "{r:?}");
        assert!(
            report.contains(&format!("| {} |", &r[col("method")])),
            "{report}"
        );
    }
    // `full` draws every sample; MWKD runs at its Table III budget, scaled (15,000 of 50,000).
    assert_eq!(num(&rows[0], "points_drawn"), 50_000.0);
    assert_eq!(&rows[4][col("target")], "B = 15000");
    for m in methods {
        for raster in ["quads", "compute"] {
            let s: serde_json::Value = serde_json::from_str(
                &std::fs::read_to_string(out.join(m).join(raster).join("summary.json")).unwrap(),
            )
            .unwrap();
            assert_eq!(s["raster"], raster, "{m}");
            assert_eq!(s["complete"], true, "{m} {raster}");
        }
    }
}
