//! The seed files of each target: small real files, and files the writers and the method
//! builders produce from a tiny generated scene.

use std::path::{Path, PathBuf};

use methods::store::{ChunkRef, Repository};
use methods::{MethodKind, Params, lpc, mwkd};
use scenes::PointCloud;
use scenes::generators::Generator;
use scenes::ply::{self, PlyFormat};

use crate::mutate;

use crate::corpus::{Corpus, Seed};
use crate::targets::Target;

/// The small scene every method is built from.
fn scene() -> Result<PointCloud, String> {
    Generator::Statue
        .generate(2000, 1)
        .map_err(|e| e.to_string())
}

/// A small generated cloud: terrain (georeferenced, normals and colours) or statue (normals).
fn small_cloud(n: usize, terrain: bool) -> Result<PointCloud, String> {
    let g = if terrain {
        Generator::Terrain
    } else {
        Generator::Statue
    };
    g.generate(n, 5).map_err(|e| e.to_string())
}

fn repo_root() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .map_or_else(|| PathBuf::from("."), Path::to_path_buf)
}

fn read_seed(path: &Path) -> Result<Seed, String> {
    Ok(Seed {
        name: path
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        bytes: std::fs::read(path).map_err(|e| format!("{}: {e}", path.display()))?,
    })
}

/// Writes a seed with `write` into `work` and reads it back.
fn written(
    work: &Path,
    name: &str,
    write: impl FnOnce(&Path) -> Result<(), String>,
) -> Result<Seed, String> {
    let p = work.join(name);
    write(&p)?;
    read_seed(&p)
}

const SQUARE: [[f64; 3]; 4] = [
    [0.0, 0.0, 0.0],
    [1.0, 0.0, 0.0],
    [1.0, 1.0, 0.0],
    [0.0, 1.0, 0.0],
];

/// A hand-written binary PLY: a vertex list property, an extra element, faces, in `be`.
fn binary_with_lists(be: bool) -> Vec<u8> {
    let fmt = if be {
        "binary_big_endian"
    } else {
        "binary_little_endian"
    };
    let mut b = format!(
        "ply\nformat {fmt} 1.0\ncomment hand-written\nelement vertex 4\nproperty float x\n\
         property float y\nproperty float z\nproperty list uchar short tags\nproperty ushort red\n\
         property ushort green\nproperty ushort blue\nelement edge 1\nproperty int a\n\
         property int b\nelement face 2\nproperty list uchar uint vertex_indices\nend_header\n"
    )
    .into_bytes();
    let f32b = |v: f32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
    let u16b = |v: u16| if be { v.to_be_bytes() } else { v.to_le_bytes() };
    let u32b = |v: u32| if be { v.to_be_bytes() } else { v.to_le_bytes() };
    for (k, p) in SQUARE.iter().enumerate() {
        for c in p {
            b.extend_from_slice(&f32b(*c as f32));
        }
        b.push(k as u8);
        for t in 0..k {
            b.extend_from_slice(&u16b(t as u16));
        }
        for c in [1000u16, 30000, 65535] {
            b.extend_from_slice(&u16b(c));
        }
    }
    b.extend_from_slice(&u32b(0));
    b.extend_from_slice(&u32b(1));
    for face in [[0u32, 1, 2], [0, 2, 3]] {
        b.push(3);
        for v in face {
            b.extend_from_slice(&u32b(v));
        }
    }
    b
}

const ASCII_MIXED: &str = "ply\nformat ascii 1.0\ncomment hand-written\nobj_info x\n\
element vertex 4\nproperty double x\nproperty double y\nproperty double z\nproperty char flag\n\
property float nx\nproperty float ny\nproperty float nz\nproperty uchar red\nproperty uchar green\n\
property uchar blue\nproperty float radius\nelement material 1\nproperty list uchar float k\n\
element face 2\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 -1 0 0 1 255 0 0 0.1\n1 0 0 2 0 0 1 0 255 0 0.1\n\r\n1 1 0 3 0 0 1 0 0 255 0.2\n\
0 1 0 4 0 0 1 9 9 9 0.3\n2 0.5 0.25\n3 0 1 2\n4 0 1 2 3\n";

/// Turns a LAS 1.2 file into LAS 1.4 (same point format) with one EVLR after the points:
/// 148 header bytes inserted at 227, the offsets moved, the 64-bit count filled in.
fn to_las14(b: &[u8], compressed: bool) -> Vec<u8> {
    let grow = 375 - 227;
    let points_at = mutate::get_le(b, 96, 4) as usize;
    let count = mutate::get_le(b, 107, 4);
    let mut out = b[..227].to_vec();
    out.extend(std::iter::repeat_n(0u8, grow));
    out.extend_from_slice(&b[227..]);
    out[25] = 4;
    mutate::put_le(&mut out, 94, 2, 375);
    mutate::put_le(&mut out, 96, 4, (points_at + grow) as u64);
    mutate::put_le(&mut out, 247, 8, count);
    if compressed {
        let table = mutate::get_le(&out, points_at + grow, 8);
        mutate::put_le(&mut out, points_at + grow, 8, table + grow as u64);
    }
    let evlr_at = out.len() as u64;
    let mut evlr = vec![0u8; 60];
    evlr[2..12].copy_from_slice(b"splatbench");
    mutate::put_le(&mut evlr, 18, 2, 7);
    mutate::put_le(&mut evlr, 20, 8, 6);
    evlr.extend_from_slice(b"fuzzed");
    out.extend_from_slice(&evlr);
    mutate::put_le(&mut out, 235, 8, evlr_at);
    mutate::put_le(&mut out, 243, 4, 1);
    out
}

/// Method build parameters small enough for a 2000-point scene to get a real hierarchy.
fn build_params(kind: MethodKind) -> Vec<&'static str> {
    match kind {
        MethodKind::Lpc => vec!["m=128", "mem_mb=16"],
        MethodKind::Mwkd => vec!["fanout=4", "vbo=100"],
        _ => vec![],
    }
}

/// Builds `kind` from [`scene`] into `work/<name>`; returns the directory.
fn build(kind: MethodKind, work: &Path) -> Result<PathBuf, String> {
    let dir = work.join(kind.name());
    let cloud = scene()?;
    let params = Params::parse(&build_params(kind)).map_err(|e| e.to_string())?;
    kind.build(&cloud, &params, "statue:2000:1", &dir, &scenes::NoProgress)
        .map_err(|e| format!("building {kind}: {e}"))?;
    Ok(dir)
}

/// Every file of a build directory, by name (sorted, for a stable seed order).
fn dir_seeds(dir: &Path) -> Result<Vec<Seed>, String> {
    let mut names: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| format!("{}: {e}", dir.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.is_file())
        .collect();
    names.sort();
    names.iter().map(|p| read_seed(p)).collect()
}

/// Chunk references of an LPC or MWKD build.
fn refs(kind: MethodKind, dir: &Path) -> Result<Vec<ChunkRef>, String> {
    let e = |e: methods::MethodError| e.to_string();
    Ok(match kind {
        MethodKind::Lpc => lpc::index::read(&dir.join(lpc::INDEX_FILE))
            .map_err(e)?
            .iter()
            .map(|n| n.chunk)
            .collect(),
        _ => mwkd::index::read(&dir.join(mwkd::INDEX_FILE))
            .map_err(e)?
            .iter()
            .map(|n| n.chunk)
            .collect(),
    })
}

/// Decompressed chunks of a build (at most `most`).
fn raw_chunks(kind: MethodKind, dir: &Path, most: usize) -> Result<Vec<Seed>, String> {
    let r = refs(kind, dir)?;
    let repo = Repository::open(&dir.join(lpc::REPO_FILE)).map_err(|e| e.to_string())?;
    let step = r.len().div_ceil(most).max(1);
    r.iter()
        .enumerate()
        .step_by(step)
        .map(|(i, c)| {
            Ok(Seed {
                name: format!("chunk-{i}"),
                bytes: repo.read(c, "seed").map_err(|e| e.to_string())?,
            })
        })
        .collect()
}

/// Builds the corpus of `target`, writing what it needs under `work`.
pub fn corpus(target: Target, work: &Path) -> Result<Corpus, String> {
    std::fs::create_dir_all(work).map_err(|e| format!("{}: {e}", work.display()))?;
    let real = repo_root().join("scenes/tests/data/real");
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("seeds");
    let mut dir = None;
    let mut refs_out = Vec::new();
    let bounds = scene()?.bounds();
    let seeds = match target {
        Target::PlyAscii => ply_ascii_seeds(work)?,
        Target::PlyBinary => ply_binary_seeds(work)?,
        Target::Las => las_seeds(work, &committed)?,
        Target::Laz => laz_seeds(work, &real, &committed)?,
        Target::Pcd => [
            "ascii.pcd",
            "binary.pcd",
            "binary_compressed.pcd",
            "ascii_organized.pcd",
            "binary_compressed_organized.pcd",
        ]
        .iter()
        .map(|n| read_seed(&real.join(n)))
        .collect::<Result<_, _>>()?,
        Target::E57 => vec![read_seed(&real.join("pipeSpherical.e57"))?],
        Target::Sbc => sbc_seeds(work)?,
        Target::SceneToml => scene_toml_seeds(),
        Target::PathToml => path_toml_seeds()?,
        Target::Method(kind) => {
            let d = build(kind, work)?;
            let s = dir_seeds(&d)?;
            dir = Some(d);
            s
        }
        Target::LpcCloud => raw_chunks(MethodKind::Lpc, &build(MethodKind::Lpc, work)?, 8)?,
        Target::MwkdNode => raw_chunks(MethodKind::Mwkd, &build(MethodKind::Mwkd, work)?, 8)?,
        Target::SelfTest => vec![Seed {
            name: "selftest.bin".into(),
            bytes: Vec::new(),
        }],
        Target::Http => {
            let d = build(MethodKind::Lpc, work)?;
            let repo = read_seed(&d.join(lpc::REPO_FILE))?.bytes;
            let (s, r) = crate::http::seeds(&refs(MethodKind::Lpc, &d)?, &repo);
            refs_out = r;
            s
        }
        Target::Repo => {
            let mut s = Vec::new();
            for kind in [MethodKind::Lpc, MethodKind::Mwkd] {
                let d = build(kind, work)?;
                let mut seed = read_seed(&d.join(lpc::REPO_FILE))?;
                seed.name = format!("{kind}-repo.bin");
                s.push(seed);
                refs_out.push((refs(kind, &d)?, kind == MethodKind::Mwkd));
            }
            s
        }
    };
    Ok(Corpus {
        seeds,
        dir,
        refs: refs_out,
        bounds,
    })
}

/// A scene error as the corpus builder's error text.
fn err(e: scenes::SceneError) -> String {
    e.to_string()
}

/// ASCII PLY seeds: a cloud with attributes, a mesh, mixed element types.
fn ply_ascii_seeds(work: &Path) -> Result<Vec<Seed>, String> {
    Ok(vec![
        written(work, "attrs.ply", |p| {
            ply::write(p, &small_cloud(30, true)?, PlyFormat::Ascii)
                .map(drop)
                .map_err(err)
        })?,
        written(work, "mesh.ply", |p| {
            ply::write_mesh(p, &SQUARE, &[[0, 1, 2], [0, 2, 3]], PlyFormat::Ascii)
                .map(drop)
                .map_err(err)
        })?,
        Seed {
            name: "mixed.ply".into(),
            bytes: ASCII_MIXED.as_bytes().to_vec(),
        },
    ])
}

/// Binary PLY seeds, little and big endian: a cloud with attributes, a mesh, list properties.
fn ply_binary_seeds(work: &Path) -> Result<Vec<Seed>, String> {
    let mut s = Vec::new();
    for (f, tag) in [
        (PlyFormat::BinaryLittleEndian, "le"),
        (PlyFormat::BinaryBigEndian, "be"),
    ] {
        s.push(written(work, &format!("attrs-{tag}.ply"), |p| {
            ply::write(p, &small_cloud(30, true)?, f)
                .map(drop)
                .map_err(err)
        })?);
        s.push(written(work, &format!("mesh-{tag}.ply"), |p| {
            ply::write_mesh(p, &SQUARE, &[[0, 1, 2], [0, 2, 3]], f)
                .map(drop)
                .map_err(err)
        })?);
    }
    for be in [false, true] {
        s.push(Seed {
            name: format!("lists-{be}.ply"),
            bytes: binary_with_lists(be),
        });
    }
    Ok(s)
}

/// LAS seeds: with and without colour, a 1.4 header, and the committed format-6 file.
fn las_seeds(work: &Path, committed: &Path) -> Result<Vec<Seed>, String> {
    let c = written(work, "rgb.las", |p| {
        scenes::las::write(p, &small_cloud(40, true)?)
            .map(drop)
            .map_err(err)
    })?;
    let p = written(work, "plain.las", |p| {
        scenes::las::write(p, &small_cloud(40, false)?)
            .map(drop)
            .map_err(err)
    })?;
    let v14 = Seed {
        name: "v14.las".into(),
        bytes: to_las14(&c.bytes, false),
    };
    Ok(vec![
        c,
        p,
        v14,
        read_seed(&committed.join("las14-format6.las"))?,
    ])
}

/// LAZ seeds: a real file, ours with and without colour, a 1.4 header, the committed
/// formats 6 and 7.
fn laz_seeds(work: &Path, real: &Path, committed: &Path) -> Result<Vec<Seed>, String> {
    let c = written(work, "rgb.laz", |p| {
        scenes::las::write(p, &small_cloud(300, true)?)
            .map(drop)
            .map_err(err)
    })?;
    let v14 = Seed {
        name: "v14.laz".into(),
        bytes: to_las14(&c.bytes, true),
    };
    Ok(vec![
        read_seed(&real.join("plane.laz"))?,
        c,
        written(work, "plain.laz", |p| {
            scenes::las::write(p, &small_cloud(300, false)?)
                .map(drop)
                .map_err(err)
        })?,
        v14,
        read_seed(&committed.join("las14-format6.laz"))?,
        read_seed(&committed.join("las14-format7.laz"))?,
    ])
}

/// Column-file seeds, with and without attributes.
fn sbc_seeds(work: &Path) -> Result<Vec<Seed>, String> {
    Ok(vec![
        written(work, "attrs.sbc", |p| {
            scenes::colfile::write(p, &small_cloud(40, true)?)
                .map(drop)
                .map_err(err)
        })?,
        written(work, "plain.sbc", |p| {
            scenes::colfile::write(p, &small_cloud(40, false)?)
                .map(drop)
                .map_err(err)
        })?,
    ])
}

/// Scene `.toml` seeds: generators and files with their keys.
fn scene_toml_seeds() -> Vec<Seed> {
    [
        "generator = \"statue\"\npoints = 200\nseed = 3\n",
        "generator = \"terrain\"\npoints = 100\nkeep_attributes = true\nup = \"y\"\n",
        "file = \"scan.ply\"\nsample = 1000\nseed = 2\nup = \"z\"\n",
        "file = \"tile.laz\"\n",
        "generator = \"isosurface\"\npoints = 150\n",
    ]
    .iter()
    .enumerate()
    .map(|(i, t)| Seed {
        name: format!("scene{i}.toml"),
        bytes: t.as_bytes().to_vec(),
    })
    .collect()
}

/// Camera-path seeds: every committed keyframe file under `scenes/paths/`.
fn path_toml_seeds() -> Result<Vec<Seed>, String> {
    let paths = repo_root().join("scenes/paths");
    let mut names: Vec<PathBuf> = std::fs::read_dir(&paths)
        .map_err(|e| format!("{}: {e}", paths.display()))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|e| e == "toml"))
        .collect();
    names.sort();
    let s = names
        .iter()
        .map(|p| read_seed(p))
        .collect::<Result<Vec<_>, _>>()?;
    if s.is_empty() {
        return Err(format!("no .toml camera paths in {}", paths.display()));
    }
    Ok(s)
}
