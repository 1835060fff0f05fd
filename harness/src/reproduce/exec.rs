//! Running a spec's measures (its rows are evaluated in [`super::evaluate`]).
//!
//! Builds are shared: a build is keyed by method, build parameters and scene, made once per
//! reproduction under `OUT/builds/`, and reused by every measure (of any spec) with the same
//! key; a build left by an earlier reproduction is reused only when it was made by the same
//! clean commit. Runs and sweeps always run again, into `OUT/runs/<spec>/<measure>/` (the
//! runner's ordinary `frames.csv`, `summary.json` and plots).
//!
//! Times a verdict reads ([`super::spec::Spec::timed`]) are medians of [`TIMING_REPEATS`]
//! builds or runs (for measures shorter than [`REPEAT_BELOW_S`]), made in scratch
//! directories beside the measure's and removed after; the measure list says so.
//!
//! Metrics a measure provides to expressions:
//! - build: every number of `build.json` (`points_in`, `nodes`, `levels`, `bytes_in`,
//!   `bytes_out`, `bits_per_sample`, `seconds`, `points_per_s`) and of its `extra`;
//! - run: `STAT.COLUMN` for every numeric `frames.csv` column, STAT one of `median`, `mean`,
//!   `min`, `max`, `first`, `last` over the frames after `skip`; `peak_rss_bytes`,
//!   `method_resident_bytes`, `run_seconds` and `rss_max_{anon,file,shmem}_bytes` (Linux) of
//!   `summary.json`; and
//!   `build.KEY` of its build;
//! - sweep: `TARGET.STAT.COLUMN` per target, TARGET the run directory's name with `-` and
//!   `.` written `_` (`eps_2`, `eps_0_5`, `budget_25000`), and `build.KEY`;
//! - plan: the numbers of `splatbench plan --json` (`levels`, `nodes`, `leaves`, `depth`,
//!   `samples_total`, `leaf_points_min`, …).

use std::collections::{BTreeMap, HashMap};
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context as _, anyhow, bail};
use methods::{BuildStats, Manifest, MethodKind, Params};
use scenes::spec::SceneSource;
use scenes::{Progress, SceneSpec};

use super::spec::{Measure, MeasureKind, Spec};
use crate::gpu::Gpu;
use crate::render::RenderSettings;
use crate::runner::{GIT_COMMIT, RunConfig};

/// Runs (or builds) whose time a verdict reads are timed this many times, the median kept
/// ([`super::spec::Spec::timed`]): one timing of a short build or of a few frames moves by
/// ×1.3–1.6 from one reproduction to the next on this 2-core machine (QSplat Fig. 6's build
/// rate ratio 1.13 → 1.59, Fig. 1's traversal rate ratio 1.51 → 1.78, same commit), enough
/// to flip a verdict; the median of three is what one slow outlier cannot move.
pub const TIMING_REPEATS: usize = 3;
/// Only measures shorter than this are repeated: a longer build or run holds its own noise
/// to a smaller share, and repeating the paper profile's builds (minutes to an hour each)
/// would triple the profile.
pub const REPEAT_BELOW_S: f64 = 60.0;
/// The key of `build.json`'s `extra` that says the build's time is such a median.
pub const TIMING_BUILDS: &str = "timing_builds";

/// What one measure produced.
#[derive(Debug, Clone, Default)]
pub struct MeasureResult {
    /// Metric values by key.
    pub metrics: BTreeMap<String, f64>,
    /// `(median FLIP, median points)` per target (sweeps).
    pub curve: Vec<(f64, f64)>,
    /// Per target of a sweep: its name and its medians (points, FLIP, holes, PSNR).
    pub sweep: Vec<SweepLine>,
    /// The measure's output directory (runs, sweeps).
    pub dir: Option<PathBuf>,
    /// Not run: it serves only GPU rows and the adapter is not a GPU.
    pub skipped_for_gpu: bool,
    /// Why it failed.
    pub error: Option<String>,
    /// Wall seconds.
    pub seconds: f64,
    /// What this measure had to make first, with its time and size (`scene made: 980 s,
    /// 3.05 GB`): the phases of its wall time. Empty when it reused everything.
    pub made: Vec<String>,
}

/// What [`Context::execute`] returns: metrics, a sweep's curve and per-target lines.
type Executed = (BTreeMap<String, f64>, Vec<(f64, f64)>, Vec<SweepLine>);

/// One target of a sweep as the report lists it.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct SweepLine {
    /// `eps-2`, `budget-25000`.
    pub target: String,
    /// Median points drawn.
    pub points: Option<f64>,
    /// Median of the frames' mean FLIP.
    pub flip: Option<f64>,
    /// Median hole ratio.
    pub holes: Option<f64>,
    /// Largest hole ratio of a frame.
    pub holes_max: Option<f64>,
    /// Median PSNR.
    pub psnr: Option<f64>,
}

/// The state of a reproduction: the GPU (opened when first needed), the builds made so far.
pub struct Context<'a> {
    /// Output root.
    pub out: PathBuf,
    /// Scene / reference cache.
    pub cache: PathBuf,
    /// The `splatbench` binary, for `isolate` runs.
    pub exe: Option<PathBuf>,
    /// Phase progress.
    pub progress: &'a dyn Progress,
    gpu: Option<Option<Gpu>>,
    builds: HashMap<String, (PathBuf, BuildStats)>,
}

impl<'a> Context<'a> {
    /// A context writing under `out`.
    pub fn new(out: &Path, cache: &Path, exe: Option<PathBuf>, progress: &'a dyn Progress) -> Self {
        Self {
            out: out.to_path_buf(),
            cache: cache.to_path_buf(),
            exe,
            progress,
            gpu: None,
            builds: HashMap::new(),
        }
    }

    /// The GPU, opened on first use; `None` when the machine has no adapter at all.
    pub fn gpu(&mut self) -> anyhow::Result<Option<&Gpu>> {
        if self.gpu.is_none() {
            self.gpu = Some(Gpu::new()?);
        }
        Ok(self.gpu.as_ref().and_then(Option::as_ref))
    }

    /// Whether the adapter is a real GPU (not a CPU rasteriser such as lavapipe).
    pub fn has_real_gpu(&mut self) -> anyhow::Result<bool> {
        Ok(self
            .gpu()?
            .is_some_and(|g| !g.adapter.device_type.eq_ignore_ascii_case("cpu")))
    }

    /// The adapter, if one was opened.
    pub fn adapter(&self) -> Option<&crate::gpu::AdapterDesc> {
        self.gpu
            .as_ref()
            .and_then(Option::as_ref)
            .map(|g| &g.adapter)
    }

    /// Runs `m` of `spec`.
    pub fn measure(&mut self, spec: &Spec, m: &Measure) -> MeasureResult {
        let t = Instant::now();
        let mut r = match self.try_measure(spec, m) {
            Ok(r) => r,
            Err(e) => MeasureResult {
                error: Some(format!("{e:#}")),
                ..MeasureResult::default()
            },
        };
        r.seconds = t.elapsed().as_secs_f64();
        r
    }

    fn try_measure(&mut self, spec: &Spec, m: &Measure) -> anyhow::Result<MeasureResult> {
        if m.kind == MeasureKind::Plan {
            return plan(m);
        }
        let scene = scene_of(spec, m)?;
        let timed = spec.timed().get(m.id.as_str()).copied().unwrap_or_default();
        // Rows judged on a GPU only: their timings matter where the adapter is one (asked
        // only then, so a build-only spec never opens the adapter).
        let on_gpu = |ctx: &mut Self| -> anyhow::Result<bool> {
            Ok((timed.build_on_gpu || timed.frames_on_gpu) && ctx.has_real_gpu()?)
        };
        let gpu_judged = on_gpu(self)?;
        let mut made = Vec::new();
        let (build_dir, stats) = self.build(m, scene, &mut made)?;
        let stats = if timed.build || (timed.build_on_gpu && gpu_judged) {
            self.time_build(m, scene, &build_dir, stats, &mut made)?
        } else {
            stats
        };
        let build_metrics = build_metrics(&stats);
        let mut r = MeasureResult {
            made,
            ..MeasureResult::default()
        };
        if m.kind == MeasureKind::Build {
            r.metrics = build_metrics;
            return Ok(r);
        }
        let dir = self.out.join("runs").join(&spec.id).join(&m.id);
        let t = Instant::now();
        let (metrics, curve, sweep) = self.execute(m, scene, &build_dir, &dir)?;
        (r.metrics, r.curve, r.sweep) = (metrics, curve, sweep);
        let once = t.elapsed().as_secs_f64();
        if (timed.frames || (timed.frames_on_gpu && gpu_judged)) && once < REPEAT_BELOW_S {
            // The frames' times as the median of repeats, each in a scratch directory beside
            // the measure's (removed after); everything else is the same in every repeat.
            let mut all = vec![std::mem::take(&mut r.metrics)];
            for k in 1..TIMING_REPEATS {
                let scratch = dir.with_file_name(format!("{}.timing-{k}", m.id));
                all.push(self.execute(m, scene, &build_dir, &scratch)?.0);
                std::fs::remove_dir_all(&scratch)
                    .with_context(|| format!("removing {}", scratch.display()))?;
            }
            r.metrics = median_metrics(&all);
            r.made.push(format!(
                "times: the median of {TIMING_REPEATS} runs ({once:.1} s each)"
            ));
        }
        for (k, v) in build_metrics {
            r.metrics.insert(format!("build.{k}"), v);
        }
        r.dir = Some(dir);
        Ok(r)
    }

    /// Runs a run or sweep measure into `dir` (emptied first): its metrics, and for a sweep
    /// its curve and per-target lines.
    fn execute(
        &mut self,
        m: &Measure,
        scene: &SceneSpec,
        build_dir: &Path,
        dir: &Path,
    ) -> anyhow::Result<Executed> {
        if dir.exists() {
            std::fs::remove_dir_all(dir)
                .with_context(|| format!("removing the old {}", dir.display()))?;
        }
        let base = self.run_config(m, scene, build_dir, dir)?;
        let (mut metrics, mut curve, mut sweep) = (BTreeMap::new(), Vec::new(), Vec::new());
        match m.kind {
            MeasureKind::Run => {
                if m.isolate {
                    self.run_isolated(m, scene, build_dir, dir)?;
                } else {
                    let progress = self.progress;
                    let gpu = self.gpu()?.ok_or_else(no_adapter)?;
                    crate::runner::run(&base, gpu, progress)?;
                    crate::plot::plot_run(dir)?;
                }
                metrics = run_metrics(dir, m.skip)?;
            }
            MeasureKind::Sweep => {
                let progress = self.progress;
                let gpu = self.gpu()?.ok_or_else(no_adapter)?;
                crate::sweep::run_targets(&base, &m.targets, dir, gpu, progress, |_| {})?;
                for t in &m.targets {
                    let tm = run_metrics(&dir.join(&t.name), m.skip)?;
                    let get = |k: &str| tm.get(k).copied();
                    if let (Some(f), Some(p)) =
                        (get("median.flip_mean"), get("median.points_drawn"))
                    {
                        curve.push((f, p));
                    }
                    sweep.push(SweepLine {
                        target: t.name.clone(),
                        points: get("median.points_drawn"),
                        flip: get("median.flip_mean"),
                        holes: get("median.hole_ratio"),
                        holes_max: get("max.hole_ratio"),
                        psnr: get("median.psnr_db"),
                    });
                    let key = t.name.replace(['-', '.'], "_");
                    for (k, v) in tm {
                        if !k.starts_with("build.") {
                            metrics.insert(format!("{key}.{k}"), v);
                        }
                    }
                }
            }
            MeasureKind::Build | MeasureKind::Plan => unreachable!("not run here"),
        }
        Ok((metrics, curve, sweep))
    }

    /// `stats` of the build in `dir` timed as the median of [`TIMING_REPEATS`] builds when a
    /// verdict reads its time and it took less than [`REPEAT_BELOW_S`]: the others are made
    /// in a scratch directory beside it (removed after), the median build's figures (its
    /// phases with it) are written to `dir`'s `build.json`, with `timing_builds` = the count,
    /// so a later measure reusing the build reads the same. A build timed already (this
    /// reproduction, or an earlier one of the same commit) is not timed again.
    fn time_build(
        &mut self,
        m: &Measure,
        scene: &SceneSpec,
        dir: &Path,
        stats: BuildStats,
        made: &mut Vec<String>,
    ) -> anyhow::Result<BuildStats> {
        if stats.extra.contains_key(TIMING_BUILDS) || stats.seconds >= REPEAT_BELOW_S {
            return Ok(stats);
        }
        // Its warnings were printed when the build was first made.
        let cloud = scene
            .load(Some(&self.cache), self.progress)
            .with_context(|| format!("loading scene '{}'", scene.text))?
            .cloud;
        let scratch = dir.with_extension("timing");
        let mut all = vec![stats];
        for _ in 1..TIMING_REPEATS {
            if scratch.exists() {
                std::fs::remove_dir_all(&scratch)
                    .with_context(|| format!("removing {}", scratch.display()))?;
            }
            all.push(
                m.method
                    .build(
                        &cloud,
                        &m.build_params,
                        &scene.label(),
                        &scratch,
                        self.progress,
                    )
                    .with_context(|| format!("building {} on {}", m.method, scene.label()))?,
            );
        }
        if scratch.exists() {
            std::fs::remove_dir_all(&scratch)
                .with_context(|| format!("removing {}", scratch.display()))?;
        }
        let times: Vec<String> = all.iter().map(|s| format!("{:.2}", s.seconds)).collect();
        all.sort_by(|a, b| a.seconds.total_cmp(&b.seconds));
        let mut stats = all.swap_remove(all.len() / 2);
        stats
            .extra
            .insert(TIMING_BUILDS.into(), (TIMING_REPEATS as u64).into());
        stats
            .write(dir)
            .with_context(|| format!("writing {}", dir.join(BuildStats::FILE).display()))?;
        made.push(format!(
            "build time: the median of {TIMING_REPEATS} builds ({} s)",
            times.join(", ")
        ));
        let key = build_key(m.method, &m.build_params, scene);
        self.builds.insert(key, (dir.to_path_buf(), stats.clone()));
        Ok(stats)
    }

    /// The build of `m` on `scene`: made once per key, or reused from `OUT/builds/` when an
    /// earlier reproduction made it with this same clean commit.
    /// What it had to make (the scene, the build) is added to `made` with its time and size.
    fn build(
        &mut self,
        m: &Measure,
        scene: &SceneSpec,
        made: &mut Vec<String>,
    ) -> anyhow::Result<(PathBuf, BuildStats)> {
        let key = build_key(m.method, &m.build_params, scene);
        if let Some(b) = self.builds.get(&key) {
            return Ok(b.clone());
        }
        let mut h = scenes::hash::Fnv64::default();
        h.write_str(&key);
        let dir = self.out.join("builds").join(format!(
            "{}-{}-{:08x}",
            m.method,
            sanitize(&scene.label()),
            h.finish() as u32
        ));
        let stamp = dir.join("reproduce-key.json");
        let reusable = !GIT_COMMIT.ends_with("-dirty")
            && std::fs::read_to_string(&stamp)
                .ok()
                .and_then(|s| serde_json::from_str::<serde_json::Value>(&s).ok())
                .is_some_and(|v| v["key"] == key.as_str() && v["commit"] == GIT_COMMIT)
            && Manifest::read(&dir).is_ok();
        let stats = match (reusable, BuildStats::read(&dir)) {
            (true, Ok(stats)) => stats,
            _ => {
                if dir.exists() {
                    std::fs::remove_dir_all(&dir)
                        .with_context(|| format!("removing the old {}", dir.display()))?;
                }
                let file = scene.cache_file(&self.cache);
                let cached = file.as_ref().is_some_and(|f| f.is_file());
                let t = Instant::now();
                let cloud = scene
                    .load(Some(&self.cache), self.progress)
                    .with_context(|| format!("loading scene '{}'", scene.text))?
                    .warn();
                if let (Some(f), false) = (&file, cached) {
                    let bytes = std::fs::metadata(f).map_or(0, |m| m.len());
                    made.push(format!(
                        "scene made: {:.0} s, {}",
                        t.elapsed().as_secs_f64(),
                        gigabytes(bytes)
                    ));
                }
                let t = Instant::now();
                let stats = m
                    .method
                    .build(&cloud, &m.build_params, &scene.label(), &dir, self.progress)
                    .with_context(|| format!("building {} on {}", m.method, scene.label()))?;
                made.push(format!(
                    "build made: {:.0} s, {}",
                    t.elapsed().as_secs_f64(),
                    gigabytes(dir_bytes(&dir))
                ));
                crate::results::write_json(
                    &stamp,
                    &serde_json::json!({ "key": key, "commit": GIT_COMMIT }),
                )?;
                stats
            }
        };
        self.builds.insert(key, (dir.clone(), stats.clone()));
        Ok((dir, stats))
    }

    /// Deletes the builds (under `OUT/builds/`) that no measure of `later` uses: what the
    /// paper profile does after each measure, so that its disk holds the builds still to be
    /// run, not all of a spec's (MWKD Table IV's nine builds of 186.85 M samples would need
    /// ≈ 37 GB at once). Returns the bytes freed.
    pub fn prune_builds<'s>(
        &mut self,
        later: impl IntoIterator<Item = (&'s Spec, &'s Measure)>,
    ) -> anyhow::Result<u64> {
        let keep: std::collections::HashSet<String> = later
            .into_iter()
            .filter_map(|(spec, m)| {
                let scene = scene_of(spec, m).ok()?;
                Some(build_key(m.method, &m.build_params, scene))
            })
            .collect();
        let mut freed = 0;
        let gone: Vec<String> = self
            .builds
            .keys()
            .filter(|k| !keep.contains(*k))
            .cloned()
            .collect();
        for key in gone {
            if let Some((dir, _)) = self.builds.remove(&key) {
                freed += dir_bytes(&dir);
                std::fs::remove_dir_all(&dir)
                    .with_context(|| format!("removing the build {}", dir.display()))?;
            }
        }
        Ok(freed)
    }

    /// Deletes the cached column files of `done`'s scenes that no spec of `later` uses: what
    /// the paper profile does between specs when it runs whole, so that its disk use is the
    /// largest spec's, not the sum (paper/README.md). Returns the bytes freed.
    pub fn prune_scenes(&mut self, done: &Spec, later: &[Spec]) -> anyhow::Result<u64> {
        let keep: std::collections::HashSet<PathBuf> = later
            .iter()
            .flat_map(|spec| spec.measures.iter().map(move |m| (spec, m)))
            .filter_map(|(spec, m)| scene_of(spec, m).ok()?.cache_file(&self.cache))
            .collect();
        let mut freed = 0;
        for scene in done.scenes.values() {
            let Some(file) = scene.cache_file(&self.cache) else {
                continue;
            };
            if !keep.contains(&file) && file.is_file() {
                freed += std::fs::metadata(&file).map_or(0, |m| m.len());
                std::fs::remove_file(&file)
                    .with_context(|| format!("removing the cached scene {}", file.display()))?;
            }
        }
        Ok(freed)
    }

    fn run_config(
        &self,
        m: &Measure,
        scene: &SceneSpec,
        build_dir: &Path,
        out: &Path,
    ) -> anyhow::Result<RunConfig> {
        let target = m
            .targets
            .first()
            .map(|t| t.target)
            .ok_or_else(|| anyhow!("measure '{}' has no target", m.id))?;
        Ok(RunConfig {
            method: m.method,
            params: m.runtime_params.clone(),
            scene: scene.clone(),
            path: m
                .path
                .clone()
                .ok_or_else(|| anyhow!("measure '{}' has no path", m.id))?,
            frames: m.frames,
            target,
            render: RenderSettings {
                width: m.width,
                height: m.height,
                kernel: m.kernel,
                cache_bytes: m
                    .gpu_cache_mb
                    .checked_mul(1 << 20)
                    .context("gpu_cache_mb is too large")?,
                shade: Default::default(),
                raster: Default::default(),
            },
            seed: scene_seed(scene),
            save_images: false,
            metrics: m.metrics,
            out: out.to_path_buf(),
            cache: self.cache.clone(),
            build_dir: Some(build_dir.to_path_buf()),
            build_url: None,
            allow_missing_chunks: false,
            reference_raster: m.reference_raster,
            reference_kernel: m.reference_kernel,
        })
    }

    /// `splatbench run … --build-dir` in a child process, so its memory is its own.
    fn run_isolated(
        &self,
        m: &Measure,
        scene: &SceneSpec,
        build_dir: &Path,
        out: &Path,
    ) -> anyhow::Result<()> {
        let exe = self.exe.as_ref().ok_or_else(|| {
            anyhow!(
                "measure '{}' runs isolated, but no splatbench binary was given",
                m.id
            )
        })?;
        let t = m.targets.first().context("no target")?;
        let mut cmd = std::process::Command::new(exe);
        cmd.arg("run")
            .args(crate::memory::check_skipped().then_some("--skip-memory-check"))
            .args(["--method", m.method.name(), "--scene", &scene.text])
            .args(["--seed", &scene_seed(scene).to_string()])
            .args(["--path", m.path_text.as_deref().unwrap_or("orbit")])
            .args(["--frames", &m.frames.to_string()])
            .args([
                "--width",
                &m.width.to_string(),
                "--height",
                &m.height.to_string(),
            ])
            .args(["--kernel", m.kernel.name()])
            .args(["--gpu-cache-mb", &m.gpu_cache_mb.to_string()])
            .arg("--build-dir")
            .arg(build_dir)
            .arg("--out")
            .arg(out)
            .arg("--cache")
            .arg(&self.cache);
        if let SceneSource::Ply {
            sample: Some(n), ..
        } = scene.source
        {
            cmd.args(["--sample", &n.to_string()]);
        }
        match (t.target.eps_px(), t.target.budget_points()) {
            (_, Some(b)) => cmd.args(["--budget", &b.to_string()]),
            (e, None) => cmd.args(["--eps", &e.unwrap_or(1.0).to_string()]),
        };
        for (k, v) in &m.runtime_params.0 {
            cmd.args(["--param", &format!("{k}={v}")]);
        }
        if !m.metrics {
            cmd.arg("--no-metrics");
        }
        if let Some(r) = m.reference_raster {
            cmd.args(["--reference-raster", r.name()]);
        }
        if let Some(k) = m.reference_kernel {
            cmd.args(["--reference-kernel", k.name()]);
        }
        let o = cmd
            .stdin(std::process::Stdio::null())
            .output()
            .with_context(|| format!("starting {}", exe.display()))?;
        if !o.status.success() {
            bail!(
                "the isolated run failed ({}): {}",
                o.status,
                String::from_utf8_lossy(&o.stderr).trim()
            );
        }
        Ok(())
    }
}

fn no_adapter() -> anyhow::Error {
    anyhow!(
        "no GPU adapter found: install Mesa's software Vulkan driver (scripts/setup.sh) or run \
         on a machine with a GPU"
    )
}

/// `1.23 GB`.
pub(super) fn gigabytes(bytes: u64) -> String {
    format!("{:.2} GB", bytes as f64 / 1e9)
}

/// Bytes of the files under `dir` (0 where it cannot be read: a figure for the report).
/// Per key, the median of the values the repeats have for it (the mean of the middle two
/// for an even count); a key some repeat lacks keeps the values the others have.
pub fn median_metrics(all: &[BTreeMap<String, f64>]) -> BTreeMap<String, f64> {
    let mut keys: Vec<&String> = all.iter().flat_map(|m| m.keys()).collect();
    keys.sort_unstable();
    keys.dedup();
    keys.into_iter()
        .map(|k| {
            let mut v: Vec<f64> = all.iter().filter_map(|m| m.get(k).copied()).collect();
            v.sort_by(f64::total_cmp);
            let n = v.len();
            let med = if n % 2 == 1 {
                v[n / 2]
            } else {
                0.5 * (v[n / 2 - 1] + v[n / 2])
            };
            (k.clone(), med)
        })
        .collect()
}

fn dir_bytes(dir: &Path) -> u64 {
    crate::results::dir_size(dir).map_or(0, |(_, bytes)| bytes)
}

fn scene_of<'s>(spec: &'s Spec, m: &Measure) -> anyhow::Result<&'s SceneSpec> {
    let name = m.scene.as_deref().context("no scene")?;
    spec.scenes
        .get(name)
        .ok_or_else(|| anyhow!("scene '{name}' is not defined"))
}

fn scene_seed(scene: &SceneSpec) -> u64 {
    match scene.source {
        SceneSource::Generator { seed, .. } | SceneSource::Ply { seed, .. } => seed,
        _ => 1,
    }
}

/// The identity of a build: method, build parameters, scene (and its resampling).
fn build_key(method: MethodKind, params: &Params, scene: &SceneSpec) -> String {
    let p: Vec<String> = params.0.iter().map(|(k, v)| format!("{k}={v}")).collect();
    format!("{method}|{}|{}|{:?}", p.join(" "), scene.text, scene.source)
}

fn sanitize(s: &str) -> String {
    s.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

fn build_metrics(stats: &BuildStats) -> BTreeMap<String, f64> {
    let mut m = BTreeMap::new();
    if let Ok(serde_json::Value::Object(o)) = serde_json::to_value(stats) {
        for (k, v) in &o {
            if let Some(x) = v.as_f64() {
                m.insert(k.clone(), x);
            }
        }
    }
    for (k, v) in &stats.extra {
        if let Some(x) = v.as_f64() {
            m.entry(k.clone()).or_insert(x);
        }
    }
    m
}

fn plan(m: &Measure) -> anyhow::Result<MeasureResult> {
    use methods::mwkd;
    let p = mwkd::MwkdParams::from_params(&m.build_params)?;
    let points = m.points.context("a plan needs points")?;
    let plan = mwkd::tree::Plan::new(points, u64::from(p.effective_fanout()), p.vbo)?;
    let mut r = MeasureResult::default();
    if let serde_json::Value::Object(o) = plan.to_json() {
        for (k, v) in o {
            if let Some(x) = v.as_f64() {
                r.metrics.insert(k, x);
            }
        }
    }
    Ok(r)
}

/// `STAT.COLUMN` over the frames of `dir/frames.csv` after the first `skip`, plus
/// `summary.json`'s `peak_rss_bytes`, `method_resident_bytes`, `run_seconds` and `rss_max` by
/// kind.
pub fn run_metrics(dir: &Path, skip: usize) -> anyhow::Result<BTreeMap<String, f64>> {
    let file = dir.join("frames.csv");
    let mut rd =
        csv::Reader::from_path(&file).with_context(|| format!("reading {}", file.display()))?;
    let headers: Vec<String> = rd
        .headers()
        .with_context(|| format!("reading {}", file.display()))?
        .iter()
        .map(String::from)
        .collect();
    let mut cols: Vec<Vec<f64>> = vec![Vec::new(); headers.len()];
    let mut frames = 0;
    for (i, rec) in rd.records().enumerate() {
        let rec = rec.with_context(|| format!("reading {}", file.display()))?;
        frames += 1;
        if i < skip {
            continue;
        }
        for (c, v) in rec.iter().enumerate() {
            if let Ok(x) = v.trim().parse::<f64>()
                && x.is_finite()
                && c < cols.len()
            {
                cols[c].push(x);
            }
        }
    }
    if frames <= skip {
        bail!(
            "{}: {frames} frames, none left after skipping {skip}",
            file.display()
        );
    }
    let mut m = BTreeMap::new();
    for (h, v) in headers.iter().zip(&cols) {
        if v.is_empty() {
            continue;
        }
        let mut s = v.clone();
        s.sort_by(f64::total_cmp);
        m.insert(
            format!("median.{h}"),
            crate::results::median(v.iter().copied()).unwrap_or(s[s.len() / 2]),
        );
        m.insert(format!("mean.{h}"), v.iter().sum::<f64>() / v.len() as f64);
        m.insert(format!("min.{h}"), s[0]);
        m.insert(format!("max.{h}"), s[s.len() - 1]);
        m.insert(format!("first.{h}"), v[0]);
        m.insert(format!("last.{h}"), v[v.len() - 1]);
    }
    let v = crate::results::read_complete_summary(dir)?;
    for k in ["peak_rss_bytes", "method_resident_bytes", "run_seconds"] {
        if let Some(x) = v[k].as_f64() {
            m.insert(k.into(), x);
        }
    }
    for k in ["anon", "file", "shmem"] {
        if let Some(x) = v["rss_max"][k].as_f64() {
            m.insert(format!("rss_max_{k}_bytes"), x);
        }
    }
    Ok(m)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Per key, the middle value of three repeats (whichever repeat has it), the mean of the
    /// middle two of an even count; a deterministic figure is the same in every repeat and
    /// stays what it is.
    #[test]
    fn repeats_keep_the_median_of_each_key() {
        let m = |pairs: &[(&str, f64)]| -> BTreeMap<String, f64> {
            pairs.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect()
        };
        let all = [
            m(&[("median.wall_ms", 30.0), ("median.points_drawn", 7.0)]),
            m(&[("median.wall_ms", 10.0), ("median.points_drawn", 7.0)]),
            m(&[
                ("median.wall_ms", 90.0),
                ("median.points_drawn", 7.0),
                ("x", 1.0),
            ]),
        ];
        let med = median_metrics(&all);
        assert_eq!(med["median.wall_ms"], 30.0);
        assert_eq!(med["median.points_drawn"], 7.0);
        assert_eq!(med["x"], 1.0);
        assert_eq!(median_metrics(&all[..2])["median.wall_ms"], 20.0);
    }

    /// Only the times that a verdict reads are repeated: a build's rate under a verdict rule,
    /// a run's build time read as `build.seconds`; not a time a `report` row shows, not a
    /// count under a verdict; a relative speed judged on a GPU only is marked as such.
    #[test]
    fn the_timings_a_verdict_reads_are_the_ones_repeated() {
        let text = r#"
id = "t"
paper = "p"
title = "t"
source = "s"

[scenes.s]
generator = "statue"
points = 1000
seed = 1

[[measure]]
id = "b"
kind = "build"
method = "qsplat"
scene = "s"

[[measure]]
id = "r"
kind = "run"
method = "qsplat"
scene = "s"
frames = 2
eps = 2
width = 32
height = 32

[[measure]]
id = "q"
kind = "run"
method = "lpc"
scene = "s"
frames = 2
eps = 2
width = 32
height = 32

[[row]]
what = "a build rate"
paper = [0.5, 2]
ours = "b.points_per_s / b.points_per_s"
rule = "inside"

[[row]]
what = "a frame time, shown"
ours = "r.median.wall_ms"
rule = "report"

[[row]]
what = "a build time through a run"
paper = 1
ours = "r.build.seconds / r.build.seconds"
rule = "exact"

[[row]]
what = "a speed"
paper = 1
ours = "q.median.splats_per_s / r.median.splats_per_s"
rule = "at_least"
judge_on_gpu = true

[[row]]
what = "a count"
paper = 1
ours = "q.median.points_drawn / q.median.points_drawn"
rule = "exact"
"#;
        let d = tempfile::tempdir().unwrap();
        let spec = super::super::load::parse(
            text,
            &d.path().join("t.toml"),
            d.path(),
            super::super::spec::Profile::Quick,
        )
        .unwrap();
        let timed = spec.timed();
        let t = |build, build_on_gpu, frames, frames_on_gpu| super::super::spec::Timed {
            build,
            build_on_gpu,
            frames,
            frames_on_gpu,
        };
        assert_eq!(timed["b"], t(true, false, false, false));
        assert_eq!(timed["r"], t(true, false, false, true));
        assert_eq!(timed["q"], t(false, false, false, true));
        assert_eq!(timed.len(), 3);
        for (key, timing) in [
            ("seconds", true),
            ("build.split_seconds", true),
            ("eps_5.median.cpu_select_ms", true),
            ("median.splats_per_s", true),
            ("median.points_drawn", false),
            ("peak_rss_bytes", false),
            ("bits_per_sample", false),
        ] {
            assert_eq!(super::super::spec::is_timing_key(key), timing, "{key}");
        }
    }

    #[test]
    fn run_metrics_skip_leading_frames_and_need_a_complete_run() {
        let d = tempfile::tempdir().unwrap();
        std::fs::write(
            d.path().join("frames.csv"),
            "frame,points_drawn,flip_mean\n0,10,\n1,20,0.5\n2,40,0.25\n3,30,0.75\n",
        )
        .unwrap();
        std::fs::write(d.path().join("summary.json"), r#"{"complete": false}"#).unwrap();
        assert!(
            format!("{:#}", run_metrics(d.path(), 0).unwrap_err()).contains("did not complete")
        );
        std::fs::write(
            d.path().join("summary.json"),
            r#"{"complete": true, "peak_rss_bytes": 123}"#,
        )
        .unwrap();
        let m = run_metrics(d.path(), 1).unwrap();
        assert_eq!(m["median.points_drawn"], 30.0);
        assert_eq!(m["first.points_drawn"], 20.0);
        assert_eq!(m["last.points_drawn"], 30.0);
        assert_eq!(m["max.flip_mean"], 0.75);
        assert_eq!(m["mean.flip_mean"], 0.5);
        assert_eq!(m["peak_rss_bytes"], 123.0);
        assert!(run_metrics(d.path(), 4).is_err());
    }
}
