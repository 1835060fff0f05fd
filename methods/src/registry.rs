//! The one explicit list of methods. Adding a method = a variant here and one arm in each
//! `match`; nothing registers itself.

use std::path::Path;

use scenes::{PointCloud, Progress};

use crate::store::access::RepoAt;
use crate::store::remote::RemoteOpener;
use crate::strays::{self, Strays};
use crate::{
    BuildStats, LodMethod, Manifest, MethodError, Params, clod, full, lpc, mwkd, potree, qsplat,
    spt, voxel,
};

/// Every registered method.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum MethodKind {
    /// No LOD: every sample drawn with its own spacing. Also the full-resolution reference.
    Full,
    /// QSplat: quantised bounding-sphere hierarchy traversed on the CPU every frame.
    Qsplat,
    /// Sequential Point Trees (Dachsbacher, Vogelgsang, Stamminger 2003).
    Spt,
    /// Layered Point Clouds (Gobbetti & Marton 2004).
    Lpc,
    /// Multi-way kd-tree (Goswami, Erol, Mukhi, Pajarola, Gobbetti ~2010).
    Mwkd,
    /// Potree 2.0's octree (Schütz, Ohrhallinger, Wimmer 2020): today's practice.
    Potree,
    /// Colour-filtered voxel LOD (Schütz, Kerbl, Klaus, Wimmer 2023): 128³ voxels of mean
    /// colour in inner nodes, the original points in leaves.
    Voxel,
    /// Continuous LOD (Schütz, Krösl, Wimmer 2019): a flattened layered point cloud filtered
    /// point by point every frame.
    Clod,
}

impl MethodKind {
    /// All methods, in registry order.
    pub const ALL: &'static [MethodKind] = &[
        MethodKind::Full,
        MethodKind::Qsplat,
        MethodKind::Spt,
        MethodKind::Lpc,
        MethodKind::Mwkd,
        MethodKind::Potree,
        MethodKind::Voxel,
        MethodKind::Clod,
    ];

    /// The registry name (`--method` value, `method.json`).
    pub fn name(self) -> &'static str {
        match self {
            MethodKind::Full => "full",
            MethodKind::Qsplat => qsplat::NAME,
            MethodKind::Spt => spt::NAME,
            MethodKind::Lpc => lpc::NAME,
            MethodKind::Mwkd => mwkd::NAME,
            MethodKind::Potree => potree::NAME,
            MethodKind::Voxel => voxel::NAME,
            MethodKind::Clod => clod::NAME,
        }
    }

    /// One line describing the method.
    pub fn describe(self) -> &'static str {
        match self {
            MethodKind::Full => {
                "no LOD: every sample as a splat of its own spacing (the reference)"
            }
            MethodKind::Qsplat => {
                "QSplat (2000): quantised bounding-sphere tree, per-frame CPU traversal, streamed splats"
            }
            MethodKind::Spt => {
                "Sequential Point Trees: sorted node list, CPU prefix search, GPU interval test"
            }
            MethodKind::Lpc => {
                "Layered Point Clouds: out-of-core binary tree of ~M-sample clouds, LZO repository, loader thread"
            }
            MethodKind::Mwkd => {
                "multi-way kd-tree: balanced N-ary tree of s-splat nodes, budget priority queue, async loading"
            }
            MethodKind::Potree => {
                "Potree 2.0: nested octree of spacing-halving subsamples, point budget by projected node size"
            }
            MethodKind::Voxel => {
                "colour-filtered voxel LOD (2023): 128³ mean-colour voxels per inner node, original points in leaves, children replace"
            }
            MethodKind::Clod => {
                "continuous LOD (2019): Potree's levels flattened, every point filtered per frame on the GPU by its randomised level"
            }
        }
    }

    /// Looks a method up by registry name (exact, lower case): [`std::str::FromStr`]'s lookup
    /// as a [`MethodError::Unknown`] (not a parameter error: it said "method parameter:
    /// unknown method …").
    pub fn from_name(name: &str) -> Result<Self, MethodError> {
        Ok(name.parse::<Self>()?)
    }

    /// Checks `params` against the method's parameter struct without building.
    pub fn check_params(self, params: &Params) -> Result<(), MethodError> {
        let (_, params) = &strays::split_params(params)?;
        match self {
            MethodKind::Full => params.to_typed::<full::FullParams>(self.name()).map(drop),
            MethodKind::Qsplat => qsplat::QsplatParams::from_params(params).map(drop),
            MethodKind::Spt => spt::SptParams::from_params(params).map(drop),
            MethodKind::Lpc => lpc::LpcParams::from_params(params).map(drop),
            MethodKind::Mwkd => mwkd::MwkdParams::from_params(params).map(drop),
            MethodKind::Potree => potree::PotreeParams::from_params(params).map(drop),
            MethodKind::Voxel => voxel::VoxelParams::from_params(params).map(drop),
            MethodKind::Clod => clod::ClodParams::from_params(params).map(drop),
        }
    }

    /// Builds the method's representation of `cloud` into `dir` (created if missing).
    pub fn build(
        self,
        cloud: &PointCloud,
        params: &Params,
        scene: &str,
        dir: &Path,
        progress: &dyn Progress,
    ) -> Result<BuildStats, MethodError> {
        std::fs::create_dir_all(dir).map_err(|e| MethodError::io(dir, e))?;
        let stats = match strays::split_params(params)? {
            (Strays::In, own) => self.build_method(cloud, &own, scene, dir, progress)?,
            (Strays::Apart, own) => strays::build(self, cloud, params, &own, scene, dir, progress)?,
        };
        stats.write(dir)?;
        Ok(stats)
    }

    /// The method's own build (its parameters without [`strays::PARAM`]).
    pub(crate) fn build_method(
        self,
        cloud: &PointCloud,
        params: &Params,
        scene: &str,
        dir: &Path,
        progress: &dyn Progress,
    ) -> Result<BuildStats, MethodError> {
        match self {
            MethodKind::Full => full::build(cloud, params, scene, dir, progress),
            MethodKind::Qsplat => qsplat::build(cloud, params, scene, dir, progress),
            MethodKind::Spt => spt::build(cloud, params, scene, dir, progress),
            MethodKind::Lpc => lpc::build(cloud, params, scene, dir, progress),
            MethodKind::Mwkd => mwkd::build(cloud, params, scene, dir, progress),
            MethodKind::Potree => potree::build(cloud, params, scene, dir, progress),
            MethodKind::Voxel => voxel::build(cloud, params, scene, dir, progress),
            MethodKind::Clod => clod::build(cloud, params, scene, dir, progress),
        }
    }

    /// Every parameter's default value as text (`m` → `2048`), the way `--param` would give
    /// it; parameters whose default is "absent" (estimated, or off) are left out. The
    /// defaults are the papers' choices unless the method's README says otherwise, so `tune`
    /// marks them in its recommendation.
    pub fn defaults(self) -> std::collections::BTreeMap<String, String> {
        let value = match self {
            MethodKind::Full => serde_json::to_value(full::FullParams::default()),
            MethodKind::Qsplat => serde_json::to_value(qsplat::QsplatParams::default()),
            MethodKind::Spt => serde_json::to_value(spt::SptParams::default()),
            MethodKind::Lpc => serde_json::to_value(lpc::LpcParams::default()),
            MethodKind::Mwkd => serde_json::to_value(mwkd::MwkdParams::default()),
            MethodKind::Potree => serde_json::to_value(potree::PotreeParams::default()),
            MethodKind::Voxel => serde_json::to_value(voxel::VoxelParams::default()),
            MethodKind::Clod => serde_json::to_value(clod::ClodParams::default()),
        };
        let mut out = std::collections::BTreeMap::new();
        if let Ok(serde_json::Value::Object(map)) = value {
            for (k, v) in map {
                match v {
                    serde_json::Value::Null => {}
                    serde_json::Value::String(s) => {
                        out.insert(k, s);
                    }
                    // An `f32` parameter arrives widened to `f64` (0.7 → 0.699999988079071):
                    // written as the `f32` it is, so a default reads as it was set and a grid
                    // value `0.7` is recognised as it.
                    serde_json::Value::Number(n)
                        if n.as_f64().is_some_and(|f| {
                            !(n.is_i64() || n.is_u64()) && f64::from(f as f32) == f
                        }) =>
                    {
                        let f = n.as_f64().unwrap_or_default() as f32;
                        out.insert(k, format!("{f:?}"));
                    }
                    other => {
                        out.insert(k, other.to_string());
                    }
                }
            }
        }
        out.insert(strays::PARAM.into(), "in".into());
        out
    }

    /// The documented effect that dominates a run of this method with `params` (the
    /// parameters in force) that measured `observed`, if one does (each method's README
    /// documents its own; today LPC's spacing rule).
    pub fn known_effect(
        self,
        params: &Params,
        observed: &crate::Observed,
    ) -> Option<crate::KnownEffect> {
        match self {
            MethodKind::Lpc => lpc::known_effect(params, observed),
            MethodKind::Clod => clod::known_effect(params, observed),
            MethodKind::Full
            | MethodKind::Qsplat
            | MethodKind::Spt
            | MethodKind::Mwkd
            | MethodKind::Potree
            | MethodKind::Voxel => None,
        }
    }

    /// Parameters that only steer rendering (read at `open`, not used by `build`): a run of
    /// an existing build may change these and no others.
    pub fn runtime_params(self) -> &'static [&'static str] {
        match self {
            MethodKind::Full | MethodKind::Qsplat => &[],
            MethodKind::Spt => spt::RUNTIME_PARAMS,
            MethodKind::Lpc => lpc::RUNTIME_PARAMS,
            MethodKind::Mwkd => mwkd::RUNTIME_PARAMS,
            MethodKind::Potree => potree::RUNTIME_PARAMS,
            MethodKind::Voxel => voxel::RUNTIME_PARAMS,
            MethodKind::Clod => clod::RUNTIME_PARAMS,
        }
    }

    /// True for the methods that send every point every frame and select on the GPU (CLOD:
    /// its paper filters all points each frame, the cost it accepts); a budget then bounds
    /// the points that pass the filter ([`LodMethod::drawn_points`]), not the points sent.
    pub fn filters_every_point(self) -> bool {
        self == MethodKind::Clod
    }

    /// True for the methods that refine a view by loading chunks of several levels (LPC's
    /// clouds and Potree's nodes, whose union is drawn; MWKD's nodes, a cut of them; voxel's
    /// nodes, each where no drawn child replaces it), frame after frame as they arrive. Such a method must not get worse as it refines
    /// (`tests/refinement.rs`).
    pub fn draws_layers(self) -> bool {
        match self {
            MethodKind::Full | MethodKind::Qsplat | MethodKind::Spt | MethodKind::Clod => false,
            MethodKind::Lpc | MethodKind::Mwkd | MethodKind::Potree | MethodKind::Voxel => true,
        }
    }

    /// True if `dir` is another tool's output that this method reads as it is (no
    /// `method.json`): a PotreeConverter 2.0 directory for `potree`.
    pub fn reads_foreign(self, dir: &Path) -> bool {
        self == MethodKind::Potree
            && !dir.join(Manifest::FILE).exists()
            && dir.join(potree::format::METADATA_FILE).exists()
    }

    /// Opens another tool's output ([`MethodKind::reads_foreign`]) with positions relative
    /// to `origin` (the scene's) and `runtime` parameters; returns the method and what
    /// stands for its `build.json`.
    pub fn open_foreign(
        self,
        dir: &Path,
        origin: glam::DVec3,
        runtime: &Params,
    ) -> Result<(Box<dyn LodMethod>, BuildStats), MethodError> {
        if !self.reads_foreign(dir) {
            return Err(MethodError::Param(format!(
                "{}: not a directory {self} reads as it is (it reads {})",
                dir.display(),
                match self {
                    MethodKind::Potree =>
                        "PotreeConverter 2.0 output: metadata.json, \
                                           hierarchy.bin, octree.bin",
                    _ => "its own builds only",
                }
            )));
        }
        self.check_runtime(
            runtime,
            &format!("{} was built by another tool", dir.display()),
        )?;
        let params = potree::PotreeParams::from_params(runtime)?;
        let m = potree::Potree::open_dir(dir, origin, &params)?;
        Ok((Box::new(m), potree::Potree::foreign_stats(dir)?))
    }

    /// Refuses any key of `runtime` that is not one of [`MethodKind::runtime_params`]: the
    /// error names it and says what to do (`instead`).
    fn check_runtime(self, runtime: &Params, instead: &str) -> Result<(), MethodError> {
        match runtime
            .0
            .keys()
            .find(|k| !self.runtime_params().contains(&k.as_str()))
        {
            Some(k) => Err(MethodError::Param(format!(
                "'{k}' changes how {self} builds, not how it renders: {instead} (runtime \
                 parameters of {self}: {})",
                if self.runtime_params().is_empty() {
                    "none".to_string()
                } else {
                    self.runtime_params().join(", ")
                }
            ))),
            None => Ok(()),
        }
    }

    /// Opens a build directory written by [`MethodKind::build`] (of any method).
    pub fn open(dir: &Path) -> Result<Box<dyn LodMethod>, MethodError> {
        Self::open_with(dir, &Params::default())
    }

    /// Opens a build directory with some of its runtime parameters replaced
    /// ([`MethodKind::runtime_params`]); any other key is an error naming it.
    pub fn open_with(dir: &Path, runtime: &Params) -> Result<Box<dyn LodMethod>, MethodError> {
        Self::open_from(dir, None, runtime)
    }

    /// The small files of a build that a remote open copies besides the manifest and
    /// `build.json` (its repository is read by range requests); `None` for the methods
    /// that read their build from a local directory only.
    pub fn remote_files(self) -> Option<&'static [&'static str]> {
        match self {
            MethodKind::Lpc => Some(&[lpc::INDEX_FILE, lpc::INFO_FILE]),
            MethodKind::Mwkd => Some(&[mwkd::INDEX_FILE, mwkd::INFO_FILE]),
            // Potree's hierarchy is copied whole (22 bytes a node: ≈ 2 MB for a billion
            // points at 50 k a leaf) where Potree's viewer reads it by chunks; its points are
            // read by ranges.
            MethodKind::Potree => Some(&[
                potree::INFO_FILE,
                potree::format::METADATA_FILE,
                potree::format::HIERARCHY_FILE,
            ]),
            MethodKind::Voxel => Some(&[
                voxel::INFO_FILE,
                potree::format::METADATA_FILE,
                potree::format::HIERARCHY_FILE,
            ]),
            MethodKind::Full | MethodKind::Qsplat | MethodKind::Spt | MethodKind::Clod => None,
        }
    }

    /// Copies the small files of the build served at `url` (its manifest, `build.json` and
    /// [`MethodKind::remote_files`]) into the directory `into`, each fetched once through
    /// `open` (a client: `harness::remote`), and returns where its repository is read: the
    /// same URL's repository (`repo.bin`; Potree's and voxel's `octree.bin`), by range
    /// requests. The methods that read a whole build (full, QSplat, SPT, CLOD) and builds
    /// with `strays=apart` (a second build inside) are refused with an error saying so.
    pub fn fetch_remote(
        url: &str,
        into: &Path,
        open: RemoteOpener<'_>,
    ) -> Result<RepoAt, MethodError> {
        let base = if url.ends_with('/') {
            url.to_string()
        } else {
            format!("{url}/")
        };
        std::fs::create_dir_all(into).map_err(|e| MethodError::io(into, e))?;
        let copy = |name: &str| -> Result<(), MethodError> {
            let bytes = open(&format!("{base}{name}")).get()?;
            let path = into.join(name);
            std::fs::write(&path, bytes).map_err(|e| MethodError::io(&path, e))
        };
        copy(Manifest::FILE)?;
        let manifest = Manifest::read(into)?;
        let kind = Self::from_name(&manifest.method)?;
        let Some(files) = kind.remote_files() else {
            return Err(MethodError::Remote {
                url: base,
                msg: format!(
                    "a {kind} build is read from a local directory (its files are not \
                     chunked for range requests): copy it and use --build-dir; remote builds \
                     are LPC's, MWKD's, Potree's and voxel's"
                ),
            });
        };
        if strays::split_params(&manifest.params)?.0 != Strays::In {
            return Err(MethodError::Remote {
                url: base,
                msg: "a strays=apart build holds a second build inside: open it from a local \
                      directory (--build-dir)"
                    .into(),
            });
        }
        copy(BuildStats::FILE)?;
        for name in files {
            copy(name)?;
        }
        let repo = match kind {
            MethodKind::Mwkd => mwkd::codec::REPO_FILE,
            MethodKind::Potree | MethodKind::Voxel => potree::format::OCTREE_FILE,
            _ => lpc::REPO_FILE,
        };
        Ok(RepoAt::Remote(open(&format!("{base}{repo}"))))
    }

    /// Opens a remote build whose small files [`MethodKind::fetch_remote`] copied into
    /// `dir`, its chunks read at `repo`; `runtime` as for [`MethodKind::open_with`].
    pub fn open_remote(
        dir: &Path,
        repo: &RepoAt,
        runtime: &Params,
    ) -> Result<Box<dyn LodMethod>, MethodError> {
        Self::open_from(dir, Some(repo), runtime)
    }

    /// [`MethodKind::open_with`], the repository at `repo` when given.
    fn open_from(
        dir: &Path,
        repo: Option<&RepoAt>,
        runtime: &Params,
    ) -> Result<Box<dyn LodMethod>, MethodError> {
        let mut manifest = Manifest::read(dir)?;
        let kind = Self::from_name(&manifest.method)?;
        if repo.is_some() && kind.remote_files().is_none() {
            return Err(MethodError::Param(format!(
                "a {kind} build is read from a local directory only"
            )));
        }
        kind.check_runtime(runtime, "rebuild instead")?;
        for (k, v) in &runtime.0 {
            manifest.params.0.insert(k.clone(), v.clone());
        }
        let (rule, own) = strays::split_params(&manifest.params)?;
        manifest.params = own;
        kind.check_params(&manifest.params)?;
        let inner: Box<dyn LodMethod> = match kind {
            MethodKind::Full => Box::new(full::Full::open(dir, manifest)?),
            MethodKind::Qsplat => Box::new(qsplat::Qsplat::open(dir, manifest)?),
            MethodKind::Spt => Box::new(spt::Spt::open(dir, manifest)?),
            MethodKind::Lpc => Box::new(match repo {
                Some(r) => lpc::Lpc::open_at(dir, manifest, r)?,
                None => lpc::Lpc::open(dir, manifest)?,
            }),
            MethodKind::Mwkd => Box::new(match repo {
                Some(r) => mwkd::Mwkd::open_at(dir, manifest, r)?,
                None => mwkd::Mwkd::open(dir, manifest)?,
            }),
            MethodKind::Potree => Box::new(match repo {
                Some(r) => potree::Potree::open_at(dir, manifest, r)?,
                None => potree::Potree::open(dir, manifest)?,
            }),
            MethodKind::Voxel => Box::new(match repo {
                Some(r) => voxel::open_at(dir, manifest, r)?,
                None => voxel::open(dir, manifest)?,
            }),
            MethodKind::Clod => Box::new(clod::Clod::open(dir, manifest)?),
        };

        match rule {
            Strays::In => Ok(inner),
            Strays::Apart => strays::Apart::open(dir, inner),
        }
    }
}

impl std::fmt::Display for MethodKind {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(self.name())
    }
}

impl std::str::FromStr for MethodKind {
    type Err = crate::error::UnknownName;

    /// The method of a registry name (exact, lower case).
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        crate::error::UnknownName::lookup("method", Self::ALL, Self::name, s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_the_parameters_and_check_as_given() {
        let lpc = MethodKind::Lpc.defaults();
        assert_eq!(lpc["m"], "2048");
        assert_eq!(lpc["spacing_rule"], "mean");
        assert!(!lpc.contains_key("spacing"), "absent defaults are left out");
        // f32 parameters read as set (not widened: 0.699999988079071), integral ones keep
        // their ".0" as serde writes an f64.
        let clod = MethodKind::Clod.defaults();
        assert_eq!(
            (clod["fovea"].as_str(), clod["point_size"].as_str()),
            ("0.7", "1.0")
        );
        let mwkd = MethodKind::Mwkd.defaults();
        assert_eq!(
            (mwkd["fanout"].as_str(), mwkd["vbo"].as_str()),
            ("4", "8192")
        );
        for kind in MethodKind::ALL {
            let d = kind.defaults();
            assert_eq!(d["strays"], "in");
            let pairs: Vec<String> = d.iter().map(|(k, v)| format!("{k}={v}")).collect();
            let params = Params::parse(&pairs).unwrap_or_else(|e| panic!("{kind}: {e}"));
            kind.check_params(&params)
                .unwrap_or_else(|e| panic!("{kind}: {pairs:?}: {e}"));
        }
    }

    /// The names parse back to their variants (methods and kernels: what the CLI's parsers
    /// rely on), and an unknown name is an error listing every known one and naming no flag.
    #[test]
    fn names_parse_back_and_unknown_names_list_the_known() {
        for kind in MethodKind::ALL {
            assert_eq!(kind.name().parse::<MethodKind>(), Ok(*kind));
        }
        for shape in crate::SplatShape::ALL {
            assert_eq!(shape.name().parse::<crate::SplatShape>(), Ok(*shape));
        }
        let e = "QSplat".parse::<MethodKind>().unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown method 'QSplat' (known: full, qsplat, spt, lpc, mwkd, potree, voxel, clod)"
        );
        let e = "disc".parse::<crate::SplatShape>().unwrap_err().to_string();
        assert_eq!(
            e,
            "unknown kernel 'disc' (known: square, circle, ellipse, gaussian)"
        );
    }
}
