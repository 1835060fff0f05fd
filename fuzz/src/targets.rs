//! The fuzz targets: what each one's seed files are, how an input is made from them, and how
//! the decoder under test is driven with it.

use std::collections::HashSet;
use std::path::{Path, PathBuf};

use methods::store::{ChunkRef, Repository};
use methods::{Feedback, LodMethod, MethodKind, Params, Target as Aim, lpc, mwkd};
use scenes::generators::Generator;
use scenes::paths::PathSpec;
use scenes::ply::{self, PlyFormat, PlyOptions};
use scenes::rng::Pcg32;
use scenes::{Aabb, PointCloud, View};

use crate::mutate;

/// Every target, in the order `all` runs them.
pub const ALL: [Target; 18] = [
    Target::PlyAscii,
    Target::PlyBinary,
    Target::Las,
    Target::Laz,
    Target::Pcd,
    Target::E57,
    Target::Sbc,
    Target::SceneToml,
    Target::PathToml,
    Target::Method(MethodKind::Full),
    Target::Method(MethodKind::Qsplat),
    Target::Method(MethodKind::Spt),
    Target::Method(MethodKind::Lpc),
    Target::Method(MethodKind::Mwkd),
    Target::LpcCloud,
    Target::MwkdNode,
    Target::Repo,
    Target::Http,
];

/// A fuzz target.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Target {
    /// `scenes::ply::read` on ascii PLY files.
    PlyAscii,
    /// `scenes::ply::read` on binary PLY files (both byte orders).
    PlyBinary,
    /// `scenes::las::read` on uncompressed LAS (1.2 and 1.4).
    Las,
    /// `scenes::las::read` on LAZ (pointwise and layered chunks).
    Laz,
    /// `scenes::pcd::read` on PCD files (ascii, binary, binary_compressed).
    Pcd,
    /// `scenes::e57::read` on E57 files (the `e57` crate).
    E57,
    /// `scenes::colfile::open` on column files.
    Sbc,
    /// `SceneSpec::parse` on scene `.toml` files.
    SceneToml,
    /// `Keyframes::from_toml` on camera path files, then the cameras of the path.
    PathToml,
    /// A method's build directory: one file mutated, then `MethodKind::open` and frames.
    Method(MethodKind),
    /// `lpc::cloud::decode` on decompressed LPC clouds.
    LpcCloud,
    /// `mwkd::codec::decode` on decompressed MWKD nodes.
    MwkdNode,
    /// `store::Repository::read` (checksum, LZO) then the method's decoder.
    Repo,
    /// `store::http::RemoteFile::get_range` on a mutated HTTP answer, then the chunk
    /// ([`crate::http`]).
    Http,
    /// Not a decoder: checks the supervision itself (a panic at input 3, an abort at 5, a
    /// panic on another thread at 6, a hang at 7). Not part of `all`.
    SelfTest,
}

impl Target {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Target::PlyAscii => "ply-ascii",
            Target::PlyBinary => "ply-binary",
            Target::Las => "las",
            Target::Laz => "laz",
            Target::Pcd => "pcd",
            Target::E57 => "e57",
            Target::Sbc => "sbc",
            Target::SceneToml => "scene-toml",
            Target::PathToml => "path-toml",
            Target::Method(k) => k.name(),
            Target::LpcCloud => "lpc-cloud",
            Target::MwkdNode => "mwkd-node",
            Target::Repo => "repo",
            Target::Http => "http",
            Target::SelfTest => "selftest",
        }
    }

    /// The target called `name`.
    pub fn from_name(name: &str) -> Option<Target> {
        ALL.iter()
            .copied()
            .chain([Target::SelfTest])
            .find(|t| t.name() == name)
    }

    /// What the target covers (for `--list` and the README).
    pub fn describe(self) -> &'static str {
        match self {
            Target::PlyAscii => "PLY reader, ascii bodies: header lines, counts, tokens, lines",
            Target::PlyBinary => {
                "PLY reader, binary LE/BE: header counts and types, records, lists"
            }
            Target::Las => "LAS reader (las crate): header fields, VLRs, EVLRs, point records",
            Target::Laz => "LAZ reader (laz crate): laszip VLR, chunk table, chunks, layers",
            Target::Pcd => "PCD reader: header lines, ascii/binary/LZF-compressed bodies",
            Target::E57 => "E57 reader (e57 crate): pages and checksums, XML, binary sections",
            Target::Sbc => "column file (.sbc) open: header fields (checksum resealed), columns",
            Target::SceneToml => "scene .toml parsing (SceneSpec::parse), small generators loaded",
            Target::PathToml => "keyframe path .toml parsing and validation, cameras evaluated",
            Target::Method(_) => {
                "a build directory: one file mutated (checksums resealed), open + frames + chunks"
            }
            Target::LpcCloud => "LPC cloud decoder (lpc::cloud::decode) on raw chunk bytes",
            Target::MwkdNode => "MWKD node decoder (mwkd::codec::decode) on raw chunk bytes",
            Target::Repo => "repository chunks: bounds, checksum (resealed), LZO, then decode",
            Target::Http => {
                "HTTP range answers (ureq client, our checks), then LZO and the LPC decoder"
            }
            Target::SelfTest => "the supervisor itself: a panic, an abort, a thread panic, a hang",
        }
    }
}

/// One seed file.
#[derive(Debug, Clone)]
pub struct Seed {
    /// Its name (the file's name in a build directory; the extension matters elsewhere).
    pub name: String,
    /// Its bytes.
    pub bytes: Vec<u8>,
}

/// A target's seeds and what its decoder needs beside the input.
pub struct Corpus {
    /// The seed files.
    pub seeds: Vec<Seed>,
    /// Method targets: the build directory the seeds were read from.
    pub dir: Option<PathBuf>,
    /// `repo`: each seed repository's chunk references, and whether it is MWKD's.
    pub refs: Vec<(Vec<ChunkRef>, bool)>,
    /// Bounds of the scene, for views (method and path targets).
    pub bounds: Aabb,
}

/// One input: the seed it came from and its (mutated) bytes.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Input {
    /// Index into [`Corpus::seeds`].
    pub seed: usize,
    /// The bytes to decode.
    pub bytes: Vec<u8>,
}

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
    let err = |e: scenes::SceneError| e.to_string();
    let real = repo_root().join("scenes/tests/data/real");
    let committed = Path::new(env!("CARGO_MANIFEST_DIR")).join("seeds");
    let mut dir = None;
    let mut refs_out = Vec::new();
    let bounds = scene()?.bounds();
    let seeds = match target {
        Target::PlyAscii => vec![
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
        ],
        Target::PlyBinary => {
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
            s
        }
        Target::Las => {
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
            vec![c, p, v14, read_seed(&committed.join("las14-format6.las"))?]
        }
        Target::Laz => {
            let c = written(work, "rgb.laz", |p| {
                scenes::las::write(p, &small_cloud(300, true)?)
                    .map(drop)
                    .map_err(err)
            })?;
            let v14 = Seed {
                name: "v14.laz".into(),
                bytes: to_las14(&c.bytes, true),
            };
            vec![
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
            ]
        }
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
        Target::Sbc => vec![
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
        ],
        Target::SceneToml => [
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
        .collect(),
        Target::PathToml => {
            let mut s = Vec::new();
            let paths = repo_root().join("scenes/paths");
            let mut names: Vec<PathBuf> = std::fs::read_dir(&paths)
                .map_err(|e| format!("{}: {e}", paths.display()))?
                .filter_map(|e| e.ok().map(|e| e.path()))
                .filter(|p| p.extension().is_some_and(|e| e == "toml"))
                .collect();
            names.sort();
            for p in names {
                s.push(read_seed(&p)?);
            }
            if s.is_empty() {
                return Err(format!("no .toml camera paths in {}", paths.display()));
            }
            s
        }
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

// ---------------------------------------------------------------------------------------------
// Inputs
// ---------------------------------------------------------------------------------------------

/// Recomputes the checksums a format keeps over bytes a mutation may have changed, so the
/// input reaches the decoder behind the check (a mismatch would stop nearly every input).
fn reseal(name: &str, b: &mut [u8]) {
    let fnv = scenes::hash::fnv1a64;
    if name.ends_with(".sbc") && b.len() >= 128 {
        let sum = fnv(&b[..120]);
        mutate::put_le(b, 120, 8, sum);
    } else if name == "tree.qs" && b.len() >= 80 {
        let sum = scenes::hash::Fnv64::default()
            .write(&b[..72])
            .write(&b[80..])
            .finish();
        mutate::put_le(b, 72, 8, sum);
    } else if (name == "lod.bin" || name == "nodes.bin") && b.len() >= 24 {
        let sum = fnv(&b[24..]);
        mutate::put_le(b, 16, 8, sum);
    } else if name.ends_with(".e57") {
        mutate::reseal_e57(b);
    } else if name == "index.bin" && b.len() >= 24 {
        let sum = methods::store::checksum(&b[24..]);
        mutate::put_le(b, 16, 8, sum);
    }
}

/// Chunk references with checksums recomputed over `repo`'s bytes where they lie inside.
fn resealed_refs(refs: &[ChunkRef], repo: &[u8]) -> Vec<ChunkRef> {
    refs.iter()
        .map(|r| {
            let mut r = *r;
            let start = r.offset as usize;
            if let Some(s) = start
                .checked_add(r.stored as usize)
                .and_then(|end| repo.get(start..end))
            {
                r.checksum = methods::store::checksum(s);
            }
            r
        })
        .collect()
}

/// Input `i` of the stream `seed`: a seed file and 1–4 stacked mutations, drawn from
/// `Pcg32::stream(seed, i)` alone, so any input can be made again from `(seed, i)`.
pub fn input(target: Target, corpus: &Corpus, seed: u64, i: u64) -> Input {
    if target == Target::SelfTest {
        return Input {
            seed: 0,
            bytes: i.to_le_bytes().to_vec(),
        };
    }
    let mut r = Pcg32::stream(seed, i);
    let n = corpus.seeds.len();
    let pick = mutate::below(&mut r, n);
    let other = mutate::below(&mut r, n);
    let s = &corpus.seeds[pick];
    let mut b = s.bytes.clone();
    let aware = |r: &mut Pcg32, b: &mut Vec<u8>| match target {
        Target::PlyAscii | Target::PlyBinary => mutate::ply(r, b),
        Target::Pcd => mutate::pcd(r, b),
        Target::Las | Target::Laz => mutate::las(r, b),
        Target::SceneToml | Target::PathToml => mutate::toml(r, b),
        Target::Method(_) if s.name.ends_with(".json") => mutate::toml(r, b),
        _ => {}
    };
    for _ in 0..1 + r.below(4) {
        if r.below(2) == 0 {
            aware(&mut r, &mut b);
        } else {
            mutate::bytes(&mut r, &mut b, &corpus.seeds[other].bytes);
        }
    }
    if r.below(8) != 0 {
        reseal(&s.name, &mut b);
    }
    Input {
        seed: pick,
        bytes: b,
    }
}

// ---------------------------------------------------------------------------------------------
// Execution
// ---------------------------------------------------------------------------------------------

/// Frame `i` of 8 of a built-in path around `b`, 160 × 120 pixels.
fn view(path: &PathSpec, i: usize, b: &Aabb) -> View {
    View {
        camera: path.camera(i, 8, b),
        width: 160,
        height: 120,
    }
}

/// Drives an opened method: a few views and targets, frames until nothing is missing (at
/// most 20 each), every drawn chunk decoded and the drawn points counted.
fn drive(m: &mut dyn LodMethod, bounds: &Aabb) -> Result<(), String> {
    let views = [
        view(&PathSpec::Orbit, 1, bounds),
        view(&PathSpec::Zoom, 6, bounds),
    ];
    let mut cached = HashSet::new();
    for v in &views {
        for aim in [Aim::Tolerance(2.0), Aim::Budget(300)] {
            for frame in 0..20u64 {
                let fb = Feedback {
                    frame,
                    cached: cached.clone(),
                    ..Feedback::default()
                };
                let list = m.frame(v, aim, &fb).map_err(|e| e.to_string())?;
                for item in &list.items {
                    if let Some(methods::Cached { id, .. }) = item.cached() {
                        m.chunk(id).map_err(|e| e.to_string())?;
                        cached.insert(id);
                    }
                }
                m.drawn_points(v, &list).map_err(|e| e.to_string())?;
                if list.fetch.is_empty() {
                    break;
                }
                std::thread::sleep(std::time::Duration::from_millis(1));
            }
        }
    }
    let _ = m.stats();
    Ok(())
}

/// Runs `input` through the target's decoder with files under `scratch` (a fresh directory
/// per call is made and removed). `Err` is the decoder's error: the expected outcome for
/// most inputs, not a finding.
pub fn execute(
    target: Target,
    corpus: &Corpus,
    input: &Input,
    scratch: &Path,
) -> Result<(), String> {
    std::fs::create_dir_all(scratch).map_err(|e| format!("{}: {e}", scratch.display()))?;
    let seed = &corpus.seeds[input.seed];
    let ext = Path::new(&seed.name)
        .extension()
        .map(|e| e.to_string_lossy().into_owned())
        .unwrap_or_else(|| "bin".into());
    let file = scratch.join(format!("input.{ext}"));
    let write =
        |p: &Path, b: &[u8]| std::fs::write(p, b).map_err(|e| format!("{}: {e}", p.display()));
    let out = match target {
        Target::PlyAscii | Target::PlyBinary => {
            write(&file, &input.bytes)?;
            let plain = ply::read(&file, &PlyOptions::default()).map(drop);
            // Resampling too (meshes only; a cloud's error here is expected and not counted).
            let _ = ply::read(
                &file,
                &PlyOptions {
                    sample: Some(64),
                    seed: 1,
                },
            );
            plain.map_err(|e| e.to_string())
        }
        Target::Las | Target::Laz => {
            write(&file, &input.bytes)?;
            scenes::las::read(&file)
                .map(drop)
                .map_err(|e| e.to_string())
        }
        Target::Pcd => {
            write(&file, &input.bytes)?;
            scenes::pcd::read(&file)
                .map(drop)
                .map_err(|e| e.to_string())
        }
        Target::E57 => {
            write(&file, &input.bytes)?;
            scenes::e57::read(&file)
                .map(drop)
                .map_err(|e| e.to_string())
        }
        Target::Sbc => {
            write(&file, &input.bytes)?;
            scenes::colfile::open(&file)
                .map(|c| {
                    // Touch every column.
                    let s: f32 = c.positions().iter().map(|p| p[0]).sum();
                    let _ = (s, c.normals().map(<[_]>::len), c.colors().map(<[_]>::len));
                    let _ = c.radii().map(|r| r.iter().sum::<f32>());
                })
                .map_err(|e| e.to_string())
        }
        Target::SceneToml => {
            write(&file, &input.bytes)?;
            let spec = scenes::SceneSpec::parse(&file.to_string_lossy(), None, 1)
                .map_err(|e| e.to_string())?;
            let _ = spec.label();
            match &spec.source {
                scenes::spec::SceneSource::Generator { points, .. } if *points <= 5000 => spec
                    .load(None, &scenes::NoProgress)
                    .map(drop)
                    .map_err(|e| e.to_string()),
                _ => Ok(()),
            }
        }
        Target::PathToml => {
            let text = String::from_utf8_lossy(&input.bytes);
            let k =
                scenes::paths::Keyframes::from_toml(&text, "fuzz").map_err(|e| e.to_string())?;
            let cams = scenes::paths::PathSpec::Keyframes(k).cameras(24, &corpus.bounds);
            let _ = cams.iter().map(|c| c.fov_y).sum::<f32>();
            Ok(())
        }
        Target::Method(_) => {
            let Some(src) = &corpus.dir else {
                return Err("no build directory".into());
            };
            let dir = scratch.join("build");
            std::fs::create_dir_all(&dir).map_err(|e| e.to_string())?;
            for s in &corpus.seeds {
                let bytes = if s.name == seed.name {
                    &input.bytes
                } else {
                    &s.bytes
                };
                write(&dir.join(&s.name), bytes)?;
            }
            // A mutated repository still has to match the index's checksums to be decoded.
            if seed.name == lpc::REPO_FILE {
                let kind =
                    MethodKind::from_name(src.file_name().and_then(|n| n.to_str()).unwrap_or(""));
                reseal_index(kind.ok(), &dir, &input.bytes)?;
            }
            let r = match MethodKind::open(&dir) {
                Ok(mut m) => drive(m.as_mut(), &corpus.bounds),
                Err(e) => Err(e.to_string()),
            };
            let _ = std::fs::remove_dir_all(&dir);
            r
        }
        Target::SelfTest => self_test(&input.bytes),
        Target::LpcCloud => lpc::cloud::decode(0, &input.bytes)
            .map(drop)
            .map_err(|e| e.to_string()),
        Target::MwkdNode => mwkd::codec::decode(0, &input.bytes)
            .map(drop)
            .map_err(|e| e.to_string()),
        Target::Http => crate::http::run(&input.bytes, &corpus.refs[input.seed].0[0]),
        Target::Repo => {
            write(&file, &input.bytes)?;
            let (refs, is_mwkd) = &corpus.refs[input.seed];
            let refs = resealed_refs(refs, &input.bytes);
            let repo = Repository::open(&file).map_err(|e| e.to_string())?;
            let mut first = None;
            for (i, r) in refs.iter().enumerate() {
                let res = repo.read(r, &format!("chunk {i}")).and_then(|raw| {
                    let id = i as u32;
                    if *is_mwkd {
                        mwkd::codec::decode(id, &raw).map(drop)
                    } else {
                        lpc::cloud::decode(id, &raw).map(drop)
                    }
                });
                if let Err(e) = res {
                    first.get_or_insert(e.to_string());
                }
            }
            first.map_or(Ok(()), Err)
        }
    };
    let _ = std::fs::remove_file(&file);
    out
}

/// Rewrites a build's `index.bin` so its chunk checksums match `repo` (LPC and MWKD).
fn reseal_index(kind: Option<MethodKind>, dir: &Path, repo: &[u8]) -> Result<(), String> {
    let e = |e: methods::MethodError| e.to_string();
    let index = dir.join(lpc::INDEX_FILE);
    match kind {
        Some(MethodKind::Lpc) => {
            let mut nodes = lpc::index::read(&index).map_err(e)?;
            let refs: Vec<ChunkRef> = nodes.iter().map(|n| n.chunk).collect();
            for (n, r) in nodes.iter_mut().zip(resealed_refs(&refs, repo)) {
                n.chunk = r;
            }
            lpc::index::write(&index, &nodes).map_err(e)?;
        }
        Some(MethodKind::Mwkd) => {
            let mut nodes = mwkd::index::read(&index).map_err(e)?;
            let refs: Vec<ChunkRef> = nodes.iter().map(|n| n.chunk).collect();
            for (n, r) in nodes.iter_mut().zip(resealed_refs(&refs, repo)) {
                n.chunk = r;
            }
            mwkd::index::write(&index, &nodes).map_err(e)?;
        }
        _ => {}
    }
    Ok(())
}

/// [`Target::SelfTest`]'s "decoder": misbehaves on purpose at fixed inputs.
fn self_test(bytes: &[u8]) -> Result<(), String> {
    match mutate::get_le(bytes, 0, 8) {
        3 => panic!("selftest: a panic"),
        5 => {
            // 8 GiB: more than the child's default 4 GiB address space, less than what the
            // kernel would refuse on its own, so this checks that the limit is in force.
            let v: Vec<u8> = Vec::with_capacity(std::hint::black_box(8 << 30));
            Err(format!("allocated {} bytes", v.capacity()))
        }
        6 => {
            let t = std::thread::Builder::new()
                .name("selftest-loader".into())
                .spawn(|| panic!("selftest: a panic on a loader thread"))
                .map_err(|e| e.to_string())?;
            let _ = t.join();
            Ok(())
        }
        7 => {
            std::thread::sleep(std::time::Duration::from_secs(3600));
            Ok(())
        }
        _ => Err("selftest: an ordinary decoder error".into()),
    }
}
