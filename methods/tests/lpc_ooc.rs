//! LPC's streamed levels simulated in passes (`lpc/multilevel.rs`): byte identity with the
//! in-core build over several streamed levels and across groups, temporary-file traffic
//! counted exactly, a damaged temporary file named in the error.
#![allow(clippy::unwrap_used)]

use std::path::Path;
use std::sync::Mutex;

use methods::lpc::index::{self, NONE, Node};
use methods::lpc::{self, LpcParams, build};
use methods::{BuildStats, MethodError, Params};
use scenes::PointCloud;
use scenes::generators::Generator;

const P: [&str; 4] = ["m=256", "spacing=0.004", "nn_spacing=0.001", "seed=9"];

fn build_with(
    cloud: &PointCloud,
    p: &[&str],
    dir: &Path,
    mem: u64,
    progress: &dyn scenes::Progress,
) -> Result<BuildStats, MethodError> {
    std::fs::create_dir_all(dir).unwrap();
    let lp = LpcParams::from_params(&Params::parse(p).unwrap()).unwrap();
    build::build_with_budget(cloud, &lp, "test", dir, progress, mem)
}

/// Builds with `mem` bytes; returns the index, `index.bin` + `repo.bin` and `temp_bytes`.
fn build_files(cloud: &PointCloud, p: &[&str], dir: &Path, mem: u64) -> (Vec<Node>, Vec<u8>, u64) {
    let stats = build_with(cloud, p, dir, mem, &scenes::NoProgress).unwrap();
    for e in std::fs::read_dir(dir).unwrap() {
        let name = e.unwrap().file_name().into_string().unwrap();
        assert!(!name.ends_with(".tmp"), "left {name}");
    }
    let mut bytes = std::fs::read(dir.join(lpc::INDEX_FILE)).unwrap();
    bytes.extend(std::fs::read(dir.join(lpc::REPO_FILE)).unwrap());
    let nodes = index::read(&dir.join(lpc::INDEX_FILE)).unwrap();
    (nodes, bytes, stats.extra["temp_bytes"].as_u64().unwrap())
}

/// The nodes streamed with budget `mem` (their subtree does not fit, 40 bytes a sample) and
/// the in-core roots (they fit, their parent does not).
struct Streamed {
    streamed: Vec<usize>,
    in_core_roots: Vec<usize>,
    /// Levels holding a streamed node.
    levels: u32,
}

fn streamed(nodes: &[Node], mem: u64) -> Streamed {
    let fits = |i: usize| nodes[i].subtree * build::IN_CORE_BYTES_PER_SAMPLE <= mem;
    let mut parent = vec![NONE; nodes.len()];
    for (i, x) in nodes.iter().enumerate() {
        for c in x.child_ids() {
            parent[c as usize] = i as u32;
        }
    }
    let streamed: Vec<usize> = (0..nodes.len()).filter(|&i| !fits(i)).collect();
    let in_core_roots = (0..nodes.len())
        .filter(|&i| fits(i) && parent[i] != NONE && !fits(parent[i] as usize))
        .collect();
    let levels = streamed
        .iter()
        .map(|&i| nodes[i].level + 1)
        .max()
        .unwrap_or(0);
    Streamed {
        streamed,
        in_core_roots,
        levels,
    }
}

fn clouds() -> Vec<(&'static str, PointCloud)> {
    vec![
        ("statue", Generator::Statue.generate(60_000, 3).unwrap()),
        ("terrain", Generator::Terrain.generate(60_000, 4).unwrap()),
    ]
}

/// 4 000 samples per in-core subtree: 5 streamed levels on `statue`, 9 on `terrain` (its
/// uneven density makes uneven splits), past [`build::MAX_LEVELS`]: a second group starts.
const SMALL: u64 = 4_000 * 40;
/// 6 000 samples per in-core subtree: 4 streamed levels on `statue`, 7 on `terrain`, one
/// group each.
const ONE_GROUP: u64 = 6_000 * 40;

#[test]
fn streamed_levels_equal_the_in_core_build_byte_for_byte() {
    for (name, c) in clouds() {
        let d1 = tempfile::tempdir().unwrap();
        let (_, want, _) = build_files(&c, &P, d1.path(), 1 << 30);
        for mem in [SMALL, ONE_GROUP] {
            let d2 = tempfile::tempdir().unwrap();
            let (nodes, got, _) = build_files(&c, &P, d2.path(), mem);
            let s = streamed(&nodes, mem);
            assert!(s.levels >= 3, "{name}: {} streamed levels", s.levels);
            assert!(want == got, "{name}, {mem} B: index.bin / repo.bin differ");
        }
    }
}

#[test]
fn groups_past_the_limits_equal_the_in_core_build() {
    // M = 16 and 100 samples per in-core subtree: about 11 streamed levels and more than
    // MAX_FILES frontier nodes, so groups start again from frontier files.
    let c = Generator::Statue.generate(200_000, 5).unwrap();
    let p = ["m=16", "spacing=0.004", "nn_spacing=0.001", "seed=3"];
    let mem = 100 * 40;
    let d1 = tempfile::tempdir().unwrap();
    let d2 = tempfile::tempdir().unwrap();
    let (_, want, _) = build_files(&c, &p, d1.path(), 1 << 30);
    let (nodes, got, temp) = build_files(&c, &p, d2.path(), mem);
    let s = streamed(&nodes, mem);
    assert!(s.levels > build::MAX_LEVELS, "{} streamed levels", s.levels);
    assert!(s.in_core_roots.len() > build::MAX_FILES);
    assert!(want == got, "index.bin / repo.bin differ");
    // Every sample outside the streamed clouds is written at least once, and some twice
    // (the groups that start again); far less than once per streamed level.
    let n = 200_000u64;
    let once: u64 = s.in_core_roots.iter().map(|&i| nodes[i].subtree).sum();
    assert!(temp > 20 * (n + once), "{temp}");
    assert!(temp <= 20 * (n + 3 * n), "{temp}");
}

#[test]
fn temp_bytes_count_each_sample_once() {
    // Below no group limit (fewer streamed levels than MAX_LEVELS, fewer streamed and
    // in-core-root nodes together than MAX_FILES and MAX_SIMULATED), the temporary files are
    // the cloud file (20 bytes × N), one file per in-core subtree whose parent is streamed
    // (each of its samples written once, 20 bytes) and, once more, the file of each streamed
    // child of a node of the root's group that was speculated (its children written in the
    // pass that learns them, since an even split of it would fit) but does not fit: a new
    // group starts from that file. The samples of the streamed levels between are never
    // written.
    let m = 256u64;
    for (name, c) in clouds() {
        let d = tempfile::tempdir().unwrap();
        let (nodes, _, temp) = build_files(&c, &P, d.path(), ONE_GROUP);
        let s = streamed(&nodes, ONE_GROUP);
        assert!(
            s.levels >= 3 && s.levels <= build::MAX_LEVELS,
            "{name}: {}",
            s.levels
        );
        let nodes_in_group = s.streamed.len() + s.in_core_roots.len();
        assert!(
            nodes_in_group <= build::MAX_FILES.min(build::MAX_SIMULATED),
            "{name}: {nodes_in_group}"
        );
        let fits = |n: u64| n * build::IN_CORE_BYTES_PER_SAMPLE <= ONE_GROUP;
        let n = c.len() as u64;
        let frontier: u64 = s.in_core_roots.iter().map(|&i| nodes[i].subtree).sum();
        let streamed_clouds: u64 = s.streamed.iter().map(|&i| nodes[i].points as u64).sum();
        assert_eq!(frontier, n - streamed_clouds, "{name}");
        // The root's group: the root and the streamed children of its unspeculated nodes.
        let (mut stack, mut again) = (vec![0usize], 0u64);
        while let Some(i) = stack.pop() {
            let spec = fits((nodes[i].subtree - m).div_ceil(2));
            for ch in nodes[i].child_ids().map(|c| c as usize) {
                match (fits(nodes[ch].subtree), spec) {
                    (true, _) => {}
                    (false, true) => again += nodes[ch].subtree,
                    (false, false) => stack.push(ch),
                }
            }
        }
        eprintln!("{name}: {frontier} + {again} samples written");
        assert_eq!(temp, 20 * (n + frontier + again), "{name}");
        // At most twice per sample to frontier files, plus the cloud file.
        assert!(temp <= 3 * 20 * n, "{name}");
    }
}

/// Truncates every frontier file to half when the in-core phase begins after a group.
struct Truncate<'a> {
    dir: &'a Path,
    done: Mutex<Vec<String>>,
}

impl scenes::Progress for Truncate<'_> {
    fn start(&self, what: &str, _: u64) {
        if what != "lpc: partition" {
            return;
        }
        let mut done = self.done.lock().unwrap();
        for e in std::fs::read_dir(self.dir).unwrap() {
            let name = e.unwrap().file_name().into_string().unwrap();
            if name.starts_with("lpc-part-") && !done.contains(&name) {
                let path = self.dir.join(&name);
                let len = std::fs::metadata(&path).unwrap().len();
                let f = std::fs::OpenOptions::new().write(true).open(&path).unwrap();
                f.set_len(len / 2).unwrap();
                done.push(name);
            }
        }
    }
    fn inc(&self, _: u64) {}
    fn finish(&self) {}
}

#[test]
fn a_short_temporary_file_is_an_error_naming_it() {
    let c = Generator::Statue.generate(60_000, 3).unwrap();
    // Frontier files read in core (they fit), then frontier files that start a group.
    for (p, mem) in [
        (&P[..], SMALL),
        (&["m=16", "spacing=0.004", "nn_spacing=0.001"][..], 100 * 40),
    ] {
        let d = tempfile::tempdir().unwrap();
        let t = Truncate {
            dir: d.path(),
            done: Mutex::new(Vec::new()),
        };
        let e = build_with(&c, p, d.path(), mem, &t)
            .unwrap_err()
            .to_string();
        let done = t.done.lock().unwrap();
        assert!(!done.is_empty());
        assert!(
            done.iter()
                .any(|f| e.contains(&d.path().join(f).display().to_string())),
            "{e}"
        );
        // The drop guard removed the temporary files.
        for e in std::fs::read_dir(d.path()).unwrap() {
            let name = e.unwrap().file_name().into_string().unwrap();
            assert!(!name.ends_with(".tmp"), "left {name}");
        }
    }
}

#[test]
fn a_budget_below_one_cloud_equals_the_in_core_build() {
    // 100 samples per in-core subtree with M = 256: leaves of 101–255 samples are streamed
    // (simulated nodes without children).
    let c = Generator::Statue.generate(5_000, 7).unwrap();
    let d1 = tempfile::tempdir().unwrap();
    let d2 = tempfile::tempdir().unwrap();
    let (_, want, _) = build_files(&c, &P, d1.path(), 1 << 30);
    let (nodes, got, temp) = build_files(&c, &P, d2.path(), 100 * 40);
    let s = streamed(&nodes, 100 * 40);
    assert!(s.streamed.iter().any(|&i| nodes[i].is_leaf()));
    assert!(want == got, "index.bin / repo.bin differ");
    // No in-core subtree: only the cloud file, unless a group passed its limits.
    assert!(temp >= 20 * 5_000, "{temp}");
}
