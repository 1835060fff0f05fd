//! `--grid key=v1,v2,…`: parsing, validation against the method's parameters, the split
//! into build and runtime keys, and the cartesian product of settings.

use std::collections::BTreeMap;

use anyhow::{anyhow, bail};
use methods::{MethodKind, Params};

/// The most settings one tune may have (the product of the grids' sizes): each is at least
/// one build or run per target.
pub const MAX_SETTINGS: usize = 10_000;

/// One `--grid`: a parameter and its values, in the order given.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Axis {
    /// Parameter name.
    pub key: String,
    /// Its values, as `--param` takes them.
    pub values: Vec<String>,
    /// True if the parameter only steers rendering ([`MethodKind::runtime_params`]): its
    /// values share a build.
    pub runtime: bool,
}

/// A checked grid over a method's parameters.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Grid {
    /// The axes, in the order given (the first varies slowest).
    pub axes: Vec<Axis>,
    /// Parameters fixed for every setting (`--param`).
    pub fixed: BTreeMap<String, String>,
}

/// One point of the grid.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Setting {
    /// Position in the product (row order).
    pub index: usize,
    /// `key=value` per axis, in axis order.
    pub values: Vec<(String, String)>,
    /// The build this setting runs on: its index in [`Grid::builds`].
    pub build: usize,
}

impl Setting {
    /// `m=512 fanout=4`: the setting as people read it.
    pub fn label(&self) -> String {
        self.values
            .iter()
            .map(|(k, v)| format!("{k}={v}"))
            .collect::<Vec<_>>()
            .join(" ")
    }

    /// `m-512_fanout-4`: the setting as a folder name.
    pub fn folder(&self) -> String {
        folder(&self.values)
    }
}

/// `key-value` pairs joined by `_`, each character outside `[A-Za-z0-9.+-]` written `_`.
fn folder(values: &[(String, String)]) -> String {
    if values.is_empty() {
        return "default".into();
    }
    let clean = |s: &str| -> String {
        s.chars()
            .map(|c| {
                if c.is_ascii_alphanumeric() || ".+-".contains(c) {
                    c
                } else {
                    '_'
                }
            })
            .collect()
    };
    values
        .iter()
        .map(|(k, v)| format!("{}-{}", clean(k), clean(v)))
        .collect::<Vec<_>>()
        .join("_")
}

impl Grid {
    /// Parses `--grid` texts (`key=v1,v2,…`) and checks them against `method` with the fixed
    /// `--param` values `fixed`: every key must be a parameter of the method and every
    /// combination must be accepted by it ([`MethodKind::check_params`]), before anything is
    /// built. With `existing_build` (`--build-dir`, `--build-url`) only runtime keys may
    /// vary, as for `run --build-dir`. Errors name the flag, the key and the value.
    pub fn parse(
        method: MethodKind,
        grids: &[String],
        fixed: &Params,
        existing_build: bool,
    ) -> anyhow::Result<Self> {
        if grids.is_empty() {
            bail!(
                "tune needs at least one --grid KEY=V1,V2,… (e.g. --grid m=1024,2048,4096); \
                 the parameters of {method} are listed in methods/src/{method}/README.md"
            );
        }
        let runtime = method.runtime_params();
        let mut axes: Vec<Axis> = Vec::new();
        for g in grids {
            let (key, list) = g
                .split_once('=')
                .ok_or_else(|| anyhow!("--grid {g}: not KEY=V1,V2,… (e.g. m=1024,2048)"))?;
            let key = key.trim();
            if key.is_empty() {
                bail!("--grid {g}: the key is empty");
            }
            if list.trim().is_empty() {
                bail!("--grid {g}: no values (give KEY=V1,V2,…)");
            }
            let values: Vec<String> = list.split(',').map(|v| v.trim().to_string()).collect();
            if let Some(i) = values.iter().position(String::is_empty) {
                bail!("--grid {g}: value {} is empty", i + 1);
            }
            if let Some(v) = values
                .iter()
                .enumerate()
                .find_map(|(i, v)| values[..i].contains(v).then_some(v))
            {
                bail!("--grid {g}: {key}={v} is given twice");
            }
            if axes.iter().any(|a| a.key == key) {
                bail!("--grid: '{key}' is gridded twice (give its values in one --grid)");
            }
            if fixed.0.contains_key(key) {
                bail!("--grid {g}: '{key}' is also fixed by --param {key}=…: give one of them");
            }
            let is_runtime = runtime.contains(&key);
            if existing_build && !is_runtime {
                bail!(
                    "--grid {g}: '{key}' changes how {method} builds, not how it renders: it \
                     cannot vary over one existing build, --build-dir or --build-url (runtime \
                     parameters of {method}: {}); drop that flag to build each value",
                    if runtime.is_empty() {
                        "none".to_string()
                    } else {
                        runtime.join(", ")
                    }
                );
            }
            // Each value alone, so that an error names the value that is wrong.
            for v in &values {
                let mut p = fixed.clone();
                p.0.insert(key.to_string(), v.clone());
                method
                    .check_params(&p)
                    .map_err(|e| anyhow!("--grid {g}: {key}={v}: {e}"))?;
            }
            axes.push(Axis {
                key: key.to_string(),
                values,
                runtime: is_runtime,
            });
        }
        if existing_build && let Some(k) = fixed.0.keys().find(|k| !runtime.contains(&k.as_str())) {
            bail!(
                "--param {k}: '{k}' changes how {method} builds: it cannot be set over an \
                 existing build (--build-dir, --build-url)"
            );
        }
        let count = axes
            .iter()
            .try_fold(1usize, |n, a| n.checked_mul(a.values.len()))
            .filter(|&n| n <= MAX_SETTINGS)
            .ok_or_else(|| {
                anyhow!(
                    "--grid: the product of the grids' sizes ({}) is more than {MAX_SETTINGS} \
                     settings",
                    axes.iter()
                        .map(|a| a.values.len().to_string())
                        .collect::<Vec<_>>()
                        .join(" × ")
                )
            })?;
        let grid = Self {
            axes,
            fixed: fixed.0.clone(),
        };
        // Every combination, as the method would take it.
        for s in grid.settings() {
            method
                .check_params(&grid.params(&s))
                .map_err(|e| anyhow!("--grid: the setting {}: {e}", s.label()))?;
        }
        let folders: std::collections::BTreeSet<String> =
            grid.settings().iter().map(Setting::folder).collect();
        if folders.len() != count {
            bail!("--grid: two settings name the same folder; use plainer values");
        }
        Ok(grid)
    }

    /// Every setting, the first axis varying slowest.
    pub fn settings(&self) -> Vec<Setting> {
        let n: usize = self.axes.iter().map(|a| a.values.len()).product();
        let builds = self.builds();
        (0..n)
            .map(|index| {
                let mut rest = index;
                let mut values = vec![(String::new(), String::new()); self.axes.len()];
                for (i, a) in self.axes.iter().enumerate().rev() {
                    values[i] = (a.key.clone(), a.values[rest % a.values.len()].clone());
                    rest /= a.values.len();
                }
                let build_values = self.build_values(&values);
                let build = builds.iter().position(|b| *b == build_values).unwrap_or(0);
                Setting {
                    index,
                    values,
                    build,
                }
            })
            .collect()
    }

    /// The distinct builds: the build keys' values of each, in order of first use.
    pub fn builds(&self) -> Vec<Vec<(String, String)>> {
        let n: usize = self.axes.iter().map(|a| a.values.len()).product();
        let mut out: Vec<Vec<(String, String)>> = Vec::new();
        for index in 0..n {
            let mut rest = index;
            let mut values = vec![(String::new(), String::new()); self.axes.len()];
            for (i, a) in self.axes.iter().enumerate().rev() {
                values[i] = (a.key.clone(), a.values[rest % a.values.len()].clone());
                rest /= a.values.len();
            }
            let b = self.build_values(&values);
            if !out.contains(&b) {
                out.push(b);
            }
        }
        out
    }

    /// The build keys' values of a setting's values.
    fn build_values(&self, values: &[(String, String)]) -> Vec<(String, String)> {
        values
            .iter()
            .zip(&self.axes)
            .filter(|(_, a)| !a.runtime)
            .map(|(v, _)| v.clone())
            .collect()
    }

    /// A build's folder name (`m-512`, or `default` when only runtime keys vary).
    pub fn build_folder(values: &[(String, String)]) -> String {
        folder(values)
    }

    /// All parameters of a setting: the fixed ones and its values.
    pub fn params(&self, s: &Setting) -> Params {
        let mut p = Params(self.fixed.clone());
        for (k, v) in &s.values {
            p.0.insert(k.clone(), v.clone());
        }
        p
    }

    /// The parameters a build takes: the fixed build keys and its values.
    pub fn build_params(&self, method: MethodKind, build: &[(String, String)]) -> Params {
        let runtime = method.runtime_params();
        let mut p = Params(
            self.fixed
                .iter()
                .filter(|(k, _)| !runtime.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
        );
        for (k, v) in build {
            p.0.insert(k.clone(), v.clone());
        }
        p
    }

    /// The runtime parameters of a setting: the fixed runtime keys and its runtime values.
    pub fn runtime_params(&self, method: MethodKind, s: &Setting) -> Params {
        let runtime = method.runtime_params();
        let mut p = Params(
            self.fixed
                .iter()
                .filter(|(k, _)| runtime.contains(&k.as_str()))
                .map(|(k, v)| (k.clone(), v.clone()))
                .collect(),
        );
        for ((k, v), a) in s.values.iter().zip(&self.axes) {
            if a.runtime {
                p.0.insert(k.clone(), v.clone());
            }
        }
        p
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(method: MethodKind, grids: &[&str], fixed: &[&str], existing: bool) -> String {
        let grids: Vec<String> = grids.iter().map(|s| s.to_string()).collect();
        match Grid::parse(
            method,
            &grids,
            &Params::parse(fixed).unwrap_or_default(),
            existing,
        ) {
            Ok(g) => format!("ok {}", g.settings().len()),
            Err(e) => format!("{e:#}"),
        }
    }

    #[test]
    fn grids_are_checked_against_the_method() {
        let lpc = MethodKind::Lpc;
        assert_eq!(parse(lpc, &["m=512,1024"], &[], false), "ok 2");
        for (grids, needle) in [
            (&[][..], "at least one --grid"),
            (&["m"][..], "not KEY=V1,V2"),
            (&["=1,2"][..], "the key is empty"),
            (&["m="][..], "no values"),
            (&["m=1,,2"][..], "value 2 is empty"),
            (&["m=512,512"][..], "m=512 is given twice"),
            (&["m=512", "m=1024"][..], "'m' is gridded twice"),
            (&["mm=1,2"][..], "unknown field `mm`"),
            (&["m=512,abc"][..], "m=abc"),
            (&["m=0"][..], "m=0"),
        ] {
            let e = parse(lpc, grids, &[], false);
            assert!(e.contains(needle), "{grids:?}: '{needle}' in {e}");
        }
        let e = parse(lpc, &["m=512"], &["m=1024"], false);
        assert!(e.contains("also fixed by --param"), "{e}");
    }

    #[test]
    fn build_keys_cannot_vary_over_an_existing_build() {
        let lpc = MethodKind::Lpc;
        assert_eq!(parse(lpc, &["fetch_per_frame=8,32"], &[], true), "ok 2");
        let e = parse(lpc, &["m=512,1024"], &[], true);
        assert!(e.contains("changes how lpc builds"), "{e}");
        let e = parse(lpc, &["fetch_per_frame=8,32"], &["m=512"], true);
        assert!(e.contains("--param m"), "{e}");
        let e = parse(MethodKind::Qsplat, &["split=midpoint,median"], &[], true);
        assert!(e.contains("runtime parameters of qsplat: none"), "{e}");
    }

    #[test]
    fn settings_are_the_product_and_builds_are_shared_by_runtime_keys() {
        let grids = vec!["fanout=2,4".to_string(), "c0=1,2,3".to_string()];
        let g = Grid::parse(MethodKind::Mwkd, &grids, &Params::default(), false).unwrap();
        let s = g.settings();
        assert_eq!(s.len(), 6);
        assert_eq!(s[0].label(), "fanout=2 c0=1");
        assert_eq!(s[1].label(), "fanout=2 c0=2");
        assert_eq!(s[3].label(), "fanout=4 c0=1");
        assert_eq!(s[4].folder(), "fanout-4_c0-2");
        assert_eq!(g.builds().len(), 2, "c0 is a runtime key");
        assert_eq!(
            s.iter().map(|s| s.build).collect::<Vec<_>>(),
            [0, 0, 0, 1, 1, 1]
        );
        assert_eq!(
            g.build_params(MethodKind::Mwkd, &g.builds()[1]).0,
            [("fanout".to_string(), "4".to_string())].into()
        );
        assert_eq!(
            g.runtime_params(MethodKind::Mwkd, &s[4]).0,
            [("c0".to_string(), "2".to_string())].into()
        );
        assert_eq!(Grid::build_folder(&[]), "default");
    }
}
