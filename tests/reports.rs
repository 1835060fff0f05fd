//! The reproduction's inputs and outputs cannot drift apart unnoticed (issue 35, items 3, 4
//! and 7): the committed reports record the hashes of the specs (and the quick baseline) they
//! were made from and must match the files; every claim of the papers maps to a spec row or
//! to a stated reason; every spec loads for every profile.
#![allow(clippy::unwrap_used)]

use std::path::{Path, PathBuf};

use harness::reproduce::inputs::{self, QUICK_BASELINE};
use harness::reproduce::load::load_dir;
use harness::reproduce::spec::{Profile, Spec};
use harness::reproduce::{claims, verdict};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

fn specs_at(root: &Path, profile: Profile) -> Vec<Spec> {
    load_dir(&root.join("paper/specs"), root, profile).unwrap()
}

/// Every spec, as the first profile that runs it has it: a claim's rows may live in a spec of
/// any profile (an experiment too large for the quick profile runs in full or paper only).
fn all_specs() -> Vec<Spec> {
    let mut specs: Vec<Spec> = Vec::new();
    for p in Profile::ALL {
        for s in specs_at(&root(), p) {
            if !specs.iter().any(|t| t.id == s.id) {
                specs.push(s);
            }
        }
    }
    specs
}

#[test]
fn every_spec_loads_for_every_profile() {
    for p in Profile::ALL {
        let specs = specs_at(&root(), p);
        // Our own tables (cross-method, spt-list, mwkd-budget-sweep) are not in `paper`.
        let least = if p == Profile::Paper { 11 } else { 14 };
        assert!(specs.len() >= least, "{p}: {} specs", specs.len());
    }
}

/// Every committed report is current; the quick one must exist (the full one is removed
/// while stale and published again by its command: "re-measured or removed").
#[test]
fn committed_reports_match_their_specs_and_the_baseline() {
    let root = root();
    assert!(root.join("paper/report-quick.md").is_file());
    for (profile, baseline) in [
        (Profile::Quick, Some(root.join(QUICK_BASELINE))),
        (Profile::Full, None),
        (Profile::Paper, None),
    ] {
        let report = root.join(format!("paper/report-{}.md", profile.name()));
        if !report.exists() {
            continue;
        }
        let stale = inputs::stale(&report, &specs_at(&root, profile), baseline.as_deref());
        assert!(
            stale.is_empty(),
            "{} is stale — regenerate it with `splatbench reproduce --profile {} --publish paper`:\n{}",
            report.display(),
            profile.name(),
            stale.join("\n")
        );
    }
}

/// The staleness check on a temporary copy of the inputs: current, then a spec changed, a
/// spec added, the baseline re-blessed — each named.
#[test]
fn a_changed_spec_or_baseline_makes_a_report_stale() {
    let tmp = tempfile::tempdir().unwrap();
    let r = tmp.path();
    for dir in ["paper/specs", "paper/paths"] {
        std::fs::create_dir_all(r.join(dir)).unwrap();
        for e in std::fs::read_dir(root().join(dir)).unwrap() {
            let e = e.unwrap();
            std::fs::copy(e.path(), r.join(dir).join(e.file_name())).unwrap();
        }
    }
    std::fs::create_dir_all(r.join("results/baselines")).unwrap();
    std::fs::copy(root().join(QUICK_BASELINE), r.join(QUICK_BASELINE)).unwrap();
    let specs = specs_at(r, Profile::Quick);
    let hashes = specs
        .iter()
        .map(|s| (s.id.clone(), inputs::spec_hash(s).unwrap()))
        .collect();
    let baseline = inputs::file_hash(&r.join(QUICK_BASELINE)).unwrap();
    let report = r.join("report.md");
    std::fs::write(&report, inputs::markdown(&hashes, Some(&baseline))).unwrap();
    let check = || {
        inputs::stale(
            &report,
            &specs_at(r, Profile::Quick),
            Some(&r.join(QUICK_BASELINE)),
        )
    };
    assert_eq!(check(), Vec::<String>::new());
    // A spec edited.
    let spec = r.join("paper/specs/lpc-vs-qsplat.toml");
    let text = std::fs::read_to_string(&spec).unwrap();
    std::fs::write(&spec, format!("{text}\n# edited\n")).unwrap();
    let s = check();
    assert!(
        s.len() == 1 && s[0].contains("'lpc-vs-qsplat' changed"),
        "{s:?}"
    );
    std::fs::write(&spec, &text).unwrap();
    // A camera file a spec names.
    let path = r.join("paper/paths/still-mid.toml");
    let cam = std::fs::read_to_string(&path).unwrap();
    std::fs::write(&path, format!("{cam}\n# moved\n")).unwrap();
    assert!(
        check().iter().any(|m| m.contains("changed")),
        "{:?}",
        check()
    );
    std::fs::write(&path, &cam).unwrap();
    // A spec added.
    std::fs::copy(&spec, r.join("paper/specs/zz-copy.toml")).unwrap();
    let copy = std::fs::read_to_string(r.join("paper/specs/zz-copy.toml")).unwrap();
    std::fs::write(
        r.join("paper/specs/zz-copy.toml"),
        copy.replace("id = \"lpc-vs-qsplat\"", "id = \"zz-copy\""),
    )
    .unwrap();
    assert!(
        check()
            .iter()
            .any(|m| m.contains("'zz-copy' is not in the report"))
    );
    std::fs::remove_file(r.join("paper/specs/zz-copy.toml")).unwrap();
    assert_eq!(check(), Vec::<String>::new());
    // The baseline re-blessed without the report.
    let b = std::fs::read_to_string(r.join(QUICK_BASELINE)).unwrap();
    std::fs::write(r.join(QUICK_BASELINE), format!("{b} ")).unwrap();
    let s = check();
    assert!(s.len() == 1 && s[0].contains("re-blessed"), "{s:?}");
    // A report that records nothing.
    std::fs::write(&report, "# an old report\n").unwrap();
    assert!(check().iter().any(|m| m.contains("records no spec hashes")));
}

#[test]
fn every_claim_maps_to_a_row_or_a_stated_reason() {
    let list = claims::load(&root().join("paper/claims.toml")).unwrap();
    let mut bad = claims::check(&list, &all_specs());
    bad.extend(claims::check_tests(&list, &root()));
    assert!(bad.is_empty(), "paper/claims.toml:\n{}", bad.join("\n"));
    let (rows, open, not) = claims::counts(&list);
    assert_eq!(rows + open + not, list.len());
    // The claims issue 35 lists by name are all there.
    for id in ["lpc-", "spt-", "qsplat-", "mwkd-"] {
        assert!(
            list.iter().filter(|c| c.id.starts_with(id)).count() >= 20,
            "{id}"
        );
    }
}

/// A claim mapped wrongly is refused: to a row that does not exist, to rows and a status,
/// to nothing.
#[test]
fn a_wrong_claim_mapping_is_named() {
    let specs = specs_at(&root(), Profile::Quick);
    let parse = |t: &str| claims::parse(t).unwrap();
    let head = "[[claim]]\nid = \"lpc-x\"\npaper = \"lpc\"\nwhere = \"§6\"\nquote = \"q\"\nvalue = \"v\"\nkind = \"count\"\n";
    let e = claims::check(
        &parse(&format!(
            "{head}rows = [{{ spec = \"lpc-vs-qsplat\", what = \"no such row\" }}]\n"
        )),
        &specs,
    );
    assert!(e[0].contains("has no row 'no such row'"), "{e:?}");
    let e = claims::check(&parse(head), &specs);
    assert!(e[0].contains("maps to no row"), "{e:?}");
    let e = claims::check(
        &parse(&format!("{head}status = \"open\"\nreason = \" \"\n")),
        &specs,
    );
    assert!(e[0].contains("needs its reason"), "{e:?}");
    let e = claims::check(
        &parse(&format!(
            "{head}status = \"open\"\nreason = \"r\"\n{head}status = \"open\"\nreason = \"r\"\n"
        )),
        &specs,
    );
    assert!(e[0].contains("twice"), "{e:?}");
    let named = |t: &str| parse(&format!("{head}tests = [\"{t}\"]\n"));
    assert!(claims::check(&named("x::y"), &specs).is_empty());
    for (t, want) in [
        (
            "harness/tests/render.rs::no_such_test",
            "no test `no_such_test`",
        ),
        ("no/such/file.rs::f", "no test `f`"),
        ("just_a_name", "not `path::function`"),
    ] {
        let e = claims::check_tests(&named(t), &root());
        assert!(e.len() == 1 && e[0].contains(want), "{t}: {e:?}");
    }
    let real = "harness/tests/render.rs::ellipse_axis_ratio_is_n_dot_v_clamped_at_a_tenth";
    assert!(claims::check_tests(&named(real), &root()).is_empty());
}

/// Every committed rule of kind `band`, `at_most`, `at_least`, `inside` and `within` fails on
/// a value outside it (a hand-made number just past each bound); `by_construction` rows never
/// count as a verdict.
#[test]
fn every_committed_rule_fails_outside_its_band() {
    use verdict::{Paper, Rule, Verdict, judge};
    let mut judged = 0;
    for spec in all_specs() {
        for row in &spec.rows {
            let who = format!("{}: '{}'", spec.id, row.what);
            let j = |v: f64| {
                let mut ours = vec![v];
                if let Some(Paper::List(l)) = &row.paper {
                    ours = l.clone();
                }
                judge(row.rule, row.paper.as_ref(), &ours, row.tolerance, row.band).unwrap()
            };
            let outside: Vec<f64> = match (row.rule, &row.paper, row.band) {
                (Rule::Band, _, Some((lo, hi))) => [lo, hi]
                    .iter()
                    .filter(|b| b.is_finite())
                    .map(|&b| b + b.abs().max(1e-9) * 1e-3 * if b == lo { -1.0 } else { 1.0 })
                    .collect(),
                (Rule::AtMost, Some(Paper::Value(p)), _) => vec![p + p.abs().max(1e-9) * 1e-3],
                (Rule::AtLeast, Some(Paper::Value(p)), _) => vec![p - p.abs().max(1e-9) * 1e-3],
                (Rule::Inside, Some(Paper::Range(lo, hi)), _) => {
                    vec![
                        lo - lo.abs().max(1e-9) * 1e-3,
                        hi + hi.abs().max(1e-9) * 1e-3,
                    ]
                }
                (Rule::Within, Some(Paper::Value(p)), _) => {
                    let t = row.tolerance.unwrap();
                    vec![p * (1.0 + t) * 1.001, p * (1.0 - t) * 0.999]
                }
                (Rule::Exact, Some(Paper::Value(p)), _) => vec![p + p.abs().max(1.0) * 1e-6],
                (Rule::ByConstruction, ..) => {
                    assert!(!j(0.0).is_verdict(), "{who}");
                    continue;
                }
                _ => continue,
            };
            for v in outside {
                assert_eq!(j(v), Verdict::Differs, "{who}: {v} should fail");
                judged += 1;
            }
        }
    }
    assert!(judged > 20, "{judged} bounds tried");
}
