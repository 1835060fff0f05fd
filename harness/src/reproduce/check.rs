//! Checking a spec as written ([`super::raw`]) and resolving it for one profile: every
//! scene, camera path, method, parameter, expression and rule is validated before anything
//! runs, and an error names the spec file and the field.

use std::collections::BTreeMap;
use std::path::Path;

use methods::{MethodKind, Params};
use scenes::SceneSpec;
use scenes::generators::Generator;
use scenes::paths::PathSpec;

use super::raw::{RawMeasure, RawScene, RawSpec};
use super::spec::{Figure, Measure, MeasureKind, Profile, Row, RowElsewhere, Spec, SpecError};
use crate::render::{Kernel, Raster};
use crate::sweep::SweepTarget;

/// The measures a profile leaves out (a measure's own `profiles`), by id, with the profiles
/// they run in.
type Elsewhere<'r> = BTreeMap<&'r str, &'r [Profile]>;

pub(super) struct Checker<'a> {
    pub(super) file: &'a Path,
    pub(super) root: &'a Path,
    pub(super) profile: Profile,
}

impl Checker<'_> {
    pub(super) fn err(&self, field: impl Into<String>, message: impl Into<String>) -> SpecError {
        let message = message.into();
        SpecError {
            file: self.file.to_path_buf(),
            field: field.into(),
            message: message.replace("{profile}", self.profile.name()),
        }
    }

    pub(super) fn spec(&self, raw: &RawSpec) -> Result<Spec, SpecError> {
        self.check_header(raw)?;
        let mut scenes = BTreeMap::new();
        for (name, s) in &raw.scenes {
            scenes.insert(name.clone(), self.scene(name, s)?);
        }
        let reference = self.reference(raw)?;
        let spec_profiles = match &raw.profiles {
            None => Profile::ALL.to_vec(),
            Some(p) if p.is_empty() => {
                return Err(self.err("profiles", "lists no profile (omit it for all)"));
            }
            Some(p) => p.clone(),
        };
        let (measures, elsewhere) = self.measures(raw, &scenes, reference, &spec_profiles)?;
        let (rows, rows_elsewhere) = self.rows(raw, &measures, &elsewhere)?;
        let figures = self.figures(raw, &measures, &elsewhere)?;
        let spec = Spec {
            file: self.file.to_path_buf(),
            id: raw.id.clone(),
            paper: raw.paper.clone(),
            title: raw.title.clone(),
            source: raw.source.clone(),
            notes: raw.notes.clone(),
            profiles: spec_profiles,
            scenes,
            measures,
            rows,
            rows_elsewhere,
            figures,
        };
        let used = spec.measure_uses();
        if let Some(m) = spec
            .measures
            .iter()
            .find(|m| !used.contains_key(m.id.as_str()))
        {
            return Err(self.err(
                format!("measure '{}'", m.id),
                "no row, reason or figure uses it (remove it, or add a row)",
            ));
        }
        Ok(spec)
    }

    /// The spec's `id` is its file's name; `paper`, `title` and `source` are not empty.
    fn check_header(&self, raw: &RawSpec) -> Result<(), SpecError> {
        let stem = self
            .file
            .file_stem()
            .and_then(|s| s.to_str())
            .unwrap_or_default();
        if raw.id != stem {
            return Err(self.err(
                "id",
                format!(
                    "'{}' must equal the file's name without .toml ('{stem}')",
                    raw.id
                ),
            ));
        }
        for (field, v) in [
            ("paper", &raw.paper),
            ("title", &raw.title),
            ("source", &raw.source),
        ] {
            if v.trim().is_empty() {
                return Err(self.err(field, "must not be empty"));
            }
        }
        Ok(())
    }

    /// The rasteriser of the spec's references (`reference`; `None`: the run's, quads).
    fn reference(&self, raw: &RawSpec) -> Result<Option<Raster>, SpecError> {
        Ok(match &raw.reference {
            None => None,
            Some(v) => {
                let name = self.text("reference", v)?;
                match Raster::ALL.into_iter().find(|r| r.name() == name) {
                    Some(Raster::Quads) => None,
                    Some(r) => Some(r),
                    None => {
                        return Err(self.err(
                            "reference",
                            format!("unknown rasteriser '{name}' (quads, compute)"),
                        ));
                    }
                }
            }
        })
    }

    /// The measures this profile runs (each with the spec's `reference` rasteriser when it
    /// renders), and those it leaves out (a measure's own `profiles`, a subset of
    /// `spec_profiles`) with the profiles they run in. Ids are unique.
    fn measures<'r>(
        &self,
        raw: &'r RawSpec,
        scenes: &BTreeMap<String, SceneSpec>,
        reference: Option<Raster>,
        spec_profiles: &[Profile],
    ) -> Result<(Vec<Measure>, Elsewhere<'r>), SpecError> {
        let mut measures: Vec<Measure> = Vec::new();
        // Measures this profile leaves out (a measure's own `profiles`), with where they run.
        let mut elsewhere: Elsewhere<'r> = BTreeMap::new();
        for m in &raw.measures {
            let mut checked = self.measure(m, scenes)?;
            if matches!(checked.kind, MeasureKind::Run | MeasureKind::Sweep) {
                checked.reference_raster = reference;
                if let (Some(Raster::Compute), Some(k)) = (reference, checked.reference_kernel)
                    && k != Kernel::Square
                {
                    return Err(self.err(
                        format!("measure '{}': reference_kernel", m.id),
                        format!(
                            "'{}': the {} profile draws the spec's references by the compute \
                             rasteriser (`reference`), which draws square splats only",
                            k.name(),
                            self.profile
                        ),
                    ));
                }
            }
            if measures.iter().any(|o| o.id == checked.id) || elsewhere.contains_key(m.id.as_str())
            {
                return Err(self.err(format!("measure '{}'", m.id), "id given twice"));
            }
            match &m.profiles {
                None => measures.push(checked),
                Some(p) => {
                    let field = format!("measure '{}': profiles", m.id);
                    if p.is_empty() {
                        return Err(self.err(field, "lists no profile (omit it for all)"));
                    }
                    if let Some(x) = p.iter().find(|x| !spec_profiles.contains(x)) {
                        return Err(
                            self.err(field, format!("'{x}' is not one of the spec's profiles"))
                        );
                    }
                    if p.contains(&self.profile) {
                        measures.push(checked);
                    } else {
                        elsewhere.insert(&m.id, p);
                    }
                }
            }
        }
        Ok((measures, elsewhere))
    }

    /// The rows this profile checks, and those it leaves out with the measures they read
    /// (`elsewhere`); at least one of the spec's rows, and at least one here.
    fn rows(
        &self,
        raw: &RawSpec,
        measures: &[Measure],
        elsewhere: &Elsewhere<'_>,
    ) -> Result<(Vec<Row>, Vec<RowElsewhere>), SpecError> {
        if raw.rows.is_empty() {
            return Err(self.err("row", "a spec needs at least one [[row]]"));
        }
        let mut rows = Vec::new();
        let mut rows_elsewhere = Vec::new();
        for (i, r) in raw.rows.iter().enumerate() {
            // A row that reads a measure this profile leaves out is left out with it (it is
            // checked in the profiles that run the measure).
            match self.row_profiles(i, r, elsewhere)? {
                Some(p) => rows_elsewhere.push(RowElsewhere {
                    what: r.what.clone(),
                    profiles: p,
                }),
                None => rows.push(self.row(i, r, measures)?),
            }
        }
        if rows.is_empty() {
            return Err(self.err(
                "profiles",
                format!(
                    "the {} profile leaves out every row (give the spec's own profiles instead)",
                    self.profile
                ),
            ));
        }
        Ok((rows, rows_elsewhere))
    }

    /// The figures, each of the sweep measures this profile runs (a figure all of whose
    /// sweeps run elsewhere is left out).
    fn figures(
        &self,
        raw: &RawSpec,
        measures: &[Measure],
        elsewhere: &Elsewhere<'_>,
    ) -> Result<Vec<Figure>, SpecError> {
        let mut figures = Vec::new();
        for f in &raw.figures {
            let field = format!("figure '{}'", f.name);
            if f.name.is_empty()
                || !f
                    .name
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '-')
            {
                return Err(self.err(field, "name: letters, digits and '-' only"));
            }
            if f.sweeps.is_empty() {
                return Err(self.err(field, "sweeps: name at least one sweep measure"));
            }
            let sweeps: Vec<String> = f
                .sweeps
                .iter()
                .filter(|s| !elsewhere.contains_key(s.as_str()))
                .cloned()
                .collect();
            if sweeps.is_empty() {
                continue;
            }
            for s in &sweeps {
                match measures.iter().find(|m| &m.id == s) {
                    Some(m) if m.kind == MeasureKind::Sweep => {}
                    Some(_) => return Err(self.err(field, format!("sweeps: '{s}' is not a sweep"))),
                    None => {
                        return Err(self.err(field, format!("sweeps: no measure '{s}'")));
                    }
                }
            }
            figures.push(Figure {
                name: f.name.clone(),
                title: f.title.clone(),
                sweeps,
            });
        }
        Ok(figures)
    }

    /// A value that may differ by profile: `v` itself, or its entry for the profile when it
    /// is `{ quick = …, full = …, paper = … }` (`paper` falls back to `full`), with the
    /// prefix (`"full: "`) an error about the value names.
    fn for_profile<'v>(
        &self,
        field: &str,
        v: &'v toml::Value,
    ) -> Result<(&'v toml::Value, String), SpecError> {
        match v {
            toml::Value::Table(t) => {
                let names = Profile::ALL.map(Profile::name);
                if let Some(k) = t.keys().find(|k| !names.contains(&k.as_str())) {
                    return Err(self.err(
                        field,
                        format!("unknown profile '{k}' ({})", names.join(", ")),
                    ));
                }
                let (key, what) = match (self.profile, t.contains_key("paper")) {
                    (Profile::Paper, false) => ("full", "paper (full's value): ".to_owned()),
                    (p, _) => (p.name(), format!("{p}: ")),
                };
                let Some(v) = t.get(key) else {
                    return Err(self.err(
                        field,
                        format!("gives no value for profile '{}'", self.profile),
                    ));
                };
                Ok((v, what))
            }
            v => Ok((v, String::new())),
        }
    }

    fn count(&self, field: &str, v: &toml::Value) -> Result<u64, SpecError> {
        match self.for_profile(field, v)? {
            (toml::Value::Integer(i), _) if *i >= 0 => Ok(*i as u64),
            (v, what) => Err(self.err(
                field,
                format!(
                    "{what}must be a non-negative integer or {{ quick = N, full = M, paper = P }}, not {v}"
                ),
            )),
        }
    }

    /// A string, or `{ quick = "…", full = "…", paper = "…" }` resolved for the profile.
    fn text(&self, field: &str, v: &toml::Value) -> Result<String, SpecError> {
        match self.for_profile(field, v)? {
            (toml::Value::String(s), _) => Ok(s.clone()),
            (v, what) => Err(self.err(
                field,
                format!("{what}must be a string or {{ quick = \"…\", full = \"…\" }}, not {v}"),
            )),
        }
    }

    fn scene(&self, name: &str, s: &RawScene) -> Result<SceneSpec, SpecError> {
        let field = format!("scenes.{name}");
        let sample = s
            .sample
            .as_ref()
            .map(|v| self.count(&format!("{field}.sample"), v))
            .transpose()?
            .map(|v| v as usize);
        let seed = s.seed.unwrap_or(1);
        let text = match (&s.generator, &s.file) {
            (Some(g), None) => {
                let g = self.text(&format!("{field}.generator"), g)?;
                let g = &g;
                let generator = Generator::ALL
                    .iter()
                    .find(|x| x.name() == g)
                    .ok_or_else(|| {
                        let known: Vec<_> = Generator::ALL.iter().map(|x| x.name()).collect();
                        self.err(
                            format!("{field}.generator"),
                            format!("unknown generator '{g}' (known: {})", known.join(", ")),
                        )
                    })?;
                let Some(points) = &s.points else {
                    return Err(self.err(format!("{field}.points"), "a generator needs `points`"));
                };
                let n = self.count(&format!("{field}.points"), points)?;
                if n == 0 {
                    return Err(self.err(format!("{field}.points"), "must be at least 1"));
                }
                match &s.sampling {
                    None => format!("{}:{n}:{seed}", generator.name()),
                    Some(v) => {
                        let m = self.text(&format!("{field}.sampling"), v)?;
                        if scenes::generators::Sampling::from_name(&m).is_none() {
                            return Err(self.err(
                                format!("{field}.sampling"),
                                format!("'{m}' is not one of: random, even"),
                            ));
                        }
                        format!("{}:{n}:{seed}:{m}", generator.name())
                    }
                }
            }
            (None, Some(f)) => {
                if s.sampling.is_some() {
                    return Err(self.err(
                        format!("{field}.sampling"),
                        "applies to generators (a file's samples are what they are)",
                    ));
                }
                if s.points.is_some() {
                    return Err(self.err(
                        format!("{field}.points"),
                        "a file has its own points (use `sample` to resample a mesh)",
                    ));
                }
                let p = self.root.join(f);
                if !p.is_file() {
                    return Err(self.err(
                        format!("{field}.file"),
                        format!("{} does not exist", p.display()),
                    ));
                }
                p.to_string_lossy().into_owned()
            }
            _ => {
                return Err(self.err(field, "give exactly one of `generator` and `file`"));
            }
        };
        SceneSpec::parse(&text, sample, seed).map_err(|e| self.err(field, e.to_string()))
    }

    fn measure(
        &self,
        m: &RawMeasure,
        scenes: &BTreeMap<String, SceneSpec>,
    ) -> Result<Measure, SpecError> {
        let field = |f: &str| format!("measure '{}': {f}", m.id);
        if m.id.is_empty() || !m.id.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(self.err(
                format!("measure '{}'", m.id),
                "id: letters, digits and '_' only (it is used in expressions)",
            ));
        }
        let method = MethodKind::from_name(&m.method)
            .map_err(|e| self.err(field("method"), param_message(&e)))?;
        let is_render = matches!(m.kind, MeasureKind::Run | MeasureKind::Sweep);
        let (build_params, runtime_params) = self.measure_params(m, method, &field)?;
        let scene = self.measure_scene(m, scenes, &field)?;
        // Plans.
        let points = match (&m.points, m.kind) {
            (Some(v), MeasureKind::Plan) => Some(self.count(&field("points"), v)?),
            (None, MeasureKind::Plan) => {
                return Err(self.err(field("points"), "a plan needs `points`"));
            }
            (Some(_), _) => return Err(self.err(field("points"), "belongs to plan measures")),
            (None, _) => None,
        };
        if m.kind == MeasureKind::Plan && method != MethodKind::Mwkd {
            return Err(self.err(field("method"), "only mwkd can plan a tree without data"));
        }
        if !is_render {
            for (name, given) in [
                ("path", m.path.is_some()),
                ("frames", m.frames.is_some()),
                ("skip", m.skip.is_some()),
                ("eps", m.eps.is_some()),
                ("budget", m.budget.is_some()),
                ("width", m.width.is_some()),
                ("height", m.height.is_some()),
                ("kernel", m.kernel.is_some()),
                ("gpu_cache_mb", m.gpu_cache_mb.is_some()),
                ("metrics", m.metrics.is_some()),
                ("isolate", m.isolate.is_some()),
            ] {
                self.deny(m, &field, name, given)?;
            }
        }
        // Rendering.
        let (path, path_text) = if is_render {
            let (spec, resolved) = self.measure_path(m, &field)?;
            (Some(spec), Some(resolved))
        } else {
            (None, None)
        };
        if m.isolate == Some(true) && m.kind != MeasureKind::Run {
            return Err(self.err(field("isolate"), "only a run measure can be isolated"));
        }
        let (frames, skip) = self.frames_and_skip(m, is_render, &field)?;
        let targets = if is_render {
            self.targets(m, &field)?
        } else {
            Vec::new()
        };
        let kernel = match &m.kernel {
            None => Kernel::Square,
            Some(k) => self.kernel_named(&field, "kernel", k)?,
        };
        self.deny(
            m,
            &field,
            "reference_kernel",
            m.reference_kernel.is_some() && !is_render,
        )?;
        let reference_kernel = m
            .reference_kernel
            .as_deref()
            .map(|k| self.kernel_named(&field, "reference_kernel", k))
            .transpose()?;
        Ok(Measure {
            id: m.id.clone(),
            kind: m.kind,
            method,
            scene,
            build_params,
            runtime_params,
            path,
            path_text,
            frames,
            skip,
            targets,
            width: self.image_size(&field, "width", &m.width)?,
            height: self.image_size(&field, "height", &m.height)?,
            kernel,
            gpu_cache_mb: m
                .gpu_cache_mb
                .unwrap_or(crate::render::DEFAULT_GPU_CACHE_MB),
            metrics: m.metrics.unwrap_or(true),
            isolate: m.isolate.unwrap_or(false),
            points,
            reference_raster: None,
            reference_kernel,
        })
    }

    /// An error when field `name` of measure `m` is `given` but does not apply to its kind.
    fn deny(
        &self,
        m: &RawMeasure,
        field: &dyn Fn(&str) -> String,
        name: &str,
        given: bool,
    ) -> Result<(), SpecError> {
        if given {
            Err(self.err(
                field(name),
                format!("does not apply to a {:?} measure", m.kind).to_lowercase(),
            ))
        } else {
            Ok(())
        }
    }

    /// A measure's parameters: TOML values as `--param` text, checked for `method`, split
    /// into build and runtime keys (a build measure takes no runtime key).
    fn measure_params(
        &self,
        m: &RawMeasure,
        method: MethodKind,
        field: &dyn Fn(&str) -> String,
    ) -> Result<(Params, Params), SpecError> {
        let mut pairs = Vec::new();
        for (k, v) in &m.params {
            let (v, _) = self.for_profile(&field(&format!("params.{k}")), v)?;
            let text = match v {
                toml::Value::String(s) => s.clone(),
                toml::Value::Integer(_) | toml::Value::Float(_) | toml::Value::Boolean(_) => {
                    v.to_string()
                }
                _ => {
                    return Err(self.err(
                        field(&format!("params.{k}")),
                        "must be a string, number or boolean",
                    ));
                }
            };
            pairs.push(format!("{k}={text}"));
        }
        let all =
            Params::parse(&pairs).map_err(|e| self.err(field("params"), param_message(&e)))?;
        method
            .check_params(&all)
            .map_err(|e| self.err(field("params"), param_message(&e)))?;
        let (mut build_params, mut runtime_params) = (Params::default(), Params::default());
        for (k, v) in all.0 {
            if method.runtime_params().contains(&k.as_str()) {
                runtime_params.0.insert(k, v);
            } else {
                build_params.0.insert(k, v);
            }
        }
        if m.kind == MeasureKind::Build && !runtime_params.is_empty() {
            return Err(self.err(
                field("params"),
                format!(
                    "{} only steer rendering, not a build",
                    runtime_params
                        .0
                        .keys()
                        .cloned()
                        .collect::<Vec<_>>()
                        .join(", ")
                ),
            ));
        }
        Ok((build_params, runtime_params))
    }

    /// A measure's scene: one of `scenes`, required except for a plan (which has none).
    fn measure_scene(
        &self,
        m: &RawMeasure,
        scenes: &BTreeMap<String, SceneSpec>,
        field: &dyn Fn(&str) -> String,
    ) -> Result<Option<String>, SpecError> {
        Ok(match (&m.scene, m.kind) {
            (None, MeasureKind::Plan) => None,
            (Some(_), MeasureKind::Plan) => {
                return Err(self.err(field("scene"), "a plan has no data: give `points`"));
            }
            (None, _) => return Err(self.err(field("scene"), "is required")),
            (Some(s), _) if !scenes.contains_key(s) => {
                let known: Vec<_> = scenes.keys().cloned().collect();
                return Err(self.err(
                    field("scene"),
                    format!(
                        "'{s}' is not defined in [scenes] (defined: {})",
                        if known.is_empty() {
                            "none".into()
                        } else {
                            known.join(", ")
                        }
                    ),
                ));
            }
            (Some(s), _) => Some(s.clone()),
        })
    }

    /// A rendering measure's camera path (`orbit` unless given): a built-in one, or a file
    /// relative to the spec's root; with its text as resolved.
    fn measure_path(
        &self,
        m: &RawMeasure,
        field: &dyn Fn(&str) -> String,
    ) -> Result<(PathSpec, String), SpecError> {
        let text = m.path.as_deref().unwrap_or("orbit");
        let (spec, resolved) =
            if PathSpec::builtin(text).is_some() {
                (PathSpec::parse(text), text.to_string())
            } else {
                let p = self.root.join(text);
                if !p.is_file() {
                    return Err(self.err(
                    field("path"),
                    format!(
                        "'{text}' is neither a built-in path ({}) nor a file ({} does not exist)",
                        PathSpec::BUILTIN.iter().map(|b| b.0).collect::<Vec<_>>().join(", "),
                        p.display()
                    ),
                ));
                }
                let resolved = p.to_string_lossy().into_owned();
                (PathSpec::parse(&resolved), resolved)
            };
        Ok((
            spec.map_err(|e| self.err(field("path"), e.to_string()))?,
            resolved,
        ))
    }

    /// A measure's frame count and frames skipped: a rendering measure needs at least one
    /// frame, and one left after the skipped ones.
    fn frames_and_skip(
        &self,
        m: &RawMeasure,
        is_render: bool,
        field: &dyn Fn(&str) -> String,
    ) -> Result<(usize, usize), SpecError> {
        let frames = match &m.frames {
            Some(v) => self.count(&field("frames"), v)? as usize,
            None if is_render => return Err(self.err(field("frames"), "is required")),
            None => 0,
        };
        if is_render && frames == 0 {
            return Err(self.err(field("frames"), "must be at least 1"));
        }
        let skip = match &m.skip {
            Some(v) => self.count(&field("skip"), v)? as usize,
            None => 0,
        };
        if is_render && skip >= frames {
            return Err(self.err(
                field("skip"),
                format!("{skip} leaves none of the {frames} frames"),
            ));
        }
        Ok((frames, skip))
    }

    /// An image side (field `name`): 512 unless given, else 1…16384 pixels.
    fn image_size(
        &self,
        field: &dyn Fn(&str) -> String,
        name: &str,
        v: &Option<toml::Value>,
    ) -> Result<u32, SpecError> {
        match v {
            None => Ok(512),
            Some(v) => {
                let n = self.count(&field(name), v)?;
                if (1..=16_384).contains(&n) {
                    Ok(n as u32)
                } else {
                    Err(self.err(field(name), format!("{n} px is outside 1…16384")))
                }
            }
        }
    }

    /// The splat kernel named `k` (field `name`).
    fn kernel_named(
        &self,
        field: &dyn Fn(&str) -> String,
        name: &str,
        k: &str,
    ) -> Result<Kernel, SpecError> {
        Kernel::ALL
            .iter()
            .copied()
            .find(|x| x.name() == k)
            .ok_or_else(|| {
                let known: Vec<_> = Kernel::ALL.iter().map(|x| x.name()).collect();
                self.err(
                    field(name),
                    format!("unknown kernel '{k}' (known: {})", known.join(", ")),
                )
            })
    }

    fn targets(
        &self,
        m: &RawMeasure,
        field: &dyn Fn(&str) -> String,
    ) -> Result<Vec<SweepTarget>, SpecError> {
        let (name, v) = match (&m.eps, &m.budget) {
            (Some(v), None) => ("eps", v),
            (None, Some(v)) => ("budget", v),
            _ => {
                return Err(self.err(
                    field("eps"),
                    "give exactly one of `eps` (pixels) and `budget` (points)",
                ));
            }
        };
        let (v, _) = self.for_profile(&field(name), v)?;
        let items: Vec<&toml::Value> = match (v, m.kind) {
            (toml::Value::Array(a), MeasureKind::Sweep) => a.iter().collect(),
            (toml::Value::Array(_), _) => {
                return Err(self.err(field(name), "a run has one target (a sweep takes a list)"));
            }
            (v, _) => vec![v],
        };
        if items.is_empty() {
            return Err(self.err(field(name), "the list is empty"));
        }
        let mut out: Vec<SweepTarget> = Vec::new();
        for it in items {
            let t = if name == "eps" {
                let px = match it {
                    toml::Value::Float(f) => *f,
                    toml::Value::Integer(i) => *i as f64,
                    _ => {
                        return Err(
                            self.err(field(name), format!("{it} is not a number of pixels"))
                        );
                    }
                };
                SweepTarget::tolerance(px as f32)
            } else {
                match it {
                    toml::Value::Integer(i) if *i > 0 => SweepTarget::budget(*i as u64),
                    _ => return Err(self.err(field(name), format!("{it} is not a budget ≥ 1"))),
                }
            }
            .map_err(|e| self.err(field(name), e.to_string()))?;
            if out.iter().any(|o| o.name == t.name) {
                return Err(self.err(field(name), format!("{} is given twice", t.value)));
            }
            out.push(t);
        }
        Ok(out)
    }
}

/// A method error's message without the CLI's `--param:` prefix (a spec has no flags).
fn param_message(e: &methods::MethodError) -> String {
    match e {
        methods::MethodError::Param(m) => m.clone(),
        e => e.to_string(),
    }
}
