//! What a report was made from, so that a committed report cannot go stale unnoticed: the
//! content hash of every spec it ran (the spec file and the camera files it names), and for
//! the quick profile the hash of the regression baseline (`results/baselines/quick.json`)
//! present when it ran. The report prints them in its "Inputs" section, one line each:
//!
//! ```text
//! - spec `lpc-vs-qsplat`: `1b2c…` (16 hex digits)
//! - baseline `results/baselines/quick.json`: `9f3e…`
//! ```
//!
//! [`stale`] compares those lines with the files on disk: a spec changed (or added, or
//! removed) since the report was made, or a baseline re-blessed without the report being
//! regenerated in the same commit, is named. Content hashes, not commit ids: a commit cannot
//! contain its own id.

use std::collections::BTreeMap;
use std::path::Path;

use scenes::hash::Fnv64;

use super::spec::Spec;

/// The quick regression baseline, relative to the repository root.
pub const QUICK_BASELINE: &str = "results/baselines/quick.json";

/// FNV-1a 64 of a spec's file and of the keyframe files its measures name (sorted), as 16
/// hex digits.
pub fn spec_hash(spec: &Spec) -> std::io::Result<String> {
    let mut h = Fnv64::default();
    h.write(&std::fs::read(&spec.file)?);
    let mut paths: Vec<&str> = spec
        .measures
        .iter()
        .filter_map(|m| m.path_text.as_deref())
        .filter(|p| Path::new(p).is_file())
        .collect();
    paths.sort_unstable();
    paths.dedup();
    for p in paths {
        h.write(&std::fs::read(p)?);
    }
    Ok(format!("{:016x}", h.finish()))
}

/// FNV-1a 64 of a file, as 16 hex digits.
pub fn file_hash(path: &Path) -> std::io::Result<String> {
    let mut h = Fnv64::default();
    h.write(&std::fs::read(path)?);
    Ok(format!("{:016x}", h.finish()))
}

/// The "Inputs" lines of a report's markdown.
pub fn markdown(specs: &BTreeMap<String, String>, baseline: Option<&str>) -> String {
    let mut o = String::from(
        "## Inputs\n\nContent hashes (FNV-1a 64) of what this report was made from; a test compares them with the files (`harness::reproduce::inputs`).\n\n",
    );
    for (id, h) in specs {
        o.push_str(&format!("- spec `{id}`: `{h}`\n"));
    }
    if let Some(h) = baseline {
        o.push_str(&format!("- baseline `{QUICK_BASELINE}`: `{h}`\n"));
    }
    o
}

/// Reads the "Inputs" lines back from a report: spec hashes by id, and the baseline's.
pub fn parse(report: &str) -> (BTreeMap<String, String>, Option<String>) {
    let mut specs = BTreeMap::new();
    let mut baseline = None;
    for line in report.lines() {
        let hash = |rest: &str| {
            rest.strip_prefix(": `")
                .and_then(|r| r.strip_suffix('`'))
                .map(str::to_string)
        };
        if let Some(rest) = line.strip_prefix("- spec `") {
            if let Some((id, tail)) = rest.split_once('`')
                && let Some(h) = hash(tail)
            {
                specs.insert(id.to_string(), h);
            }
        } else if let Some(rest) = line.strip_prefix(&format!("- baseline `{QUICK_BASELINE}`")) {
            baseline = hash(rest);
        }
    }
    (specs, baseline)
}

/// What is stale in the committed report `report` against the specs loaded from `specs` (all
/// of them: a published report is complete) and, when given, the baseline file: one sentence
/// per difference, empty when the report is current.
pub fn stale(report: &Path, specs: &[Spec], baseline: Option<&Path>) -> Vec<String> {
    let name = report.display();
    let text = match std::fs::read_to_string(report) {
        Ok(t) => t,
        Err(e) => return vec![format!("{name}: cannot read: {e}")],
    };
    let (recorded, recorded_baseline) = parse(&text);
    let mut out = Vec::new();
    if recorded.is_empty() {
        out.push(format!(
            "{name}: records no spec hashes (made before reports recorded their inputs): regenerate it"
        ));
    }
    for s in specs {
        match (recorded.get(&s.id), spec_hash(s)) {
            (_, Err(e)) => out.push(format!("{}: cannot read: {e}", s.file.display())),
            (None, Ok(_)) if !recorded.is_empty() => {
                out.push(format!("{name}: spec '{}' is not in the report", s.id))
            }
            (Some(r), Ok(h)) if *r != h => out.push(format!(
                "{name}: spec '{}' changed since the report was made ({} → {h}): regenerate the report",
                s.id, r
            )),
            _ => {}
        }
    }
    for id in recorded.keys() {
        if !specs.iter().any(|s| &s.id == id) {
            out.push(format!("{name}: spec '{id}' no longer exists"));
        }
    }
    if let Some(b) = baseline {
        match (recorded_baseline, file_hash(b)) {
            (_, Err(e)) => out.push(format!("{}: cannot read: {e}", b.display())),
            (None, Ok(_)) => out.push(format!(
                "{name}: records no hash of {} (regenerate it with the baseline)",
                b.display()
            )),
            (Some(r), Ok(h)) if r != h => out.push(format!(
                "{name}: {} was re-blessed since the report was made ({r} → {h}): regenerate the quick report in the same commit",
                b.display()
            )),
            _ => {}
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inputs_round_trip() {
        let mut specs = BTreeMap::new();
        specs.insert("a-b".to_string(), "0123456789abcdef".to_string());
        specs.insert("c".to_string(), "fedcba9876543210".to_string());
        let md = markdown(&specs, Some("00000000000000ff"));
        let (s, b) = parse(&md);
        assert_eq!(s, specs);
        assert_eq!(b.as_deref(), Some("00000000000000ff"));
        assert_eq!(parse("no inputs here").0.len(), 0);
    }
}
