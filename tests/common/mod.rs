//! What the test files share: the binary, the check for a clean failure, a run's config.
#![allow(clippy::unwrap_used, dead_code)]

use assert_cmd::Command;

/// The `splatbench` binary.
pub fn bin() -> Command {
    Command::cargo_bin("splatbench").unwrap()
}

/// Runs `cmd`, which must fail cleanly: a non-zero exit, no panic, and `needle` in its stderr.
pub fn fails(cmd: &mut Command, needle: &str) {
    let out = cmd.output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{cmd:?} should fail: {err}");
    assert!(!err.contains("panicked"), "{cmd:?} panicked: {err}");
    assert!(
        err.contains(needle),
        "{cmd:?}: expected '{needle}' in: {err}"
    );
}

/// Runs every line of the jobs file `jobs` as `xargs -P 2 … sh -c` would (two at a time, as
/// a scheduler might); returns the parts' directories under `out/parts/`, sorted.
pub fn run_jobs(jobs: &std::path::Path, out: &std::path::Path) -> Vec<std::path::PathBuf> {
    let o = std::process::Command::new("xargs")
        .args(["-P", "2", "-d", "\n", "-n", "1", "sh", "-c"])
        .stdin(std::fs::File::open(jobs).unwrap())
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let mut parts: Vec<std::path::PathBuf> = std::fs::read_dir(out.join("parts"))
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    parts.sort();
    parts
}

/// A CSV file's rows, each column by name.
pub fn read_csv(path: &std::path::Path) -> Vec<std::collections::BTreeMap<String, String>> {
    let mut rd = csv::Reader::from_path(path).unwrap();
    let h = rd.headers().unwrap().clone();
    rd.records()
        .map(|r| {
            h.iter()
                .zip(r.unwrap().iter())
                .map(|(k, v)| (k.to_string(), v.to_string()))
                .collect()
        })
        .collect()
}

/// A `splatbench serve` process, killed when dropped (however the test ends).
pub struct Serving(pub std::process::Child);

impl Drop for Serving {
    fn drop(&mut self) {
        let _ = self.0.kill();
        let _ = self.0.wait();
    }
}

/// Starts `splatbench serve DIR --addr ADDR` with `extra` flags; returns the process and the
/// URL its first line of stdout announces ("… at http://HOST:PORT/").
pub fn serve(dir: &std::path::Path, addr: &str, extra: &[&str]) -> (Serving, String) {
    use std::io::BufRead;
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_splatbench"))
        .args(["serve", dir.to_str().unwrap(), "--addr", addr])
        .args(extra)
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let mut first = String::new();
    std::io::BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut first)
        .unwrap();
    let url = first
        .trim()
        .split(" at ")
        .nth(1)
        .unwrap_or_else(|| panic!("first line {first:?}"))
        .to_string();
    (Serving(child), url)
}

/// Runs a command that must fail cleanly: exit 1, `Error:` naming `needle`, no panic.
pub fn fails_with(args: &[&str], needle: &str) {
    fails(bin().args(args), needle);
}

pub fn have_gpu(test: &str) -> bool {
    harness::gpu::gpu_for_test(test).is_some()
}

pub fn csv_table(path: &std::path::Path) -> (Vec<String>, Vec<csv::StringRecord>) {
    let mut r = csv::Reader::from_path(path).unwrap();
    let h = r.headers().unwrap().iter().map(String::from).collect();
    let rows = r.records().map(|r| r.unwrap()).collect();
    (h, rows)
}

pub fn write_file(dir: &std::path::Path, name: &str, bytes: &[u8]) -> String {
    let p = dir.join(name);
    std::fs::write(&p, bytes).unwrap();
    p.to_string_lossy().into_owned()
}

/// `params` with one frame of simulated loader latency (`delay_frames=1`) for a method that
/// loads its data asynchronously. With none (the default) a frame holds whatever the loader
/// thread happened to decode in time, which differs between a loaded machine and an idle one
/// (voxel's terrain frame 0: 9.9 % holes against 3.05 %); with one frame the loader waits for
/// what is due, so every frame's loaded set is the same on any machine.
pub fn with_exact_loading<'a>(method: methods::MethodKind, params: &[&'a str]) -> Vec<&'a str> {
    let mut out = params.to_vec();
    if method.runtime_params().contains(&"delay_frames") {
        out.push("delay_frames=1");
    }
    out
}

/// A run at 1 px with metrics, a square kernel, a 64 MiB GPU cache and seed 1, building into
/// `dir/name` (scene cache in `dir/cache`); tests override fields with `..config(…)`.
#[allow(clippy::too_many_arguments)]
pub fn config(
    method: methods::MethodKind,
    params: &[&str],
    scene: &str,
    path: &str,
    frames: usize,
    size: u32,
    dir: &std::path::Path,
    name: &str,
) -> harness::runner::RunConfig {
    harness::runner::RunConfig {
        method,
        params: methods::Params::parse(params).unwrap(),
        scene: scenes::SceneSpec::parse(scene, None, 1).unwrap(),
        path: scenes::paths::PathSpec::parse(path).unwrap(),
        frames,
        target: methods::Target::tolerance(1.0).unwrap(),
        render: harness::render::RenderSettings {
            width: size,
            height: size,
            kernel: harness::render::Kernel::Square,
            cache_bytes: 64 << 20,
            shade: Default::default(),
            raster: Default::default(),
        },
        seed: 1,
        save_images: false,
        metrics: true,
        out: dir.join(name),
        cache: dir.join("cache"),
        build_dir: None,
        build_url: None,
        allow_missing_chunks: false,
        reference_kernel: None,
        reference_raster: None,
    }
}

/// Reads `column` of every row of `dir/frames.csv`.
pub fn column(dir: &std::path::Path, column: &str) -> Vec<f64> {
    let mut r = csv::Reader::from_path(dir.join("frames.csv")).unwrap();
    let h = r.headers().unwrap().clone();
    let col = h
        .iter()
        .position(|c| c == column)
        .unwrap_or_else(|| panic!("no column {column}"));
    r.records()
        .map(|row| row.unwrap()[col].parse().unwrap())
        .collect()
}

/// The repository's root (the root package's manifest directory).
pub fn root() -> std::path::PathBuf {
    std::path::PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// A minimal valid reproduction spec (`id = "t"`, one scene, one build measure, one row) that
/// the reproduce tests edit.
pub const SPEC_GOOD: &str = r#"
id = "t"
paper = "P"
title = "T"
source = "S"

[scenes.s]
generator = "statue"
points = { quick = 2000, full = 3000 }

[[measure]]
id = "b"
kind = "build"
method = "qsplat"
scene = "s"

[[row]]
what = "w"
paper = 4
ours = "b.bytes_per_node"
rule = "exact"
"#;
