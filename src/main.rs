//! `splatbench`: build LOD representations of point clouds, run them along camera paths on a
//! GPU (wgpu; Mesa's lavapipe where there is none), and record speed and image error.
//!
//! Errors print as `Error: {:#}` (the whole context chain) and exit with status 1.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context as _, bail};
use clap::{Args, Parser, Subcommand};
use harness::gpu::Gpu;
use harness::render::{Kernel, RenderSettings};
use harness::runner::{RunConfig, Summary};
use methods::{MethodKind, Params, Target};
use scenes::SceneSpec;
use scenes::paths::PathSpec;

/// The scene the demo uses: generated, so it needs no download.
const DEMO_SCENE: &str = "statue:60000:1";

#[derive(Parser)]
#[command(
    name = "splatbench",
    version,
    about = "Benchmark harness for multiresolution point rendering (QSplat, SPT, LPC, MWKD)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// List methods, scene generators, camera paths and kernels.
    List,
    /// Build a method's representation of a scene into a directory.
    Build {
        #[command(flatten)]
        method: MethodArgs,
        #[command(flatten)]
        scene: SceneArgs,
        /// Output directory.
        #[arg(long)]
        out: PathBuf,
        /// Cache directory for large generated scenes.
        #[arg(long, default_value = "results/cache")]
        cache: PathBuf,
    },
    /// Build, then run a camera path, writing frames.csv, summary.json and plots.
    Run(RunArgs),
    /// Plot run directories (timeline per run, one comparison across them).
    Plot {
        /// Run directories (each with frames.csv).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Where the comparison plot goes (default: the first directory's parent).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Build once, then run the camera path at several budgets or tolerances: a run directory
    /// per target, `sweep.csv` (medians per target) and `sweep.png/.svg` (FLIP against points
    /// drawn).
    Sweep(SweepArgs),
    /// Overlay several sweeps' curves in one plot (`sweep-comparison.png/.svg`).
    PlotSweep {
        /// Sweep directories (each with sweep.csv).
        #[arg(required = true)]
        dirs: Vec<PathBuf>,
        /// Where the comparison plot goes.
        #[arg(long)]
        out: PathBuf,
    },
    /// Write a scene to a file: `.las`/`.laz` (LAS 1.4), `.ply` (binary little-endian) or
    /// `.sbc` (splatbench column file), by the extension of `--out`.
    Export {
        #[command(flatten)]
        scene: SceneArgs,
        /// Output file.
        #[arg(long)]
        out: PathBuf,
        /// Cache directory for large generated scenes.
        #[arg(long, default_value = "results/cache")]
        cache: PathBuf,
    },
    /// A method's tree shape for a number of points, without data (levels, nodes, leaves,
    /// samples per node). Answered by `mwkd`; data-dependent methods say they cannot.
    Plan(PlanArgs),
    /// Every registered method on the embedded scene along a short orbit: CSV + plots.
    Demo {
        /// Output directory.
        #[arg(long, default_value = "results/demo")]
        out: PathBuf,
        /// Frames along the orbit.
        #[arg(long, default_value_t = 24)]
        frames: usize,
    },
}

#[derive(Args, Clone)]
struct MethodArgs {
    /// Method.
    #[arg(long, value_enum)]
    method: MethodKind,
    /// Method parameter, `key=value` (repeatable).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
}

#[derive(Args, Clone)]
struct SceneArgs {
    /// Scene: `generator:points[:seed]` (e.g. statue:200000), or a .ply/.las/.laz/.sbc/.toml file.
    #[arg(long)]
    scene: String,
    /// Resample a PLY mesh surface to this many points.
    #[arg(long)]
    sample: Option<usize>,
    /// Seed for generators and resampling that do not name their own.
    #[arg(long, default_value_t = 1)]
    seed: u64,
}

#[derive(Args, Clone)]
struct RenderArgs {
    /// Image width, pixels.
    #[arg(long, default_value_t = 512)]
    width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 512)]
    height: u32,
    /// Splat kernel (a method's `--param kernel=` overrides it).
    #[arg(long, value_enum, default_value = "square")]
    kernel: Kernel,
    /// GPU chunk-cache budget, MiB.
    #[arg(long, default_value_t = 512)]
    gpu_cache_mb: u64,
}

#[derive(Args, Clone)]
#[group(multiple = false)]
struct TargetArgs {
    /// Pixel tolerance (default 1).
    #[arg(long, allow_negative_numbers = true)]
    eps: Option<f32>,
    /// Point budget per frame.
    #[arg(long)]
    budget: Option<u64>,
}

#[derive(Args, Clone)]
struct RunArgs {
    #[command(flatten)]
    method: MethodArgs,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    render: RenderArgs,
    #[command(flatten)]
    target: TargetArgs,
    /// Camera path: orbit, zoom, flythrough, or a keyframe .toml file.
    #[arg(long, default_value = "orbit")]
    path: String,
    /// Frames along the path.
    #[arg(long, default_value_t = 60)]
    frames: usize,
    /// Save every frame and its reference as PNG under images/.
    #[arg(long)]
    save_images: bool,
    /// Skip the reference and the image metrics (speed only).
    #[arg(long)]
    no_metrics: bool,
    /// Output directory.
    #[arg(long)]
    out: PathBuf,
    /// Cache directory (large scenes, reference builds and images).
    #[arg(long, default_value = "results/cache")]
    cache: PathBuf,
    /// Run an existing build (a `splatbench build --out` directory of the same method and
    /// scene) instead of building: the run's memory is then the method's alone. `--param`
    /// may change only runtime parameters (LPC: fetch_per_frame, core_mb, delay_frames,
    /// occlusion, occlusion_threshold).
    #[arg(long)]
    build_dir: Option<PathBuf>,
}

#[derive(Args, Clone)]
struct SweepArgs {
    #[command(flatten)]
    method: MethodArgs,
    #[command(flatten)]
    scene: SceneArgs,
    #[command(flatten)]
    render: RenderArgs,
    /// Point budgets per frame, comma-separated, one run each (e.g. 25000,50000,100k).
    #[arg(long, value_name = "POINTS,...", allow_hyphen_values = true)]
    budgets: Option<String>,
    /// Pixel tolerances, comma-separated, one run each (e.g. 8,4,2,1).
    #[arg(long, value_name = "PX,...", allow_hyphen_values = true)]
    eps: Option<String>,
    /// Camera path: orbit, zoom, flythrough, or a keyframe .toml file.
    #[arg(long, default_value = "orbit")]
    path: String,
    /// Frames along the path.
    #[arg(long, default_value_t = 60)]
    frames: usize,
    /// Output directory: build/ (unless --build-dir), one run directory per target
    /// (budget-25000/, eps-2/, …), sweep.csv, sweep.png and sweep.svg.
    #[arg(long)]
    out: PathBuf,
    /// Cache directory (large scenes, reference builds and images).
    #[arg(long, default_value = "results/cache")]
    cache: PathBuf,
    /// Run every target on an existing build (as `run --build-dir`) instead of building into
    /// OUT/build; `--param` may then change only runtime parameters.
    #[arg(long)]
    build_dir: Option<PathBuf>,
}

/// One target of a sweep.
struct SweepTarget {
    /// The target.
    target: Target,
    /// Its value as `sweep.csv` records it (a budget's points, a tolerance's pixels).
    value: f64,
    /// Its run directory's name: `budget-25000`, `eps-2`.
    name: String,
}

#[derive(Args, Clone)]
struct PlanArgs {
    /// Method (`mwkd`, or a registered one).
    #[arg(long)]
    method: Option<String>,
    /// Number of input points (digits, `_` separators, k/M/G suffix).
    #[arg(long)]
    points: Option<String>,
    /// Method parameter, `key=value` (repeatable), e.g. fanout=6, vbo=4009.
    #[arg(long = "param", value_name = "KEY=VALUE")]
    params: Vec<String>,
    /// Print JSON instead of the table.
    #[arg(long)]
    json: bool,
}

fn main() {
    if let Err(e) = real_main() {
        eprintln!("Error: {e:#}");
        std::process::exit(1);
    }
}

fn real_main() -> anyhow::Result<()> {
    let cli = Cli::parse();
    match cli.command {
        Command::List => list(),
        Command::Build {
            method,
            scene,
            out,
            cache,
        } => {
            let stats = build(&method, &scene, &out, &cache)?;
            println!("{}", serde_json::to_string_pretty(&stats)?);
            Ok(())
        }
        Command::Run(args) => {
            let gpu = open_gpu()?;
            let cfg = run_config(&args)?;
            let s = harness::runner::run(&cfg, &gpu, &harness::progress::Bar::new())?;
            let plots = harness::plot::plot_run(&cfg.out)?;
            print_summary(&s);
            println!(
                "wrote {}/frames.csv, summary.json and {} plot files",
                cfg.out.display(),
                plots.len()
            );
            Ok(())
        }
        Command::Plot { dirs, out } => {
            for d in &dirs {
                harness::plot::plot_run(d)?;
            }
            let out = out.unwrap_or_else(|| {
                dirs[0]
                    .parent()
                    .map(PathBuf::from)
                    .unwrap_or_else(|| PathBuf::from("."))
            });
            let files = harness::plot::plot_comparison(&dirs, &out)?;
            for f in files {
                println!("{}", f.display());
            }
            Ok(())
        }
        Command::Sweep(args) => sweep(&args),
        Command::PlotSweep { dirs, out } => {
            for f in harness::plot::plot_sweeps(&dirs, &out)? {
                println!("{}", f.display());
            }
            Ok(())
        }
        Command::Export { scene, out, cache } => export(&scene, &out, &cache),
        Command::Plan(args) => plan(&args),
        Command::Demo { out, frames } => demo(&out, frames),
    }
}

fn plan(a: &PlanArgs) -> anyhow::Result<()> {
    use methods::mwkd;
    let Some(name) = a.method.as_deref() else {
        bail!("--method is required (e.g. --method {})", mwkd::NAME);
    };
    let params = Params::parse(&a.params)?;
    if name != mwkd::NAME {
        match MethodKind::from_name(name) {
            Ok(kind) => bail!(
                "method '{kind}' cannot plan without data: its structure depends on the sample \
                 positions (build it with `splatbench build --method {kind}`); `plan` answers \
                 for: {}",
                mwkd::NAME
            ),
            Err(e) => bail!("{e}"),
        }
    }
    let Some(points) = a.points.as_deref() else {
        bail!("--points is required (the number of input samples, e.g. --points 186850683)");
    };
    let n = scenes::spec::parse_count(points).map_err(|e| anyhow::anyhow!("--points: {e}"))?;
    let p = mwkd::MwkdParams::from_params(&params)?;
    if p.tree == mwkd::TreeKind::Octree {
        bail!(
            "--param tree=octree: an octree's shape depends on the data; only tree=mwkd and tree=kd can be planned"
        );
    }
    let plan = mwkd::tree::Plan::new(n as u64, u64::from(p.effective_fanout()), p.vbo)?;
    if a.json {
        println!("{}", serde_json::to_string_pretty(&plan.to_json())?);
    } else {
        print!("{}", plan.table());
    }
    Ok(())
}

fn list() -> anyhow::Result<()> {
    println!("methods:");
    for m in MethodKind::ALL {
        println!("  {:<12} {}", m.name(), m.describe());
    }
    println!("scene generators (generator:points[:seed]):");
    for g in scenes::generators::Generator::ALL {
        println!("  {:<12} {}", g.name(), g.describe());
    }
    println!("camera paths (or a keyframe .toml file):");
    for (name, what) in PathSpec::BUILTIN {
        println!("  {name:<12} {what}");
    }
    println!("kernels:");
    for k in Kernel::ALL {
        println!("  {}", k.name());
    }
    Ok(())
}

fn build(
    m: &MethodArgs,
    s: &SceneArgs,
    out: &std::path::Path,
    cache: &std::path::Path,
) -> anyhow::Result<methods::BuildStats> {
    let params = Params::parse(&m.params)?;
    m.method.check_params(&params)?;
    let spec = SceneSpec::parse(&s.scene, s.sample, s.seed)?;
    let bar = harness::progress::Bar::new();
    let cloud = spec
        .load(Some(cache), &bar)
        .with_context(|| format!("loading scene '{}'", s.scene))?;
    Ok(m.method.build(&cloud, &params, &spec.label(), out, &bar)?)
}

fn export(s: &SceneArgs, out: &std::path::Path, cache: &std::path::Path) -> anyhow::Result<()> {
    let ext = out
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .unwrap_or_default();
    if !matches!(ext.as_str(), "las" | "laz" | "ply" | "sbc") {
        bail!(
            "--out {}: the extension must be .las, .laz, .ply or .sbc",
            out.display()
        );
    }
    let spec = SceneSpec::parse(&s.scene, s.sample, s.seed)?;
    let cloud = spec
        .load(Some(cache), &harness::progress::Bar::new())
        .with_context(|| format!("loading scene '{}'", s.scene))?;
    let bytes = match ext.as_str() {
        "las" | "laz" => scenes::las::write(out, &cloud)?,
        "ply" => scenes::ply::write(out, &cloud, scenes::ply::PlyFormat::BinaryLittleEndian)?,
        _ => scenes::colfile::write(out, &cloud)?,
    };
    println!(
        "wrote {} ({} points, {}, {bytes} bytes)",
        out.display(),
        cloud.len(),
        cloud.attributes()
    );
    Ok(())
}

fn run_config(a: &RunArgs) -> anyhow::Result<RunConfig> {
    let params = Params::parse(&a.method.params)?;
    let target = match (a.target.eps, a.target.budget) {
        (_, Some(b)) => Target::budget(b)?,
        (e, None) => Target::tolerance(e.unwrap_or(1.0))?,
    };
    Ok(RunConfig {
        method: a.method.method,
        params,
        scene: SceneSpec::parse(&a.scene.scene, a.scene.sample, a.scene.seed)?,
        path: PathSpec::parse(&a.path)?,
        frames: a.frames,
        target,
        render: RenderSettings {
            width: a.render.width,
            height: a.render.height,
            kernel: a.render.kernel,
            cache_bytes: a
                .render
                .gpu_cache_mb
                .checked_mul(1 << 20)
                .context("--gpu-cache-mb is too large")?,
        },
        seed: a.scene.seed,
        save_images: a.save_images,
        metrics: !a.no_metrics,
        out: a.out.clone(),
        cache: a.cache.clone(),
        build_dir: a.build_dir.clone(),
    })
}

/// `splatbench sweep`: targets, parameters, scene spec, path and frames are checked before
/// anything is built or rendered; then one build (or `--build-dir`, checked by the runner at
/// the first target), one ordinary run per target (each through [`run_config`] with
/// `build_dir` set, so the runner's `--build-dir` path opens it), then `sweep.csv` and its plot.
fn sweep(a: &SweepArgs) -> anyhow::Result<()> {
    let targets = sweep_targets(a.budgets.as_deref(), a.eps.as_deref())?;
    anyhow::ensure!(a.frames >= 1, "--frames must be at least 1");
    let params = Params::parse(&a.method.params)?;
    a.method.method.check_params(&params)?;
    let build_dir = a.build_dir.clone().unwrap_or_else(|| a.out.join("build"));
    let configs = targets
        .iter()
        .map(|t| {
            run_config(&RunArgs {
                method: MethodArgs {
                    method: a.method.method,
                    // A build of our own already holds every --param (its method.json records
                    // them); the runner lets a run of a build change runtime parameters only.
                    params: if a.build_dir.is_some() {
                        a.method.params.clone()
                    } else {
                        Vec::new()
                    },
                },
                scene: a.scene.clone(),
                render: a.render.clone(),
                target: TargetArgs {
                    eps: t.target.eps_px(),
                    budget: t.target.budget_points(),
                },
                path: a.path.clone(),
                frames: a.frames,
                save_images: false,
                no_metrics: false,
                out: a.out.join(&t.name),
                cache: a.cache.clone(),
                build_dir: Some(build_dir.clone()),
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let gpu = open_gpu()?;
    std::fs::create_dir_all(&a.out).with_context(|| format!("creating {}", a.out.display()))?;
    // A sweep.csv (or plot) of an earlier sweep must not outlive a failure of this one.
    for stale in ["sweep.csv", "sweep.png", "sweep.svg"] {
        let p = a.out.join(stale);
        match std::fs::remove_file(&p) {
            Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
                return Err(e).with_context(|| format!("removing the old {}", p.display()));
            }
            _ => {}
        }
    }
    if a.build_dir.is_none() {
        eprintln!("building {} into {}", a.method.method, build_dir.display());
        build(&a.method, &a.scene, &build_dir, &a.cache)?;
    }
    let bar = harness::progress::Bar::new();
    let mut rows = Vec::with_capacity(targets.len());
    for (cfg, t) in configs.iter().zip(&targets) {
        let s = harness::runner::run(cfg, &gpu, &bar)
            .and_then(|s| harness::plot::plot_run(&cfg.out).map(|_| s))
            .with_context(|| format!("sweep target {}", t.name))?;
        print_summary(&s);
        let frames = harness::plot::read_frames(&cfg.out.join("frames.csv"))?;
        let params = s
            .params
            .0
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ");
        rows.push(harness::plot::SweepRow::of_run(&frames, &params, t.value)?);
    }
    let csv = a.out.join("sweep.csv");
    harness::plot::write_sweep(&csv, &rows)?;
    let plots = harness::plot::plot_sweep(&a.out)?;
    println!(
        "wrote {} ({} targets), {} and {} run directories",
        csv.display(),
        rows.len(),
        plots
            .iter()
            .map(|p| p.display().to_string())
            .collect::<Vec<_>>()
            .join(", "),
        configs.len()
    );
    Ok(())
}

/// The targets of `--budgets` or `--eps` (exactly one of them), in the order given. Empty
/// lists and items, non-numbers, a budget of 0, a negative or non-finite tolerance and a
/// target given twice are errors naming the flag.
fn sweep_targets(budgets: Option<&str>, eps: Option<&str>) -> anyhow::Result<Vec<SweepTarget>> {
    let (flag, list) = match (budgets, eps) {
        (Some(_), Some(_)) => {
            bail!("--budgets and --eps are exclusive: a sweep varies one kind of target")
        }
        (None, None) => bail!(
            "a sweep needs its targets: --budgets POINTS,... (e.g. 25000,50000,100000) or \
             --eps PX,... (e.g. 8,4,2,1)"
        ),
        (Some(b), None) => ("--budgets", b),
        (None, Some(e)) => ("--eps", e),
    };
    if list.trim().is_empty() {
        bail!("{flag}: the list is empty (give comma-separated values, e.g. {flag} 4,2,1)");
    }
    let mut targets: Vec<SweepTarget> = Vec::new();
    for (i, item) in list.split(',').map(str::trim).enumerate() {
        if item.is_empty() {
            bail!("{flag} {list}: value {} is empty", i + 1);
        }
        let t = if flag == "--budgets" {
            let n = scenes::spec::parse_count(item)
                .map_err(|e| anyhow::anyhow!("{flag}: budget '{item}': {e}"))?;
            let target = Target::budget(n as u64)?;
            SweepTarget {
                target,
                value: n as f64,
                name: format!("budget-{n}"),
            }
        } else {
            let px: f32 = item.parse().map_err(|_| {
                anyhow::anyhow!("{flag}: '{item}' is not a number of pixels (e.g. 2 or 0.5)")
            })?;
            let px = if px == 0.0 { 0.0 } else { px }; // -0 → 0
            let target = Target::tolerance(px).map_err(|_| {
                anyhow::anyhow!(
                    "{flag}: '{item}': a tolerance must be a finite number of pixels ≥ 0"
                )
            })?;
            // f32's shortest text, so that 0.1 is recorded as 0.1, not 0.10000000149.
            let text = px.to_string();
            SweepTarget {
                target,
                value: text.parse()?,
                name: format!("eps-{text}"),
            }
        };
        if let Some(same) = targets.iter().find(|o| o.name == t.name) {
            bail!("{flag}: {} is given twice", same.value);
        }
        targets.push(t);
    }
    Ok(targets)
}

fn open_gpu() -> anyhow::Result<Gpu> {
    match Gpu::new()? {
        Some(g) => {
            eprintln!(
                "adapter: {} ({}, {})",
                g.adapter.name, g.adapter.backend, g.adapter.device_type
            );
            Ok(g)
        }
        None => bail!(
            "no GPU adapter found: install Mesa's software Vulkan driver (scripts/setup.sh: \
             mesa-vulkan-drivers libvulkan1) or run on a machine with a GPU"
        ),
    }
}

fn print_summary(s: &Summary) {
    let f = |v: Option<f64>| v.map(|v| format!("{v:.4}")).unwrap_or_else(|| "-".into());
    println!(
        "{:<8} {:<22} frames {:>4}  points {:>10}  {} ms {:>8}  splats/s {:>12}  flip {:>7}  holes {:>7}",
        s.method,
        s.scene.label,
        s.frames,
        f(s.medians.points_drawn),
        s.splats_per_s_basis,
        f(s.medians.gpu_ms.or(s.medians.wall_ms)),
        f(s.medians.splats_per_s),
        f(s.medians.flip_mean),
        f(s.medians.hole_ratio),
    );
}

fn demo(out: &std::path::Path, frames: usize) -> anyhow::Result<()> {
    let t0 = Instant::now();
    let gpu = open_gpu()?;
    let bar = harness::progress::Bar::new();
    let mut dirs = Vec::new();
    println!(
        "demo: every method on the embedded scene {DEMO_SCENE}, {frames} frames of orbit, 512x512, eps 1 px"
    );
    for m in MethodKind::ALL {
        let dir = out.join(m.name());
        let cfg = RunConfig {
            method: *m,
            params: Params::default(),
            scene: SceneSpec::parse(DEMO_SCENE, None, 1)?,
            path: PathSpec::parse("orbit")?,
            frames,
            target: Target::tolerance(1.0)?,
            render: RenderSettings::default(),
            seed: 1,
            save_images: false,
            metrics: true,
            out: dir.clone(),
            cache: out.join("cache"),
            build_dir: None,
        };
        let s = harness::runner::run(&cfg, &gpu, &bar)?;
        harness::plot::plot_run(&dir)?;
        print_summary(&s);
        dirs.push(dir);
    }
    let files = harness::plot::plot_comparison(&dirs, out)?;
    println!(
        "demo done in {:.1} s: {} run directories, comparison plots {}",
        t0.elapsed().as_secs_f64(),
        dirs.len(),
        files
            .iter()
            .map(|f| f.display().to_string())
            .collect::<Vec<_>>()
            .join(", ")
    );
    Ok(())
}
