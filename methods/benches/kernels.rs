//! CPU kernels shared by the methods: normal encoding, leaf-radius estimation (k nearest
//! neighbours), QSplat's and SPT's trees, scene generation, `full`'s per-frame selection and
//! QSplat's traversal (throughput = nodes visited), and the chunk store's LZO + checksum on
//! one chunk. Timing is reported, never asserted.
//! Run: `cargo bench -p methods --bench kernels` (QSplat only: `... -- qsplat/`; store only:
//! `... -- store/`; MWKD only: `... -- mwkd/`; generation and k-NN: `... -- kernels/`; PLY
//! reading: `... -- scene_io/`).
#![allow(missing_docs, clippy::unwrap_used)]

use criterion::{Criterion, Throughput, criterion_group, criterion_main};
use methods::{Feedback, MethodKind, Params, Target, store};
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
    // A height field (2.5-D, aerial-scan-like) beside the closed statue surface.
    let terrain = Generator::Terrain.generate(n, 1).unwrap();
    g.bench_function("knn_spacing_k6_terrain", |b| {
        b.iter(|| scenes::spacing::knn_spacing(terrain.positions(), methods::leaf::LEAF_K))
    });
    // QSplat's hierarchy (partition, properties, quantisation; radii given).
    let radii = methods::leaf::leaf_radii(&terrain).radii.into_owned();
    g.bench_function("qsplat_tree_terrain", |b| {
        b.iter(|| methods::qsplat::build::build_tree(&terrain, &radii).unwrap())
    });
    // SPT's point tree (Morton sort, per-node disks or balls and errors; radii given): with
    // normals (disks, errors) and without (balls, as a LAS scan without normals).
    g.bench_function("spt_tree_terrain", |b| {
        b.iter(|| methods::spt::build::build_tree(&terrain, &radii, 255.0))
    });
    let bare = terrain.clone().without_normals();
    g.bench_function("spt_tree_terrain_no_normals", |b| {
        b.iter(|| methods::spt::build::build_tree(&bare, &radii, 255.0))
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

/// The chunk store on realistic chunks of about 40 KiB raw, as an LPC cloud might be
/// encoded: `f32` = 2048 terrain samples as the uploaded columns (positions `f32 × 3`,
/// octahedral normals and packed colours `u32`; float mantissas leave LZO almost nothing);
/// `q16` = 2900 samples with positions quantised to `u16 × 3` in the chunk's bounding box,
/// then the same normals and colours. LZO compression (build), decompression and checksum
/// (every read), and a whole `Repository::read` (bounds + checksum + decompression + page
/// release, so pages fault back in each time). Throughput in raw bytes, except the
/// checksum's (stored bytes).
fn store(c: &mut Criterion) {
    let dir = tempfile::tempdir().unwrap();
    let mut g = c.benchmark_group("store");
    g.warm_up_time(std::time::Duration::from_secs(1));
    g.measurement_time(std::time::Duration::from_secs(2));
    for (name, n, quantise) in [("f32", 2048, false), ("q16", 2900, true)] {
        let cloud = Generator::Terrain.generate(n, 1).unwrap();
        let batch = methods::SplatBatch::from_cloud_range(&cloud, 0..cloud.len(), None);
        let mut raw: Vec<u8> = if quantise {
            let b = cloud.bounds();
            let ext = (b.max - b.min).max(glam::Vec3::splat(1e-12));
            batch
                .positions
                .iter()
                .flat_map(|p| {
                    let q = (glam::Vec3::from(*p) - b.min) / ext * 65535.0;
                    [q.x as u16, q.y as u16, q.z as u16]
                })
                .flat_map(u16::to_le_bytes)
                .collect()
        } else {
            bytemuck::cast_slice(&batch.positions).to_vec()
        };
        raw.extend_from_slice(bytemuck::cast_slice(batch.normals.as_deref().unwrap()));
        raw.extend_from_slice(bytemuck::cast_slice(batch.colors.as_deref().unwrap()));
        let stored = store::compress(&raw);
        eprintln!(
            "store/{name}: chunk of {} raw bytes compresses to {} ({:.1} %)",
            raw.len(),
            stored.len(),
            100.0 * stored.len() as f64 / raw.len() as f64
        );
        let path = dir.path().join(format!("{name}.bin"));
        let mut w = store::RepoWriter::create(&path).unwrap();
        let r = w.append(&raw).unwrap();
        w.finish().unwrap();
        let repo = store::Repository::open(&path).unwrap();

        g.throughput(Throughput::Bytes(raw.len() as u64));
        g.bench_function(format!("lzo_compress_{name}"), |b| {
            b.iter(|| store::compress(&raw))
        });
        g.bench_function(format!("lzo_decompress_{name}"), |b| {
            b.iter(|| store::decompress(&stored, raw.len(), "chunk").unwrap())
        });
        g.bench_function(format!("repository_read_{name}"), |b| {
            b.iter(|| repo.read(&r, "chunk").unwrap())
        });
        g.throughput(Throughput::Bytes(stored.len() as u64));
        g.bench_function(format!("checksum_{name}"), |b| {
            b.iter(|| store::checksum(&stored))
        });
    }
    g.finish();
}

/// MWKD's kernels: `Representatives` for one inner node (4 leaves of 2048 samples each pass
/// 512 up: throughput = input splats), the node codec (encode / decode one 8192-splat node),
/// and the per-frame front selection on a 1 M-point build (budget `LODSelection` and the
/// `--eps` front; throughput = nodes in the index).
fn mwkd(c: &mut Criterion) {
    use methods::mwkd::{build::Columns, build::leaf_splats, codec, reps, select, tree::Tree};
    let mut g = c.benchmark_group("mwkd");
    g.sample_size(10);
    let cloud = Generator::Statue.generate(8192, 3).unwrap();
    let tree = Tree::split(cloud.positions(), 4, 2048).unwrap();
    let leaves: Vec<reps::Splats> = tree
        .leaves()
        .map(|i| leaf_splats(Columns::of(&cloud), &tree, i))
        .collect();
    let cfg = reps::RepConfig::default();
    g.throughput(Throughput::Elements(8192));
    g.bench_function("representatives_4x2048_to_4x512", |b| {
        b.iter(|| {
            leaves
                .iter()
                .map(|l| reps::representatives(l, 512, &cfg).reps.len())
                .sum::<usize>()
        })
    });
    let pos: Vec<[f32; 3]> = cloud.positions().to_vec();
    let radii = vec![0.01f32; pos.len()];
    let normals = cloud.normals().unwrap().to_vec();
    let (bytes, _) = codec::encode(&pos, &radii, Some(&normals), None).unwrap();
    g.bench_function("codec_encode_8192", |b| {
        b.iter(|| codec::encode(&pos, &radii, Some(&normals), None).unwrap())
    });
    g.bench_function("codec_decode_8192", |b| {
        b.iter(|| codec::decode(0, &bytes).unwrap())
    });
    let big = Generator::Statue.generate(1_000_000, 1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let params = Params::parse(&["vbo=2048"]).unwrap();
    MethodKind::Mwkd
        .build(&big, &params, "bench", dir.path(), &scenes::NoProgress)
        .unwrap();
    let nodes = methods::mwkd::index::read(&dir.path().join("index.bin")).unwrap();
    let view = scenes::View {
        camera: PathSpec::parse("orbit")
            .unwrap()
            .camera(0, 1, &big.bounds()),
        width: 1024,
        height: 1024,
    };
    let metric = select::Metric {
        c0: 1.0,
        c1: 1.0,
        c2: 0.0,
    };
    let ctx = select::Ctx::new(&nodes, &view, metric);
    g.throughput(Throughput::Elements(nodes.len() as u64));
    g.bench_function("budget_front_1m_b200k", |b| {
        b.iter(|| select::budget_front(&ctx, 200_000, &|_| false).points)
    });
    g.bench_function("eps_front_1m_1px", |b| {
        b.iter(|| select::eps_front(&ctx, 1.0, &|_| false).points)
    });
    g.finish();
}

/// Reading a binary little-endian PLY (positions, normals, no faces) of 1 M vertices as our
/// writer writes it (`double` positions), per byte of the file.
fn scene_io(c: &mut Criterion) {
    let n = 1_000_000;
    let cloud = Generator::Statue.generate(n, 1).unwrap();
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("statue.ply");
    let bytes =
        scenes::ply::write(&path, &cloud, scenes::ply::PlyFormat::BinaryLittleEndian).unwrap();
    let mut g = c.benchmark_group("scene_io");
    g.sample_size(10);
    g.throughput(Throughput::Bytes(bytes));
    g.bench_function("ply_read_binary_1m", |b| {
        b.iter(|| scenes::ply::read(&path, &scenes::ply::PlyOptions::default()).unwrap())
    });
    g.finish();
}

criterion_group!(benches, kernels, store, mwkd, scene_io);
criterion_main!(benches);
