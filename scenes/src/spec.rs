//! Scene specifications: what `--scene` accepts, and loading it.
//!
//! - `generator:points[:seed[:sampling]]`, e.g. `statue:200000`, `terrain:1000000:7` or
//!   `statue:1M:1:even` (seed defaults to the run's `--seed`; sampling `random` or `even`,
//!   default [`Generator::default_sampling`]; see [`crate::generators::even`]);
//! - a file: `.ply` (with `--sample N` to resample a mesh), `.las`, `.laz`, `.e57`, `.pcd`, or
//!   a splatbench column file `.sbc`;
//! - a scene file `.toml` (fields below, unknown keys are errors); relative `file` paths are
//!   relative to the TOML file:
//!   ```toml
//!   generator = "statue"   # or: file = "scan.ply"
//!   points = 200000        # generators only
//!   seed = 1               # optional
//!   sampling = "even"      # optional, generators only: random | even
//!   sample = 100000        # optional, meshes only
//!   keep_attributes = true # optional: keep constant colour/normal columns (see screen)
//!   up = "y"               # optional: the file's up axis, turned to +Z (see axis)
//!   ```
//!
//! Generated scenes of more than [`CACHE_MIN_POINTS`] points, and evenly sampled scenes of
//! any size (their sample elimination is the slow part), are written once to a column file
//! in the cache directory and memory-mapped from then on, so a 100 M-point scene is generated
//! once and streamed, never held in memory. So are LAS/LAZ files of that many points (read by
//! streaming, [`crate::las::read_to_columns`]; the cached file is named by a hash of the
//! file's canonical path, length, modification time and [`crate::os::FileStamp`] (device,
//! inode, inode change time in nanoseconds), so an edited file is read again even when its
//! length is the same and its modification time was set back: [`las_cache_path`]),
//! unless a `--shading` needs their intensity or classification (read in memory then).

use std::path::{Path, PathBuf};

use crate::generators::{Generator, Sampling};
use crate::hash::Fnv64;
use crate::{PointCloud, Progress, SceneError};

/// The most points `--sample` may resample a mesh to (the result is held in memory).
pub use crate::ply::MAX_SAMPLE;

/// Generated scenes at least this large are cached as column files.
pub const CACHE_MIN_POINTS: usize = 2_000_000;
/// Bumped whenever a generator's output changes, so cached scenes and references refresh.
pub const GENERATOR_VERSION: u32 = 1;
/// Bumped whenever even sampling's output changes (its scenes' keys carry both versions;
/// random scenes keep theirs). 2: tiles from the first candidates, out of core (issue 35).
pub const EVEN_SAMPLING_VERSION: u32 = 2;
/// Bumped whenever the LAS reader's output changes, so cached LAS scenes refresh.
pub const LAS_CACHE_VERSION: u32 = 1;

/// The cached column file of the LAS/LAZ file `path` under `dir`, or `None` when the file has
/// fewer than [`CACHE_MIN_POINTS`] points (or its header cannot be read: the reader then
/// reports that).
///
/// The guarantee: a cached file is served only for the same path, length, modification time
/// and [`crate::os::FileStamp`]. On Unix the stamp's inode change time is set by the kernel on
/// every write and every metadata change (restoring the mtime included) and cannot be set by
/// a user, and a rewrite through a temporary file and a rename gets a new inode; so a stale
/// cache needs a same-length rewrite in place within one tick of the file system's timestamp
/// clock (a few milliseconds) of the stamp taken when the cache was written. Elsewhere the
/// stamp holds the creation time only, and the guarantee is the length and mtime's.
pub fn las_cache_path(dir: &Path, path: &Path) -> Option<PathBuf> {
    let meta = std::fs::metadata(path).ok()?;
    if crate::las::point_count(path).ok()? < CACHE_MIN_POINTS as u64 {
        return None;
    }
    let canonical = std::fs::canonicalize(path).ok()?;
    let mtime = meta
        .modified()
        .ok()
        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
        .map_or(0, |d| d.as_nanos());
    let key = Fnv64::default()
        .write_str(&canonical.to_string_lossy())
        .write(&meta.len().to_le_bytes())
        .write(&mtime.to_le_bytes())
        .write(&crate::os::FileStamp::of(&meta).to_le_bytes())
        .finish();
    Some(
        dir.join("scenes")
            .join(format!("las-{key:016x}-v{LAS_CACHE_VERSION}.sbc")),
    )
}

/// Where a scene's samples come from.
#[derive(Debug, Clone, PartialEq)]
pub enum SceneSource {
    /// A procedural generator.
    Generator {
        /// Which one.
        generator: Generator,
        /// Sample count.
        points: usize,
        /// Seed.
        seed: u64,
        /// How the samples are placed.
        sampling: Sampling,
    },
    /// A PLY file, optionally resampled.
    Ply {
        /// The file.
        path: PathBuf,
        /// Resample the mesh surface to this many points.
        sample: Option<usize>,
        /// Seed of the resampling.
        seed: u64,
    },
    /// A LAS or LAZ file.
    Las {
        /// The file.
        path: PathBuf,
    },
    /// An E57 file (every scan, posed).
    E57 {
        /// The file.
        path: PathBuf,
    },
    /// A PCD file (PCL's format).
    Pcd {
        /// The file.
        path: PathBuf,
    },
    /// A splatbench column file.
    Columns {
        /// The file.
        path: PathBuf,
    },
}

/// The file extensions a scene can have, as the error for any other lists them.
pub const FILE_EXTENSIONS: &str = ".ply .las .laz .e57 .pcd .sbc .toml";

/// A loaded scene, and what the reader dropped or ignored on the way.
#[derive(Debug)]
pub struct Loaded {
    /// The samples.
    pub cloud: PointCloud,
    /// One sentence per thing dropped or ignored (an attribute, invalid points), naming the
    /// file: a run records them in its summary, the CLI prints them as warnings.
    pub warnings: Vec<String>,
}

impl Loaded {
    fn quiet(cloud: PointCloud) -> Self {
        Self {
            cloud,
            warnings: Vec::new(),
        }
    }
    /// Prints each warning to stderr (`warning: …`) and returns the cloud.
    pub fn warn(self) -> PointCloud {
        for w in &self.warnings {
            eprintln!("warning: {w}");
        }
        self.cloud
    }
}

/// A parsed `--scene` value.
#[derive(Debug, Clone, PartialEq)]
pub struct SceneSpec {
    /// The text as given.
    pub text: String,
    /// What it resolves to.
    pub source: SceneSource,
    /// Keep colour and normal columns that hold one value for every sample
    /// ([`crate::screen`]); `--keep-attributes`, or `keep_attributes = true` in a scene file.
    pub keep_attributes: bool,
    /// The file's up axis, turned to +Z at load (`--up`, `up = "y"` in a scene file).
    pub up: crate::Up,
    /// Colour the points by this scalar of the file instead of its colours
    /// (`--shading intensity|classification`; [`crate::scalar`]).
    pub colour_from: Option<crate::Scalar>,
}

#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    generator: Option<String>,
    file: Option<PathBuf>,
    points: Option<usize>,
    seed: Option<u64>,
    sample: Option<usize>,
    sampling: Option<String>,
    keep_attributes: Option<bool>,
    up: Option<String>,
}

impl SceneSpec {
    /// Parses a `--scene` value. `sample` is `--sample`, `seed` the run's default seed.
    pub fn parse(text: &str, sample: Option<usize>, seed: u64) -> Result<Self, SceneError> {
        let err = |msg: String| SceneError::Spec {
            spec: text.to_string(),
            msg,
        };
        if Path::new(text).is_dir() {
            // A folder such as `laspy-2.7.0` reads as a file with the extension `.0`.
            return Err(err(format!(
                "is a directory: name one of its point-cloud files ({FILE_EXTENSIONS})"
            )));
        }
        let lower = text.to_ascii_lowercase();
        let ext = |e: &str| lower.ends_with(e);
        let source = if ext(".toml") {
            return Self::parse_file(Path::new(text), sample, seed);
        } else if ext(".ply") {
            SceneSource::Ply {
                path: text.into(),
                sample,
                seed,
            }
        } else if ext(".las") || ext(".laz") {
            SceneSource::Las { path: text.into() }
        } else if ext(".sbc") {
            SceneSource::Columns { path: text.into() }
        } else if ext(".e57") {
            SceneSource::E57 { path: text.into() }
        } else if ext(".pcd") {
            SceneSource::Pcd { path: text.into() }
        } else if let Some(e) = file_extension(text) {
            return Err(err(format!(
                "'.{e}' files are not read (supported: {FILE_EXTENSIONS})"
            )));
        } else {
            let mut parts = text.split(':');
            let name = parts.next().unwrap_or_default();
            let generator = Generator::from_name(name).ok_or_else(|| {
                let known: Vec<_> = Generator::ALL.iter().map(|g| g.name()).collect();
                err(format!(
                    "not a file ({FILE_EXTENSIONS}) nor a generator (known: {}); \
                     generators are written generator:points[:seed]",
                    known.join(", ")
                ))
            })?;
            let points = match parts.next() {
                Some(p) => parse_count(p).map_err(|m| err(format!("points: {m}")))?,
                None => return Err(err("missing point count: write e.g. statue:200000".into())),
            };
            let seed = match parts.next() {
                Some(s) => s
                    .parse()
                    .map_err(|_| err(format!("seed '{s}' is not a non-negative integer")))?,
                None => seed,
            };
            let sampling = match parts.next() {
                Some(s) => Sampling::from_name(s)
                    .ok_or_else(|| err(format!("sampling '{s}' is not one of: random, even")))?,
                None => generator.default_sampling(),
            };
            if parts.next().is_some() {
                return Err(err(
                    "too many ':' fields (generator:points[:seed[:sampling]])".into(),
                ));
            }
            SceneSource::Generator {
                generator,
                points,
                seed,
                sampling,
            }
        };
        if sample.is_some() && !matches!(source, SceneSource::Ply { .. }) {
            return Err(err("--sample applies only to PLY meshes".into()));
        }
        if let Some(n) = sample.filter(|&n| n > MAX_SAMPLE) {
            return Err(err(format!(
                "--sample {n} is more than the limit {MAX_SAMPLE} (the resampled cloud is held \
                 in memory, 27 bytes a point)"
            )));
        }
        Ok(Self {
            text: text.to_string(),
            source,
            keep_attributes: false,
            up: crate::Up::Z,
            colour_from: None,
        })
    }

    /// This spec with the file's up axis set (`--up`); `None` keeps a scene file's `up`.
    pub fn with_up(mut self, up: Option<crate::Up>) -> Self {
        if let Some(u) = up {
            self.up = u;
        }
        self
    }

    /// This spec with [`SceneSpec::colour_from`] set.
    pub fn with_colour_from(mut self, scalar: Option<crate::Scalar>) -> Self {
        self.colour_from = scalar;
        self
    }

    /// This spec with [`SceneSpec::keep_attributes`] set (`--keep-attributes`); a scene file's
    /// `keep_attributes = true` stays set.
    pub fn with_keep_attributes(mut self, keep: bool) -> Self {
        self.keep_attributes |= keep;
        self
    }

    fn parse_file(path: &Path, sample: Option<usize>, seed: u64) -> Result<Self, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError::io(path, e))?;
        let f: SceneFile =
            toml::from_str(&text).map_err(|e| SceneError::format(path, e.to_string()))?;
        let seed = f.seed.unwrap_or(seed);
        let sample = sample.or(f.sample);
        let spec = match (f.generator, f.file) {
            (Some(g), None) => {
                let points = f
                    .points
                    .ok_or_else(|| SceneError::format(path, "a generator scene needs `points`"))?;
                if sample.is_some() {
                    return Err(SceneError::format(
                        path,
                        "`sample` applies only to PLY meshes",
                    ));
                }
                let text = match &f.sampling {
                    Some(m) => format!("{g}:{points}:{seed}:{m}"),
                    None => format!("{g}:{points}:{seed}"),
                };
                Self::parse(&text, None, seed)
            }
            (None, Some(file)) => {
                if f.points.is_some() {
                    return Err(SceneError::format(
                        path,
                        "`points` applies to generators; use `sample` to resample a mesh",
                    ));
                }
                if f.sampling.is_some() {
                    return Err(SceneError::format(
                        path,
                        "`sampling` applies to generators (a file's samples are what they are)",
                    ));
                }
                let file = path.parent().unwrap_or(Path::new(".")).join(file);
                Self::parse(&file.to_string_lossy(), sample, seed)
            }
            _ => Err(SceneError::format(
                path,
                "give exactly one of `generator` and `file`",
            )),
        }
        .map_err(|e| match e {
            SceneError::Spec { msg, .. } => SceneError::format(path, msg),
            e => e,
        })?;
        let up = match f.up {
            Some(u) => u
                .parse()
                .map_err(|m: String| SceneError::format(path, format!("up: {m}")))?,
            None => crate::Up::Z,
        };
        Ok(Self {
            text: path.to_string_lossy().into_owned(),
            keep_attributes: f.keep_attributes.unwrap_or(false),
            up,
            ..spec
        })
    }

    /// Short label for results (`statue:200000:1`, or the file name).
    pub fn label(&self) -> String {
        match &self.source {
            SceneSource::Generator {
                generator,
                points,
                seed,
                sampling,
            } => {
                if *sampling == generator.default_sampling() {
                    format!("{}:{points}:{seed}", generator.name())
                } else {
                    format!("{}:{points}:{seed}:{}", generator.name(), sampling.name())
                }
            }
            SceneSource::Ply { path, sample, .. } => {
                let name = file_name(path);
                match sample {
                    Some(n) => format!("{name}@{n}"),
                    None => name,
                }
            }
            SceneSource::Las { path }
            | SceneSource::E57 { path }
            | SceneSource::Pcd { path }
            | SceneSource::Columns { path } => file_name(path),
        }
    }

    /// Identity of the scene's content: generator + count + seed + version, or the bytes of
    /// the file (plus the resampling). Used as the key of cached scenes and reference images.
    pub fn content_hash(&self) -> Result<u64, SceneError> {
        let mut h = Fnv64::default();
        match &self.source {
            SceneSource::Generator {
                generator,
                points,
                seed,
                sampling,
            } => {
                h.write_str(generator.name())
                    .write(&points.to_le_bytes())
                    .write(&seed.to_le_bytes())
                    .write(&GENERATOR_VERSION.to_le_bytes());
                if *sampling != Sampling::Random {
                    // Random scenes keep the hashes they had before there was a choice.
                    h.write_str("sampling").write_str(sampling.name());
                    if *sampling == Sampling::Even && EVEN_SAMPLING_VERSION > 1 {
                        h.write(&EVEN_SAMPLING_VERSION.to_le_bytes());
                    }
                }
            }
            SceneSource::Ply { path, sample, seed } => {
                hash_file(&mut h, path)?;
                if let Some(n) = sample {
                    h.write(&n.to_le_bytes()).write(&seed.to_le_bytes());
                }
            }
            SceneSource::Las { path }
            | SceneSource::E57 { path }
            | SceneSource::Pcd { path }
            | SceneSource::Columns { path } => hash_file(&mut h, path)?,
        }
        if self.keep_attributes && !matches!(self.source, SceneSource::Generator { .. }) {
            // The same file gives another cloud when its constant columns are kept.
            h.write_str("keep_attributes");
        }
        if self.up != crate::Up::Z {
            h.write_str("up").write_str(&self.up.to_string());
        }
        if let Some(s) = self.colour_from {
            h.write_str("colour_from").write_str(s.name());
        }
        Ok(h.finish())
    }

    /// Loads the scene. Large generated scenes go through `cache_dir` (when given) as column
    /// files. The load is a `progress` phase ("scene: load"; a generator's own phase takes
    /// over from it), so a build's timed phases cover it.
    pub fn load(
        &self,
        cache_dir: Option<&Path>,
        progress: &dyn Progress,
    ) -> Result<Loaded, SceneError> {
        progress.start("scene: load", 0);
        let read = self.read(cache_dir, progress);
        progress.finish();
        let (mut loaded, scalar) = read?;
        if let Some(field) = self.colour_from {
            let path = self.file().ok_or_else(|| SceneError::Spec {
                spec: self.text.clone(),
                msg: format!("a generated scene has no {field} to shade by"),
            })?;
            let values = scalar.ok_or_else(|| {
                SceneError::format(
                    path,
                    format!(
                        "the file has no {field}{} (choose another --shading)",
                        match field {
                            crate::Scalar::Intensity => "",
                            crate::Scalar::Classification => ": only LAS/LAZ files carry one",
                        }
                    ),
                )
            })?;
            let colours = crate::scalar::colours(path, field, &values)?;
            drop(values);
            loaded.cloud = loaded.cloud.with_colors(colours)?;
        }
        loaded.cloud = loaded.cloud.with_up(self.up)?;
        if self.keep_attributes || matches!(self.source, SceneSource::Generator { .. }) {
            // Generators fill every column they declare.
            return Ok(loaded);
        }
        let (cloud, mut dropped) = crate::screen::drop_constant_columns(loaded.cloud, &self.text);
        let mut warnings = loaded.warnings;
        warnings.append(&mut dropped);
        Ok(Loaded { cloud, warnings })
    }

    /// The file the scene is read from, if it is not generated.
    pub fn file(&self) -> Option<&Path> {
        match &self.source {
            SceneSource::Generator { .. } => None,
            SceneSource::Ply { path, .. }
            | SceneSource::Las { path }
            | SceneSource::E57 { path }
            | SceneSource::Pcd { path }
            | SceneSource::Columns { path } => Some(path),
        }
    }

    /// The column file under `cache_dir` that a generated scene is cached in: scenes of at
    /// least [`CACHE_MIN_POINTS`], and even ones of any size (their sample elimination is
    /// the slow part, ≈ 6 s per million); `None` for other scenes.
    pub fn cache_file(&self, cache_dir: &Path) -> Option<PathBuf> {
        let SceneSource::Generator {
            generator,
            points,
            seed,
            sampling,
        } = &self.source
        else {
            return None;
        };
        if *points < CACHE_MIN_POINTS && *sampling != Sampling::Even {
            return None;
        }
        let suffix = match sampling {
            Sampling::Random => String::new(),
            Sampling::Even => format!("-even{EVEN_SAMPLING_VERSION}"),
        };
        Some(cache_dir.join("scenes").join(format!(
            "{}-{points}-{seed}{suffix}-v{GENERATOR_VERSION}.sbc",
            generator.name()
        )))
    }

    /// Reads the scene as its source holds it, with the scalar [`Self::colour_from`] names
    /// when that is set and the file has it.
    fn read(
        &self,
        cache_dir: Option<&Path>,
        progress: &dyn Progress,
    ) -> Result<(Loaded, Option<Vec<f32>>), SceneError> {
        check_magic(&self.source)?;
        let plain = match &self.source {
            SceneSource::Generator {
                generator,
                points,
                seed,
                sampling,
            } => match cache_dir.and_then(|dir| self.cache_file(dir).map(|p| (dir, p))) {
                Some((dir, path)) => {
                    if path.exists() {
                        crate::colfile::open(&path)
                    } else {
                        std::fs::create_dir_all(path.parent().unwrap_or(dir))
                            .map_err(|e| SceneError::io(dir, e))?;
                        generator
                            .generate_to_file_sampled(*points, *seed, *sampling, &path, progress)
                    }
                }
                _ => generator.generate_sampled(*points, *seed, *sampling),
            },
            SceneSource::Ply { path, sample, seed } => {
                let opts = crate::ply::PlyOptions {
                    sample: *sample,
                    seed: *seed,
                };
                let (cloud, warnings) = crate::ply::read_noted(path, &opts)?;
                return Ok((Loaded { cloud, warnings }, None));
            }
            SceneSource::Las { path } => {
                if self.colour_from.is_none()
                    && let Some(cached) = cache_dir.and_then(|d| las_cache_path(d, path))
                {
                    if cached.exists() {
                        crate::colfile::open(&cached)
                    } else {
                        let dir = cached.parent().unwrap_or(Path::new("."));
                        std::fs::create_dir_all(dir).map_err(|e| SceneError::io(dir, e))?;
                        crate::las::read_to_columns(path, &cached)
                    }
                } else {
                    let (cloud, scalar) = crate::las::read_with(path, self.colour_from)?;
                    return Ok((Loaded::quiet(cloud), scalar));
                }
            }
            SceneSource::Columns { path } => crate::colfile::open(path),
            SceneSource::E57 { path } => {
                let e = crate::e57::read(path)?;
                let mut warnings = e.warnings;
                if e.dropped > 0 {
                    warnings.push(format!(
                        "{}: points dropped: {} of {} in {} scans (invalid or direction-only \
                         coordinate)",
                        path.display(),
                        e.dropped,
                        e.dropped + e.cloud.len(),
                        e.scans
                    ));
                }
                let scalar = match self.colour_from {
                    Some(crate::Scalar::Intensity) => e.intensity,
                    _ => None,
                };
                return Ok((
                    Loaded {
                        cloud: e.cloud,
                        warnings,
                    },
                    scalar,
                ));
            }
            SceneSource::Pcd { path } => {
                let p = crate::pcd::read(path)?;
                let mut warnings = p.warnings;
                if p.dropped > 0 {
                    warnings.push(format!(
                        "{}: points dropped: {} of {} (non-finite coordinate: the holes of an \
                         organised cloud)",
                        path.display(),
                        p.dropped,
                        p.dropped + p.cloud.len()
                    ));
                }
                let scalar = match self.colour_from {
                    Some(crate::Scalar::Intensity) => p.intensity,
                    _ => None,
                };
                return Ok((
                    Loaded {
                        cloud: p.cloud,
                        warnings,
                    },
                    scalar,
                ));
            }
        };
        plain.map(|c| (Loaded::quiet(c), None))
    }
}

/// The extension of a `--scene` value that names a file (`scan.xyz` → `xyz`), if it has one
/// and is not a generator spec (`statue:1000` has no extension; `a.b:7` is not a file either).
/// Refuses a file whose first bytes are another known format's than its extension names
/// ([`crate::sniff::expect`]).
fn check_magic(source: &SceneSource) -> Result<(), SceneError> {
    let (path, expected) = match source {
        SceneSource::Generator { .. } => return Ok(()),
        SceneSource::Ply { path, .. } => (path, "PLY"),
        SceneSource::Las { path } => (path, "LAS"),
        SceneSource::E57 { path } => (path, "E57"),
        SceneSource::Pcd { path } => (path, "PCD"),
        SceneSource::Columns { path } => (path, "splatbench column"),
    };
    crate::sniff::expect(path, expected)
}

fn file_extension(text: &str) -> Option<&str> {
    let name = text.rsplit(['/', '\\']).next().unwrap_or(text);
    let (stem, ext) = name.rsplit_once('.')?;
    let plausible = !name.contains(':')
        && !stem.is_empty()
        && !ext.is_empty()
        && ext.len() <= 8
        && ext.chars().all(|c| c.is_ascii_alphanumeric());
    plausible.then_some(ext)
}

fn file_name(p: &Path) -> String {
    p.file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| p.to_string_lossy().into_owned())
}

fn hash_file(h: &mut Fnv64, path: &Path) -> Result<(), SceneError> {
    use std::io::Read;
    let mut f = std::fs::File::open(path).map_err(|e| SceneError::io(path, e))?;
    let mut buf = vec![0u8; 1 << 20];
    loop {
        let n = f.read(&mut buf).map_err(|e| SceneError::io(path, e))?;
        if n == 0 {
            return Ok(());
        }
        h.write(&buf[..n]);
    }
}

/// Parses a point count: digits with optional `_` separators and a `k`/`M`/`G` suffix.
pub fn parse_count(s: &str) -> Result<usize, String> {
    let t = s.trim().replace('_', "");
    let (digits, mul) = match t.chars().last() {
        Some('k' | 'K') => (&t[..t.len() - 1], 1_000),
        Some('m' | 'M') => (&t[..t.len() - 1], 1_000_000),
        Some('g' | 'G') => (&t[..t.len() - 1], 1_000_000_000),
        _ => (&t[..], 1),
    };
    let n: usize = digits
        .parse()
        .map_err(|_| format!("'{s}' is not a point count (e.g. 200000, 200k, 10M)"))?;
    let n = n
        .checked_mul(mul)
        .ok_or_else(|| format!("'{s}' is too large"))?;
    if n == 0 {
        return Err("must be at least 1".into());
    }
    Ok(n)
}

#[cfg(test)]
#[path = "spec_tests.rs"]
mod tests;
