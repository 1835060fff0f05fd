//! Checking a spec's rows: each row's expressions, rule, paper value and reason against the
//! measures of the profile, and which rows another profile measures (a measure's own
//! `profiles`).

use std::collections::{BTreeMap, BTreeSet};

use super::check::Checker;
use super::expr::Expr;
use super::raw::RawRow;
use super::spec::{Format, Measure, MeasureKind, Piece, Profile, Row, SpecError};
use super::verdict::{Paper, Rule, check_shape};

impl Checker<'_> {
    /// Where row `i` is measured, when this profile leaves out a measure its `ours` reads
    /// (`elsewhere`: the measures left out, with their profiles); `None`: it is measured here.
    /// A reason may not read a measure its row does not: the row would be judged in a profile
    /// whose reason cannot be filled in.
    pub(super) fn row_profiles(
        &self,
        i: usize,
        r: &RawRow,
        elsewhere: &BTreeMap<&str, &[Profile]>,
    ) -> Result<Option<Vec<Profile>>, SpecError> {
        if elsewhere.is_empty() {
            return Ok(None);
        }
        let field = |f: &str| format!("row {} ('{}'): {f}", i + 1, r.what);
        let refs = |text: &str, f: &str| -> Result<Vec<String>, SpecError> {
            let mut out = Vec::new();
            if f == "reason" {
                for p in template(text).map_err(|e| self.err(field(f), e))? {
                    if let Piece::Value(e, _) = p {
                        out.extend(e.measures().into_iter().map(str::to_string));
                    }
                }
            } else {
                let e = Expr::parse(text).map_err(|e| self.err(field(f), e))?;
                out.extend(e.measures().into_iter().map(str::to_string));
            }
            Ok(out)
        };
        let mut ours = Vec::new();
        match &r.ours {
            toml::Value::String(t) => ours.extend(refs(t, "ours")?),
            toml::Value::Array(a) => {
                for t in a.iter().filter_map(|v| v.as_str()) {
                    ours.extend(refs(t, "ours")?);
                }
            }
            _ => {}
        }
        // The profiles that run every measure the row reads.
        let mut here: Option<Vec<Profile>> = None;
        for m in &ours {
            if let Some(p) = elsewhere.get(m.as_str()) {
                here = Some(match here {
                    None => p.to_vec(),
                    Some(h) => h.into_iter().filter(|x| p.contains(x)).collect(),
                });
            }
        }
        if let (None, Some(text)) = (&here, &r.reason)
            && let Some(m) = refs(text, "reason")?
                .into_iter()
                .find(|m| elsewhere.contains_key(m.as_str()))
        {
            return Err(self.err(
                field("reason"),
                format!(
                    "reads measure '{m}', which the {} profile leaves out, \
                     though the row does not",
                    self.profile
                ),
            ));
        }
        Ok(here)
    }

    pub(super) fn row(&self, i: usize, r: &RawRow, measures: &[Measure]) -> Result<Row, SpecError> {
        let field = |f: &str| format!("row {} ('{}'): {f}", i + 1, r.what);
        let texts: Vec<&str> = match &r.ours {
            toml::Value::String(s) => vec![s.as_str()],
            toml::Value::Array(a) => a
                .iter()
                .map(|v| {
                    v.as_str()
                        .ok_or_else(|| self.err(field("ours"), "a list of expressions (strings)"))
                })
                .collect::<Result<_, _>>()?,
            _ => return Err(self.err(field("ours"), "an expression or a list of them")),
        };
        let ours: Vec<Expr> = texts
            .iter()
            .map(|t| Expr::parse(t).map_err(|e| self.err(field("ours"), e)))
            .collect::<Result<_, _>>()?;
        let number = |v: &toml::Value| match v {
            toml::Value::Float(f) => Some(*f),
            toml::Value::Integer(i) => Some(*i as f64),
            _ => None,
        };
        let paper = match &r.paper {
            None => None,
            Some(v) => Some(match (v, r.rule) {
                (toml::Value::Array(a), rule) => {
                    let nums: Vec<f64> = a
                        .iter()
                        .map(|x| number(x).ok_or_else(|| self.err(field("paper"), "numbers only")))
                        .collect::<Result<_, _>>()?;
                    if rule == Rule::Inside && nums.len() == 2 {
                        Paper::Range(nums[0], nums[1])
                    } else {
                        Paper::List(nums)
                    }
                }
                (v, _) => Paper::Value(
                    number(v).ok_or_else(|| self.err(field("paper"), "a number or a list"))?,
                ),
            }),
        };
        check_shape(r.rule, paper.as_ref(), ours.len(), r.tolerance)
            .map_err(|e| self.err(field("rule"), e))?;
        let band = r.band.map(|[lo, hi]| (lo, hi));
        super::verdict::check_band(r.rule, band).map_err(|e| self.err(field("band"), e))?;
        match (
            r.rule == Rule::Band,
            r.band_reason.as_deref().map(str::trim),
        ) {
            (true, None | Some("")) => {
                return Err(self.err(field("band_reason"), "rule 'band' needs its reason"));
            }
            (false, Some(_)) => {
                return Err(self.err(field("band_reason"), "belongs to rule 'band' only"));
            }
            _ => {}
        }
        if r.judge_on_gpu && r.needs_gpu {
            return Err(self.err(
                field("judge_on_gpu"),
                "a row is either a GPU's figure (needs_gpu) or measured everywhere and judged on a GPU (judge_on_gpu), not both",
            ));
        }
        let reason = r
            .reason
            .as_deref()
            .map(|t| template(t).map_err(|e| self.err(field("reason"), e)))
            .transpose()?;
        let row = Row {
            what: r.what.clone(),
            paper,
            paper_text: r.paper_text.clone(),
            ours,
            rule: r.rule,
            tolerance: r.tolerance,
            format: r.format,
            reason,
            needs_gpu: r.needs_gpu,
            band,
            band_reason: r.band_reason.clone(),
            judge_on_gpu: r.judge_on_gpu,
        };
        // Every reference names a measure; points_at_flip names a sweep.
        let mut exprs: Vec<(&Expr, &str)> = row.ours.iter().map(|e| (e, "ours")).collect();
        for p in row.reason.iter().flatten() {
            if let Piece::Value(e, _) = p {
                exprs.push((e, "reason"));
            }
        }
        for (e, which) in exprs {
            for id in e.measures() {
                if !measures.iter().any(|m| m.id == id) {
                    let known: BTreeSet<&str> = measures.iter().map(|m| m.id.as_str()).collect();
                    return Err(self.err(
                        field(which),
                        format!(
                            "'{id}' is not a measure of this spec (measures: {})",
                            known.into_iter().collect::<Vec<_>>().join(", ")
                        ),
                    ));
                }
            }
            check_sweep_args(e, measures).map_err(|m| self.err(field(which), m))?;
        }
        Ok(row)
    }
}

fn check_sweep_args(e: &Expr, measures: &[Measure]) -> Result<(), String> {
    use super::expr::Func;
    match e {
        Expr::Call(Func::PointsAtFlip(m), args) => {
            if measures
                .iter()
                .any(|x| &x.id == m && x.kind != MeasureKind::Sweep)
            {
                return Err(format!("points_at_flip: '{m}' is not a sweep measure"));
            }
            args.iter().try_for_each(|a| check_sweep_args(a, measures))
        }
        Expr::Call(_, args) => args.iter().try_for_each(|a| check_sweep_args(a, measures)),
        Expr::Neg(a) => check_sweep_args(a, measures),
        Expr::Bin(a, _, b) => {
            check_sweep_args(a, measures)?;
            check_sweep_args(b, measures)
        }
        Expr::Num(_) | Expr::Ref { .. } => Ok(()),
    }
}

/// Splits a reason into text and `{expr}` / `{expr:%}` values (`{{` and `}}` are braces).
fn template(text: &str) -> Result<Vec<Piece>, String> {
    let mut out = Vec::new();
    let mut lit = String::new();
    let mut rest = text;
    while let Some(i) = rest.find(['{', '}']) {
        lit.push_str(&rest[..i]);
        let (c, after) = (rest.as_bytes()[i], &rest[i + 1..]);
        if after.as_bytes().first() == Some(&c) {
            lit.push(c as char);
            rest = &after[1..];
            continue;
        }
        if c == b'}' {
            return Err("an unmatched '}' (write '}}' for a brace)".into());
        }
        let end = after
            .find('}')
            .ok_or("an unclosed '{' (write '{{' for a brace)")?;
        let inner = &after[..end];
        let (expr, format) = match inner.rsplit_once(':') {
            Some((e, "%")) => (e, Format::Percent),
            Some((e, "si")) => (e, Format::Si),
            Some((e, "int")) => (e, Format::Int),
            Some((_, f)) => {
                return Err(format!("'{{{inner}}}': unknown format ':{f}' (%, si, int)"));
            }
            None => (inner, Format::Auto),
        };
        if !lit.is_empty() {
            out.push(Piece::Text(std::mem::take(&mut lit)));
        }
        out.push(Piece::Value(Expr::parse(expr.trim())?, format));
        rest = &after[end + 1..];
    }
    lit.push_str(rest);
    if !lit.is_empty() {
        out.push(Piece::Text(lit));
    }
    Ok(out)
}
