//! The check's table as text: figure, method, scene, frame/target, old, new, allowed,
//! verdict; failures first.

use std::collections::BTreeMap;

use super::{Report, Row, Verdict};

/// The table's columns.
pub const HEADER: [&str; 8] = [
    "figure",
    "method",
    "scene",
    "frame/target",
    "old",
    "new",
    "allowed",
    "verdict",
];

/// The report as an aligned text table of at most `max_rows` rows (`None`: all, times
/// included), then the times (one line per figure — the geometric mean and range of new/old
/// over the runs — with `--all` or when a time failed its gate; else one line of geometric
/// means) and a closing line counting what was compared and what failed. With a limit,
/// times are left out of the table unless they fail the timing gate. Runs compared across
/// experiments (`--compare-across`) are listed first with how they differ.
pub fn render_table(report: &Report, max_rows: Option<usize>) -> String {
    let cells = |r: &Row| {
        [
            r.figure.clone(),
            r.method.clone(),
            r.scene.clone(),
            r.at.clone(),
            r.old.clone(),
            r.new.clone(),
            r.allowed.clone(),
            r.verdict.word().to_string(),
        ]
    };
    let listed: Vec<&Row> = report
        .rows
        .iter()
        .filter(|r| max_rows.is_none() || r.verdict != Verdict::Ratio)
        .collect();
    let shown: Vec<&Row> = listed
        .iter()
        .copied()
        .take(max_rows.unwrap_or(usize::MAX))
        .collect();
    let mut widths: Vec<usize> = HEADER.iter().map(|h| h.chars().count()).collect();
    for r in &shown {
        for (w, c) in widths.iter_mut().zip(cells(r)) {
            *w = (*w).max(c.chars().count().min(60));
        }
    }
    let line = |fields: &[String]| {
        let mut s = String::new();
        for (i, (f, w)) in fields.iter().zip(&widths).enumerate() {
            if i > 0 {
                s.push_str("  ");
            }
            s.push_str(f);
            if i + 1 < fields.len() {
                s.push_str(&" ".repeat(w.saturating_sub(f.chars().count())));
            }
        }
        s.trim_end().to_string() + "\n"
    };
    let mut out = String::new();
    if !report.across.is_empty() {
        out.push_str(&format!(
            "compared across experiments: {}\n",
            report.across.join("; ")
        ));
    }
    if !shown.is_empty() {
        out.push_str(&line(&HEADER.map(String::from)));
        for r in &shown {
            out.push_str(&line(&cells(r)));
        }
        if shown.len() < listed.len() {
            out.push_str(&format!(
                "… {} more rows (--all prints every row)\n",
                listed.len() - shown.len()
            ));
        }
    }
    let mut times: BTreeMap<&str, Vec<f64>> = BTreeMap::new();
    for r in &report.rows {
        if let Some(x) = r.ratio.filter(|x| x.is_finite() && *x > 0.0) {
            times.entry(r.figure.as_str()).or_default().push(x);
        }
    }
    let gmean =
        |ratios: &[f64]| (ratios.iter().map(|x| x.ln()).sum::<f64>() / ratios.len() as f64).exp();
    let slower = report.rows.iter().any(|r| r.verdict == Verdict::Slower);
    if max_rows.is_none() || slower {
        for (figure, ratios) in &times {
            let (lo, hi) = ratios.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), x| {
                (lo.min(*x), hi.max(*x))
            });
            out.push_str(&format!(
                "time {figure}: new/old ×{:.3} (geometric mean of {} runs; ×{lo:.3} to ×{hi:.3})\n",
                gmean(ratios),
                ratios.len()
            ));
        }
    } else if !times.is_empty() {
        let each: Vec<String> = times
            .iter()
            .map(|(figure, ratios)| format!("{figure} ×{:.3}", gmean(ratios)))
            .collect();
        let runs = times.values().map(Vec::len).max().unwrap_or(0);
        out.push_str(&format!(
            "times, new/old (geometric mean of {runs} runs; --all lists each): {}\n",
            each.join(", ")
        ));
    }
    if !report.recorded.is_empty() {
        let names: Vec<&str> = report.recorded.iter().map(String::as_str).collect();
        out.push_str(&format!(
            "recorded, not compared (they follow the machine or thread timing: resident \
             memory, the loader's queue, selections that follow the clock): {}\n",
            names.join(", ")
        ));
    }
    let failures = report.failures();
    out.push_str(&format!(
        "{}: {} runs, {} figures compared, {} failing, {} changed within their allowance\n",
        if failures == 0 { "holds" } else { "REGRESSION" },
        report.runs,
        report.compared,
        failures,
        report
            .rows
            .iter()
            .filter(|r| r.verdict == Verdict::Within)
            .count()
    ));
    out
}
