//! Methods that refine a view by loading chunks of several levels (`MethodKind::draws_layers`:
//! LPC, MWKD, Potree, voxel) must not get worse as they refine (issue 35, item 0).
//!
//! The view: `paper/paths/still-close.toml` (0.8 R from the statue's centre, fov 40°), where
//! the finest levels project above 1 px, at ε = 1 px, on an evenly sampled statue (the
//! papers' kind of data: `statue:N:seed:even`). The first frame draws what the untimed
//! warm-up frame requested (the loaders run with `delay_frames=1`, so every frame's loaded
//! set is exact on any machine); later frames add finer chunks until nothing is left to load.
//! Rules, for every frame against the first:
//! - **FLIP never above the first frame's** (no margin: refining adds detail; measured
//!   first → converged LPC 0.127 → 0.061, MWKD 0.031 → 0.031);
//! - **holes at most [`HOLE_MARGIN`] above the first frame's, and above QSplat's at the same
//!   ε** (QSplat: 0). The margin is measured, doubled: LPC's converged frame keeps 1.04 %
//!   (this view) and 0.52 % (240 k samples, 512²) of the reference's pixels bare where its
//!   one splat size per cloud is just the layers' average spacing (the even sampling still
//!   leaves 17 % bare under discs of exactly the area per sample,
//!   `results/measurements/issue-35-sampling.md`).
//!
//! The rule can fail: LPC's literal reading of the paper (`enlarge=cloud`: only the stopped
//! cloud enlarged, its ancestors left at ε) keeps 18.6 % holes and FLIP 0.31 converged, and
//! Potree's default point size (1.7 × its level's spacing, the viewer's adaptive size:
//! leaves are sparser than their level's spacing) 6.9 % and FLIP 0.16; both are asserted to
//! fail, and Potree with `point_size=2` (the viewer's size slider) to pass.
#![allow(clippy::unwrap_used)]

mod common;

use harness::runner::run;
use methods::MethodKind;

/// Holes a converged frame may add to the first frame's (and to QSplat's), as a fraction of
/// the reference's covered pixels: the measured 1.04 %, doubled.
const HOLE_MARGIN: f64 = 0.02;
const SCENE: &str = "statue:120000:1:even";
const SIZE: u32 = 384;

struct Frames {
    points: Vec<f64>,
    holes: Vec<f64>,
    flip: Vec<f64>,
}

fn run_close(
    gpu: &harness::gpu::Gpu,
    dir: &std::path::Path,
    method: MethodKind,
    params: &[&str],
    frames: usize,
) -> Frames {
    let name = format!("{method}-{}", params.join("-"));
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/paper/paths/still-close.toml");
    // What each frame holds, and when the run converges, the same on any machine.
    let params = common::with_exact_loading(method, params);
    let cfg = common::config(method, &params, SCENE, path, frames, SIZE, dir, &name);
    run(&cfg, gpu, &scenes::NoProgress).unwrap_or_else(|e| panic!("{name}: {e:#}"));
    let rows = read(&cfg.out.join("frames.csv"));
    let col = |c: &str| rows.iter().map(|r| r[c].parse::<f64>().unwrap()).collect();
    Frames {
        points: col("points_drawn"),
        holes: col("hole_ratio"),
        flip: col("flip_mean"),
    }
}

fn read(path: &std::path::Path) -> Vec<std::collections::HashMap<String, String>> {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h = r.headers().unwrap().clone();
    r.records()
        .map(|row| {
            let row = row.unwrap();
            h.iter()
                .zip(row.iter())
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

/// Why a run breaks the rule (`None`: it holds).
fn broken(f: &Frames, qsplat_holes: f64) -> Option<String> {
    let n = f.points.len();
    assert!(
        f.points[n - 1] == f.points[n - 2],
        "not converged: points {:?}",
        f.points
    );
    for i in 1..n {
        if f.flip[i] > f.flip[0] {
            return Some(format!(
                "frame {i}: FLIP {:.4} > first {:.4}",
                f.flip[i], f.flip[0]
            ));
        }
        // Both: within the margin of the first frame's *and* of QSplat's.
        let bound = f.holes[0].min(qsplat_holes) + HOLE_MARGIN;
        if f.holes[i] > bound {
            return Some(format!(
                "frame {i}: holes {:.4} > {bound:.4} (first {:.4}, QSplat {qsplat_holes:.4}, + {HOLE_MARGIN})",
                f.holes[i], f.holes[0]
            ));
        }
    }
    None
}

#[test]
fn layered_methods_never_get_worse_as_they_refine() {
    let Some(gpu) = harness::gpu::gpu_for_test("layered_methods_never_get_worse_as_they_refine")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let qsplat = run_close(&gpu, tmp.path(), MethodKind::Qsplat, &[], 1);
    let qsplat_holes = qsplat.holes[0];
    // Frames until nothing is left to load: LPC refines one level per frame (the paper's
    // rule), MWKD and Potree load a front at once.
    let frames = |m: MethodKind| if m == MethodKind::Lpc { 10 } else { 4 };
    let mut layered = 0;
    for &m in MethodKind::ALL.iter().filter(|m| m.draws_layers()) {
        layered += 1;
        let f = run_close(&gpu, tmp.path(), m, &[], frames(m));
        let verdict = broken(&f, qsplat_holes);
        if m == MethodKind::Potree {
            // Potree's own point size: documented, and shown to be the size by the slider.
            assert!(
                verdict.is_some(),
                "potree's default now refines cleanly: update its README and this test"
            );
            let sized = run_close(&gpu, tmp.path(), m, &["point_size=2"], frames(m));
            assert_eq!(broken(&sized, qsplat_holes), None, "potree point_size=2");
        } else {
            assert_eq!(verdict, None, "{m}: holes {:?} FLIP {:?}", f.holes, f.flip);
        }
    }
    assert!(layered >= 4, "lpc, mwkd, potree, voxel");
    // The literal reading of LPC's enlarged size fails the rule.
    let literal = run_close(&gpu, tmp.path(), MethodKind::Lpc, &["enlarge=cloud"], 10);
    let why = broken(&literal, qsplat_holes);
    assert!(
        why.is_some(),
        "enlarge=cloud should leave holes: {:?}",
        literal.holes
    );
}
