//! Image metrics on a 1024² pair (a reference of soft blobs and the same image shifted by two
//! pixels with noise): the whole `compare` (PSNR, SSIM, FLIP, holes) and each metric alone.
//! `flip_mean_nv_flip` is the previous implementation (NVIDIA's C++), for a ratio in the same
//! run; `flip_prepare` and `flip_error_mean_prepared` are the two halves of ours. Timing is
//! reported, never asserted.
//! Run: `cargo bench -p harness --bench metrics`.
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{Criterion, criterion_group, criterion_main};
use harness::image::Image;
use harness::metrics;

/// A `w × h` image of smooth colour blobs on black (a quarter of the pixels background), and
/// the same shifted right by `shift` pixels with ±`noise` added per channel (seeded).
fn pair(w: u32, h: u32, shift: u32, noise: u8) -> (Image, Image) {
    let px = |x: u32, y: u32| -> [u8; 4] {
        let (fx, fy) = (x as f32 / 37.0, y as f32 / 29.0);
        let v = (fx.sin() * fy.cos() + 0.5).clamp(0.0, 1.0);
        if v < 0.25 {
            [0, 0, 0, 0]
        } else {
            [
                (255.0 * v) as u8,
                (180.0 * v) as u8,
                (90.0 + 120.0 * v) as u8,
                255,
            ]
        }
    };
    let mut seed = 0x9E37_79B9_7F4A_7C15u64;
    let mut jitter = |c: u8| {
        seed ^= seed << 13;
        seed ^= seed >> 7;
        seed ^= seed << 17;
        let d = (seed % (2 * u64::from(noise) + 1)) as i32 - i32::from(noise);
        (i32::from(c) + d).clamp(0, 255) as u8
    };
    let (mut a, mut b) = (Vec::new(), Vec::new());
    for y in 0..h {
        for x in 0..w {
            a.extend(px(x, y));
            let p = px(x.saturating_sub(shift), y);
            b.extend([jitter(p[0]), jitter(p[1]), jitter(p[2]), p[3]]);
        }
    }
    (
        Image::from_rgba(w, h, a).unwrap(),
        Image::from_rgba(w, h, b).unwrap(),
    )
}

fn bench(c: &mut Criterion) {
    let (reference, test) = pair(1024, 1024, 2, 10);
    let mut g = c.benchmark_group("metrics_1024");
    g.sample_size(10);
    g.bench_function("compare", |b| {
        b.iter(|| metrics::compare(&reference, &test).unwrap())
    });
    g.bench_function("flip_mean", |b| {
        b.iter(|| metrics::flip_mean(&reference, &test).unwrap())
    });
    // The previous version's FLIP (NVIDIA's C++ through `nv-flip`, one thread), for the
    // ratio in the same run.
    g.bench_function("flip_mean_nv_flip", |b| {
        b.iter(|| {
            let (w, h) = (reference.width, reference.height);
            let r = nv_flip::FlipImageRgb8::with_data(w, h, &reference.to_rgb());
            let t = nv_flip::FlipImageRgb8::with_data(w, h, &test.to_rgb());
            let map = nv_flip::flip(r, t, nv_flip::DEFAULT_PIXELS_PER_DEGREE).to_vec();
            map.iter().map(|&e| f64::from(e)).sum::<f64>() / map.len() as f64
        })
    });
    let (prepared_ref, prepared_test) = (
        metrics::flip::FlipFeatures::new(&reference, None),
        metrics::flip::FlipFeatures::new(&test, None),
    );
    g.bench_function("flip_prepare", |b| {
        b.iter(|| metrics::flip::FlipFeatures::new(&test, None))
    });
    g.bench_function("flip_error_mean_prepared", |b| {
        b.iter(|| metrics::flip::error_mean(&prepared_ref, &prepared_test))
    });
    g.bench_function("ssim", |b| {
        b.iter(|| metrics::ssim(&reference, &test).unwrap())
    });
    g.bench_function("psnr_db", |b| {
        b.iter(|| metrics::psnr_db(&reference, &test).unwrap())
    });
    g.finish();
}

criterion_group!(benches, bench);
criterion_main!(benches);
