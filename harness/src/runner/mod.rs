//! The camera-path runner: builds a method on a scene, drives it along a path, renders every
//! frame, compares it with the full-resolution reference and writes `frames.csv`,
//! `summary.json` and plots.
//!
//! The **reference** for a view is the `full` method (every sample a splat of its own leaf
//! radius, ≥ 1 px) rendered with the same renderer settings. Reference images are cached in
//! `<cache>/refs/` under a key hashing the scene's content, the camera, the resolution, the
//! kernel, the adapter (name and backend), the image shaders' sources
//! ([`crate::render::image_shaders_hash`]) and [`REFERENCE_VERSION`]; the `full` build they need lives in
//! `<cache>/full/<scene hash>/` and is made only when an image is missing.
//!
//! Timing: one untimed warm-up frame (shader compilation) precedes the path. `splats_per_s`
//! uses GPU time when the adapter has timestamp queries, else wall time; `summary.json` says
//! which (`splats_per_s_basis`).
//!
//! `frames.csv` columns after [`FrameRow::COLUMNS`] ([`frame_columns`]): the method's
//! [`LodMethod::extra_columns`], then [`INTERVAL_COLUMNS`] for interval-tested methods (SPT),
//! then [`OCCLUSION_COLUMNS`] for occlusion-culled methods (LPC with `occlusion=true`), then
//! for methods that load chunks (LPC, MWKD) `chunks_failed` and [`TRAFFIC_COLUMNS`].
//!
//! Occlusion culling: the renderer runs the list's [`methods::OcclusionPass`] (see
//! [`crate::render`]); [`next_feedback`] hands the candidates it found visible and occluded
//! to the method's next frame as [`Feedback::visible`] / [`Feedback::occluded`] (frame 0 —
//! and the warm-up frame — start with both empty, so everything is queried against an empty
//! phase 1). With occlusion culling `gpu_ms` is the sum of the three phases' GPU intervals,
//! `points_drawn`/`chunks_drawn` count phase 1 + phase 3, and `upload_bytes` never includes
//! an occluded cloud.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context as _;
use methods::{BuildStats, Feedback, LodMethod, MethodKind, Params, Target};
use scenes::paths::PathSpec;
use scenes::{Aabb, Progress, SceneSpec, View};

use crate::gpu::Gpu;
use crate::image::Image;
use crate::metrics::{FrameMetrics, PathMetrics};
use crate::render::{FrameStats, RenderSettings, Renderer};
use crate::results::{FrameRow, FramesWriter, write_json};

mod columns;
mod prepare;
mod reference;
mod summary;

pub use columns::{
    INTERVAL_COLUMNS, OCCLUSION_COLUMNS, TRAFFIC_COLUMNS, frame_columns, frame_counters,
    next_feedback,
};
pub use prepare::{
    BuildSource, OpenedMethod, PreparedScene, check_gpu_budget, load_scene, open_method,
};
pub use reference::Reference;
pub use summary::{FailedChunk, Medians, SceneStats, Summary, Tails, TrafficTotals};

/// Bump when the renderer's output changes through its Rust side (a shader's change is in the
/// key already: [`crate::render::image_shaders_hash`]), to invalidate cached reference images.
pub const REFERENCE_VERSION: u32 = 1;

/// The git commit this binary was built from.
pub const GIT_COMMIT: &str = env!("SPLATBENCH_GIT_COMMIT");

/// Everything a run needs.
#[derive(Debug, Clone)]
pub struct RunConfig {
    /// The method.
    pub method: MethodKind,
    /// Its parameters.
    pub params: Params,
    /// The scene.
    pub scene: SceneSpec,
    /// The camera path.
    pub path: PathSpec,
    /// Frames along the path.
    pub frames: usize,
    /// Tolerance or budget.
    pub target: Target,
    /// Renderer settings.
    pub render: RenderSettings,
    /// Seed (recorded; scenes and methods take theirs from their specs/params).
    pub seed: u64,
    /// Save every frame (and its reference) as PNG under `images/`.
    pub save_images: bool,
    /// Compare against the reference (image metrics).
    pub metrics: bool,
    /// Output directory.
    pub out: PathBuf,
    /// Cache directory (scenes, reference builds and images).
    pub cache: PathBuf,
    /// Open this existing build directory instead of building into `out/build` (its
    /// `method.json` must name the same method, scene and sample count; `params` may only
    /// change the method's runtime parameters, [`MethodKind::runtime_params`]). Lets a run
    /// measure the method alone, without the build's memory, and compare runtime settings
    /// (e.g. LPC's `occlusion`, `core_mb`) on one build.
    pub build_dir: Option<PathBuf>,
    /// Open the build served at this URL (`splatbench serve`) instead: its small files are
    /// copied once into `out/remote-build/`, its chunks read by HTTP range requests
    /// ([`MethodKind::fetch_remote`]; LPC, MWKD, Potree and voxel). The same checks as
    /// `build_dir`.
    pub build_url: Option<RemoteBuild>,
    /// Finish with exit status 0 although chunks failed to load (`--allow-missing-chunks`);
    /// they are reported either way.
    pub allow_missing_chunks: bool,
    /// The rasteriser of the reference images (`--reference-raster`; `None`: the run's).
    /// `compute` draws the reference as square splats whatever the run's kernel: ≈ 15×
    /// faster on lavapipe, what makes references of 10⁸ samples affordable.
    pub reference_raster: Option<crate::render::Raster>,
    /// The splat kernel of the reference images (`--reference-kernel`; `None`: the run's):
    /// what compares runs of different kernels against one image of the full cloud.
    pub reference_kernel: Option<crate::render::Kernel>,
}

/// The settings the reference images of a run drawn with `render` use: the run's, with
/// `kernel` as their kernel and `raster` as their rasteriser when given (square splats for
/// `compute`, the only kernel it draws: a kernel other than square with `compute` is refused
/// where the flags are read).
pub fn reference_settings(
    render: RenderSettings,
    raster: Option<crate::render::Raster>,
    kernel: Option<crate::render::Kernel>,
) -> RenderSettings {
    let render = RenderSettings {
        kernel: kernel.unwrap_or(render.kernel),
        ..render
    };
    match raster {
        None => render,
        Some(crate::render::Raster::Compute) => RenderSettings {
            raster: crate::render::Raster::Compute,
            kernel: crate::render::Kernel::Square,
            ..render
        },
        Some(r) => RenderSettings {
            raster: r,
            ..render
        },
    }
}

/// How long one HTTP request of a remote build may take unless told (`--remote-timeout`).
pub const REMOTE_TIMEOUT: std::time::Duration = std::time::Duration::from_secs(30);

/// A build served over HTTP (`--build-url`).
#[derive(Debug, Clone, PartialEq)]
pub struct RemoteBuild {
    /// The URL of the build directory.
    pub url: String,
    /// How long one request may take, connection to last byte ([`REMOTE_TIMEOUT`] by
    /// default): a server that never answers ends the run with an error after this long.
    pub timeout: std::time::Duration,
}

/// The view of frame `i`.
pub fn frame_view(
    path: &PathSpec,
    i: usize,
    frames: usize,
    bounds: &Aabb,
    r: RenderSettings,
) -> View {
    View {
        camera: path.camera(i, frames, bounds),
        width: r.width,
        height: r.height,
    }
}

/// The most frames one run may have: a run keeps a row (≈ 300 bytes) per frame, and a
/// million frames at 60 fps are already 4.6 hours of camera path.
pub const MAX_FRAMES: usize = 1_000_000;

/// Runs one configuration; returns the summary (also written to `out/summary.json`).
pub fn run(cfg: &RunConfig, gpu: &Gpu, progress: &dyn Progress) -> anyhow::Result<Summary> {
    let t_run = Instant::now();
    let target = check_config(cfg)?;
    std::fs::create_dir_all(&cfg.out)
        .with_context(|| format!("creating output directory {}", cfg.out.display()))?;
    let prepared = load_scene(&cfg.scene, cfg.render, &cfg.cache, progress)?;
    let mut scene_warnings = prepared.warnings.clone();
    let OpenedMethod {
        method,
        build,
        params,
        warnings,
    } = open_build(cfg, &prepared, progress)?;
    scene_warnings.extend(warnings);
    check_gpu_budget(cfg.method, method.as_ref(), cfg.render.cache_bytes)?;
    let renderer = Renderer::new(gpu, prepared.render)?;
    let summary = initial_summary(cfg, gpu, &prepared, scene_warnings, build, params, target);
    let PreparedScene {
        cloud,
        bounds,
        hash: scene_hash,
        label,
        render,
        ..
    } = prepared;
    let reference = cfg.metrics.then(|| {
        Reference::new(
            gpu,
            &cloud,
            label.clone(),
            scene_hash,
            &cfg.cache,
            reference_settings(render, cfg.reference_raster, cfg.reference_kernel),
        )
    });
    let summary_path = cfg.out.join("summary.json");
    write_json(&summary_path, &summary)?;
    let columns = frame_columns(method.as_ref());
    let frames = FramesWriter::create(&cfg.out, &columns)?;
    let images = cfg.out.join("images");
    if cfg.save_images {
        std::fs::create_dir_all(&images)
            .with_context(|| format!("creating {}", images.display()))?;
    }
    let mut run = PathRun {
        cfg,
        progress,
        target,
        bounds,
        render,
        label,
        images,
        summary,
        frames,
        reference,
        renderer,
        method,
    };
    run.warm_up()?;
    let (rows, traffic) = run.frames()?;
    run.finish(&rows, &traffic, &summary_path, t_run)
}

/// Checks what a run can check before it loads anything: the frame count, the target, the
/// method's parameters and whether the frame's images fit in memory ([`crate::memory`]).
/// Returns the validated target.
fn check_config(cfg: &RunConfig) -> anyhow::Result<Target> {
    anyhow::ensure!(cfg.frames >= 1, "--frames must be at least 1");
    anyhow::ensure!(
        cfg.frames <= MAX_FRAMES,
        "--frames {} is more than the limit {MAX_FRAMES} (a run keeps a row per frame in memory)",
        cfg.frames
    );
    let target = cfg.target.validate()?;
    cfg.method.check_params(&cfg.params)?;
    crate::memory::check_frame(&cfg.render, cfg.metrics)?;
    Ok(target)
}

/// Builds the method into `out/build`, or opens the build `--build-dir` or `--build-url`
/// names (not both).
fn open_build(
    cfg: &RunConfig,
    prepared: &PreparedScene,
    progress: &dyn Progress,
) -> anyhow::Result<OpenedMethod> {
    anyhow::ensure!(
        cfg.build_dir.is_none() || cfg.build_url.is_none(),
        "--build-dir and --build-url name two builds: give one"
    );
    let remote_dir = cfg.out.join("remote-build");
    let build_into = cfg.out.join("build");
    let source = match (&cfg.build_dir, &cfg.build_url) {
        (Some(dir), _) => BuildSource::Dir(dir),
        (None, Some(remote)) => BuildSource::Remote(remote, &remote_dir),
        (None, None) => BuildSource::Build(&build_into),
    };
    open_method(cfg.method, &cfg.params, prepared, source, progress)
}

/// The summary as it stands before the first frame (`complete: false`, no medians): the
/// configuration, the adapter, the scene (with `warnings`), the build and its `params`.
fn initial_summary(
    cfg: &RunConfig,
    gpu: &Gpu,
    prepared: &PreparedScene,
    warnings: Vec<String>,
    build: BuildStats,
    params: Params,
    target: Target,
) -> Summary {
    let PreparedScene {
        cloud,
        bounds,
        outside,
        hash: scene_hash,
        label,
        render,
        ..
    } = prepared;
    let reference_render = reference_settings(*render, cfg.reference_raster, cfg.reference_kernel);
    Summary {
        complete: false,
        adapter: gpu.adapter.clone(),
        git_commit: GIT_COMMIT.into(),
        command: crate::results::invocation(),
        seed: cfg.seed,
        width: cfg.render.width,
        height: cfg.render.height,
        method: cfg.method.name().into(),
        params,
        target,
        kernel: cfg.render.kernel,
        raster: cfg.render.raster,
        reference_raster: reference_render.raster,
        reference_kernel: reference_render.kernel,
        shading: render.shade.shading,
        path: cfg.path.name(),
        frames: cfg.frames,
        gpu_cache_budget_bytes: cfg.render.cache_bytes,
        scene: SceneStats {
            label: label.clone(),
            spec: cfg.scene.text.clone(),
            points: cloud.len() as u64,
            attributes: cloud.attributes().to_string(),
            bounds: cloud.bounds(),
            framed_bounds: *bounds,
            outside_frame: *outside,
            reference_radii_capped: None,
            origin: cloud.origin().to_array(),
            content_hash: format!("{scene_hash:016x}"),
            warnings,
        },
        build,
        splats_per_s_basis: if gpu.timestamps { "gpu_ms" } else { "wall_ms" },
        medians: Medians::default(),
        p95: Tails::default(),
        failed_chunks: Vec::new(),
        traffic: None,
        known_effect: None,
        peak_rss_bytes: 0,
        method_resident_bytes: 0,
        rss_max: None,
        run_seconds: 0.0,
    }
}

/// A run once its method is open and its outputs created: drives the method along the path
/// and records each frame.
struct PathRun<'a> {
    cfg: &'a RunConfig,
    progress: &'a dyn Progress,
    target: Target,
    /// The bounds the path frames.
    bounds: Aabb,
    /// The renderer settings (the scene's shading resolved).
    render: RenderSettings,
    /// The scene's label.
    label: String,
    /// Where frames and references are saved (`--save-images`).
    images: PathBuf,
    summary: Summary,
    // Dropped in this order, as the locals they were.
    frames: FramesWriter,
    reference: Option<Reference<'a>>,
    renderer: Renderer<'a>,
    method: Box<dyn LodMethod>,
}

impl PathRun<'_> {
    /// Warm-up (shader compilation, first uploads): untimed, not recorded; the cache is
    /// cleared so frame 0 pays its uploads like any cold start.
    fn warm_up(&mut self) -> anyhow::Result<()> {
        let v0 = frame_view(
            &self.cfg.path,
            0,
            self.cfg.frames,
            &self.bounds,
            self.render,
        );
        let warm = self.method.frame(&v0, self.target, &Feedback::default())?;
        self.renderer
            .draw(&v0, &warm, self.method.as_ref(), false)?;
        self.renderer.clear_cache();
        Ok(())
    }

    /// Draws every frame of the path, writing each to `frames.csv`; returns the rows and the
    /// method's traffic at the end.
    fn frames(&mut self) -> anyhow::Result<(Vec<FrameRow>, methods::store::access::Traffic)> {
        let cfg = self.cfg;
        let mut rows = Vec::with_capacity(cfg.frames);
        // Frame 0's traffic includes the warm-up frame's (the root and first requests).
        let mut traffic = methods::store::access::Traffic::default();
        let mut last: Option<(FrameStats, View)> = None;
        let mut path_metrics = PathMetrics::new();
        let label = &self.label;
        self.progress
            .start(&format!("{} on {label}", cfg.method), cfg.frames as u64);
        for i in 0..cfg.frames {
            let view = frame_view(&cfg.path, i, cfg.frames, &self.bounds, self.render);
            let feedback = next_feedback(i as u64, &self.renderer, last.as_ref(), &view);
            let (row, stats) = self.frame(i, &view, &feedback, &mut path_metrics, &mut traffic)?;
            rows.push(row);
            last = Some((stats, view));
            self.progress.inc(1);
        }
        self.progress.finish();
        Ok((rows, traffic))
    }

    /// Frame `i`: selects, draws, compares with the reference, records failed chunks and
    /// the frame's counters (`traffic`: the method's traffic before it, updated), and
    /// writes its row.
    fn frame(
        &mut self,
        i: usize,
        view: &View,
        feedback: &Feedback,
        path_metrics: &mut PathMetrics,
        traffic: &mut methods::store::access::Traffic,
    ) -> anyhow::Result<(FrameRow, FrameStats)> {
        let cfg = self.cfg;
        let t = Instant::now();
        let list = self
            .method
            .frame(view, self.target, feedback)
            .with_context(|| format!("{} frame {i}", cfg.method))?;
        let cpu_select_ms = t.elapsed().as_secs_f64() * 1e3;
        let need_image = self.reference.is_some() || cfg.save_images;
        let (stats, img) = self
            .renderer
            .draw(view, &list, self.method.as_ref(), need_image)?;
        if let (true, Some(img)) = (cfg.save_images, img.as_ref()) {
            img.save_png(&self.images.join(format!("frame_{i:04}.png")))?;
        }
        let (m, metrics_ms) = match img {
            Some(img) => self.compare(i, view, img, path_metrics)?,
            None => (None, None),
        };
        self.record_failed_chunks(i);
        let now = self.method.traffic();
        let counters = frame_counters(
            self.method.as_ref(),
            &list,
            &stats,
            self.summary.failed_chunks.len(),
            now.since(traffic),
        );
        *traffic = now;
        let row = self.frame_row(i, &stats, cpu_select_ms, m, metrics_ms);
        self.frames.push(&row, &counters)?;
        if let Some(b) = crate::rss::breakdown() {
            self.summary.rss_max = Some(self.summary.rss_max.map_or(b, |m| m.max(b)));
        }
        Ok((row, stats))
    }

    /// Compares frame `i`'s image with the reference image of its view (saved too with
    /// `--save-images`); returns the metrics and the milliseconds they took, `None` without
    /// a reference.
    fn compare(
        &mut self,
        i: usize,
        view: &View,
        img: Image,
        path_metrics: &mut PathMetrics,
    ) -> anyhow::Result<(Option<FrameMetrics>, Option<f64>)> {
        let Some(r) = self.reference.as_mut() else {
            return Ok((None, None));
        };
        let (ref_img, depth) = r.frame(view, self.progress)?;
        if self.cfg.save_images {
            ref_img.save_png(&self.images.join(format!("ref_{i:04}.png")))?;
        }
        let t = Instant::now();
        let m = path_metrics.frame_warped(view, depth, ref_img, img)?;
        Ok((Some(m), Some(t.elapsed().as_secs_f64() * 1e3)))
    }

    /// Adds the chunks that failed to load in frame `i` (and not before) to the summary,
    /// reporting each on stderr.
    fn record_failed_chunks(&mut self, i: usize) {
        for (id, error) in self.method.failed_chunks() {
            if !self.summary.failed_chunks.iter().any(|f| f.id == id) {
                eprintln!(
                    "error: frame {i}: {} chunk {id} failed to load: {error}",
                    self.cfg.method
                );
                self.summary.failed_chunks.push(FailedChunk {
                    id,
                    frame: i as u64,
                    error,
                });
            }
        }
    }

    /// The row of frame `i` in `frames.csv` (before the method's extra columns).
    fn frame_row(
        &self,
        i: usize,
        stats: &FrameStats,
        cpu_select_ms: f64,
        m: Option<FrameMetrics>,
        metrics_ms: Option<f64>,
    ) -> FrameRow {
        let (cfg, target) = (self.cfg, self.target);
        let denom = stats.gpu_ms.unwrap_or(stats.wall_ms);
        // Splats actually drawn: those that passed the GPU's LOD test, if there was one.
        let drawn = stats.gpu_passed.unwrap_or(stats.points);
        let lag = |k: usize| m.and_then(|m| m.warped[k]);
        FrameRow {
            frame: i as u64,
            method: cfg.method.name().into(),
            scene: self.label.clone(),
            path: cfg.path.name(),
            target: match target {
                Target::Tolerance(_) => "eps".into(),
                Target::Budget(_) => "budget".into(),
            },
            eps_px: target.eps_px().map(f64::from),
            budget: target.budget_points(),
            points_drawn: drawn,
            chunks_drawn: stats.chunks,
            gpu_ms: stats.gpu_ms,
            wall_ms: stats.wall_ms,
            cpu_select_ms,
            upload_bytes: stats.upload_bytes,
            splats_per_s: if denom > 0.0 {
                drawn as f64 / denom * 1e3
            } else {
                0.0
            },
            rss_bytes: crate::rss::current_bytes(),
            gpu_cache_bytes: stats.cache_bytes,
            psnr_db: m.map(|m| m.image.psnr_db),
            ssim: m.map(|m| m.image.ssim),
            flip_mean: m.map(|m| m.image.flip_mean),
            hole_ratio: m.map(|m| m.image.hole_ratio),
            extra_coverage: m.map(|m| m.image.extra_coverage),
            popping_flip: m.and_then(|m| m.popping_flip),
            warped_flip_l1: lag(0).map(|l| l.method),
            warped_ref_flip_l1: lag(0).map(|l| l.reference),
            popping_warped_l1: lag(0).map(|l| l.popping()),
            pop_events_l1: lag(0).map(|l| l.pops),
            warp_valid_l1: lag(0).map(|l| l.valid),
            warped_flip_l7: lag(1).map(|l| l.method),
            warped_ref_flip_l7: lag(1).map(|l| l.reference),
            popping_warped_l7: lag(1).map(|l| l.popping()),
            pop_events_l7: lag(1).map(|l| l.pops),
            warp_valid_l7: lag(1).map(|l| l.valid),
            metrics_ms,
        }
    }

    /// Completes the summary after the last frame (the reference's capped radii, medians of
    /// `rows`, `traffic` totals, memory, duration since `t_run`), writes it to
    /// `summary_path`, and fails the run when chunks failed to load without
    /// `--allow-missing-chunks`.
    fn finish(
        self,
        rows: &[FrameRow],
        traffic: &methods::store::access::Traffic,
        summary_path: &Path,
        t_run: Instant,
    ) -> anyhow::Result<Summary> {
        let cfg = self.cfg;
        let mut summary = self.summary;
        summary.scene.reference_radii_capped =
            self.reference.as_ref().and_then(Reference::radii_capped);
        if let Some(n) = summary.scene.reference_radii_capped.filter(|&n| n > 0) {
            let w = format!(
                "{}: the reference capped the splat radius of {n} isolated samples (k-NN radius \
                 above {} × its {} quantile)",
                cfg.scene.text,
                methods::leaf::OUTLIER_CAP,
                methods::leaf::OUTLIER_QUANTILE
            );
            eprintln!("warning: {w}");
            summary.scene.warnings.push(w);
        }
        summary.medians = Medians::of(rows);
        summary.p95 = Tails::of(rows);
        summary.known_effect = cfg.method.known_effect(
            &summary.params,
            &methods::Observed {
                hole_ratio: summary.medians.hole_ratio,
            },
        );
        let method = &self.method;
        if method.loads_chunks() {
            summary.traffic = Some(TrafficTotals::of(traffic, method.throughput()));
        }
        summary.peak_rss_bytes = crate::rss::peak_bytes();
        summary.method_resident_bytes = method.stats().resident_bytes;
        summary.run_seconds = t_run.elapsed().as_secs_f64();
        let failed = summary.failed_chunks.len();
        summary.complete = failed == 0 || cfg.allow_missing_chunks;
        write_json(summary_path, &summary)?;
        if !summary.complete {
            let first = &summary.failed_chunks[0];
            anyhow::bail!(
                "{failed} chunk(s) of {} failed to load (first, in frame {}: {}): the frames drew \
                 without them, so {} is not a faithful measurement (summary.json says \
                 \"complete\": false and lists them; --allow-missing-chunks accepts them)",
                cfg.method,
                first.frame,
                first.error,
                cfg.out.display()
            );
        }
        Ok(summary)
    }
}
