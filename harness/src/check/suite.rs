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
//! [method.potree]            # per method, replacing `scenes`, `eps` or `budgets` for it
//! scenes = ["statue:200000:1"]
//! budgets = [40000]
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
    /// Per method, lists that replace the suite's for that method (a method whose hierarchy
    /// needs more samples than the others' scenes hold to have more than one level, or whose
    /// root exceeds their budget).
    #[serde(default)]
    pub method: BTreeMap<String, MethodOverride>,
}

/// `[method.NAME]` of a suite file: what replaces the suite's lists for that method.
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MethodOverride {
    /// Scenes, instead of the suite's `scenes`.
    pub scenes: Option<Vec<String>>,
    /// Pixel tolerances, instead of the suite's `eps`.
    pub eps: Option<Vec<f32>>,
    /// Point budgets, instead of the suite's `budgets`.
    pub budgets: Option<Vec<u64>>,
}

/// One method of a suite: its parameters and targets.
#[derive(Debug, Clone)]
pub struct SuiteMethod {
    /// The method.
    pub kind: MethodKind,
    /// Its parameters (`params.NAME`).
    pub params: Params,
    /// Kinds of targets (`eps`, `budget`): each a list swept together.
    pub targets: Vec<(&'static str, Vec<SweepTarget>)>,
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
    /// Methods with their parameters and targets.
    pub methods: Vec<SuiteMethod>,
    /// Scenes, each with the indices (into `methods`) of the methods run on it, in the
    /// order first named.
    pub scenes: Vec<(SceneSpec, Vec<usize>)>,
    /// Paths.
    pub paths: Vec<PathSpec>,
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
        for (table, keys) in [
            ("params", raw.params.keys().collect::<Vec<_>>()),
            ("method", raw.method.keys().collect()),
        ] {
            for m in keys {
                if !raw.methods.contains(m) {
                    return Err(err(
                        &format!("{table}.{m}"),
                        "is not one of the suite's methods".into(),
                    ));
                }
            }
        }
        let mut methods = Vec::new();
        let mut scenes: Vec<(SceneSpec, Vec<usize>)> = Vec::new();
        for (i, name) in raw.methods.iter().enumerate() {
            let kind = MethodKind::from_name(name).map_err(|e| err("methods", e.to_string()))?;
            let params = Params::parse(raw.params.get(name).map_or(&[][..], Vec::as_slice))
                .and_then(|p| kind.check_params(&p).map(|_| p))
                .map_err(|e| err(&format!("params.{name}"), e.to_string()))?;
            let over = raw.method.get(name).cloned().unwrap_or_default();
            let (scenes_field, scene_list) =
                own_or_suite(name, "scenes", &over.scenes, &raw.scenes);
            if scene_list.is_empty() {
                return Err(err(&scenes_field, "the list is empty".into()));
            }
            for text in scene_list {
                let spec = SceneSpec::parse(text, None, 1)
                    .map_err(|e| err(&scenes_field, e.to_string()))?;
                match scenes.iter_mut().find(|(s, _)| s.label() == spec.label()) {
                    Some((_, users)) => users.push(i),
                    None => scenes.push((spec, vec![i])),
                }
            }
            let (eps_field, eps) = own_or_suite(name, "eps", &over.eps, &raw.eps);
            let (budgets_field, budgets) =
                own_or_suite(name, "budgets", &over.budgets, &raw.budgets);
            if eps.is_empty() && budgets.is_empty() {
                return Err(err(
                    &format!("{eps_field}/{budgets_field}"),
                    format!("give at least one target for {name}"),
                ));
            }
            let mut targets = Vec::new();
            if !eps.is_empty() {
                let t = eps
                    .iter()
                    .map(|&e| SweepTarget::tolerance(e).map_err(|e| err(&eps_field, e.to_string())))
                    .collect::<anyhow::Result<Vec<_>>>()?;
                targets.push(("eps", t));
            }
            if !budgets.is_empty() {
                let t = budgets
                    .iter()
                    .map(|&b| {
                        SweepTarget::budget(b).map_err(|e| err(&budgets_field, e.to_string()))
                    })
                    .collect::<anyhow::Result<Vec<_>>>()?;
                targets.push(("budget", t));
            }
            methods.push(SuiteMethod {
                kind,
                params,
                targets,
            });
        }
        let paths = raw
            .paths
            .iter()
            .map(|p| PathSpec::parse(p).map_err(|e| err("paths", e.to_string())))
            .collect::<anyhow::Result<Vec<_>>>()?;
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
            kernel,
        })
    }

    /// Number of sweeps the suite runs: one per method, each of its scenes, path and kind of
    /// target.
    pub fn sweeps(&self) -> usize {
        self.count(|m| m.targets.len())
    }

    /// Number of runs the suite makes: one per sweep and target of its kind.
    pub fn runs(&self) -> usize {
        self.count(|m| m.targets.iter().map(|(_, t)| t.len()).sum())
    }

    /// `per(method)` summed over every method's scenes, times the paths.
    fn count(&self, per: impl Fn(&SuiteMethod) -> usize) -> usize {
        let pairs: usize = self
            .scenes
            .iter()
            .flat_map(|(_, users)| users.iter().map(|&i| per(&self.methods[i])))
            .sum();
        pairs * self.paths.len()
    }
}

/// Method `name`'s list `key`: its `[method.NAME]` one if given, else the suite's; with the
/// field that errors name (`method.NAME.KEY` or `KEY`).
fn own_or_suite<'a, T>(
    name: &str,
    key: &str,
    own: &'a Option<Vec<T>>,
    suite: &'a [T],
) -> (String, &'a [T]) {
    match own {
        Some(list) => (format!("method.{name}.{key}"), list),
        None => (key.to_string(), suite),
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
    for (scene, users) in &suite.scenes {
        let label = scene.label();
        let methods: Vec<_> = users.iter().map(|&i| &suite.methods[i]).collect();
        let build_dir = |method: MethodKind| {
            out.join("builds")
                .join(format!("{method}-{}", folder_name(&label)))
        };
        let cloud = scene
            .load(Some(cache), progress)
            .with_context(|| format!("loading scene '{}'", scene.text))?
            .warn();
        for m in &methods {
            let (method, params) = (m.kind, &m.params);
            method
                .build(&cloud, params, &label, &build_dir(method), progress)
                .with_context(|| format!("building {method} on {label}"))?;
        }
        drop(cloud);
        for m in &methods {
            let method = m.kind;
            for path in &suite.paths {
                for (kind, targets) in &m.targets {
                    let dir = out.join(format!(
                        "{method}-{}-{}-{kind}",
                        folder_name(&label),
                        folder_name(&path.name())
                    ));
                    let base = RunConfig {
                        method,
                        params: Params::default(),
                        scene: scene.clone(),
                        path: path.clone(),
                        frames: suite.raw.frames,
                        target: targets[0].target,
                        render: RenderSettings {
                            width: suite.raw.width,
                            height: suite.raw.height,
                            kernel: suite.kernel,
                            cache_bytes: suite
                                .raw
                                .gpu_cache_mb
                                .unwrap_or(crate::render::DEFAULT_GPU_CACHE_MB)
                                << 20,
                            shade: Default::default(),
                            raster: Default::default(),
                        },
                        seed: 1,
                        save_images: false,
                        metrics: true,
                        out: dir.clone(),
                        cache: cache.to_path_buf(),
                        build_dir: Some(build_dir(method)),
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
