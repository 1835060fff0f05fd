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
//! rows = [{ spec = "lpc-vs-qsplat", what = "…" }]   # the rows testing it, or:
//! status = "open"                      # reproducible, no row yet: `reason` says what it needs
//! status = "not_reproducible"          # `reason` says why
//! reason = "…"
//! ```
//!
//! [`check`] holds the list to that: every claim mapped exactly one way, every row it names
//! present in its spec (by `what`, exactly), every reason non-empty, ids unique.

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
        match (c.rows.is_empty(), c.status) {
            (false, None) if c.reason.is_none() => {}
            (false, _) => out.push(format!(
                "{who}: maps to rows and also has a status or reason: one or the other"
            )),
            (true, None) => out.push(format!(
                "{who}: maps to no row and gives no status (open or not_reproducible) with a reason"
            )),
            (true, Some(_)) if reason.is_empty() => {
                out.push(format!("{who}: a status needs its reason"))
            }
            (true, Some(_)) => {}
        }
        for r in &c.rows {
            match specs.iter().find(|s| s.id == r.spec) {
                None => out.push(format!("{who}: no spec '{}'", r.spec)),
                Some(s) if !s.rows.iter().any(|row| row.what == r.what) => {
                    out.push(format!("{who}: spec '{}' has no row '{}'", r.spec, r.what))
                }
                Some(_) => {}
            }
        }
    }
    out
}

/// Counts of claims by mapping: (with rows, open, not reproducible).
pub fn counts(claims: &[Claim]) -> (usize, usize, usize) {
    let rows = claims.iter().filter(|c| !c.rows.is_empty()).count();
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
