//! What a run and the viewer do before their first frame: load the scene (with the shading's
//! scalar, the framing and the content hash), and build or open the method on it (a build
//! directory of ours, another tool's output such as PotreeConverter's, or a served build).

use std::path::{Path, PathBuf};

use anyhow::Context as _;
use methods::{BuildStats, LodMethod, MethodKind, Params};
use scenes::{Aabb, PointCloud, Progress, SceneSpec};

use crate::render::{RenderSettings, Shade};

use super::RemoteBuild;

/// A scene loaded for rendering.
pub struct PreparedScene {
    /// The samples.
    pub cloud: PointCloud,
    /// What the reader dropped, and samples outside the framing (printed to stderr too).
    pub warnings: Vec<String>,
    /// The bounds the camera paths frame.
    pub bounds: Aabb,
    /// Samples outside [`PreparedScene::bounds`].
    pub outside: u64,
    /// The scene's content hash (reference images are keyed by it).
    pub hash: u64,
    /// Its label (`statue:1000000:1`, a file's name).
    pub label: String,
    /// The renderer settings with the shading resolved for this cloud (`auto`) and the
    /// elevation range of its framing.
    pub render: RenderSettings,
}

/// Loads `spec` (through `cache`) for renderer settings `render`.
pub fn load_scene(
    spec: &SceneSpec,
    render: RenderSettings,
    cache: &Path,
    progress: &dyn Progress,
) -> anyhow::Result<PreparedScene> {
    // Shading by a file scalar loads it as the cloud's colour (scenes::scalar).
    let scene = spec.clone().with_colour_from(render.shade.shading.scalar());
    let loaded = scene
        .load(Some(cache), progress)
        .with_context(|| format!("loading scene '{}'", spec.text))?;
    let mut warnings = loaded.warnings.clone();
    let cloud = loaded.warn();
    let framing = scenes::framing::framing(&cloud);
    if framing.outside > 0 {
        let w = format!(
            "{}: {} of {} samples lie far outside the rest (beyond half the robust extent of \
             the 0.1–99.9 % quantile box): drawn, but the camera paths frame the others. \
             Every method's hierarchy spans them by default (the papers' rule), which coarsens \
             the rest; `--param strays=apart` builds it over the others and draws the strays \
             beside it (methods/src/strays.rs)",
            spec.text,
            framing.outside,
            cloud.len()
        );
        eprintln!("warning: {w}");
        warnings.push(w);
    }
    if let Some(w) = up_hint(spec, &cloud, &framing.framed) {
        eprintln!("warning: {w}");
        warnings.push(w);
    }
    let render = RenderSettings {
        shade: Shade {
            shading: render.shade.shading.resolve(cloud.attributes()),
            elevation: [framing.framed.min.z, framing.framed.max.z],
            ..render.shade
        },
        ..render
    };
    Ok(PreparedScene {
        hash: scene.content_hash()?,
        label: scene.label(),
        bounds: framing.framed,
        outside: framing.outside,
        cloud,
        warnings,
        render,
    })
}

/// A file read Z-up (no `--up`, no `up` in its scene file) whose samples have a flat base
/// at the low or high y end ([`scenes::framing::flat_base`]) is likely Y-up (Stanford's
/// scans, most graphics PLY data) and would render on its side: the warning says so and
/// names `--up`. Only ±y is suggested: a flat end elsewhere is more often a wall or a roof
/// than a base, and files that are X-up or upside down are rare (laspy's `plane.laz` has
/// 12.6 % of its samples at its high z end). LAS/LAZ files are never hinted: their z is
/// elevation by the format. Generated scenes are Z-up by construction.
fn up_hint(spec: &SceneSpec, cloud: &PointCloud, framed: &Aabb) -> Option<String> {
    use scenes::spec::SceneSource;
    let file = !matches!(
        spec.source,
        SceneSource::Generator { .. } | SceneSource::Las { .. }
    );
    if !file || spec.up != scenes::Up::Z {
        return None;
    }
    let base = scenes::framing::flat_base(cloud, framed)?;
    if !matches!(base.up, scenes::Up::Y | scenes::Up::NegY) {
        return None;
    }
    let (axis, end) = match base.up.to_string().strip_prefix('-') {
        Some(a) => (a.to_string(), "high"),
        None => (base.up.to_string(), "low"),
    };
    Some(format!(
        "{}: the samples have a flat base at the {end} {axis} end ({:.1} % of them lie in its \
         slab of {:.0} % of the extent, at most {:.1} % at any other end), as a {}-up file \
         standing on it would; splatbench's world is Z-up, so it would render on its side: if \
         it does, run with `--up {}` (or `up = \"{}\"` in a scene file)",
        spec.text,
        base.share * 100.0,
        scenes::axis::BASE_SLAB * 100.0,
        base.next * 100.0,
        base.up.to_string().to_uppercase(),
        base.up,
        base.up
    ))
}

/// Where a method's build comes from.
pub enum BuildSource<'a> {
    /// Build into this directory.
    Build(&'a Path),
    /// Open this existing directory (`--build-dir`): ours, or another tool's output the
    /// method reads ([`MethodKind::reads_foreign`]).
    Dir(&'a Path),
    /// Fetch the small files of a served build into the directory, read its chunks over HTTP.
    Remote(&'a RemoteBuild, &'a Path),
}

/// A method ready to draw.
pub struct OpenedMethod {
    /// The method.
    pub method: Box<dyn LodMethod>,
    /// Its build statistics.
    pub build: BuildStats,
    /// The parameters in force (a build directory's, with `--param`'s runtime ones over them).
    pub params: Params,
    /// Mismatches worth a warning (printed to stderr too).
    pub warnings: Vec<String>,
}

/// Builds or opens `kind` with `params` on `scene` from `source`.
pub fn open_method(
    kind: MethodKind,
    params: &Params,
    scene: &PreparedScene,
    source: BuildSource<'_>,
    progress: &dyn Progress,
) -> anyhow::Result<OpenedMethod> {
    let (cloud, label) = (&scene.cloud, &scene.label);
    let mut warnings = Vec::new();
    let (dir, flag, repo): (PathBuf, String, _) = match source {
        BuildSource::Build(dir) => {
            let build = kind
                .build(cloud, params, label, dir, progress)
                .with_context(|| format!("building {kind} on {label}"))?;
            return Ok(OpenedMethod {
                method: MethodKind::open(dir)?,
                build,
                params: params.clone(),
                warnings,
            });
        }
        BuildSource::Dir(dir) => (
            dir.to_path_buf(),
            format!("--build-dir {}", dir.display()),
            None,
        ),
        BuildSource::Remote(remote, dir) => {
            let open = crate::remote::opener(remote.timeout);
            let repo = MethodKind::fetch_remote(&remote.url, dir, &open)
                .with_context(|| format!("--build-url {}", remote.url))?;
            (
                dir.to_path_buf(),
                format!("--build-url {}", remote.url),
                Some(repo),
            )
        }
    };
    // Another tool's output (PotreeConverter's for `potree`): read as it is.
    if repo.is_none() && kind.reads_foreign(&dir) {
        let (m, build) = kind
            .open_foreign(&dir, cloud.origin(), params)
            .with_context(|| flag.clone())?;
        if m.input_points() != cloud.len() as u64 {
            let w = format!(
                "{flag}: holds {} points, the scene '{label}' {}: frames are compared with a \
                 reference of the scene's points",
                m.input_points(),
                cloud.len()
            );
            eprintln!("warning: {w}");
            warnings.push(w);
        }
        return Ok(OpenedMethod {
            method: m,
            build,
            params: params.clone(),
            warnings,
        });
    }
    let m = methods::Manifest::read(&dir).with_context(|| flag.clone())?;
    anyhow::ensure!(
        m.method == kind.name() && &m.scene == label && m.points == cloud.len() as u64,
        "{flag}: holds {} on '{}' ({} points), not {kind} on '{label}' ({} points)",
        m.method,
        m.scene,
        m.points,
        cloud.len()
    );
    // `--param` may only change runtime parameters (checked by `open_with` below).
    let mut all = m.params.clone();
    all.0.extend(params.0.clone());
    let build = BuildStats::read(&dir).with_context(|| flag.clone())?;
    let opened = match &repo {
        Some(repo) => MethodKind::open_remote(&dir, repo, params),
        None => MethodKind::open_with(&dir, params),
    };
    let method = opened.with_context(|| {
        if params.0.is_empty() {
            flag.clone()
        } else {
            format!("{flag} with --param")
        }
    })?;
    Ok(OpenedMethod {
        method,
        build,
        params: all,
        warnings,
    })
}

/// Refuses a method that keeps its whole model on the GPU when it does not fit the cache
/// budget `cache_bytes` (`--gpu-cache-mb`).
pub fn check_gpu_budget(
    kind: MethodKind,
    method: &dyn LodMethod,
    cache_bytes: u64,
) -> anyhow::Result<()> {
    if let Some(need) = method.gpu_resident_bytes()
        && need > cache_bytes
    {
        anyhow::bail!(
            "{kind} keeps its whole model on the GPU: {:.1} MiB, more than the GPU cache budget \
             of {:.1} MiB (--gpu-cache-mb); raise the budget or use a smaller scene",
            need as f64 / (1u64 << 20) as f64,
            cache_bytes as f64 / (1u64 << 20) as f64
        );
    }
    Ok(())
}
