//! Loading specs: every `*.toml` of a directory, or one file, parsed ([`super::raw`]),
//! checked for every profile ([`super::check`]) and resolved for the one asked for.

use std::path::{Path, PathBuf};

use super::check::Checker;
use super::raw::RawSpec;
use super::spec::{Profile, Spec, SpecError};

/// Loads every `*.toml` in `dir` (sorted by file name), paths inside them relative to
/// `root`, resolved for `profile`. Each spec is checked for every profile; the specs whose
/// `profiles` leave `profile` out are not returned.
pub fn load_dir(dir: &Path, root: &Path, profile: Profile) -> Result<Vec<Spec>, SpecError> {
    let err = |m: String| SpecError {
        file: dir.to_path_buf(),
        field: String::new(),
        message: m,
    };
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .map_err(|e| err(format!("cannot read the spec directory: {e}")))?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    files.sort();
    if files.is_empty() {
        return Err(err("no *.toml specs".into()));
    }
    let specs: Vec<Spec> = files
        .iter()
        .map(|f| load(f, root, profile))
        .collect::<Result<Vec<_>, _>>()?
        .into_iter()
        .filter(|s| s.profiles.contains(&profile))
        .collect();
    Ok(specs)
}

/// Loads one spec file for `profile` (checking it for every profile).
pub fn load(file: &Path, root: &Path, profile: Profile) -> Result<Spec, SpecError> {
    let text = std::fs::read_to_string(file).map_err(|e| SpecError {
        file: file.to_path_buf(),
        field: String::new(),
        message: format!("cannot read: {e}"),
    })?;
    parse(&text, file, root, profile)
}

/// Parses a spec's text (`file` names it in errors and gives the expected id).
pub fn parse(text: &str, file: &Path, root: &Path, profile: Profile) -> Result<Spec, SpecError> {
    let raw: RawSpec = toml::from_str(text).map_err(|e| SpecError {
        file: file.to_path_buf(),
        field: String::new(),
        message: e.to_string().trim_end().replace('\n', " "),
    })?;
    let mut out = None;
    for p in Profile::ALL {
        let s = Checker {
            file,
            root,
            profile: p,
        }
        .spec(&raw)?;
        if p == profile {
            out = Some(s);
        }
    }
    out.ok_or_else(|| SpecError {
        file: file.to_path_buf(),
        field: String::new(),
        message: "no profile".into(),
    })
}
