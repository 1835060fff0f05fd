//! Driving the decoder under test with an input.

use std::collections::HashSet;
use std::path::Path;

use methods::store::{ChunkRef, Repository};
use methods::{Feedback, LodMethod, MethodKind, Target as Aim, lpc, mwkd};
use scenes::paths::PathSpec;
use scenes::ply::{self, PlyOptions};
use scenes::{Aabb, View};

use crate::mutate;

use crate::corpus::{Corpus, Input};
use crate::inputs::resealed_refs;
use crate::targets::Target;

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
