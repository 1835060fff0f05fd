//! `splatbench`: build LOD representations of point clouds, run them along camera paths on a
//! GPU (wgpu; Mesa's lavapipe where there is none), and record speed and image error.
//!
//! One file per subcommand (its argument struct and its function); shared argument groups
//! are in [`args`]. What a command computes lives in the library crates.
//!
//! Errors print as `Error: {:#}` (the whole context chain) and exit with status 1 (`check`:
//! 1 on a regression, 2 on input it cannot compare).

mod args;
mod build;
mod cache;
mod check;
mod demo;
mod export;
mod jobs;
mod list;
mod merge;
mod plan;
mod plot;
mod reproduce;
mod run;
mod sampling;
mod serve;
mod shared;
mod sweep;
mod tune;
mod view;

use clap::{Parser, Subcommand};

/// `--version`: the package version and the commit the binary was built from, so a figure
/// measured with a binary can name it (e.g. `scripts/build-vs-potree.sh`).
static VERSION: std::sync::LazyLock<String> = std::sync::LazyLock::new(|| {
    format!(
        "{} ({})",
        env!("CARGO_PKG_VERSION"),
        harness::runner::GIT_COMMIT
    )
});

#[derive(Parser)]
#[command(
    name = "splatbench",
    version = VERSION.as_str(),
    about = "Benchmark harness for multiresolution point rendering (QSplat, SPT, LPC, MWKD)"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
    /// Run even when a frame's images are estimated to need more memory than is available
    /// (the estimate and its measurement: `harness::memory`; `SPLATBENCH_MEMORY_LIMIT_MB`
    /// caps what a run counts on).
    #[arg(long, global = true)]
    skip_memory_check: bool,
}

#[derive(Subcommand)]
enum Command {
    /// List methods, scene generators, camera paths and kernels.
    List,
    /// Build a method's representation of a scene into a directory.
    Build(build::BuildArgs),
    /// Build, then run a camera path, writing frames.csv, summary.json and plots.
    Run(run::RunArgs),
    /// Plot run directories (timeline per run, one comparison across them).
    Plot(plot::PlotArgs),
    /// Build once, then run the camera path at several budgets or tolerances: a run directory
    /// per target, `sweep.csv` (medians per target) and `sweep.png/.svg` (FLIP against points
    /// drawn).
    Sweep(sweep::SweepArgs),
    /// Overlay several sweeps' curves in one plot (`sweep-comparison.png/.svg`).
    PlotSweep(plot::PlotSweepArgs),
    /// Write a scene to a file: `.las`/`.laz` (LAS 1.2, 1.4 above 2³² − 1 points; positions
    /// and colours), `.ply` (binary little-endian) or `.sbc` (splatbench column file), by the
    /// extension of `--out`.
    Export(export::ExportArgs),
    /// A method's tree shape for a number of points, without data (levels, nodes, leaves,
    /// samples per node). Answered by `mwkd`; data-dependent methods say they cannot.
    Plan(plan::PlanArgs),
    /// How regularly scenes sample their surfaces: nearest-neighbour spread and the bare
    /// fraction of discs of the average spacing (random samples: CV 0.52, bare 0.37).
    Sampling(sampling::SamplingArgs),
    /// Every registered method on the embedded scene along a short orbit: CSV + plots.
    Demo(demo::DemoArgs),
    /// Regenerate the papers' tables from `paper/specs/`: ours beside the paper's numbers,
    /// a verdict per table, the report in OUT/report.md (and with --publish in paper/).
    Reproduce(reproduce::ReproduceArgs),
    /// Where the cache is (scenes, reference images and builds), its size, and --clear.
    Cache(cache::CacheCommandArgs),
    /// Compare a run, sweep, tune or reproduction (or a regression suite, run first) with a
    /// baseline: a table of what changed; exit 0 when all holds, 1 on a regression, 2 on
    /// input that cannot be compared. `--bless` writes the baseline.
    Check(check::CheckArgs),
    /// A grid over a method's parameters (build and runtime alike, each build made once):
    /// one run per setting and target, tune.csv, the Pareto front over (FLIP, cost), a
    /// recommendation per target (recommendation.md) and its plot.
    Tune(tune::TuneArgs),
    /// Serve a build directory over HTTP/1.1 with byte ranges (remote runs, and experiments
    /// with --bandwidth, --latency and --fail-after), until interrupted.
    Serve(serve::ServeArgs),
    /// Assemble the parts written by jobs that `--emit-jobs` listed into the output a local
    /// run writes.
    Merge(merge::MergeArgs),
    /// An interactive window onto one or several methods (the same renderer and draw lists
    /// as `run`): fly/orbit, HUD, reference / FLIP map / hole toggles, keyframe recording
    /// (`run --path` reads it), screenshots with their pose. Needs a display (X11; Xvfb on a
    /// headless machine).
    View(view::ViewArgs),
}

fn main() -> std::process::ExitCode {
    let cli = Cli::parse();
    harness::memory::skip_check(cli.skip_memory_check);
    quiet_headless_vulkan(&cli.command);
    if let Command::Build(a) = &cli.command
        && build::keeps_freed_memory(a)
    {
        keep_freed_heap_memory();
    }
    // `check` has three outcomes (holds, regression, unusable input): its own exit status.
    // Returning the status (rather than `process::exit`) lets every destructor run first:
    // buffered output flushed, temporary files removed.
    if let Command::Check(a) = &cli.command {
        return std::process::ExitCode::from(check::main(a));
    }
    match real_main(cli.command) {
        Ok(()) => std::process::ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("Error: {e:#}");
            std::process::ExitCode::FAILURE
        }
    }
}

/// Mesa's implicit Vulkan layer `VK_LAYER_MESA_device_select` connects to a Wayland display
/// while the devices are listed, and without one libwayland prints "error: XDG_RUNTIME_DIR is
/// invalid or not set in the environment." twice on every headless run (issue 37: noise that
/// looks like failure). A command that opens no window has no display to choose a device by,
/// so it turns the layer off with Mesa's own switch, `NODEVICE_SELECT=1` — unless the user
/// set it, or chose a device with `MESA_VK_DEVICE_SELECT` (the layer's purpose). wgpu still
/// picks the adapter (`WGPU_ADAPTER_NAME`, `WGPU_BACKEND`). `view` keeps the layer.
///
/// One of the crate's two `unsafe` blocks (`unsafe_code` is denied elsewhere): the loader
/// reads the variable from this process's environment, and re-executing the binary to set it
/// would cost a second start and a second process between the user and the signals.
#[allow(unsafe_code)]
fn quiet_headless_vulkan(command: &Command) {
    let user_chose = ["NODEVICE_SELECT", "MESA_VK_DEVICE_SELECT"]
        .iter()
        .any(|v| std::env::var_os(v).is_some());
    if matches!(command, Command::View(_)) || user_chose {
        return;
    }
    // SAFETY: the first thing `main` does after parsing its arguments: no other thread exists
    // yet to read the environment concurrently.
    unsafe { std::env::set_var("NODEVICE_SELECT", "1") };
}

/// `build`'s heap policy (glibc; issue 40): blocks below 32 MiB always from the heap, and freed
/// memory kept there (trimmed only past 2 GiB free) rather than given back to the system.
/// glibc's defaults map each block above a (growing) threshold afresh and unmap it when
/// freed, so a build that works unit by unit (QSplat, SPT, LPC's subtrees) faulted every
/// page of every unit's buffers in again: 1.15 M minor page faults in QSplat's 10 M terrain
/// build, 0.36 M with this policy. Paired with the binary before it (terrain 10 M LAS, 3 runs
/// each): wall QSplat ×0.84, SPT ×0.95; LPC ×0.93 and MWKD ×1.01 with the same settings
/// (and a 256 MiB top pad) through `GLIBC_TUNABLES`; peak RSS up to +70 MB. The files do not
/// change. Only `build` (and the builds `tune` runs as `build` processes), and not one told
/// to use less than [`build::KEEP_FREED_FROM_MB`]: a `run`'s per-frame resident set stays
/// measured under the default policy, and a small budget keeps bounding the resident set.
/// Trimming at 64 MiB kept none of the gain; mimalloc and jemalloc as the global allocator
/// were tried and not kept (LPC ×1.28 and QSplat ×1.06 slower respectively).
///
/// The crate's other `unsafe`: `mallopt` only sets the allocator's parameters.
#[cfg(all(target_os = "linux", target_env = "gnu"))]
#[allow(unsafe_code)]
fn keep_freed_heap_memory() {
    // SAFETY: called before any other thread exists; `mallopt` takes two integers and
    // touches no memory of ours. A parameter it refuses (returns 0) leaves glibc's default.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 32 << 20);
        libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
    }
}

/// Other platforms keep their allocator's defaults.
#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn keep_freed_heap_memory() {}

fn real_main(command: Command) -> anyhow::Result<()> {
    match command {
        Command::List => list::main(),
        Command::Build(a) => build::main(&a),
        Command::Run(a) => run::main(&a),
        Command::Plot(a) => plot::main(&a),
        Command::Sweep(a) => sweep::main(&a),
        Command::PlotSweep(a) => plot::plot_sweep(&a),
        Command::Export(a) => export::main(&a),
        Command::Plan(a) => plan::main(&a),
        Command::Sampling(a) => sampling::main(&a),
        Command::Demo(a) => demo::main(&a),
        Command::Cache(a) => cache::main(&a),
        Command::Reproduce(a) => reproduce::main(&a),
        Command::Tune(a) => tune::main(&a),
        Command::Merge(a) => merge::main(&a),
        Command::Serve(a) => serve::main(&a),
        Command::View(a) => view::main(&a),
        Command::Check(_) => unreachable!("handled in main"),
    }
}
