//! The papers' quantitative claims as data (`paper/claims.toml`), each mapped to the spec
//! rows that test it or to a stated reason why none does:
//!
//! ```toml
//! [[claim]]
//! id = "lpc-more-points-than-qsplat"   # unique, prefixed by the paper
//! paper = "lpc"                        # qsplat | spt | lpc | mwkd
//! where = "§6, p. 6"
//! quote = "…"                          # verbatim
//! value = "≤ +10 % points at the same tolerance"
//! kind = "count"                       # what sort of figure
//! rows = [{ spec = "lpc-vs-qsplat", what = "…" }]   # the rows testing it, and/or
//! tests = ["harness/tests/render.rs::ellipse_…"]    # tests checking it (a shader's geometry
//!                                                  # has no figure to report), or:
//! status = "open"                      # reproducible, no row yet: `reason` says what it needs
//! status = "not_reproducible"          # `reason` says why
//! reason = "…"
//! ```
//!
//! [`check`] holds the list to that: every claim mapped exactly one way, every row it names
//! present in its spec (by `what`, exactly), every reason non-empty, ids unique;
//! [`check_tests`] that every test named exists.

use std::collections::BTreeSet;
use std::path::Path;

use super::spec::Spec;

/// The file's shape.
#[derive(Debug, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ClaimsFile {
    /// Every claim, in paper order.
    pub claim: Vec<Claim>,
}

/// One claim of a paper.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Claim {
    /// Unique id, prefixed by the paper key.
    pub id: String,
    /// `qsplat`, `spt`, `lpc` or `mwkd`.
    pub paper: String,
    /// Section, figure or table.
    #[serde(rename = "where")]
    pub at: String,
    /// The paper's words.
    pub quote: String,
    /// The number(s) and conditions.
    pub value: String,
    /// What sort of figure.
    pub kind: String,
    /// The spec rows that test it.
    #[serde(default)]
    pub rows: Vec<RowRef>,
    /// The tests that check it, `path::function` from the repository root.
    #[serde(default)]
    pub tests: Vec<String>,
    /// `open` or `not_reproducible` when no row tests it.
    pub status: Option<Status>,
    /// Why (with `status`).
    pub reason: Option<String>,
}

/// A row of a spec, by its `what`.
#[derive(Debug, Clone, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RowRef {
    /// Spec id.
    pub spec: String,
    /// The row's `what`, exactly.
    pub what: String,
}

/// Why a claim has no row.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Status {
    /// Reproducible here; the row is still to be written (`reason`: what it needs).
    Open,
    /// Cannot be reproduced here (`reason`: why).
    NotReproducible,
}

/// Reads `paper/claims.toml`.
pub fn load(path: &Path) -> anyhow::Result<Vec<Claim>> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow::anyhow!("{}: cannot read: {e}", path.display()))?;
    parse(&text).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
}

/// Parses the text of a claims file.
pub fn parse(text: &str) -> Result<Vec<Claim>, String> {
    let f: ClaimsFile = toml::from_str(text).map_err(|e| e.to_string())?;
    Ok(f.claim)
}

/// Every way `claims` fails to map onto `specs`: one sentence each, empty when all hold.
pub fn check(claims: &[Claim], specs: &[Spec]) -> Vec<String> {
    let mut out = Vec::new();
    let mut ids = BTreeSet::new();
    for c in claims {
        let who = format!("claim '{}'", c.id);
        if !ids.insert(c.id.as_str()) {
            out.push(format!("{who}: id given twice"));
        }
        if !["qsplat", "spt", "lpc", "mwkd"].contains(&c.paper.as_str())
            || !c.id.starts_with(&format!("{}-", c.paper))
        {
            out.push(format!(
                "{who}: paper '{}' must be qsplat, spt, lpc or mwkd and prefix the id",
                c.paper
            ));
        }
        let reason = c.reason.as_deref().map(str::trim).unwrap_or("");
        match (c.rows.is_empty() && c.tests.is_empty(), c.status) {
            (false, None) if c.reason.is_none() => {}
            (false, _) => out.push(format!(
                "{who}: maps to rows or tests and also has a status or reason: one or the other"
            )),
            (true, None) => out.push(format!(
                "{who}: maps to no row or test and gives no status (open or not_reproducible) \
                 with a reason"
            )),
            (true, Some(_)) if reason.is_empty() => {
                out.push(format!("{who}: a status needs its reason"))
            }
            (true, Some(_)) => {}
        }
        for r in &c.rows {
            match specs.iter().find(|s| s.id == r.spec) {
                None => out.push(format!("{who}: no spec '{}'", r.spec)),
                // A row the spec's profile leaves out (a measure's `profiles`) is a row too.
                Some(s)
                    if !s.rows.iter().any(|row| row.what == r.what)
                        && !s.rows_elsewhere.iter().any(|row| row.what == r.what) =>
                {
                    out.push(format!("{who}: spec '{}' has no row '{}'", r.spec, r.what))
                }
                Some(_) => {}
            }
        }
    }
    out
}

/// Every test named by `claims` that is not a `#[test]` function of its file under `root`.
pub fn check_tests(claims: &[Claim], root: &Path) -> Vec<String> {
    let mut out = Vec::new();
    for c in claims {
        for t in &c.tests {
            let Some((file, name)) = t.rsplit_once("::") else {
                out.push(format!(
                    "claim '{}': test '{t}' is not `path::function`",
                    c.id
                ));
                continue;
            };
            let text = std::fs::read_to_string(root.join(file)).unwrap_or_default();
            let found = text
                .split("#[test]")
                .skip(1)
                .any(|after| after.trim_start().starts_with(&format!("fn {name}(")));
            if !found {
                out.push(format!("claim '{}': no test `{name}` in {file}", c.id));
            }
        }
    }
    out
}

/// Counts of claims by mapping: (with rows or tests, open, not reproducible).
pub fn counts(claims: &[Claim]) -> (usize, usize, usize) {
    let rows = claims
        .iter()
        .filter(|c| !c.rows.is_empty() || !c.tests.is_empty())
        .count();
    let open = claims
        .iter()
        .filter(|c| c.status == Some(Status::Open))
        .count();
    let not = claims
        .iter()
        .filter(|c| c.status == Some(Status::NotReproducible))
        .count();
    (rows, open, not)
}
