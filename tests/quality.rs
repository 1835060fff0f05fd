//! Image quality of every registered method against the full-resolution reference, through
//! the real runner and renderer (lavapipe in CI; "skipped: no adapter" where none exists):
//! at a 1 px tolerance, holes stay within each method's stated bound (≤ 1 % of the
//! reference's covered pixels for the methods whose splats follow the samples' own spacing;
//! LPC's one-size-per-cloud splats have the bound its paper's spacing implies) on the statue
//! orbit, the terrain orbit and a close still view.
#![allow(clippy::unwrap_used)]

mod common;

use common::{column, config};
use harness::render::{Kernel, RenderSettings};
use harness::runner::{RunConfig, run};
use methods::MethodKind;

/// A bound on the hole ratio of every frame, and why.
struct HoleBound {
    /// Largest hole ratio allowed in any frame.
    max: f64,
    /// Where the bound comes from.
    basis: Basis,
    /// What the method does that gives it (and, for a ratchet, what was measured).
    why: &'static str,
}

/// Where a [`HoleBound`] comes from.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Basis {
    /// A derivation (a model of the method, its paper, its issue's requirement): a claim about
    /// the method that a correct implementation meets.
    Derived,
    /// A measured worst frame plus [`RATCHET_MARGIN`]: not a claim about the method, a
    /// ratchet that fails when a change makes the figure worse (re-measure when a change
    /// intends it).
    Ratchet {
        /// The worst frame measured when the bound was set.
        measured: f64,
    },
}

/// A ratchet's margin over its measured worst frame: the spread of the worst frame between
/// lavapipe runs is far below it (the frames are deterministic on one adapter); it allows an
/// adapter whose rasterisation differs by a pixel here and there.
const RATCHET_MARGIN: f64 = 1.25;

impl HoleBound {
    fn derived(max: f64, why: &'static str) -> Self {
        Self {
            max,
            basis: Basis::Derived,
            why,
        }
    }

    fn ratchet(measured: f64, why: &'static str) -> Self {
        Self {
            max: measured * RATCHET_MARGIN,
            basis: Basis::Ratchet { measured },
            why,
        }
    }

    /// How the bound reads in a failure.
    fn describe(&self) -> String {
        match self.basis {
            Basis::Derived => format!("derived: {}", self.why),
            Basis::Ratchet { measured } => format!(
                "ratchet: measured {:.1} % worst frame + {:.0} %; {}",
                measured * 100.0,
                (RATCHET_MARGIN - 1.0) * 100.0,
                self.why
            ),
        }
    }
}

/// The hole bound of `method` (with `params`) on `scene` at 1 px (Potree: see its arms). QSplat, SPT and MWKD size
/// their splats from the samples' own k-NN spacing (leaf spheres, disks, radii), as the
/// reference does: their issues ask ≤ 1 %. LPC draws one splat size per cloud from the
/// input spacing `r` of eqs. (1)–(2).
fn hole_bound(method: MethodKind, params: &[&str], scene: &str, path: &str) -> HoleBound {
    let cover90 = params.contains(&"spacing_rule=cover90");
    let terrain = scene.starts_with("terrain");
    let near = path.ends_with("still-near.toml");
    match method {
        MethodKind::Full => HoleBound::derived(0.0, "full is the reference itself"),
        MethodKind::Lpc if terrain && cover90 => HoleBound::ratchet(
            0.082,
            "one spacing for a terrain whose density varies > 100x (the paper assumes \
             uniform sampling)",
        ),
        MethodKind::Lpc if terrain => HoleBound::ratchet(
            0.337,
            "the paper's average spacing on a terrain whose density varies > 100x (the paper \
             assumes uniform sampling)",
        ),
        MethodKind::Lpc if !cover90 => HoleBound::derived(
            (-1.0f64).exp(),
            "the paper's r = sqrt(A/N): squares of area r^2 at uniformly random points leave \
             exp(-1) = 36.8 % of the surface bare (Boolean model), coarser layers only add \
             cover (measured 13.4 % worst frame on the orbit, 0.2 % close up)",
        ),
        // Potree sizes a point by the spacing of the deepest drawn node holding it (1.7 s,
        // the viewer's adaptive size), not by the samples' own spacing: where the data is
        // sparser than that level's spacing (leaves hold what is left of a sparse region),
        // gaps show, as in the viewer. Measured with load=sync too (the same): sizing, not
        // loading.
        MethodKind::Potree if terrain => HoleBound::ratchet(
            0.140,
            "Potree's level-spacing point size on a terrain whose density varies > 100x",
        ),
        MethodKind::Potree if near => HoleBound::ratchet(
            0.257,
            "Potree's level-spacing point size close up on a 40 k statue, whose drawn leaves \
             are far sparser than their level's spacing",
        ),
        MethodKind::Potree => HoleBound::ratchet(
            0.0406,
            "Potree's level-spacing point size (1.7 s, narrower than the 2 s a Poisson-disk \
             sample needs) on the statue orbit",
        ),
        // voxel's inner nodes are cell-sized voxels (the root alone leaves gaps on the terrain:
        // `voxel_root_alone_on_the_terrain_then_its_leaves`), but its leaves hold the original
        // samples at their own spacing; with exact loading (`common::with_exact_loading`)
        // every frame of these small scenes draws the leaves it needs.
        MethodKind::Voxel => HoleBound::derived(
            0.01,
            "voxel's leaves draw the original samples sized to their own spacing, loaded by \
             the first frame (the method's issue asks 1 %)",
        ),
        // CLOD keeps a point only when its spacing is at least the target spacing (ε px at the
        // screen's centre, up to ε/0.3 at its edge with the paper's foveation), and its rule
        // has no floor: where even the root's spacing (cube side / 128) projects below that,
        // nothing is drawn. At 256² that is most of the terrain and the statue's periphery.
        MethodKind::Clod if terrain => HoleBound::ratchet(
            0.775,
            "CLOD's rule without a floor: the terrain's root spacing projects below the \
             foveated target spacing on most of a 256² frame",
        ),
        MethodKind::Clod if !near => HoleBound::ratchet(
            0.352,
            "CLOD's rule without a floor: the statue's root spacing projects below the \
             foveated target spacing towards the edges of a 256² frame",
        ),
        MethodKind::Clod => HoleBound::ratchet(
            0.0017,
            "close up the levels CLOD keeps are dense enough that its points, ≈ 4.5 target \
             spacings across (at least a pixel), cover the surface",
        ),
        _ => HoleBound::derived(
            0.01,
            "splats sized to cover the samples' own spacing (the method's issue asks 1 %)",
        ),
    }
}

/// Every registered method (and LPC's `spacing_rule=cover90` departure) at 1 px on three
/// views: the statue orbit, the coloured terrain orbit (density varying > 100×) and a close
/// still view of the statue (`paper/paths/still-near.toml`, the finest levels fill the view).
/// Every frame's hole ratio stays within the method's bound ([`hole_bound`], each stated and
/// explained). The loading methods run with one frame of simulated latency, so each frame's
/// loaded set is the same on every machine (voxel's root-alone frames have their own test,
/// [`voxel_root_alone_on_the_terrain_then_its_leaves`]).
#[test]
fn holes_at_1px_stay_within_each_methods_bound() {
    let Some(gpu) = harness::gpu::gpu_for_test("holes_at_1px_stay_within_each_methods_bound")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let near = concat!(env!("CARGO_MANIFEST_DIR"), "/paper/paths/still-near.toml");
    let views = [
        ("statue:40000:2", "orbit", 4),
        ("terrain:40000:2", "orbit", 4),
        ("statue:40000:2", near, 3),
    ];
    let mut configs: Vec<(MethodKind, Vec<&str>)> =
        MethodKind::ALL.iter().map(|&m| (m, Vec::new())).collect();
    configs.push((MethodKind::Lpc, vec!["spacing_rule=cover90"]));
    for (vi, (scene, path, frames)) in views.iter().enumerate() {
        for (method, params) in &configs {
            let name = format!("{method}-{}-{vi}", params.len());
            let params = common::with_exact_loading(*method, params);
            let cfg = config(
                *method,
                &params,
                scene,
                path,
                *frames,
                256,
                tmp.path(),
                &name,
            );
            run(&cfg, &gpu, &scenes::NoProgress)
                .unwrap_or_else(|e| panic!("{method} {params:?} on {scene} {path}: {e:#}"));
            let bound = hole_bound(*method, &params, scene, path);
            for (i, holes) in column(&tmp.path().join(&name), "hole_ratio")
                .into_iter()
                .enumerate()
            {
                assert!(
                    holes <= bound.max,
                    "{method} {params:?} on {scene} {path}, frame {i}: hole ratio {holes:.4} > \
                     {:.4} ({})",
                    bound.max,
                    bound.describe()
                );
            }
        }
    }
}

/// voxel draws its inner nodes' voxels cell-sized (√3·s across, the paper's pixel-sized voxels
/// taken literally): where the terrain's samples are sparser than the root's 128³ cells, gaps
/// show while the root is drawn alone, before the leaves load (`sizing=spacing` bridges them);
/// once they have loaded the leaves' own samples cover as the reference does. A loader three
/// frames late (`delay_frames=3`, exact: the loader waits for what is due) holds frames 0–1 at
/// the root alone, whatever the machine's speed.
#[test]
fn voxel_root_alone_on_the_terrain_then_its_leaves() {
    let Some(gpu) = harness::gpu::gpu_for_test("voxel_root_alone_on_the_terrain_then_its_leaves")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let cfg = config(
        MethodKind::Voxel,
        &["delay_frames=3"],
        "terrain:40000:2",
        "orbit",
        4,
        256,
        tmp.path(),
        "run",
    );
    run(&cfg, &gpu, &scenes::NoProgress).unwrap();
    let (nodes, holes) = (
        column(&cfg.out, "visible_nodes"),
        column(&cfg.out, "hole_ratio"),
    );
    let root = HoleBound::ratchet(
        0.0989,
        "voxel's cell-sized splats where the terrain's samples are sparser than the root's \
         128³ cells (density varies > 100x), the root alone",
    );
    let leaves = hole_bound(MethodKind::Voxel, &[], "terrain:40000:2", "orbit");
    for i in 0..4 {
        let (bound, state) = if i < 2 {
            assert_eq!(nodes[i], 1.0, "frame {i}: the root alone is in core");
            (&root, "root alone")
        } else {
            assert!(nodes[i] > 1.0, "frame {i}: the leaves have arrived");
            (&leaves, "leaves loaded")
        };
        assert!(
            holes[i] <= bound.max,
            "frame {i} ({state}): hole ratio {:.4} > {:.4} ({})",
            holes[i],
            bound.max,
            bound.describe()
        );
    }
}

/// QSplat's frame-rate control along a camera path with a pause (`scenes/paths/pause.toml`,
/// still on frames 41–60 of 101): with a target no frame can meet, the moving threshold sits
/// at its 64 px cap; once the camera stops, progressive refinement halves it every frame down
/// to the requested 1 px and holds it; when the camera moves again it goes back up.
#[test]
fn qsplat_refines_progressively_during_a_pause() {
    let Some(gpu) = harness::gpu::gpu_for_test("qsplat_refines_progressively_during_a_pause")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/scenes/paths/pause.toml");
    let cfg = RunConfig {
        metrics: false,
        render: RenderSettings {
            width: 96,
            height: 96,
            kernel: Kernel::Square,
            cache_bytes: 16 << 20,
            shade: Default::default(),
            raster: Default::default(),
        },
        ..config(
            MethodKind::Qsplat,
            &["target_ms=0.000001"],
            "statue:20000:3",
            path,
            101,
            96,
            tmp.path(),
            "run",
        )
    };
    run(&cfg, &gpu, &scenes::NoProgress).unwrap();
    let mut r = csv::Reader::from_path(tmp.path().join("run/frames.csv")).unwrap();
    let h = r.headers().unwrap().clone();
    let col = h
        .iter()
        .position(|c| c == "threshold_px")
        .expect("threshold_px column");
    let t: Vec<f64> = r
        .records()
        .map(|row| row.unwrap()[col].parse().unwrap())
        .collect();
    assert_eq!(t.len(), 101);
    assert_eq!(t[40], 64.0, "moving, over budget: at the cap");
    assert_eq!(
        &t[41..48],
        &[32.0, 16.0, 8.0, 4.0, 2.0, 1.0, 1.0],
        "halving while still"
    );
    assert!(
        t[48..=60].iter().all(|&x| x == 1.0),
        "holds the tolerance: {:?}",
        &t[48..=60]
    );
    assert!(t[62] > 1.0, "moving again: coarser");
}

/// LPC with a loader that delivers nothing for the first `D` frames (`delay_frames=D`: a
/// cloud requested in frame f is available from frame f + D) along a zoom: those frames
/// still render, coarser (the root drawn with its projected spacing), with no more holes
/// than the fully loaded frames (+0.2 % of the covered pixels); once the data arrive the
/// frames refine.
#[test]
fn lpc_with_a_stalled_loader_renders_coarser_without_extra_holes() {
    let Some(gpu) =
        harness::gpu::gpu_for_test("lpc_with_a_stalled_loader_renders_coarser_without_extra_holes")
    else {
        return;
    };
    const D: usize = 4;
    let tmp = tempfile::tempdir().unwrap();
    let run_with = |params: &[&str], name: &str| {
        let cfg = config(
            MethodKind::Lpc,
            params,
            "statue:60000:4",
            "zoom",
            10,
            192,
            tmp.path(),
            name,
        );
        run(&cfg, &gpu, &scenes::NoProgress).unwrap();
        cfg.out
    };
    let m = "m=512";
    let loaded = run_with(&[m], "loaded");
    let stalled = run_with(&[m, &format!("delay_frames={D}")], "stalled");
    let (p_loaded, p_stalled) = (
        column(&loaded, "points_drawn"),
        column(&stalled, "points_drawn"),
    );
    let (h_loaded, h_stalled) = (
        column(&loaded, "hole_ratio"),
        column(&stalled, "hole_ratio"),
    );
    let coarse = column(&stalled, "clouds_coarse");
    for i in 0..D {
        assert_eq!(p_stalled[i], 512.0, "frame {i}: only the root is in core");
        if p_loaded[i] > 512.0 {
            assert!(coarse[i] >= 1.0, "frame {i}: the root is drawn enlarged");
        }
    }
    // Without the stall a cloud requested in frame f is decoded by the loader thread
    // (microseconds) long before frame f + 1 is selected (a rendered frame later), so the
    // loaded run refines inside the stall window while the stalled one cannot.
    assert!(
        (0..D).any(|i| p_loaded[i] > p_stalled[i]),
        "loaded {:?} vs stalled {:?}",
        &p_loaded[..D],
        &p_stalled[..D]
    );
    for i in 0..p_loaded.len() {
        assert!(
            h_stalled[i] <= h_loaded[i] + 0.002,
            "frame {i}: holes {:.4} stalled vs {:.4} loaded",
            h_stalled[i],
            h_loaded[i]
        );
    }
    assert!(
        p_stalled[p_stalled.len() - 1] > 512.0,
        "the data arrive and the last frame refines"
    );
}

/// MWKD with a loader delayed by `D` frames along a zoom: front nodes not in core are stood
/// in for by what the previous frame drew (or their sibling group's parent), so no frame
/// has more holes than the fully loaded frame at the same pose (`load=sync`: every front
/// node read before drawing) by more than 0.1 % of the covered pixels.
#[test]
fn mwkd_with_a_delayed_loader_has_no_more_holes_than_fully_loaded() {
    let Some(gpu) = harness::gpu::gpu_for_test(
        "mwkd_with_a_delayed_loader_has_no_more_holes_than_fully_loaded",
    ) else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let run_with = |params: &[&str], name: &str| {
        let cfg = config(
            MethodKind::Mwkd,
            params,
            "statue:60000:4",
            "zoom",
            12,
            192,
            tmp.path(),
            name,
        );
        run(&cfg, &gpu, &scenes::NoProgress).unwrap();
        cfg.out
    };
    let loaded = run_with(&["vbo=1500", "load=sync"], "loaded");
    let delayed = run_with(&["vbo=1500", "delay_frames=3"], "delayed");
    let (h_loaded, h_delayed) = (
        column(&loaded, "hole_ratio"),
        column(&delayed, "hole_ratio"),
    );
    assert!(column(&loaded, "nodes_waiting").iter().all(|&w| w == 0.0));
    let waiting = column(&delayed, "nodes_waiting");
    let stand_ins = column(&delayed, "stand_ins");
    assert!(
        waiting.iter().any(|&w| w > 0.0) && stand_ins.iter().any(|&s| s > 0.0),
        "the delayed run must wait and stand in: waiting {waiting:?}, stand-ins {stand_ins:?}"
    );
    for i in 0..h_loaded.len() {
        assert!(
            h_delayed[i] <= h_loaded[i] + 0.001,
            "frame {i}: holes {:.4} delayed vs {:.4} fully loaded",
            h_delayed[i],
            h_loaded[i]
        );
    }
}

/// A real scan's stray sample: the statue with one point added 6,000 km away. Without a
/// robust reference and framing, the stray's k-NN splat covers the reference image and the
/// bounds frame an empty sky (hole ratios of 0.92–1.0 for LPC and MWKD). With them, the
/// camera frames exactly the clean statue's box, the summary counts the stray, and no
/// method's hole ratio in any frame exceeds its value on the clean statue by more than 1
/// percentage point (the stray is one sample of 20,001, outside every frame's view) — except
/// for the two methods that partition the bounding box itself, whose margins are measured
/// values with margin. LPC splits at the midpoint of the box, so the stray's 6,000 km box
/// puts it alone on one side of the root and the statue one level down, with the spacings of
/// eqs. (1)–(2) of that level (measured: +1.05 points in frame 2, −2.8 in frame 0; not the
/// random draw of the clouds: five seeds of the clean statue move frame 2 by 0.1 point):
/// margin 2 points. MWKD quantises positions to 16 bits per axis in each node's box
/// (paper §III-C), and the leaf that holds the stray spans 6,000 km: its statue samples
/// collapse onto a 92 m grid (measured: +2.3 points of holes in frame 1 from 0, FLIP 0.061
/// against 0.020 in frame 0): margin 4 points. That is each paper's rule meeting a real
/// scan's stray: a stray may move such figures, it must not ruin the image. The departure
/// `strays=apart` ([`methods::strays`]) builds on the inliers and must give the clean
/// statue's frames exactly.
#[test]
fn a_far_stray_changes_neither_the_framing_nor_the_holes() {
    let Some(gpu) =
        harness::gpu::gpu_for_test("a_far_stray_changes_neither_the_framing_nor_the_holes")
    else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let clean = scenes::generators::Generator::Statue
        .generate(20_000, 4)
        .unwrap();
    let (origin, p, n, c, _) = clean.clone().into_columns();
    let mut p = p.to_vec();
    p.push([6.0e6, 1.0e5, -2.0e5]);
    let n = n.map(|n| [n.to_vec(), vec![[0.0, 0.0, 1.0]]].concat());
    let c = c.map(|c| [c.to_vec(), vec![[255, 0, 0]]].concat());
    let stray =
        scenes::PointCloud::new(origin, p.into(), n.map(Into::into), c.map(Into::into), None)
            .unwrap();
    let (clean_file, stray_file) = (tmp.path().join("clean.sbc"), tmp.path().join("stray.sbc"));
    scenes::colfile::write(&clean_file, &clean).unwrap();
    scenes::colfile::write(&stray_file, &stray).unwrap();
    let run_on = |method: MethodKind, params: &[&str], scene: &std::path::Path, out: &str| {
        let cfg = config(
            method,
            params,
            scene.to_str().unwrap(),
            "orbit",
            3,
            128,
            tmp.path(),
            out,
        );
        let s = run(&cfg, &gpu, &scenes::NoProgress)
            .unwrap_or_else(|e| panic!("{method} {params:?} on {}: {e:#}", scene.display()));
        let holes = column(&tmp.path().join(out), "hole_ratio");
        (s.scene.framed_bounds, s.scene.outside_frame, holes)
    };
    for method in [
        MethodKind::Full,
        MethodKind::Qsplat,
        MethodKind::Lpc,
        MethodKind::Mwkd,
    ] {
        let margin = match method {
            MethodKind::Lpc => 0.02,
            MethodKind::Mwkd => 0.04,
            _ => 0.01,
        };
        let (framed, outside, before) =
            run_on(method, &[], &clean_file, &format!("{method}-clean"));
        assert_eq!(
            (framed, outside),
            (clean.bounds(), 0),
            "{method}: the clean statue is framed whole"
        );
        let (framed, outside, after) = run_on(method, &[], &stray_file, &format!("{method}-stray"));
        assert_eq!(
            (framed, outside),
            (clean.bounds(), 1),
            "{method}: the stray is counted, not framed"
        );
        for (i, (a, b)) in before.iter().zip(&after).enumerate() {
            assert!(
                b - a <= margin,
                "{method} frame {i}: hole ratio {b:.4} with the stray, {a:.4} without \
                 (margin {margin})"
            );
        }
        // `strays=apart` builds on the inliers, which are the clean statue sample for sample,
        // and draws the stray outside every view: the same frames exactly.
        let (_, _, apart) = run_on(
            method,
            &["strays=apart"],
            &stray_file,
            &format!("{method}-apart"),
        );
        assert_eq!(
            apart, before,
            "{method}: strays=apart frames are the clean statue's"
        );
    }
    // The warning names the remedy (issue 37, item 2: it did not, and `strays=apart` takes
    // QSplat's FLIP on laspy's append-bug-cpy.laz from 0.72 to 0.032).
    let summary: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(tmp.path().join("qsplat-stray/summary.json")).unwrap(),
    )
    .unwrap();
    let warnings = summary["scene"]["warnings"].to_string();
    assert!(
        warnings.contains("1 of 20001 samples lie far outside the rest")
            && warnings.contains("`--param strays=apart` builds it over the others"),
        "{warnings}"
    );
}

/// QSplat from inside a closed model (issue 13, item 2): the last frames of `zoom` put the
/// eye inside the statue. With the paper's back-face culling every surface in view faces
/// away and the frame is empty (points 0, holes 1) — the paper's behaviour, kept as the
/// default; `two_sided=true` draws them, within the 1 % hole bound of the method's splats
/// (they follow the samples' own spacing, as the reference's do).
#[test]
fn qsplat_inside_the_model() {
    let Some(gpu) = harness::gpu::gpu_for_test("qsplat_inside_the_model") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    let mut last = Vec::new();
    for (name, params) in [("culled", vec![]), ("two-sided", vec!["two_sided=true"])] {
        let cfg = config(
            MethodKind::Qsplat,
            &params,
            "statue:20000:3",
            "zoom",
            10,
            128,
            tmp.path(),
            name,
        );
        run(&cfg, &gpu, &scenes::NoProgress).unwrap();
        let dir = tmp.path().join(name);
        let (points, holes) = (column(&dir, "points_drawn"), column(&dir, "hole_ratio"));
        assert!(points[0] > 0.0, "{name}: frame 0, outside, draws");
        last.push((points[9], holes[9], points[0]));
    }
    let (culled, two) = (last[0], last[1]);
    assert_eq!(
        (culled.0, culled.1),
        (0.0, 1.0),
        "the paper's culling empties the inside view"
    );
    // Outside, two_sided adds the back faces (hidden behind the front ones).
    assert!(two.2 > culled.2, "two_sided draws back faces outside too");
    assert!(two.0 > 0.0, "two_sided draws inside");
    assert!(
        two.1 <= 0.01,
        "two_sided inside: hole ratio {:.4} > 1 %",
        two.1
    );
}

/// SPT, LPC and MWKD from inside a closed model (issue 13, item 2, the other methods): on
/// the views where QSplat's per-leaf back-face culling empties the frame (the last three
/// frames of `zoom`, eye 0.27 R to 0.05 R from the centre, and `flythrough`, mostly inside
/// the box), each draws and keeps its hole bound ([`hole_bound`]; measured: 0 holes in every
/// such frame for all three). Their back-face tests are conservative node tests
/// (`methods::cull::cone_backfacing`): never true for a node whose bounding sphere contains
/// the eye, and no splat is culled by its own normal, so the inside of the surface is drawn
/// as the reference draws it. SPT's `normal_clusters=true` skips whole back-facing normal
/// clusters, the paper's back-face culling: from inside, what is in view faces away, so a
/// skipped cluster leaves holes where the reference draws the inside of the surface
/// (measured 3.5–12.1 % on flythrough frames 2–8, 0 on zoom's inside frames and from
/// outside): bound 15 %, points still drawn.
#[test]
fn spt_lpc_and_mwkd_inside_the_model() {
    let Some(gpu) = harness::gpu::gpu_for_test("spt_lpc_and_mwkd_inside_the_model") else {
        return;
    };
    let tmp = tempfile::tempdir().unwrap();
    for (method, params) in [
        (MethodKind::Spt, vec![]),
        (MethodKind::Spt, vec!["normal_clusters=true"]),
        (MethodKind::Lpc, vec![]),
        (MethodKind::Mwkd, vec![]),
    ] {
        for (path, inside) in [("zoom", 7..10), ("flythrough", 0..10)] {
            let name = format!("{method}-{}-{path}", params.len());
            let cfg = config(
                method,
                &params,
                "statue:20000:3",
                path,
                10,
                128,
                tmp.path(),
                &name,
            );
            run(&cfg, &gpu, &scenes::NoProgress).unwrap();
            let dir = tmp.path().join(&name);
            let (points, holes) = (column(&dir, "points_drawn"), column(&dir, "hole_ratio"));
            let bound = if params.is_empty() {
                hole_bound(method, &[], "statue", path)
            } else {
                HoleBound::ratchet(
                    0.121,
                    "back-facing normal clusters skipped (the paper's culling) while the \
                     reference draws the inside of the surface",
                )
            };
            for i in inside {
                assert!(
                    points[i] > 0.0,
                    "{method} {params:?} {path} frame {i}: nothing drawn"
                );
                assert!(
                    holes[i] <= bound.max,
                    "{method} {params:?} {path} frame {i}: hole ratio {:.4} > {:.4} ({})",
                    holes[i],
                    bound.max,
                    bound.describe()
                );
            }
        }
    }
}
