//! Argument groups shared by several subcommands, flattened into their argument structs.

use std::path::PathBuf;

use clap::Args;
use clap::builder::{PossibleValue, PossibleValuesParser, TypedValueParser as _};
use harness::render::{Kernel, Shading};
use methods::MethodKind;

/// `--method`'s parser: the registry's names, each with its line of `--help`. (`methods`, the
/// GPU-free core, knows no CLI library; its enums parse with `FromStr`.)
pub fn method_parser() -> impl clap::builder::TypedValueParser<Value = MethodKind> {
    let names = MethodKind::ALL
        .iter()
        .map(|m| PossibleValue::new(m.name()).help(m.describe()));
    PossibleValuesParser::new(names).try_map(|s| s.parse::<MethodKind>())
}

/// `--kernel`'s parser: the shapes' names, each with its line of `--help`.
pub fn kernel_parser() -> impl clap::builder::TypedValueParser<Value = Kernel> {
    let names = Kernel::ALL
        .iter()
        .map(|k| PossibleValue::new(k.name()).help(k.describe()));
    PossibleValuesParser::new(names).try_map(|s| s.parse::<Kernel>())
}

/// `--param` pairs parsed and checked for `kind`, an error in the flag's words (the library
/// names no flag: its wording is "method parameter: …").
pub fn method_params(kind: MethodKind, pairs: &[String]) -> anyhow::Result<methods::Params> {
    let flag = |e: methods::MethodError| match e {
        methods::MethodError::Param(m) => anyhow::anyhow!("--param: {m}"),
        e => e.into(),
    };
    let params = methods::Params::parse(pairs).map_err(flag)?;
    kind.check_params(&params).map_err(flag)?;
    Ok(params)
}

#[derive(Args, Clone)]
pub struct MethodArgs {
    /// Method.
    #[arg(long, value_parser = method_parser())]
    pub method: MethodKind,
    /// Method parameter, `key=value` (repeatable).
    #[arg(long = "param", value_name = "KEY=VALUE")]
    pub params: Vec<String>,
}

/// Where `run`, `sweep` and `tune` take their build from instead of making one: a build
/// directory, or a build served over HTTP (`splatbench serve DIR`).
#[derive(Args, Clone)]
pub struct BuildSourceArgs {
    /// Run on an existing build (a `splatbench build --out` directory of the same method and
    /// scene) instead of building: the run's memory is then the method's alone, and `--param`
    /// may change only runtime parameters (LPC: fetch_per_frame, core_mb, delay_frames,
    /// in_flight, occlusion, occlusion_threshold).
    #[arg(long)]
    pub build_dir: Option<PathBuf>,
    /// Run on the LPC, MWKD, Potree or voxel build served at this URL (`splatbench serve
    /// DIR`) instead of building: its small files (manifest, index; Potree's hierarchy) are
    /// fetched once into remote-build/ of each run, its chunks (nodes) by HTTP range requests
    /// over kept-alive connections, LPC's and MWKD's checksums verified as for a local build.
    /// The same checks and `--param` rule as --build-dir.
    #[arg(long, value_name = "URL", conflicts_with = "build_dir")]
    pub build_url: Option<String>,
    /// Seconds one HTTP request of --build-url may take, connection to last byte. A server
    /// that never answers ends the run with an error naming the URL after this long; a chunk
    /// is tried 4 times (0.25, 0.5, 1 s apart) before it counts as failed.
    #[arg(long, value_name = "SECS", default_value_t = 30.0)]
    pub remote_timeout: f64,
}

impl BuildSourceArgs {
    /// True when the build is given (a directory or a URL), not made.
    pub fn given(&self) -> bool {
        self.build_dir.is_some() || self.build_url.is_some()
    }

    /// The remote build, its timeout checked (finite, 0.1 s to 1 h).
    pub fn remote(&self) -> anyhow::Result<Option<harness::runner::RemoteBuild>> {
        let t = self.remote_timeout;
        anyhow::ensure!(
            t.is_finite() && (0.1..=3600.0).contains(&t),
            "--remote-timeout {t}: give seconds from 0.1 to 3600"
        );
        Ok(self
            .build_url
            .as_ref()
            .map(|url| harness::runner::RemoteBuild {
                url: url.clone(),
                timeout: std::time::Duration::from_secs_f64(t),
            }))
    }
}

#[derive(Args, Clone)]
pub struct SceneArgs {
    /// Scene: `generator:points[:seed[:sampling]]` (e.g. statue:200000, statue:1M:1:random;
    /// sampling even — statue's and the isosurfaces' default — or random, terrain's), or a
    /// .ply/.las/.laz/.e57/.pcd/.sbc/.toml file.
    #[arg(long)]
    pub scene: String,
    /// Resample a PLY mesh surface to this many points.
    #[arg(long, allow_negative_numbers = true)]
    pub sample: Option<usize>,
    /// Seed for generators and resampling that do not name their own.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub seed: u64,
    /// Keep colour and normal columns that hold one value for every sample (by default they
    /// are dropped with a warning: e.g. LAS RGB left at 0 by the scanner).
    #[arg(long)]
    pub keep_attributes: bool,
    /// The file's up axis (x, y, z, -x, -y, -z), turned to splatbench's +Z at load; Stanford
    /// and most graphics PLY data are Y-up. Default: a scene file's `up`, else z.
    #[arg(long, value_parser = parse_up)]
    pub up: Option<scenes::Up>,
    /// Shading, the same for the reference and every method: auto (lambert with normals,
    /// else colour with colours, else edl), lambert, colour, edl (eye-dome lighting),
    /// elevation, intensity, classification. The last two colour the points by the file's
    /// scalar, so `build` needs them too; the others change only the images.
    #[arg(long, value_enum, default_value = "auto")]
    pub shading: Shading,
}

fn parse_up(s: &str) -> Result<scenes::Up, String> {
    s.parse()
}

impl SceneArgs {
    /// The scene spec these arguments name.
    pub fn spec(&self) -> Result<scenes::SceneSpec, scenes::SceneError> {
        Ok(
            scenes::SceneSpec::parse(&self.scene, self.sample, self.seed)?
                .with_keep_attributes(self.keep_attributes)
                .with_up(self.up)
                .with_colour_from(self.shading.scalar()),
        )
    }
}

/// `--cache`, the same for every subcommand that has one.
#[derive(Args, Clone)]
pub struct CacheArgs {
    /// Cache directory: generated scenes, reference builds and images (default
    /// $SPLATBENCH_CACHE, else splatbench/ in the user cache directory; see `splatbench cache`).
    #[arg(long = "cache", value_name = "CACHE", default_value_os_t = crate::shared::default_cache())]
    pub dir: PathBuf,
}

#[derive(Args, Clone)]
pub struct RenderArgs {
    /// Image width, pixels.
    #[arg(long, default_value_t = 512, allow_negative_numbers = true)]
    pub width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 512, allow_negative_numbers = true)]
    pub height: u32,
    /// Splat kernel (a method's `--param kernel=` overrides it).
    #[arg(long, value_parser = kernel_parser(), default_value = "square")]
    pub kernel: Kernel,
    /// GPU chunk-cache budget, MiB.
    #[arg(long, default_value_t = harness::render::DEFAULT_GPU_CACHE_MB, allow_negative_numbers = true)]
    pub gpu_cache_mb: u64,
    /// Rasteriser: `quads` (instanced quads, every kernel) or `compute` (a compute shader with
    /// 64-bit atomics, square splats only; the reference is drawn the same way).
    #[arg(long, value_enum, default_value = "quads")]
    pub raster: harness::render::Raster,
    /// Elliptical splats (`--kernel ellipse`): the largest major ÷ minor axis ratio (QSplat
    /// §3.3 clamps at 10: "fills in practically all of these holes"); ≥ 1.
    #[arg(long, default_value_t = harness::render::ELLIPSE_CLAMP)]
    pub ellipse_clamp: f32,
    /// Rasteriser of the reference images (default: the run's). `compute` draws them as
    /// square splats, ≈ 15× faster on lavapipe: for references of 10⁸ samples.
    #[arg(long, value_enum)]
    pub reference_raster: Option<harness::render::Raster>,
    /// Splat kernel of the reference images (default: the run's): compares runs of different
    /// kernels against one image of the full cloud. Square only with the compute rasteriser.
    #[arg(long, value_parser = kernel_parser())]
    pub reference_kernel: Option<Kernel>,
}

impl RenderArgs {
    /// `--reference-kernel`, refused where the references' rasteriser cannot draw it.
    pub fn reference_kernel(&self) -> anyhow::Result<Option<Kernel>> {
        let raster = self.reference_raster.unwrap_or(self.raster);
        match self.reference_kernel {
            Some(k) if k != Kernel::Square && raster == harness::render::Raster::Compute => {
                anyhow::bail!(
                    "--reference-kernel {}: the references are drawn by the compute rasteriser \
                     ({}), which draws square splats only; give --reference-raster quads",
                    k.name(),
                    if self.reference_raster.is_some() {
                        "--reference-raster compute"
                    } else {
                        "--raster compute"
                    }
                )
            }
            k => Ok(k),
        }
    }

    /// The renderer settings these flags name, shaded by `shading` (`--shading`).
    pub fn settings(&self, shading: Shading) -> anyhow::Result<harness::render::RenderSettings> {
        Ok(harness::render::RenderSettings {
            width: self.width,
            height: self.height,
            kernel: self.kernel,
            cache_bytes: self
                .gpu_cache_mb
                .checked_mul(1 << 20)
                .ok_or_else(|| anyhow::anyhow!("--gpu-cache-mb is too large"))?,
            shade: harness::render::Shade {
                shading,
                ellipse_clamp: harness::render::Shade::check_ellipse_clamp(self.ellipse_clamp)
                    .map_err(anyhow::Error::msg)?,
                ..Default::default()
            },
            raster: self.raster,
        })
    }
}

#[derive(Args, Clone)]
#[group(multiple = false)]
pub struct TargetArgs {
    /// Pixel tolerance (default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub eps: Option<f64>,
    /// Point budget per frame.
    #[arg(long, allow_negative_numbers = true)]
    pub budget: Option<u64>,
}

impl TargetArgs {
    /// The target these flags name: `--budget`, else `--eps` (default 1 px). An `--eps`
    /// beyond what an `f32` holds is refused with its value (it used to read "got inf").
    pub fn target(&self) -> anyhow::Result<methods::Target> {
        Ok(match (self.eps, self.budget) {
            (_, Some(b)) => {
                methods::Target::budget(b).map_err(|e| anyhow::anyhow!("--budget {b}: {e}"))?
            }
            (e, None) => {
                let e = e.unwrap_or(1.0);
                if e.is_finite() && e.abs() > f64::from(f32::MAX) {
                    anyhow::bail!(
                        "--eps {e:e} is beyond the largest tolerance a frame can use ({:e} px)",
                        f32::MAX
                    );
                }
                methods::Target::tolerance(e as f32)
                    .map_err(|err| anyhow::anyhow!("--eps {e}: {err}"))?
            }
        })
    }
}

/// The targets and camera path of a sweep or tune: one run per target.
#[derive(Args, Clone)]
pub struct SweepTargetArgs {
    /// Point budgets per frame, comma-separated, one run each (e.g. 25000,50000,100k).
    #[arg(long, value_name = "POINTS,...", allow_hyphen_values = true)]
    pub budgets: Option<String>,
    /// Pixel tolerances, comma-separated, one run each (e.g. 8,4,2,1).
    #[arg(long, value_name = "PX,...", allow_hyphen_values = true)]
    pub eps: Option<String>,
    /// Camera path: a built-in (orbit, zoom, flythrough, extremes; `splatbench list` says what
    /// each does) or a keyframe .toml file.
    #[arg(long, default_value = "orbit")]
    pub path: String,
    /// Frames along the path.
    #[arg(long, default_value_t = 60, allow_negative_numbers = true)]
    pub frames: usize,
}

impl SweepTargetArgs {
    /// The targets of `--budgets` or `--eps` ([`sweep_targets`]).
    pub fn list(&self) -> anyhow::Result<Vec<harness::sweep::SweepTarget>> {
        sweep_targets(self.budgets.as_deref(), self.eps.as_deref())
    }
}

/// The targets of `--budgets` or `--eps` (exactly one of them), in the order given. Empty
/// lists and items, non-numbers, a budget of 0, a negative or non-finite tolerance and a
/// target given twice are errors naming the flag.
fn sweep_targets(
    budgets: Option<&str>,
    eps: Option<&str>,
) -> anyhow::Result<Vec<harness::sweep::SweepTarget>> {
    let (flag, list) = match (budgets, eps) {
        (Some(_), Some(_)) => {
            anyhow::bail!("--budgets and --eps are exclusive: a sweep varies one kind of target")
        }
        (None, None) => anyhow::bail!(
            "a sweep needs its targets: --budgets POINTS,... (e.g. 25000,50000,100000) or \
             --eps PX,... (e.g. 8,4,2,1)"
        ),
        (Some(b), None) => ("--budgets", b),
        (None, Some(e)) => ("--eps", e),
    };
    if list.trim().is_empty() {
        anyhow::bail!("{flag}: the list is empty (give comma-separated values, e.g. {flag} 4,2,1)");
    }
    let mut targets: Vec<harness::sweep::SweepTarget> = Vec::new();
    for (i, item) in list.split(',').map(str::trim).enumerate() {
        if item.is_empty() {
            anyhow::bail!("{flag} {list}: value {} is empty", i + 1);
        }
        let t = if flag == "--budgets" {
            let n = scenes::spec::parse_count(item)
                .map_err(|e| anyhow::anyhow!("{flag}: budget '{item}': {e}"))?;
            harness::sweep::SweepTarget::budget(n as u64)?
        } else {
            let px: f32 = item.parse().map_err(|_| {
                anyhow::anyhow!("{flag}: '{item}' is not a number of pixels (e.g. 2 or 0.5)")
            })?;
            harness::sweep::SweepTarget::tolerance(px).map_err(|_| {
                anyhow::anyhow!(
                    "{flag}: '{item}': a tolerance must be a finite number of pixels ≥ 0"
                )
            })?
        };
        if let Some(same) = targets.iter().find(|o| o.name == t.name) {
            anyhow::bail!("{flag}: {} is given twice", same.value);
        }
        targets.push(t);
    }
    Ok(targets)
}

/// `--emit-jobs` and the hidden `--part` of the commands that split into jobs (`sweep`,
/// `tune`, `reproduce`).
#[derive(Args, Clone)]
pub struct JobArgs {
    /// Write one command line per job (a sweep's target, a tune's build with its runs, a
    /// reproduction's spec) to this file instead of running: for `parallel < FILE` or a Slurm
    /// array; then `splatbench merge OUT/parts/* --out OUT` writes what a local run writes.
    #[arg(long, value_name = "FILE")]
    pub emit_jobs: Option<PathBuf>,
    /// Run only job K (0-based) into --out: what an emitted job line does.
    #[arg(long, value_name = "K", hide = true)]
    pub part: Option<usize>,
}

impl JobArgs {
    /// The file to write the job lines to, refusing `--part` beside it.
    pub fn emit(&self) -> anyhow::Result<Option<&std::path::Path>> {
        anyhow::ensure!(
            self.emit_jobs.is_none() || self.part.is_none(),
            "--emit-jobs and --part are exclusive"
        );
        Ok(self.emit_jobs.as_deref())
    }
}
