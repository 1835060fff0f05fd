//! The cost of LPC's occlusion queries (§4) in the renderer: a wall in front of a 20 × 20
//! grid of small clouds (400 candidates of 1,000 splats), drawn with the occlusion pass
//! (phase 1 the wall, then a query per candidate, then the visible ones) against the same
//! splats drawn without it — exactly what the occlusion frame ends up drawing, so the
//! difference is the queries' cost. Timing is reported, never asserted (it was an ignored
//! test that only printed). Run: `cargo bench -p harness --bench occlusion` (needs an
//! adapter: lavapipe where there is no GPU; without one it says so and measures nothing).
#![allow(missing_docs, clippy::unwrap_used)]

#[path = "../tests/occlusion_scene/mod.rs"]
mod occlusion_scene;

use std::collections::HashSet;

use criterion::{Criterion, criterion_group, criterion_main};
use harness::render::{Kernel, RenderSettings, Renderer};
use methods::{ChunkId, DrawList, LodMethod, Target};
use occlusion_scene::*;

fn queries(c: &mut Criterion) {
    let Some(gpu) = harness::gpu::Gpu::new().ok().flatten() else {
        eprintln!("occlusion bench: skipped: no adapter");
        return;
    };
    let (w, h) = (512u32, 512u32);
    let mut m = Walls::scene();
    m.clouds.truncate(1);
    m.clouds[0] = grid(0.0, 0.0, 0.0, 3.0, 121, [200, 40, 40]);
    let n = 20usize;
    for i in 0..n {
        for j in 0..n {
            let t = |k: usize| (k as f32 / (n - 1) as f32 - 0.5) * 6.0;
            m.clouds
                .push(ball([t(i), t(j), -3.0], 0.15, 1_000, [40, 200, 40]));
        }
    }
    let v = scenes::View {
        width: w,
        height: h,
        ..view()
    };
    let mut r = Renderer::new(
        &gpu,
        RenderSettings {
            width: w,
            height: h,
            kernel: Kernel::Square,
            cache_bytes: 256 << 20,
            shade: Default::default(),
            raster: Default::default(),
        },
    )
    .unwrap();
    let occl = m
        .frame(&v, Target::Tolerance(1.0), &feedback(&[WALL]))
        .unwrap();
    let (s, _) = r.draw(&v, &occl, &m, false).unwrap();
    let o = s.occlusion.clone().unwrap();
    let visible: HashSet<ChunkId> = o.visible.iter().copied().collect();
    let plain = DrawList {
        items: (0..m.clouds.len() as ChunkId)
            .filter(|id| visible.contains(id))
            .map(|id| m.item(id))
            .collect(),
        ..Default::default()
    };
    eprintln!(
        "occlusion bench on {}: {} candidates, {} queried, {} occluded; {} splats drawn of {}",
        gpu.adapter.name,
        m.clouds.len(),
        o.clouds_queried,
        o.clouds_occluded,
        s.points,
        m.input_points()
    );
    let mut g = c.benchmark_group("occlusion_queries");
    g.sample_size(20);
    for (name, list) in [
        ("with_occlusion_pass", &occl),
        ("plain_same_splats", &plain),
    ] {
        g.bench_function(name, |b| b.iter(|| r.draw(&v, list, &m, false).unwrap()));
    }
    g.finish();
}

criterion_group!(benches, queries);
criterion_main!(benches);
