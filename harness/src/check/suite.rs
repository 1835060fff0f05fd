//! Regression suites: a TOML file naming a set of sweeps (methods × scenes × paths, at pixel
//! tolerances and point budgets), run by `splatbench check --suite FILE --out DIR` into a
//! directory that `check` then compares with the suite's baseline.
//!
//! ```toml
//! baseline = "quick.json"   # relative to this file
//! width = 128
//! height = 128
//! frames = 3
//! paths = ["orbit"]
//! methods = ["full", "qsplat", "spt", "lpc", "mwkd"]
//! scenes = ["statue:20000:1", "terrain:20000:1"]
//! eps = [2.0]
//! budgets = [4000]
//! [params]                   # per method, as --param (build and runtime alike)
//! lpc = ["delay_frames=1"]
//! ```
//!
//! Output: one build per method and scene under `DIR/builds/`, and one ordinary sweep
//! directory per method, scene, path and kind of target, `DIR/<method>-<scene>-<path>-eps/`
//! and `…-budget/` (run directories `eps-2/`, `budget-4000/`, `sweep.csv`); `DIR/suite.json`
//! records the suite and the command. Unknown keys, methods, parameters, scenes and paths
//! are errors naming the file and the field, before anything runs.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::{Context as _, anyhow};
use methods::{MethodKind, Params};
use scenes::SceneSpec;
use scenes::paths::PathSpec;

use crate::gpu::Gpu;
use crate::render::{Kernel, RenderSettings};
use crate::runner::RunConfig;
use crate::sweep::SweepTarget;

/// A suite file as written.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SuiteFile {
    /// The baseline file, relative to the suite file.
    pub baseline: String,
    /// Image width, pixels.
    pub width: u32,
    /// Image height, pixels.
    pub height: u32,
    /// Frames along each path.
    pub frames: usize,
    /// Camera paths (built-in names or keyframe files relative to the current directory).
    pub paths: Vec<String>,
    /// Methods (registry names).
    pub methods: Vec<String>,
    /// Scenes (`generator:points:seed` or files).
    pub scenes: Vec<String>,
    /// Pixel tolerances: one sweep per method, scene and path over them.
    #[serde(default)]
    pub eps: Vec<f32>,
    /// Point budgets: one sweep per method, scene and path over them.
    #[serde(default)]
    pub budgets: Vec<u64>,
    /// Splat kernel (default square).
    #[serde(default)]
    pub kernel: Option<String>,
    /// GPU chunk-cache budget, MiB (default 512).
    #[serde(default)]
    pub gpu_cache_mb: Option<u64>,
    /// Parameters per method, `key=value`.
    #[serde(default)]
    pub params: BTreeMap<String, Vec<String>>,
}

/// A checked suite.
#[derive(Debug, Clone)]
pub struct Suite {
    /// The file it was read from.
    pub file: PathBuf,
    /// As written.
    pub raw: SuiteFile,
    /// The baseline file (resolved against the suite's folder).
    pub baseline: PathBuf,
    /// Methods with their parameters.
    pub methods: Vec<(MethodKind, Params)>,
    /// Scenes.
    pub scenes: Vec<SceneSpec>,
    /// Paths.
    pub paths: Vec<PathSpec>,
    /// Kinds of targets: each a list swept together.
    pub targets: Vec<(&'static str, Vec<SweepTarget>)>,
    /// Kernel.
    pub kernel: Kernel,
}

impl Suite {
    /// Reads and checks a suite file; errors name the file and the field.
    pub fn load(file: &Path) -> anyhow::Result<Self> {
        let text =
            std::fs::read_to_string(file).with_context(|| format!("reading {}", file.display()))?;
        let raw: SuiteFile =
            toml::from_str(&text).map_err(|e| anyhow!("{}: {}", file.display(), e.message()))?;
        let err = |field: &str, msg: String| anyhow!("{}: {field}: {msg}", file.display());
        if raw.width == 0 || raw.height == 0 {
            return Err(err("width/height", "must be at least 1 pixel".into()));
        }
        if raw.frames == 0 {
            return Err(err("frames", "must be at least 1".into()));
        }
        if let Some(mb) = raw.gpu_cache_mb
            && !(1..=methods::params::MAX_MB).contains(&mb)
        {
            return Err(err(
                "gpu_cache_mb",
                format!("must be in 1..=2³⁰ (MiB), got {mb}"),
            ));
        }
        for (field, list) in [
            ("methods", &raw.methods),
            ("scenes", &raw.scenes),
            ("paths", &raw.paths),
        ] {
            if list.is_empty() {
                return Err(err(field, "the list is empty".into()));
            }
        }
        if raw.eps.is_empty() && raw.budgets.is_empty() {
            return Err(err("eps/budgets", "give at least one target".into()));
        }
        for m in raw.params.keys() {
            if !raw.methods.contains(m) {
                return Err(err(
                    &format!("params.{m}"),
                    "is not one of the suite's methods".into(),
                ));
            }
        }
        let mut methods = Vec::new();
        for name in &raw.methods {
            let kind = MethodKind::from_name(name).map_err(|e| err("methods", e.to_string()))?;
            let params = Params::parse(raw.params.get(name).map_or(&[][..], Vec::as_slice))
                .and_then(|p| kind.check_params(&p).map(|_| p))
                .map_err(|e| err(&format!("params.{name}"), e.to_string()))?;
            methods.push((kind, params));
        }
        let scenes = raw
            .scenes
            .iter()
            .map(|s| SceneSpec::parse(s, None, 1).map_err(|e| err("scenes", e.to_string())))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let paths = raw
            .paths
            .iter()
            .map(|p| PathSpec::parse(p).map_err(|e| err("paths", e.to_string())))
            .collect::<anyhow::Result<Vec<_>>>()?;
        let mut targets = Vec::new();
        if !raw.eps.is_empty() {
            let t = raw
                .eps
                .iter()
                .map(|&e| SweepTarget::tolerance(e).map_err(|e| err("eps", e.to_string())))
                .collect::<anyhow::Result<Vec<_>>>()?;
            targets.push(("eps", t));
        }
        if !raw.budgets.is_empty() {
            let t = raw
                .budgets
                .iter()
                .map(|&b| SweepTarget::budget(b).map_err(|e| err("budgets", e.to_string())))
                .collect::<anyhow::Result<Vec<_>>>()?;
            targets.push(("budget", t));
        }
        let kernel = match &raw.kernel {
            None => Kernel::Square,
            Some(k) => k
                .to_ascii_lowercase()
                .parse::<Kernel>()
                .map_err(|e| err("kernel", e.to_string()))?,
        };
        let baseline = file
            .parent()
            .unwrap_or_else(|| Path::new("."))
            .join(&raw.baseline);
        Ok(Self {
            file: file.to_path_buf(),
            raw,
            baseline,
            methods,
            scenes,
            paths,
            targets,
            kernel,
        })
    }

    /// Number of sweeps the suite runs.
    pub fn sweeps(&self) -> usize {
        self.methods.len() * self.scenes.len() * self.paths.len() * self.targets.len()
    }
}

/// A scene label as a folder name.
pub fn folder_name(label: &str) -> String {
    label
        .chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' || c == '.' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// Runs every sweep of `suite` into `out` (see the module docs). `out` must be absent, empty
/// or an earlier suite's output (it holds `suite.json`), which is removed first: no run of
/// another suite or definition is left to be checked. `out/suite.json` records the suite
/// and `command`, with `"complete": false` until the last sweep has run.
pub fn run(
    suite: &Suite,
    out: &Path,
    cache: &Path,
    gpu: &Gpu,
    command: &str,
    progress: &dyn scenes::Progress,
) -> anyhow::Result<()> {
    let marker = out.join("suite.json");
    if out.exists() {
        let empty = std::fs::read_dir(out)
            .with_context(|| format!("reading {}", out.display()))?
            .next()
            .is_none();
        if !empty && !marker.is_file() {
            anyhow::bail!(
                "--out {}: the directory holds files and is not a suite's output (no \
                 suite.json): give an empty or new directory",
                out.display()
            );
        }
        if !empty {
            std::fs::remove_dir_all(out)
                .with_context(|| format!("removing the old suite output {}", out.display()))?;
        }
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let record = |complete: bool| {
        crate::results::write_json(
            &marker,
            &serde_json::json!({
                "suite": suite.file.display().to_string(),
                "definition": suite.raw,
                "command": command,
                "commit": crate::runner::GIT_COMMIT,
                "complete": complete,
            }),
        )
    };
    record(false)?;
    // Each scene is loaded once for the builds of every method (the runs load it again, as
    // every run does).
    for scene in &suite.scenes {
        let label = scene.label();
        let build_dir = |method: MethodKind| {
            out.join("builds")
                .join(format!("{method}-{}", folder_name(&label)))
        };
        let cloud = scene
            .load(Some(cache), progress)
            .with_context(|| format!("loading scene '{}'", scene.text))?
            .warn();
        for (method, params) in &suite.methods {
            method
                .build(&cloud, params, &label, &build_dir(*method), progress)
                .with_context(|| format!("building {method} on {label}"))?;
        }
        drop(cloud);
        for (method, _) in &suite.methods {
            for path in &suite.paths {
                for (kind, targets) in &suite.targets {
                    let dir = out.join(format!(
                        "{method}-{}-{}-{kind}",
                        folder_name(&label),
                        folder_name(&path.name())
                    ));
                    let base = RunConfig {
                        method: *method,
                        params: Params::default(),
                        scene: scene.clone(),
                        path: path.clone(),
                        frames: suite.raw.frames,
                        target: targets[0].target,
                        render: RenderSettings {
                            width: suite.raw.width,
                            height: suite.raw.height,
                            kernel: suite.kernel,
                            cache_bytes: suite.raw.gpu_cache_mb.unwrap_or(512) << 20,
                            shade: Default::default(),
                            raster: Default::default(),
                        },
                        seed: 1,
                        save_images: false,
                        metrics: true,
                        out: dir.clone(),
                        cache: cache.to_path_buf(),
                        build_dir: Some(build_dir(*method)),
                        build_url: None,
                        allow_missing_chunks: false,
                        reference_raster: None,
                        reference_kernel: None,
                    };
                    crate::sweep::run_targets(&base, targets, &dir, gpu, progress, |_| {})
                        .with_context(|| format!("suite sweep {}", dir.display()))?;
                }
            }
        }
    }
    record(true)
}
