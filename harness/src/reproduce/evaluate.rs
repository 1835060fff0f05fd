//! Evaluating a spec's rows: each row's expressions over the measures' results, its rule's
//! verdict, its reason filled in, and numbers printed for people.

use std::collections::BTreeMap;

use super::exec::MeasureResult;
use super::expr::Env;
use super::spec::{Format, Piece, Row};
use super::verdict::{Paper, Verdict, judge};

/// One evaluated row.
#[derive(Debug, Clone, serde::Serialize, serde::Deserialize)]
pub struct RowResult {
    /// What is compared.
    pub what: String,
    /// The paper's value as printed.
    pub paper: String,
    /// Our values (one per `ours` expression; `None` when not measured).
    pub ours: Vec<Option<f64>>,
    /// Our values as printed.
    pub ours_text: String,
    /// ours / paper, for a single paper number.
    pub ratio: Option<f64>,
    /// The rule as printed.
    pub rule: String,
    /// The verdict.
    pub verdict: Verdict,
    /// The reason, filled in, when it differs.
    pub reason: Option<String>,
    /// Rule `band`'s reason (why the band is what it is).
    #[serde(default)]
    pub band_reason: Option<String>,
}

/// Expressions evaluated over a spec's measure results.
pub struct Results<'r> {
    /// By measure id.
    pub by_id: &'r BTreeMap<String, MeasureResult>,
}

impl Env for Results<'_> {
    fn metric(&self, measure: &str, key: &str) -> Result<f64, String> {
        let r = self.get(measure)?;
        r.metrics.get(key).copied().ok_or_else(|| {
            let mut known: Vec<&str> = r.metrics.keys().map(String::as_str).collect();
            let prefix = key.rsplit_once('.').map(|(p, _)| p).unwrap_or("");
            let near: Vec<&str> = known
                .iter()
                .copied()
                .filter(|k| !prefix.is_empty() && k.starts_with(prefix))
                .take(12)
                .collect();
            if !near.is_empty() {
                known = near;
            } else {
                known.truncate(12);
            }
            format!(
                "measure '{measure}' has no metric '{key}' (it has: {}, …)",
                known.join(", ")
            )
        })
    }

    fn curve(&self, measure: &str) -> Result<Vec<(f64, f64)>, String> {
        let r = self.get(measure)?;
        if r.curve.is_empty() {
            return Err(format!("'{measure}' is not a sweep with image metrics"));
        }
        Ok(r.curve.clone())
    }
}

impl Results<'_> {
    fn get(&self, measure: &str) -> Result<&MeasureResult, String> {
        let r = self
            .by_id
            .get(measure)
            .ok_or_else(|| format!("measure '{measure}' was not run"))?;
        if let Some(e) = &r.error {
            return Err(format!("measure '{measure}' failed: {e}"));
        }
        Ok(r)
    }
}

/// Evaluates a row: its values, ratio and verdict; GPU rows on a CPU adapter are "needs a
/// GPU" without values.
pub fn evaluate(row: &Row, env: &Results<'_>, real_gpu: bool) -> RowResult {
    let paper = paper_text(row);
    let rule = row.rule.describe_band(row.tolerance, row.band);
    let base = RowResult {
        what: row.what.clone(),
        paper,
        ours: vec![None; row.ours.len()],
        ours_text: "—".into(),
        ratio: None,
        rule,
        verdict: Verdict::NeedsGpu,
        reason: None,
        band_reason: row.band_reason.clone(),
    };
    if row.needs_gpu && !real_gpu {
        return base;
    }
    let values: Result<Vec<f64>, String> = row.ours.iter().map(|e| e.eval(env)).collect();
    let values = match values {
        Ok(v) => v,
        // A FLIP the sweep never reaches is a measured outcome: a figure of ours says so, a
        // judged row differs.
        Err(e) if e.contains(super::expr::NOT_REACHED) => {
            let text = e.replacen(super::expr::NOT_REACHED, "", 1);
            let verdict = if row.rule == super::verdict::Rule::Report {
                Verdict::OursOnly
            } else {
                Verdict::Differs
            };
            return RowResult {
                ours_text: format!("not reached ({text})"),
                reason: (verdict == Verdict::Differs).then(|| format!("not reached: {text}")),
                verdict,
                ..base
            };
        }
        Err(e) => {
            return RowResult {
                verdict: Verdict::Failed(e),
                ..base
            };
        }
    };
    let verdict = judge(
        row.rule,
        row.paper.as_ref(),
        &values,
        row.tolerance,
        row.band,
    )
    .unwrap_or_else(Verdict::Failed);
    // A relative speed on a CPU rasteriser: shown, not judged.
    let verdict = if row.judge_on_gpu && !real_gpu && verdict.is_verdict() {
        Verdict::NoVerdictCpu
    } else {
        verdict
    };
    let ratio = match (&row.paper, values.as_slice()) {
        (Some(Paper::Value(p)), [v]) if *p != 0.0 => Some(v / p),
        _ => None,
    };
    let reason = (verdict == Verdict::Differs)
        .then(|| row.reason.as_ref().map(|r| fill(r, env)))
        .flatten();
    RowResult {
        ours_text: values
            .iter()
            .map(|v| format_value(*v, row.format))
            .collect::<Vec<_>>()
            .join(" / "),
        ours: values.into_iter().map(Some).collect(),
        ratio,
        verdict,
        reason,
        ..base
    }
}

fn fill(pieces: &[Piece], env: &Results<'_>) -> String {
    pieces
        .iter()
        .map(|p| match p {
            Piece::Text(t) => t.clone(),
            Piece::Value(e, f) => match e.eval(env) {
                Ok(v) => format_value(v, *f),
                Err(err) => format!("[{e}: {err}]"),
            },
        })
        .collect()
}

fn paper_text(row: &Row) -> String {
    if let Some(t) = &row.paper_text {
        return t.clone();
    }
    let f = |v: f64| format_value(v, row.format);
    match &row.paper {
        None => "—".into(),
        Some(Paper::Value(v)) => f(*v),
        Some(Paper::Range(a, b)) => format!("{}–{}", f(*a), f(*b)),
        Some(Paper::List(l)) => l.iter().map(|v| f(*v)).collect::<Vec<_>>().join(" / "),
    }
}

/// Formats a number for the report.
pub fn format_value(v: f64, f: Format) -> String {
    match f {
        Format::Percent => format!("{:.1} %", 100.0 * v),
        Format::Int => thousands(v.round()),
        Format::Si => {
            let (d, s) = match v.abs() {
                a if a >= 1e9 => (1e9, "G"),
                a if a >= 1e6 => (1e6, "M"),
                a if a >= 1e3 => (1e3, "k"),
                _ => (1.0, ""),
            };
            format!("{}{s}", sig3(v / d))
        }
        Format::Auto => {
            if v.fract() == 0.0 && v.abs() < 1e15 {
                thousands(v)
            } else if v.abs() >= 1000.0 {
                thousands(v.round())
            } else {
                sig3(v)
            }
        }
    }
}

fn sig3(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let digits = (2 - v.abs().log10().floor() as i32).max(0) as usize;
    format!("{v:.digits$}")
}

/// `v` rounded, with thousands separated by commas (`-1,234`).
pub fn thousands(v: f64) -> String {
    let s = format!("{:.0}", v.abs());
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i) % 3 == 0 {
            out.push(',');
        }
        out.push(c);
    }
    if v < 0.0 { format!("-{out}") } else { out }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn numbers_print_for_people() {
        assert_eq!(format_value(55987.0, Format::Auto), "55,987");
        assert_eq!(format_value(186_850_683.0, Format::Int), "186,850,683");
        assert_eq!(format_value(0.3496, Format::Auto), "0.350");
        assert_eq!(format_value(13.84, Format::Auto), "13.8");
        assert_eq!(format_value(0.138, Format::Percent), "13.8 %");
        assert_eq!(format_value(2_350_000.0, Format::Si), "2.35M");
        assert_eq!(format_value(-1234.4, Format::Auto), "-1,234");
        assert_eq!(format_value(0.0, Format::Auto), "0");
    }
}
