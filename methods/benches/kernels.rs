//! CPU kernels shared by the methods: normal encoding, leaf-radius estimation (k nearest
//! neighbours), scene generation, `full`'s per-frame selection and QSplat's traversal
//! (throughput = nodes visited). Timing is reported, never asserted.
//! Run: `cargo bench -p methods --bench kernels` (QSplat only: `... -- qsplat/`).
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use methods::{Feedback, MethodKind, Params, Target};
use scenes::generators::Generator;
use scenes::paths::PathSpec;

fn kernels(c: &mut Criterion) {
    let n = 200_000;
    let cloud = Generator::Statue.generate(n, 1).unwrap();
    let mut g = c.benchmark_group("kernels");
    g.throughput(Throughput::Elements(n as u64));
    g.sample_size(10);
    g.bench_function("octnormal_encode", |b| {
        let normals = cloud.normals().unwrap();
        b.iter(|| {
            normals
                .iter()
                .map(|v| methods::octnormal::encode(glam::Vec3::from(*v)) as u64)
                .sum::<u64>()
        })
    });
    g.bench_function("knn_spacing_k6", |b| {
        b.iter(|| scenes::spacing::knn_spacing(cloud.positions(), methods::leaf::LEAF_K))
    });
    for generator in Generator::ALL {
        g.bench_function(format!("generate_{}", generator.name()), |b| {
            b.iter(|| generator.generate(n, 1).unwrap())
        });
    }
    let dir = tempfile::tempdir().unwrap();
    MethodKind::Full
        .build(
            &cloud,
            &Params::default(),
            "bench",
            dir.path(),
            &scenes::NoProgress,
        )
        .unwrap();
    let mut m = MethodKind::open(dir.path()).unwrap();
    let view = scenes::View {
        camera: PathSpec::parse("orbit")
            .unwrap()
            .camera(0, 1, &cloud.bounds()),
        width: 1024,
        height: 1024,
    };
    g.bench_function("full_frame_select", |b| {
        b.iter(|| {
            m.frame(&view, Target::Tolerance(1.0), &Feedback::default())
                .unwrap()
        })
    });
    g.finish();

    // QSplat's per-frame traversal, per node visited (decode + cull + project + emit).
    let qdir = tempfile::tempdir().unwrap();
    MethodKind::Qsplat
        .build(
            &cloud,
            &Params::default(),
            "bench",
            qdir.path(),
            &scenes::NoProgress,
        )
        .unwrap();
    let mut q = MethodKind::open(qdir.path()).unwrap();
    let mut g = c.benchmark_group("qsplat");
    g.sample_size(20);
    for (name, target) in [
        ("traverse_eps0", Target::Tolerance(0.0)),
        ("traverse_eps1", Target::Tolerance(1.0)),
        ("traverse_eps4", Target::Tolerance(4.0)),
        ("traverse_budget50k", Target::Budget(50_000)),
    ] {
        let visited = q
            .frame(&view, target, &Feedback::default())
            .unwrap()
            .counters[0];
        g.throughput(Throughput::Elements(visited as u64));
        g.bench_function(name, |b| {
            b.iter(|| q.frame(&view, target, &Feedback::default()).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, kernels);
criterion_main!(benches);
