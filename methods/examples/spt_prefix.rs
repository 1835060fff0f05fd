//! What makes up SPT's GPU-culled fraction: the prefix sent, and the same prefix recomputed
//! with one ingredient of the CPU bound changed at a time, all counted with the CPU mirror of
//! the vertex test (`methods::spt::select::interval_pass`, which `harness/tests/render.rs`
//! checks against the GPU counter).
//!
//! ```text
//! cargo run --release -p methods --example spt_prefix -- \
//!     --scene statue:1000000:1 --path orbit --frames 24 --width 1024 --height 1024 --eps 1 \
//!     [--param key=value ...] [--cache DIR] [--build DIR]
//! ```
//!
//! Per frame, summed over clusters (one without `normal_clusters=true`), with `s = ε/k`:
//!
//! | column | prefix |
//! |--------|--------|
//! | `sent` | what `Spt::select` sends (with the default `bound=sphere`: `r_lo` from the cluster's bounding sphere), bound `e_par + s·o·D_i > s·r_lo` (`D_i` the suffix maximum of `δ`) |
//! | `delta` | the sphere's `r_lo`, per-node `δ_i` instead of `D_i`: the shortest prefix holding every node with `e_par + s·o·δ > s·r_lo` |
//! | `no_ov` | the sphere's `r_lo`, no overlap term (`o = 0` in the bound only; may lose passing nodes, counted in `lost_no_ov`) |
//! | `chunk` | `r_lo` per chunk from the chunk spheres `index.json` stores, `D_i` bound |
//! | `box` | `r_lo` = the larger of the sphere's and the distance to the axis-aligned box of the cluster's node centres (what `bound=box` sends), `D_i` bound |
//! | `min_r` | `r_lo` = the exact smallest node distance of the cluster (O(n), an oracle), `D_i` bound |
//! | `min_r_delta` | exact smallest distance and per-node `δ` |
//! | `oracle` | last passing node + 1: the shortest prefix that loses nothing |
//!
//! `passed` = nodes passing the test (all lie in every conservative prefix). Of `sent`:
//! `coarse` fail the lower test (`e·g > s·r`: ancestors of drawn nodes), `fine` fail the upper
//! test. `lost_no_ov`: passing nodes beyond `no_ov`. `rr2*` = mean over the samples (leaves)
//! of `(r_lo / r)²` for the sphere's, the box's and the exact `r_lo`.
//!
//! The model (unified mode and one cluster; otherwise its columns are left out; the README
//! derives it): were every node at one distance `x`, the prefix would be
//! `P(x) = #{e_par > s·x}`, of which `C(x) = #{e > s·x}` (too coarse: the ancestors of the
//! cut) are culled and `f(x) = P(x) − C(x)` drawn. With distances varying, a sample at
//! distance `r` accounts for `f(r)/n` drawn nodes, so `model_passed = Σ f(r)/n` over the `n`
//! samples, and for a bound `r_lo`: `inner_* = C(r_lo)/P(r_lo)` (the floor: the share of the
//! prefix that is ancestors even at constant distance), `spread_* = model_passed / f(r_lo)`
//! (what the variation of `r` above `r_lo` leaves), `model_culled_* = 1 − model_passed /
//! P(r_lo) = 1 − (1 − inner)·spread`. `rlo_*_R`: the three bounds, and the samples' median
//! distance, in units of R (the bounds' half-diagonal, the unit of the camera paths).
//!
//! Prints one CSV row per frame, then the medians of every column.
#![allow(clippy::unwrap_used)]

use std::path::PathBuf;

use glam::Vec3;
use methods::spt::{self, Spt, select};
use methods::{IntervalTest, Manifest, Params, Target};
use scenes::View;
use scenes::paths::PathSpec;
use scenes::spec::SceneSpec;

struct Args {
    scene: String,
    path: String,
    frames: usize,
    width: u32,
    height: u32,
    eps: f32,
    params: Vec<String>,
    cache: Option<PathBuf>,
    build: Option<PathBuf>,
}

fn args() -> Args {
    let mut a = Args {
        scene: "statue:1000000:1".into(),
        path: "orbit".into(),
        frames: 24,
        width: 1024,
        height: 1024,
        eps: 1.0,
        params: Vec::new(),
        cache: None,
        build: None,
    };
    let mut it = std::env::args().skip(1);
    while let Some(k) = it.next() {
        let v = it.next().unwrap_or_else(|| panic!("{k} needs a value"));
        match k.as_str() {
            "--scene" => a.scene = v,
            "--path" => a.path = v,
            "--frames" => a.frames = v.parse().unwrap(),
            "--width" => a.width = v.parse().unwrap(),
            "--height" => a.height = v.parse().unwrap(),
            "--eps" => a.eps = v.parse().unwrap(),
            "--param" => a.params.push(v),
            "--cache" => a.cache = Some(v.into()),
            "--build" => a.build = Some(v.into()),
            _ => panic!("unknown argument {k}"),
        }
    }
    a
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    match v.len() {
        0 => f64::NAN,
        n if n % 2 == 1 => v[n / 2],
        n => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// What every frame reads: the build's nodes and the per-cluster figures `Spt::open` makes.
struct Model {
    m: Spt,
    lod: Vec<[f32; 4]>,
    pos: Vec<Vec3>,
    normals: Vec<Vec3>,
    /// Suffix maximum of δ per cluster, as `Spt::open` computes it.
    d_suffix: Vec<f32>,
    /// The axis-aligned box of each cluster's node centres.
    boxes: Vec<(Vec3, Vec3)>,
    e_par: Vec<f32>,
    /// `e` and `e_par`, descending: the constant-distance model's `C(x)` and `P(x)`.
    e_sorted: Vec<f32>,
    ep_sorted: Vec<f32>,
}

impl Model {
    fn new(m: Spt) -> Self {
        let lod = m.lod().to_vec();
        let pos: Vec<Vec3> = (0..lod.len()).map(|i| m.position(i)).collect();
        let normals: Vec<Vec3> = (0..lod.len()).map(|i| m.gpu_normal(i)).collect();
        let mut d_suffix = vec![0f32; lod.len()];
        let mut boxes = Vec::new();
        for c in &m.index().clusters {
            let r = c.start as usize..(c.start + c.count) as usize;
            let mut mx = 0f32;
            for i in r.clone().rev() {
                mx = mx.max(lod[i][2]);
                d_suffix[i] = mx;
            }
            let (lo, hi) = pos[r].iter().fold(
                (Vec3::splat(f32::INFINITY), Vec3::splat(f32::NEG_INFINITY)),
                |(lo, hi), &p| (lo.min(p), hi.max(p)),
            );
            boxes.push((lo, hi));
        }
        let e_par: Vec<f32> = lod.iter().map(|l| l[1]).collect();
        let mut e_sorted: Vec<f32> = lod.iter().map(|l| l[0]).collect();
        e_sorted.sort_by(|a, b| b.total_cmp(a));
        let mut ep_sorted = e_par.clone();
        ep_sorted.sort_by(|a, b| b.total_cmp(a));
        Self {
            m,
            lod,
            pos,
            normals,
            d_suffix,
            boxes,
            e_par,
            e_sorted,
            ep_sorted,
        }
    }
}

/// Nodes of descending `v` above `t`.
fn above(v: &[f32], t: f64) -> f64 {
    v.partition_point(|&e| e as f64 > t) as f64
}

/// The prefix columns of one frame, summed over the clusters.
#[derive(Default)]
struct Counts {
    /// The eight prefixes of the module doc's table, in its order.
    p: [u64; 8],
    passed: u64,
    coarse: u64,
    fine: u64,
    lost: u64,
    rr2: f64,
    rr2_box: f64,
    rr2_min: f64,
    leaves: u64,
    /// Σ f(r) over the samples (the constant-distance model).
    model_passed: f64,
}

/// The three lower bounds of the distance to cluster `ci`'s nodes: its sphere's, the larger
/// of that and its box's, and the exact smallest (an oracle).
fn bounds_of(md: &Model, ci: usize, eye: Vec3, dist: &[f32]) -> (f64, f64, f64) {
    let c = &md.m.index().clusters[ci];
    let r = c.start as usize..(c.start + c.count) as usize;
    let r_sphere = select::sphere_distance_lower_bound(eye, Vec3::from(c.center), c.radius);
    let r_box = r_sphere.max(select::box_distance_lower_bound(
        eye,
        md.boxes[ci].0,
        md.boxes[ci].1,
    ));
    let r_min = dist[r].iter().fold(f32::INFINITY, |m, &d| m.min(d)) as f64;
    (r_sphere, r_box, r_min)
}

/// Adds cluster `ci`'s prefixes and node counts to `k`.
#[allow(clippy::too_many_arguments)]
fn count_cluster(
    md: &Model,
    ci: usize,
    sent: usize,
    test: &IntervalTest,
    eye: Vec3,
    dist: &[f32],
    pass: &[bool],
    k: &mut Counts,
) {
    let index = md.m.index();
    let (lod, e_par, pos, normals) = (&md.lod, &md.e_par, &md.pos, &md.normals);
    let (s, o) = (test.scale, test.overlap);
    let c = &index.clusters[ci];
    let r = c.start as usize..(c.start + c.count) as usize;
    let st = r.start;
    let ep = &e_par[r.clone()];
    let ds = &md.d_suffix[r.clone()];
    let (r_sphere, r_box, r_min) = bounds_of(md, ci, eye, dist);
    let r_min = r_min * (1.0 - 1e-5);
    // Shortest prefix holding every node with e_par + s·o·δ > s·r_lo (per-node δ).
    let per_node = |r_lo: f64| {
        let rhs = s as f64 * r_lo * (1.0 - 1e-5);
        r.clone()
            .rev()
            .find(|&i| {
                e_par[i] as f64 * (1.0 + 1e-5) + (s * o * lod[i][2]) as f64 * (1.0 + 1e-5) > rhs
            })
            .map_or(0, |i| i - st + 1)
    };
    k.p[0] += sent as u64;
    k.p[1] += per_node(r_sphere) as u64;
    let no_ov = select::prefix_len(ep, ds, s, 0.0, r_sphere);
    k.p[2] += no_ov as u64;
    for ch in index.chunks.iter().filter(|ch| ch.cluster as usize == ci) {
        let cr = ch.start as usize - st..ch.start as usize - st + ch.count as usize;
        let r_ch = select::sphere_distance_lower_bound(eye, Vec3::from(ch.center), ch.radius);
        k.p[3] += select::prefix_len(&ep[cr.clone()], &ds[cr], s, o, r_ch) as u64;
    }
    k.p[4] += select::prefix_len(ep, ds, s, o, r_box) as u64;
    k.p[5] += select::prefix_len(ep, ds, s, o, r_min) as u64;
    k.p[6] += per_node(r_min) as u64;
    k.p[7] += r.clone().rev().find(|&i| pass[i]).map_or(0, |i| i - st + 1) as u64;
    let big_p = |x: f64| above(&md.ep_sorted, s as f64 * x);
    let big_c = |x: f64| above(&md.e_sorted, s as f64 * x);
    for i in r.clone() {
        if pass[i] {
            k.passed += 1;
            assert!(i - st < sent, "node {i} passes beyond the prefix");
            if i - st >= no_ov {
                k.lost += 1;
            }
        } else if i - st < sent {
            // Which side of the interval failed (the lower test alone decides).
            let lower_ok = {
                let mut root = lod[i];
                root[1] = select::ROOT_PARENT_ERROR;
                select::interval_pass(pos[i], normals[i], root, eye, test)
            };
            if lower_ok { k.fine += 1 } else { k.coarse += 1 }
        }
        if lod[i][0] == 0.0 {
            let d = dist[i] as f64;
            k.rr2 += (r_sphere / d).powi(2);
            k.rr2_box += (r_box / d).powi(2);
            k.rr2_min += (r_min / d).powi(2);
            k.model_passed += big_p(d) - big_c(d);
            k.leaves += 1;
        }
    }
}

/// The model's columns (unified mode, one cluster): the passed nodes it predicts, the three
/// bounds and the samples' median distance in units of `rr`, and per bound the floor, the
/// spread and the culled share it predicts.
fn model_columns(
    md: &Model,
    test: &IntervalTest,
    eye: Vec3,
    dist: &[f32],
    mp: f64,
    rr: f64,
) -> Vec<f64> {
    let s = test.scale as f64;
    let big_p = |x: f64| above(&md.ep_sorted, s * x);
    let big_c = |x: f64| above(&md.e_sorted, s * x);
    let (r_sphere, r_box, r_min) = bounds_of(md, 0, eye, dist);
    let median_r = median(
        (0..md.lod.len())
            .filter(|&i| md.lod[i][0] == 0.0)
            .map(|i| dist[i] as f64)
            .collect(),
    );
    let mut row = vec![mp, r_sphere / rr, r_box / rr, r_min / rr, median_r / rr];
    for r_lo in [r_sphere, r_box, r_min] {
        row.push(big_c(r_lo) / big_p(r_lo));
        row.push(mp / (big_p(r_lo) - big_c(r_lo)));
        row.push(1.0 - mp / big_p(r_lo));
    }
    row
}

/// One frame's CSV row.
fn frame_row(
    md: &Model,
    f: usize,
    view: &View,
    eps: f32,
    rr: f64,
    center: glam::DVec3,
) -> Vec<f64> {
    let eye = view.camera.position;
    let sel = md.m.select(view, Target::Tolerance(eps)).unwrap();
    let test: IntervalTest = sel.test;
    let dist: Vec<f32> = md.pos.iter().map(|p| p.distance(eye)).collect();
    let pass: Vec<bool> = (0..md.lod.len())
        .map(|i| select::interval_pass(md.pos[i], md.normals[i], md.lod[i], eye, &test))
        .collect();
    let mut k = Counts::default();
    for ci in 0..md.m.index().clusters.len() {
        let sent = sel.prefixes[ci] as usize;
        if sent > 0 {
            count_cluster(md, ci, sent, &test, eye, &dist, &pass, &mut k);
        }
    }
    let l = k.leaves.max(1) as f64;
    let eye_dist = eye.as_dvec3().distance(center) / rr;
    let mut row = vec![
        f as f64,
        eye_dist,
        k.passed as f64,
        k.coarse as f64,
        k.fine as f64,
    ];
    row.extend(k.p.map(|v| v as f64));
    row.extend([k.lost as f64, k.rr2 / l, k.rr2_box / l, k.rr2_min / l]);
    row.extend(k.p.map(|v| 1.0 - k.passed as f64 / v.max(1) as f64));
    // Model (one cluster): cut per sample f(r)/n summed over the samples, against the
    // prefix P(r_lo) of the three bounds; the floor C/P at the bound's distance.
    if md.m.index().clusters.len() == 1 && test.mode == select::MODE_UNIFIED {
        row.extend(model_columns(md, &test, eye, &dist, k.model_passed / l, rr));
    }
    row
}

fn header() -> String {
    let cols = [
        "sent",
        "delta",
        "no_ov",
        "chunk",
        "box",
        "min_r",
        "min_r_delta",
        "oracle",
    ];
    format!(
        "frame,eye_dist_R,passed,coarse,fine,{},lost_no_ov,rr2,rr2_box,rr2_min,{},model_passed,\
         rlo_sphere_R,rlo_box_R,rlo_min_R,median_r_R,{}",
        cols.join(","),
        cols.map(|c| format!("culled_{c}")).join(","),
        ["sphere", "box", "min"]
            .map(|b| format!("inner_{b},spread_{b},model_culled_{b}"))
            .join(",")
    )
}

fn main() {
    let a = args();
    let spec = SceneSpec::parse(&a.scene, None, 1).unwrap();
    let cloud = spec
        .load(a.cache.as_deref(), &scenes::NoProgress)
        .unwrap()
        .warn();
    let dir = match &a.build {
        Some(d) => d.clone(),
        None => std::env::temp_dir().join(format!("spt-prefix-{}", std::process::id())),
    };
    let params = Params::parse(&a.params).unwrap();
    if !dir.join(Manifest::FILE).exists() {
        std::fs::create_dir_all(&dir).unwrap();
        spt::build(&cloud, &params, &a.scene, &dir, &scenes::NoProgress).unwrap();
    }
    let md = Model::new(Spt::open(&dir, Manifest::read(&dir).unwrap()).unwrap());
    let index = md.m.index();
    let inner = md.lod.iter().filter(|l| l[0] > 0.0).count();
    println!(
        "# {} nodes, {} inner ({:.1} % of the list), {} clusters, {} chunks, params {:?}",
        md.lod.len(),
        inner,
        100.0 * inner as f64 / md.lod.len() as f64,
        index.clusters.len(),
        index.chunks.len(),
        a.params
    );
    println!("{}", header());
    let path = PathSpec::parse(&a.path).unwrap();
    let bounds = cloud.bounds();
    let rr = bounds.radius() as f64;
    let mut rows: Vec<Vec<f64>> = Vec::new();
    for f in 0..a.frames {
        let view = View {
            camera: path.camera(f, a.frames, &bounds),
            width: a.width,
            height: a.height,
        };
        let row = frame_row(&md, f, &view, a.eps, rr, bounds.center().as_dvec3());
        println!(
            "{}",
            row.iter()
                .map(|v| format!("{v:.6}"))
                .collect::<Vec<_>>()
                .join(",")
        );
        rows.push(row);
    }
    let med = |k: usize| median(rows.iter().map(|r| r[k]).collect());
    let n = rows.first().map_or(0, Vec::len);
    println!(
        "median,{}",
        (1..n)
            .map(|k| format!("{:.6}", med(k)))
            .collect::<Vec<_>>()
            .join(",")
    );
    if a.build.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
}
