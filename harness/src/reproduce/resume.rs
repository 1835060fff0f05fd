//! Measure checkpoints: what lets a reproduction killed mid-way (a paper-profile part takes
//! hours; a session or a batch slot may end first) go on at its first unfinished measure.
//!
//! After every measure that ran without error, `OUT/measures/SPEC/MEASURE.json` records its
//! result with what produced it: the commit (clean), the profile, the spec's hash, the adapter.
//! `reproduce --resume` takes a measure from its checkpoint only when all four are today's and
//! the measure's runs are still on disk; anything else (another commit, an edited spec, a
//! dirty tree, a missing run directory, a file that does not parse) runs the measure again.
//! Without `--resume` every measure runs and its checkpoint is rewritten.
//!
//! Decision: resuming is asked for (`--resume`), not automatic, because a second run of the
//! same commit is also how a timing is repeated; a resumed measure says so in the report's
//! measure list, with the date it was measured.
//!
//! Numbers are stored as text (`f64`'s `Display`, which `parse` reads back bit for bit,
//! `inf` and `NaN` included): JSON has no infinity, and a PSNR of identical images is one.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use anyhow::Context as _;

use super::exec::{MeasureResult, SweepLine};
use super::spec::Profile;
use crate::gpu::AdapterDesc;
use crate::runner::GIT_COMMIT;

/// Under `OUT/`.
pub const DIR: &str = "measures";

/// What produced a checkpoint: a measure is resumed only from one with the same identity.
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Identity {
    /// The binary's commit (never a `-dirty` one).
    pub commit: String,
    /// The profile.
    pub profile: Profile,
    /// The spec file's hash ([`super::inputs::spec_hash`]).
    pub spec_hash: String,
    /// The adapter the measure ran on (`None`: it needed none, e.g. a build).
    pub adapter: Option<AdapterDesc>,
}

#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct Checkpoint {
    identity: Identity,
    /// When the measure finished (UTC).
    date: String,
    metrics: BTreeMap<String, String>,
    curve: Vec<[String; 2]>,
    sweep: Vec<SavedLine>,
    dir: Option<PathBuf>,
    seconds: String,
    made: Vec<String>,
}

#[derive(serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
struct SavedLine {
    target: String,
    /// points, flip, holes, holes_max, psnr.
    values: [Option<String>; 5],
}

/// A measure taken from its checkpoint: the result and the date it was measured.
#[derive(Debug)]
pub struct Resumed {
    /// The result as the measure produced it.
    pub result: MeasureResult,
    /// When it was measured.
    pub date: String,
}

/// `OUT/measures/SPEC/MEASURE.json`.
pub fn path(out: &Path, spec: &str, measure: &str) -> PathBuf {
    out.join(DIR).join(spec).join(format!("{measure}.json"))
}

/// Whether a binary of `commit` may write or use checkpoints: not one from a dirty tree,
/// whose commit does not name what ran.
pub fn enabled(commit: &str) -> bool {
    !commit.ends_with("-dirty")
}

impl Identity {
    /// This binary's identity for a measure of a spec hashed `spec_hash`.
    pub fn now(profile: Profile, spec_hash: &str, adapter: Option<AdapterDesc>) -> Self {
        Self {
            commit: GIT_COMMIT.into(),
            profile,
            spec_hash: spec_hash.into(),
            adapter,
        }
    }
}

/// Records `r` (a measure that ran without error) at `file`; nothing when `identity`'s commit
/// is a dirty one.
pub fn save(file: &Path, identity: &Identity, r: &MeasureResult) -> anyhow::Result<()> {
    if !enabled(&identity.commit) {
        return Ok(());
    }
    let text = |v: f64| v.to_string();
    let cp = Checkpoint {
        identity: identity.clone(),
        date: super::report::utc_now(),
        metrics: r
            .metrics
            .iter()
            .map(|(k, v)| (k.clone(), text(*v)))
            .collect(),
        curve: r.curve.iter().map(|(a, b)| [text(*a), text(*b)]).collect(),
        sweep: r
            .sweep
            .iter()
            .map(|l| SavedLine {
                target: l.target.clone(),
                values: [l.points, l.flip, l.holes, l.holes_max, l.psnr].map(|v| v.map(text)),
            })
            .collect(),
        dir: r.dir.clone(),
        seconds: text(r.seconds),
        made: r.made.clone(),
    };
    if let Some(parent) = file.parent() {
        std::fs::create_dir_all(parent)
            .with_context(|| format!("creating {}", parent.display()))?;
    }
    crate::results::write_json(file, &cp)
}

/// Removes the checkpoint at `file`, if any (the measure is running again or failed).
pub fn forget(file: &Path) -> anyhow::Result<()> {
    match std::fs::remove_file(file) {
        Err(e) if e.kind() != std::io::ErrorKind::NotFound => {
            Err(e).with_context(|| format!("removing the checkpoint {}", file.display()))
        }
        _ => Ok(()),
    }
}

/// The measure recorded at `file`, when its identity is `identity` and its runs are on disk;
/// otherwise why it must run again.
pub fn load(file: &Path, identity: &Identity) -> Result<Resumed, String> {
    if !enabled(&identity.commit) {
        return Err(format!("commit {} is not a clean one", identity.commit));
    }
    if !file.is_file() {
        return Err("no checkpoint".into());
    }
    let cp: Checkpoint = crate::results::read_json(file).map_err(|e| format!("{e:#}"))?;
    if &cp.identity != identity {
        let (a, b) = (&cp.identity, identity);
        let what = if a.commit != b.commit {
            format!("commit {} (this binary: {})", a.commit, b.commit)
        } else if a.profile != b.profile {
            format!("profile {} (now {})", a.profile, b.profile)
        } else if a.spec_hash != b.spec_hash {
            "the spec as it was (edited since)".to_string()
        } else {
            "another adapter".to_string()
        };
        return Err(format!("it was measured with {what}"));
    }
    if let Some(d) = cp.dir.as_ref().filter(|d| !d.is_dir()) {
        return Err(format!("its runs ({}) are gone", d.display()));
    }
    let num = |s: &str| {
        s.parse::<f64>()
            .map_err(|_| format!("{}: '{s}' is not a number", file.display()))
    };
    let opt = |s: &Option<String>| s.as_deref().map(num).transpose();
    let mut metrics = BTreeMap::new();
    for (k, v) in &cp.metrics {
        metrics.insert(k.clone(), num(v)?);
    }
    let mut curve = Vec::new();
    for [a, b] in &cp.curve {
        curve.push((num(a)?, num(b)?));
    }
    let mut sweep = Vec::new();
    for l in &cp.sweep {
        let [points, flip, holes, holes_max, psnr] = &l.values;
        sweep.push(SweepLine {
            target: l.target.clone(),
            points: opt(points)?,
            flip: opt(flip)?,
            holes: opt(holes)?,
            holes_max: opt(holes_max)?,
            psnr: opt(psnr)?,
        });
    }
    Ok(Resumed {
        result: MeasureResult {
            metrics,
            curve,
            sweep,
            dir: cp.dir,
            seconds: num(&cp.seconds)?,
            made: cp.made,
            ..MeasureResult::default()
        },
        date: cp.date,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn identity() -> Identity {
        Identity {
            commit: "34ced1bf0411".into(),
            profile: Profile::Quick,
            spec_hash: "abc".into(),
            adapter: None,
        }
    }

    #[test]
    fn a_checkpoint_round_trips_every_number_bit_for_bit() {
        let tmp = tempfile::tempdir().unwrap();
        let runs = tmp.path().join("runs");
        std::fs::create_dir(&runs).unwrap();
        let r = MeasureResult {
            metrics: BTreeMap::from([
                ("median.psnr_db".to_string(), f64::INFINITY),
                ("median.flip_mean".to_string(), 0.1 + 0.2),
                ("odd".to_string(), f64::NAN),
                ("tiny".to_string(), f64::MIN_POSITIVE),
            ]),
            curve: vec![(1.0 / 3.0, 12345.0)],
            sweep: vec![SweepLine {
                target: "eps-2".into(),
                points: Some(7.0),
                flip: None,
                holes: Some(-0.0),
                holes_max: Some(1e-300),
                psnr: Some(f64::NEG_INFINITY),
            }],
            dir: Some(runs),
            seconds: 61.25,
            made: vec!["scene made: 3 s, 0.01 GB".into()],
            ..MeasureResult::default()
        };
        let file = path(tmp.path(), "spec-a", "m1");
        save(&file, &identity(), &r).unwrap();
        let back = load(&file, &identity()).unwrap().result;
        let bits = |m: &BTreeMap<String, f64>| {
            m.iter()
                .map(|(k, v)| (k.clone(), v.to_bits()))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&back.metrics), bits(&r.metrics));
        assert_eq!(back.curve, r.curve);
        let line = |l: &SweepLine| {
            [l.points, l.flip, l.holes, l.holes_max, l.psnr].map(|v| v.map(f64::to_bits))
        };
        assert_eq!(line(&back.sweep[0]), line(&r.sweep[0]));
        assert_eq!(back.sweep[0].target, "eps-2");
        assert_eq!(back.dir, r.dir);
        assert_eq!(back.seconds, 61.25);
        assert_eq!(back.made, r.made);
        assert!(back.error.is_none() && !back.skipped_for_gpu);
    }

    #[test]
    fn a_checkpoint_of_another_identity_or_without_its_runs_is_not_used() {
        let tmp = tempfile::tempdir().unwrap();
        let runs = tmp.path().join("runs");
        std::fs::create_dir(&runs).unwrap();
        let r = MeasureResult {
            dir: Some(runs.clone()),
            ..MeasureResult::default()
        };
        let file = path(tmp.path(), "s", "m");
        assert_eq!(load(&file, &identity()).unwrap_err(), "no checkpoint");
        save(&file, &identity(), &r).unwrap();
        assert!(load(&file, &identity()).is_ok());
        let other = |f: &dyn Fn(&mut Identity)| {
            let mut i = identity();
            f(&mut i);
            load(&file, &i).unwrap_err()
        };
        assert!(
            other(&|i| i.commit = "0123456789ab".into())
                .contains("commit 34ced1bf0411 (this binary: 0123456789ab)")
        );
        assert!(other(&|i| i.profile = Profile::Paper).contains("profile quick"));
        assert!(other(&|i| i.spec_hash = "abd".into()).contains("edited since"));
        let gpu = AdapterDesc {
            name: "x".into(),
            backend: "Vulkan".into(),
            device_type: "DiscreteGpu".into(),
            driver: "d".into(),
            driver_info: "1".into(),
        };
        assert!(other(&|i| i.adapter = Some(gpu.clone())).contains("another adapter"));
        std::fs::remove_dir(&runs).unwrap();
        assert!(load(&file, &identity()).unwrap_err().contains("are gone"));
        forget(&file).unwrap();
        forget(&file).unwrap();
        assert_eq!(load(&file, &identity()).unwrap_err(), "no checkpoint");
        std::fs::write(&file, "{").unwrap();
        assert!(load(&file, &identity()).unwrap_err().contains("parsing"));
        // A dirty binary neither writes nor reads checkpoints.
        let mut dirty = identity();
        dirty.commit = "34ced1bf0411-dirty".into();
        forget(&file).unwrap();
        save(&file, &dirty, &r).unwrap();
        assert!(!file.exists());
        assert!(load(&file, &dirty).unwrap_err().contains("not a clean one"));
    }
}
