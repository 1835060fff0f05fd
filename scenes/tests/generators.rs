#![allow(clippy::unwrap_used)]
//! The generators' contract: determinism, exact counts, attributes, analytic unit normals,
//! area-uniform statue sampling, isosurface depth complexity, terrain density contrast, and
//! `generate_to_file` ≡ `generate`.

use std::sync::atomic::{AtomicU64, Ordering};

use glam::Vec3;
use scenes::generators::{Generator, isosurface, statue, terrain};
use scenes::{PointCloud, Progress, spacing};

fn bytes(c: &PointCloud) -> Vec<u8> {
    let mut v: Vec<u8> = bytemuck::cast_slice(c.positions()).to_vec();
    if let Some(n) = c.normals() {
        v.extend_from_slice(bytemuck::cast_slice(n));
    }
    if let Some(col) = c.colors() {
        v.extend_from_slice(bytemuck::cast_slice(col));
    }
    if let Some(r) = c.radii() {
        v.extend_from_slice(bytemuck::cast_slice(r));
    }
    v
}

#[test]
fn deterministic_across_runs_and_thread_counts() {
    let n = 3 * scenes::generators::BLOCK + 123; // several blocks, a partial last one
    for &g in Generator::ALL {
        let a = g.generate(n, 42).unwrap();
        let b = g.generate(n, 42).unwrap();
        assert!(bytes(&a) == bytes(&b), "{}: two runs differ", g.name());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(1)
            .build()
            .unwrap();
        let c = pool.install(|| g.generate(n, 42).unwrap());
        assert!(bytes(&a) == bytes(&c), "{}: 1 thread differs", g.name());
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(3)
            .build()
            .unwrap();
        let c = pool.install(|| g.generate(n, 42).unwrap());
        assert!(bytes(&a) == bytes(&c), "{}: 3 threads differ", g.name());
        assert_eq!(a.origin(), c.origin());
        let d = g.generate(n, 43).unwrap();
        assert!(
            a.positions() != d.positions(),
            "{}: seeds 42 and 43 agree",
            g.name()
        );
    }
}

#[test]
fn exact_counts_attributes_and_unit_normals() {
    for &g in Generator::ALL {
        for n in [1usize, 7, 1000, 100_003] {
            let c = g.generate(n, 9).unwrap();
            assert_eq!(c.len(), n, "{} n = {n}", g.name());
            let a = c.attributes();
            assert_eq!(a, g.attributes(), "{}", g.name());
            assert!(a.normals && !a.radii);
            assert_eq!(a.colors, g == Generator::Terrain);
            assert_eq!(c.colors().is_some(), a.colors);
            for (i, nrm) in c.normals().unwrap().iter().enumerate() {
                let l = Vec3::from(*nrm).length();
                assert!(
                    (l - 1.0).abs() < 1e-5,
                    "{} normal {i} has length {l}",
                    g.name()
                );
            }
        }
        assert!(g.generate(0, 1).is_err(), "{}: n = 0", g.name());
        // Too large to allocate: an error, not an abort.
        assert!(
            g.generate(usize::MAX / 4, 1).is_err(),
            "{}: huge n",
            g.name()
        );
        assert_eq!(Generator::from_name(g.name()), Some(g));
        assert!(!g.describe().is_empty());
    }
    assert_eq!(Generator::from_name("teapot"), None);
}

#[test]
fn statue_points_lie_on_the_surface_with_outward_normals() {
    let c = Generator::Statue.generate(50_000, 5).unwrap();
    let s = statue::Statue::new(5);
    let nrm = c.normals().unwrap();
    let mut outward = 0;
    for (p, n) in c.positions().iter().zip(nrm) {
        let p = Vec3::from(*p);
        let g = s.gradient(p);
        // Distance to the surface ≈ |F| / |∇F|.
        assert!(
            s.implicit(p).abs() / g.length() < 2e-6,
            "{p}: F = {}",
            s.implicit(p)
        );
        assert!(Vec3::from(*n).dot(g.normalize()) > 0.9999);
        if Vec3::from(*n).dot(p) > 0.0 {
            outward += 1;
        }
    }
    assert!(
        outward as f64 >= 0.99 * c.len() as f64,
        "{outward} of {} outward",
        c.len()
    );
    // A 2 m standing figure: tall along Z, centred at the origin.
    let b = c.bounds();
    assert!(
        b.size().z > 1.8 && b.size().z < 2.4 && b.size().x < 0.9 && b.size().y < 0.8,
        "{b:?}"
    );
    assert!(b.center().length() < 0.1);
}

/// Mean k-NN spacing per bin of height and per octant of azimuth, max / min over bins.
fn spacing_spread(p: &[[f32; 3]]) -> (f32, f32) {
    let d = spacing::knn_spacing(p, 8);
    let mean = d.iter().sum::<f32>() / d.len() as f32;
    let var = d.iter().map(|x| (x - mean).powi(2)).sum::<f32>() / d.len() as f32;
    let cv = var.sqrt() / mean;
    let mut sum = [0.0f64; 40];
    let mut cnt = [0usize; 40];
    for (q, &s) in p.iter().zip(&d) {
        let zbin = (((q[2] + 1.2) / 2.4 * 10.0) as usize).min(9);
        let quadrant = (q[0] > 0.0) as usize + 2 * (q[1] > 0.0) as usize;
        sum[zbin * 4 + quadrant] += s as f64;
        cnt[zbin * 4 + quadrant] += 1;
    }
    let means: Vec<f64> = (0..40)
        .filter(|&b| cnt[b] >= 200)
        .map(|b| sum[b] / cnt[b] as f64)
        .collect();
    assert!(means.len() >= 32);
    let max = means.iter().copied().fold(0.0, f64::max);
    let min = means.iter().copied().fold(f64::INFINITY, f64::min);
    ((max / min) as f32, cv)
}

#[test]
fn statue_sampling_is_uniform_by_area() {
    // Area-uniform sampling ⇒ the local spacing is the same everywhere: the mean 8-NN spacing
    // of each of 40 regions (10 height slabs × 4 azimuth quadrants) is the same within noise.
    // Measured: max/min 1.04–1.07 and CV of the spacing 0.18 for seeds 1–5 (Poisson-like; the
    // rougher parts of the figure carry slightly more area per unit of macroscopic surface).
    let n = 60_000;
    let c = Generator::Statue.generate(n, 1).unwrap();
    let (spread, cv) = spacing_spread(c.positions());
    assert!(
        spread < 1.2,
        "mean spacing varies {spread}× between regions"
    );
    assert!(cv < 0.3, "coefficient of variation of the spacing {cv}");

    // Control: the same surface sampled uniformly in the sphere parameter (the mistake this
    // test guards against) fails the bound clearly (measured 1.73).
    let s = statue::Statue::new(1);
    let mut rng = scenes::rng::Pcg32::new(77);
    let naive: Vec<[f32; 3]> = (0..n)
        .map(|_| {
            let u = rng.unit_vec3();
            (statue::SEMI_AXES * (s.radial(u) * u)).to_array()
        })
        .collect();
    let (naive_spread, _) = spacing_spread(&naive);
    assert!(naive_spread > 1.4, "control spread only {naive_spread}");
}

/// Median crossing counts over 8 × 8 rays through the central half of the box's image,
/// looking along `dir`.
fn median_depth(iso: &isosurface::Isosurface, dir: Vec3) -> (usize, Vec<usize>) {
    let half = (isosurface::BOX_MAX - isosurface::BOX_MIN) * 0.25;
    let (e1, e2) = if dir.z.abs() > 0.9 {
        (Vec3::X, Vec3::Y)
    } else {
        let e1 = dir.cross(Vec3::Z).normalize();
        (e1, e1.cross(dir).normalize())
    };
    let mut counts = Vec::new();
    for i in 0..8 {
        for j in 0..8 {
            let (u, v) = ((i as f32 + 0.5) / 8.0 - 0.5, (j as f32 + 0.5) / 8.0 - 0.5);
            // The central half of the view: half the box's extent across, half vertically.
            let offset = e1 * (u * 2.0 * half.x) + e2 * (v * 2.0 * half.z);
            let origin = offset - dir * 5.0;
            counts.push(iso.crossings(origin, dir));
        }
    }
    counts.sort_unstable();
    (counts[counts.len() / 2], counts)
}

#[test]
fn isosurface_has_high_depth_complexity() {
    // Rays through the central half of the box's image, for views along x, along y and from
    // an oblique direction 30° above the horizon: the median crossing count must reach 20
    // (measured: 38, 38 and 28–29 for seeds 1–2).
    let seed = 3;
    let iso = isosurface::Isosurface::new(seed);
    let (s30, c30) = 30f32.to_radians().sin_cos();
    let views = [Vec3::X, Vec3::Y, Vec3::new(0.8 * c30, 0.6 * c30, -s30)];
    for dir in views {
        let (median, counts) = median_depth(&iso, dir);
        assert!(
            median >= 20,
            "view {dir}: median depth complexity {median}, counts {counts:?}"
        );
        assert_eq!(
            isosurface::isosurface_crossings(seed, -dir * 5.0, dir),
            iso.crossings(-dir * 5.0, dir)
        );
    }
    // Rays that miss the box, and degenerate directions, cross nothing.
    assert_eq!(iso.crossings(Vec3::new(0.0, 0.0, 5.0), Vec3::X), 0);
    assert_eq!(iso.crossings(Vec3::ZERO, Vec3::ZERO), 0);
    assert_eq!(iso.crossings(Vec3::ZERO, Vec3::NAN), 0);
}

#[test]
fn deep_isosurface_reaches_the_papers_depth_complexity() {
    // LPC's and the multi-way kd-tree's 234 M-sample isosurface: "depth complexity > 100".
    // Rice's formula at three times the wave number predicts ≈ 110 crossings along a 2-unit
    // horizontal ray through the centre (3 × 37). Measured (seeds 1–4, views along x and y):
    // 108–113 along the central rays, median 99–104 over the central half of the view (whose
    // upper and lower rays reach the thinner parts of the layer), 3.0 × the base isosurface's.
    for seed in [1, 3] {
        let deep = isosurface::Isosurface::deep(seed);
        let base = isosurface::Isosurface::new(seed);
        for dir in [Vec3::X, Vec3::Y] {
            let across = dir.cross(Vec3::Z).normalize();
            let centre: Vec<usize> = (-5..=5)
                .map(|k| deep.crossings(across * (k as f32 * 0.01) - dir * 5.0, dir))
                .collect();
            let mean = centre.iter().sum::<usize>() as f64 / centre.len() as f64;
            assert!(
                mean > 100.0,
                "seed {seed}, view {dir}: central rays {centre:?}"
            );
            let (median, counts) = median_depth(&deep, dir);
            assert!(
                median >= 90,
                "seed {seed}, view {dir}: median {median}, {counts:?}"
            );
            let (_, base_counts) = median_depth(&base, dir);
            let ratio =
                counts.iter().sum::<usize>() as f64 / base_counts.iter().sum::<usize>() as f64;
            assert!(
                (ratio - 3.0).abs() < 0.45,
                "seed {seed}, view {dir}: ×{ratio}"
            );
        }
    }
}

#[test]
fn isosurface_points_lie_on_the_zero_set_inside_the_box() {
    for (g, iso) in [
        (Generator::Isosurface, isosurface::Isosurface::new(8)),
        (Generator::IsosurfaceDeep, isosurface::Isosurface::deep(8)),
    ] {
        on_zero_set(g, &iso);
    }
}

fn on_zero_set(g: Generator, iso: &isosurface::Isosurface) {
    let c = g.generate(20_000, 8).unwrap();
    for (p, n) in c.positions().iter().zip(c.normals().unwrap()) {
        let p = Vec3::from(*p);
        assert!(
            p.cmpge(isosurface::BOX_MIN).all() && p.cmple(isosurface::BOX_MAX).all(),
            "{p}"
        );
        let (f, g) = iso.value_gradient(p);
        assert!(
            f.abs() / g.length() < 1e-5,
            "{p}: distance {}",
            f.abs() / g.length()
        );
        assert!(Vec3::from(*n).dot(g.normalize()) > 0.9999);
    }
    // The mixing layer: more surface at mid-height than near the top and bottom faces.
    let mid = c.positions().iter().filter(|p| p[2].abs() < 0.2).count();
    let outer = c.positions().iter().filter(|p| p[2].abs() > 0.4).count();
    assert!(mid > 2 * outer, "mid {mid} outer {outer}");
}

#[test]
fn terrain_is_georeferenced_with_strongly_varying_density() {
    let n = 200_000;
    let c = Generator::Terrain.generate(n, 11).unwrap();
    assert_eq!(c.origin(), terrain::ORIGIN);
    let w = c.world_position(0);
    assert!(w.x > 500_000.0 && w.y > 4_100_000.0);
    let b = c.bounds();
    assert!(
        b.min.x >= 0.0 && b.min.y >= 0.0 && b.max.x <= terrain::SIZE && b.max.y <= terrain::SIZE
    );
    assert!(
        b.min.z > 100.0 && b.max.z < 700.0 && b.size().z > 200.0,
        "{b:?}"
    );
    // Per-cell density on a 16 × 16 grid.
    let g = 16usize;
    let mut cells = vec![0u32; g * g];
    for p in c.positions() {
        let i = ((p[0] / terrain::SIZE * g as f32) as usize).min(g - 1);
        let j = ((p[1] / terrain::SIZE * g as f32) as usize).min(g - 1);
        cells[j * g + i] += 1;
    }
    let max = *cells.iter().max().unwrap();
    let min = *cells.iter().filter(|&&c| c > 0).min().unwrap();
    assert!(
        max as f64 / min as f64 >= 100.0,
        "density max/min = {max}/{min}"
    );
    // Heights follow the height field; normals point up.
    let t = terrain::Terrain::new(11);
    for (p, nrm) in c.positions().iter().zip(c.normals().unwrap()).take(5000) {
        let (h, grad) = t.height(p[0], p[1]);
        assert_eq!(p[2], h);
        let expect = Vec3::new(-grad.x, -grad.y, 1.0).normalize();
        assert!(Vec3::from(*nrm).dot(expect) > 0.99999 && nrm[2] > 0.0);
    }
    // Colours vary (grass, rock, water, …), they are not a constant.
    let colors = c.colors().unwrap();
    let distinct: std::collections::HashSet<[u8; 3]> = colors.iter().copied().collect();
    assert!(distinct.len() > 1000);
}

#[derive(Default)]
struct Count {
    total: AtomicU64,
    done: AtomicU64,
    finished: AtomicU64,
}

impl Progress for Count {
    fn start(&self, _: &str, total: u64) {
        self.total.store(total, Ordering::Relaxed);
    }
    fn inc(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }
    fn finish(&self) {
        self.finished.fetch_add(1, Ordering::Relaxed);
    }
}

#[test]
fn generate_to_file_equals_generate() {
    let dir = tempfile::tempdir().unwrap();
    for &g in Generator::ALL {
        let n = if g == Generator::Statue {
            300_000
        } else {
            270_000
        }; // > one batch
        let path = dir.path().join(format!("{}.sbc", g.name()));
        let progress = Count::default();
        let f = g.generate_to_file(n, 21, &path, &progress).unwrap();
        assert!(f.is_mapped());
        assert!(path.exists() && !scenes::colfile::temp_path(&path).exists());
        assert_eq!(progress.total.load(Ordering::Relaxed), n as u64);
        assert_eq!(progress.done.load(Ordering::Relaxed), n as u64);
        assert_eq!(progress.finished.load(Ordering::Relaxed), 1);
        let m = g.generate(n, 21).unwrap();
        assert_eq!(f.len(), n);
        assert_eq!(f.origin(), m.origin());
        assert_eq!(f.attributes(), m.attributes());
        assert!(
            bytes(&f) == bytes(&m),
            "{}: file and memory differ",
            g.name()
        );
        let reopened = scenes::colfile::open(&path).unwrap();
        assert!(bytes(&reopened) == bytes(&m));
    }
}
