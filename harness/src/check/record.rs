//! What a baseline keeps of one run, read from the run's `summary.json` and `frames.csv`;
//! and the runs found under a directory.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, anyhow, bail};

use super::figures::IDENTITY_COLUMNS;
use crate::gpu::AdapterDesc;

/// One run as a baseline records it: its identity, and every figure per frame.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RunRecord {
    /// Method.
    pub method: String,
    /// Method parameters (the build's and the runtime ones).
    pub params: BTreeMap<String, String>,
    /// Scene label.
    pub scene: String,
    /// Camera path.
    pub path: String,
    /// Frames the path was cut into.
    pub frames: u64,
    /// `eps 2` or `budget 5000`.
    pub target: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Splat kernel.
    pub kernel: String,
    /// Shading.
    pub shading: String,
    /// The adapter the run drew on.
    pub adapter: AdapterDesc,
    /// The commit of the binary that ran it.
    pub commit: String,
    /// The command that produced it, where the run recorded one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub command: Option<String>,
    /// Whether the run finished.
    pub complete: bool,
    /// Scene facts compared exactly: `points`, and the content hash as a string.
    pub scene_points: u64,
    /// The scene's content hash.
    pub content_hash: String,
    /// Every numeric `frames.csv` column but the identity ones, one value per frame in file
    /// order (`null` for an empty field); `frame` holds the frame numbers.
    pub columns: BTreeMap<String, Vec<Option<f64>>>,
    /// The numbers of the run's `build.json` (top level and `extra`).
    pub build: BTreeMap<String, f64>,
    /// Process figures of `summary.json`: `peak_rss_bytes`, `run_seconds`.
    pub process: BTreeMap<String, f64>,
}

impl RunRecord {
    /// Reads the run in `dir` (`summary.json` and `frames.csv`). Errors name the file.
    pub fn read(dir: &Path) -> anyhow::Result<Self> {
        let summary_path = dir.join("summary.json");
        let s: serde_json::Value = crate::results::read_json(&summary_path)?;
        let field = |k: &str| -> anyhow::Result<&serde_json::Value> {
            s.get(k)
                .ok_or_else(|| anyhow!("{}: no field '{k}'", summary_path.display()))
        };
        let string = |v: &serde_json::Value, k: &str| -> anyhow::Result<String> {
            v.as_str()
                .map(String::from)
                .ok_or_else(|| anyhow!("{}: '{k}' is not a string", summary_path.display()))
        };
        let number = |v: &serde_json::Value, k: &str| -> anyhow::Result<u64> {
            v.as_u64()
                .ok_or_else(|| anyhow!("{}: '{k}' is not a count", summary_path.display()))
        };
        let adapter: AdapterDesc = serde_json::from_value(field("adapter")?.clone())
            .with_context(|| format!("{}: field 'adapter'", summary_path.display()))?;
        let params: BTreeMap<String, String> = serde_json::from_value(field("params")?.clone())
            .with_context(|| format!("{}: field 'params'", summary_path.display()))?;
        let target = target_text(field("target")?)
            .ok_or_else(|| anyhow!("{}: field 'target' is unreadable", summary_path.display()))?;
        let scene = field("scene")?;
        let scene_field = |k: &str| {
            scene
                .get(k)
                .ok_or_else(|| anyhow!("{}: no field 'scene.{k}'", summary_path.display()))
        };
        let mut build = BTreeMap::new();
        if let Some(serde_json::Value::Object(b)) = s.get("build") {
            for (k, v) in b {
                if let Some(x) = v.as_f64() {
                    build.insert(k.clone(), x);
                }
            }
            if let Some(serde_json::Value::Object(extra)) = b.get("extra") {
                for (k, v) in extra {
                    if let Some(x) = v.as_f64() {
                        build.entry(k.clone()).or_insert(x);
                    }
                }
            }
        }
        let mut process = BTreeMap::new();
        for k in ["peak_rss_bytes", "run_seconds"] {
            if let Some(x) = s.get(k).and_then(serde_json::Value::as_f64) {
                process.insert(k.to_string(), x);
            }
        }
        Ok(Self {
            method: string(field("method")?, "method")?,
            params,
            scene: string(scene_field("label")?, "scene.label")?,
            path: string(field("path")?, "path")?,
            frames: number(field("frames")?, "frames")?,
            target,
            width: number(field("width")?, "width")? as u32,
            height: number(field("height")?, "height")? as u32,
            kernel: string(field("kernel")?, "kernel")?,
            shading: string(field("shading")?, "shading")?,
            adapter,
            commit: string(field("git_commit")?, "git_commit")?,
            command: s.get("command").and_then(|c| c.as_str()).map(String::from),
            complete: field("complete")?.as_bool().unwrap_or(false),
            scene_points: number(scene_field("points")?, "scene.points")?,
            content_hash: string(scene_field("content_hash")?, "scene.content_hash")?,
            columns: read_columns(&dir.join("frames.csv"))?,
            build,
            process,
        })
    }

    /// The run's frame numbers, in file order.
    pub fn frame_numbers(&self) -> Vec<u64> {
        self.columns
            .get("frame")
            .map(|v| v.iter().map(|f| f.unwrap_or(-1.0) as u64).collect())
            .unwrap_or_default()
    }

    /// The columns' names, as in the run's `frames.csv` (identity columns excepted).
    pub fn column_names(&self) -> Vec<String> {
        self.columns.keys().cloned().collect()
    }

    /// `method` with its parameters, as the check's table names a run.
    pub fn method_label(&self) -> String {
        if self.params.is_empty() {
            self.method.clone()
        } else {
            let p: Vec<String> = self
                .params
                .iter()
                .map(|(k, v)| format!("{k}={v}"))
                .collect();
            format!("{} {}", self.method, p.join(" "))
        }
    }

    /// The adapter as one line: name and backend.
    pub fn adapter_text(&self) -> String {
        adapter_text(&self.adapter)
    }
}

/// An adapter as one line: name and backend (what "the same adapter" compares).
pub fn adapter_text(a: &AdapterDesc) -> String {
    format!("{} ({})", a.name, a.backend)
}

/// `summary.json`'s target as `eps 2` / `budget 5000`.
fn target_text(v: &serde_json::Value) -> Option<String> {
    if let Some(e) = v.get("Tolerance").and_then(serde_json::Value::as_f64) {
        // Tolerances are f32: print the f32's shortest text, as the sweep names them.
        return Some(format!("eps {}", e as f32));
    }
    v.get("Budget")
        .and_then(serde_json::Value::as_u64)
        .map(|b| format!("budget {b}"))
}

/// Every column of `frames.csv` but the identity ones (`frame` kept), per frame: numbers,
/// `None` for empty fields and for non-finite ones (`NaN`: a counter not computed; JSON has
/// no NaN). A non-numeric field in a measured column is an error naming the
/// file, the column and the row.
fn read_columns(path: &Path) -> anyhow::Result<BTreeMap<String, Vec<Option<f64>>>> {
    let mut rd =
        csv::Reader::from_path(path).with_context(|| format!("reading {}", path.display()))?;
    let headers: Vec<String> = rd
        .headers()
        .with_context(|| format!("reading {}", path.display()))?
        .iter()
        .map(String::from)
        .collect();
    let keep: Vec<bool> = headers
        .iter()
        .map(|h| h == "frame" || !IDENTITY_COLUMNS.contains(&h.as_str()))
        .collect();
    let mut cols: Vec<Vec<Option<f64>>> = vec![Vec::new(); headers.len()];
    for (row, rec) in rd.records().enumerate() {
        let rec = rec.with_context(|| format!("reading {}", path.display()))?;
        for (c, field) in rec.iter().enumerate().filter(|(c, _)| keep[*c]) {
            let v = match field.trim() {
                "" => None,
                t => Some(t.parse::<f64>().map_err(|_| {
                    anyhow!(
                        "{}: row {}, column '{}': '{t}' is not a number",
                        path.display(),
                        row + 1,
                        headers[c]
                    )
                })?)
                .filter(|x| x.is_finite()),
            };
            cols[c].push(v);
        }
    }
    Ok(headers
        .into_iter()
        .zip(cols)
        .zip(keep)
        .filter(|(_, k)| *k)
        .map(|((h, c), _)| (h, c))
        .collect())
}

/// What a directory given to `check` is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DirKind {
    /// One run (`summary.json` at its top).
    Run,
    /// A sweep (`sweep.csv`).
    Sweep,
    /// A tune (`tune.csv`).
    Tune,
    /// A reproduction (`results.json`).
    Reproduce,
    /// A regression suite's output (`suite.json`).
    Suite,
    /// Some other directory holding runs.
    Runs,
}

impl DirKind {
    /// What `dir` is, by the files at its top.
    pub fn of(dir: &Path) -> Self {
        let has = |f: &str| dir.join(f).is_file();
        if has("summary.json") {
            Self::Run
        } else if has("suite.json") {
            Self::Suite
        } else if has("results.json") {
            Self::Reproduce
        } else if has("tune.csv") {
            Self::Tune
        } else if has("sweep.csv") {
            Self::Sweep
        } else {
            Self::Runs
        }
    }

    /// The kind's name, as the baseline records it.
    pub fn name(self) -> &'static str {
        match self {
            Self::Run => "run",
            Self::Sweep => "sweep",
            Self::Tune => "tune",
            Self::Reproduce => "reproduce",
            Self::Suite => "suite",
            Self::Runs => "runs",
        }
    }
}

/// How deep [`find_runs`] looks: a reproduction's sweeps are `runs/SPEC/MEASURE/TARGET/`.
const MAX_DEPTH: usize = 6;

/// The run directories under `dir` (each holding `summary.json` and `frames.csv`), keyed by
/// their path relative to `dir` with `/` separators (`.` for `dir` itself). `build/`,
/// `builds/` and `images/` folders are not searched, nor `parts/` (the jobs' copies of what
/// a merge put in the directory itself).
pub fn find_runs(dir: &Path) -> anyhow::Result<BTreeMap<String, PathBuf>> {
    if !dir.is_dir() {
        bail!("{}: no such directory", dir.display());
    }
    let mut out = BTreeMap::new();
    let mut stack = vec![(dir.to_path_buf(), 0usize)];
    while let Some((d, depth)) = stack.pop() {
        if d.join("summary.json").is_file() && d.join("frames.csv").is_file() {
            out.insert(key_of(dir, &d), d.clone());
        }
        if depth >= MAX_DEPTH {
            continue;
        }
        let entries = std::fs::read_dir(&d).with_context(|| format!("reading {}", d.display()))?;
        for e in entries {
            let e = e.with_context(|| format!("reading {}", d.display()))?;
            let name = e.file_name();
            let skip = matches!(name.to_str(), Some("build" | "builds" | "images" | "parts"))
                || name.to_string_lossy().starts_with('.');
            if !skip && e.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push((e.path(), depth + 1));
            }
        }
    }
    Ok(out)
}

fn key_of(root: &Path, dir: &Path) -> String {
    let rel = dir.strip_prefix(root).unwrap_or(dir);
    let parts: Vec<String> = rel
        .components()
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    if parts.is_empty() {
        ".".into()
    } else {
        parts.join("/")
    }
}
