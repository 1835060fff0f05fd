//! The rules that decide whether a paper's shape holds for our numbers.
//!
//! | rule | paper | holds when |
//! |---|---|---|
//! | `exact` | a number | ours = paper (to 10⁻⁹ relative: counts are exact integers) |
//! | `within` | a number, `tolerance = t` | \|ours / paper − 1\| ≤ t |
//! | `inside` | `[lo, hi]` | lo ≤ ours ≤ hi |
//! | `at_most` | a number | ours ≤ paper |
//! | `at_least` | a number | ours ≥ paper |
//! | `order` | `[a, b, …]`, `ours` a list as long | every pair of rows is ordered as the paper's (pairs the paper ties impose nothing; a tie of ours where the paper has none differs) |
//! | `band` | a number or `[lo, hi]`, shown; `band = [lo, hi]` and `band_reason` | lo ≤ ours ≤ hi: the band the spec derives from the paper's value, with its reason (`inf` for a one-sided claim) |
//! | `by_construction` | optional | never judged: true by construction (a format's fixed size, a monotone ordering), shown and not counted as a verdict |
//! | `report` | none | never judged: a figure of ours with no paper counterpart |
//!
//! A paper's value is one measurement; `at_most` / `at_least` are for claims that are
//! themselves one-sided. Where the paper gives a value ("up to 10 % more"), `band` states the
//! two-sided range that counts as the same shape and why.
//!
//! Comparisons allow a relative slack of 10⁻¹² so that a value printed at a boundary (1.15
//! against 1 ± 15 %) is judged as written, not by its last binary digit.

/// Relative slack on every comparison.
const SLACK: f64 = 1e-12;

/// A rule (`rule = "…"` in a spec row).
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "snake_case")]
pub enum Rule {
    /// Equal.
    Exact,
    /// Ratio within ± `tolerance`.
    Within,
    /// Inside the paper's range.
    Inside,
    /// At most the paper's value.
    AtMost,
    /// At least the paper's value.
    AtLeast,
    /// The rows' ordering equals the paper's.
    Order,
    /// Inside the spec's band around the paper's value (`band`, `band_reason`).
    Band,
    /// True by construction: shown, never judged.
    ByConstruction,
    /// Ours only.
    Report,
}

impl Rule {
    /// How the rule reads in the report.
    pub fn describe(self, tolerance: Option<f64>) -> String {
        match self {
            Rule::Exact => "exact".into(),
            Rule::Within => format!("ratio within ±{:.0} %", 100.0 * tolerance.unwrap_or(0.0)),
            Rule::Inside => "inside the paper's range".into(),
            Rule::AtMost => "at most the paper's".into(),
            Rule::AtLeast => "at least the paper's".into(),
            Rule::Order => "same ordering".into(),
            Rule::Band => "inside the band".into(),
            Rule::ByConstruction => "by construction".into(),
            Rule::Report => "ours only".into(),
        }
    }

    /// How the rule reads with its band (`band [0.95, 1.15]`, `band ≥ 8.3`).
    pub fn describe_band(self, tolerance: Option<f64>, band: Option<(f64, f64)>) -> String {
        match (self, band) {
            (Rule::Band, Some((lo, hi))) if hi.is_infinite() => format!("band ≥ {lo}"),
            (Rule::Band, Some((lo, hi))) if lo.is_infinite() => format!("band ≤ {hi}"),
            (Rule::Band, Some((lo, hi))) => format!("band [{lo}, {hi}]"),
            _ => self.describe(tolerance),
        }
    }
}

/// A paper's value as a spec gives it.
#[derive(Debug, Clone, PartialEq)]
pub enum Paper {
    /// One number.
    Value(f64),
    /// A range `[lo, hi]`.
    Range(f64, f64),
    /// One number per entry of an `order` row.
    List(Vec<f64>),
}

/// The outcome of a row (or a table: the worst of its rows).
#[derive(Debug, Clone, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case", tag = "verdict", content = "detail")]
pub enum Verdict {
    /// The paper's shape holds.
    Holds,
    /// It does not.
    Differs,
    /// A figure with no paper counterpart.
    OursOnly,
    /// Not measured: the adapter is a CPU rasteriser and the figure is a GPU's.
    NeedsGpu,
    /// Measured, not judged: a relative speed on a CPU rasteriser (`judge_on_gpu`).
    NoVerdictCpu,
    /// True by construction: shown, not counted.
    ByConstruction,
    /// The measurement or the evaluation failed (the message says why).
    Failed(String),
}

impl Verdict {
    /// The word the report prints.
    pub fn word(&self) -> &'static str {
        match self {
            Verdict::Holds => "holds",
            Verdict::Differs => "differs",
            Verdict::OursOnly => "ours only",
            Verdict::NeedsGpu => "needs a GPU",
            Verdict::NoVerdictCpu => "CPU rasteriser: no verdict",
            Verdict::ByConstruction => "by construction",
            Verdict::Failed(_) => "failed",
        }
    }

    /// Whether the row counts as a verdict on the paper (holds or differs).
    pub fn is_verdict(&self) -> bool {
        matches!(self, Verdict::Holds | Verdict::Differs)
    }

    /// A table's verdict from its rows': failed if any failed, else differs if any differs,
    /// else holds if any holds, else needs a GPU if any does, else no verdict on a CPU if
    /// any, else ours only (by-construction rows count as ours only).
    pub fn of_table<'a>(rows: impl IntoIterator<Item = &'a Verdict>) -> Verdict {
        let rows: Vec<&Verdict> = rows.into_iter().collect();
        if let Some(f) = rows.iter().find(|v| matches!(v, Verdict::Failed(_))) {
            return (*f).clone();
        }
        for v in [
            Verdict::Differs,
            Verdict::Holds,
            Verdict::NeedsGpu,
            Verdict::NoVerdictCpu,
        ] {
            if rows.contains(&&v) {
                return v;
            }
        }
        Verdict::OursOnly
    }
}

/// Whether `ours` satisfies `rule` against `paper`. The shapes (a number for `exact`, a
/// range for `inside`, lists of equal length for `order`, a tolerance for `within`, no paper
/// value for `report`) are checked when a spec loads ([`check_shape`]); a mismatch here is an
/// error.
pub fn judge(
    rule: Rule,
    paper: Option<&Paper>,
    ours: &[f64],
    tolerance: Option<f64>,
    band: Option<(f64, f64)>,
) -> Result<Verdict, String> {
    check_shape(rule, paper, ours.len(), tolerance)?;
    check_band(rule, band)?;
    let holds = |b: bool| if b { Verdict::Holds } else { Verdict::Differs };
    let le = |a: f64, b: f64| a <= b + SLACK * b.abs().max(a.abs());
    Ok(match (rule, paper) {
        (Rule::Report, _) => Verdict::OursOnly,
        (Rule::ByConstruction, _) => Verdict::ByConstruction,
        (Rule::Band, Some(_)) => {
            let (lo, hi) = band.unwrap_or((f64::NAN, f64::NAN));
            holds(ours[0].is_finite() && le(lo, ours[0]) && le(ours[0], hi))
        }
        (Rule::Exact, Some(Paper::Value(p))) => {
            holds((ours[0] - p).abs() <= 1e-9 * p.abs().max(1.0))
        }
        (Rule::Within, Some(Paper::Value(p))) => {
            let t = tolerance.unwrap_or(0.0);
            holds(*p != 0.0 && le((ours[0] / p - 1.0).abs(), t))
        }
        (Rule::Inside, Some(Paper::Range(lo, hi))) => holds(le(*lo, ours[0]) && le(ours[0], *hi)),
        (Rule::AtMost, Some(Paper::Value(p))) => holds(le(ours[0], *p)),
        (Rule::AtLeast, Some(Paper::Value(p))) => holds(le(*p, ours[0])),
        (Rule::Order, Some(Paper::List(p))) => {
            let mut same = true;
            for i in 0..p.len() {
                for j in i + 1..p.len() {
                    let want = p[i].total_cmp(&p[j]);
                    if want != std::cmp::Ordering::Equal && ours[i].total_cmp(&ours[j]) != want {
                        same = false;
                    }
                }
            }
            holds(same)
        }
        _ => return Err(format!("rule {rule:?} cannot judge {paper:?}")),
    })
}

/// Checks that a row's paper value, number of `ours` values and tolerance fit its rule.
pub fn check_shape(
    rule: Rule,
    paper: Option<&Paper>,
    ours: usize,
    tolerance: Option<f64>,
) -> Result<(), String> {
    let one = |what: &str| {
        if ours == 1 {
            Ok(())
        } else {
            Err(format!(
                "rule '{what}' takes one `ours` expression, not {ours}"
            ))
        }
    };
    match (rule, paper) {
        (Rule::Within, Some(Paper::Value(p))) => {
            one("within")?;
            match tolerance {
                Some(t) if t.is_finite() && t >= 0.0 && *p != 0.0 => Ok(()),
                Some(_) if *p == 0.0 => {
                    Err("rule 'within' needs a paper value other than 0".into())
                }
                Some(t) => Err(format!(
                    "tolerance {t} must be a finite fraction ≥ 0 (0.15 = ±15 %)"
                )),
                None => Err("rule 'within' needs `tolerance` (e.g. 0.15 for ±15 %)".into()),
            }
        }
        (_, _) if tolerance.is_some() => Err(format!(
            "`tolerance` belongs to rule 'within' only, not '{}'",
            rule_name(rule)
        )),
        (Rule::Exact | Rule::AtMost | Rule::AtLeast, Some(Paper::Value(_))) => one(rule_name(rule)),
        (Rule::Inside, Some(Paper::Range(lo, hi))) if lo <= hi => one("inside"),
        (Rule::Inside, Some(Paper::Range(lo, hi))) => {
            Err(format!("paper range [{lo}, {hi}] is reversed"))
        }
        (Rule::Order, Some(Paper::List(p))) if p.len() >= 2 && p.len() == ours => Ok(()),
        (Rule::Order, Some(Paper::List(p))) => Err(format!(
            "rule 'order' needs ≥ 2 paper values and as many `ours` expressions (paper {}, ours {ours})",
            p.len()
        )),
        (Rule::Band, Some(Paper::Value(_) | Paper::Range(..))) => one("band"),
        (Rule::ByConstruction, _) => {
            if ours >= 1 {
                Ok(())
            } else {
                Err("a row needs `ours`".into())
            }
        }
        (Rule::Report, None) => {
            if ours >= 1 {
                Ok(())
            } else {
                Err("a row needs `ours`".into())
            }
        }
        (Rule::Report, Some(_)) => Err(
            "rule 'report' is for figures without a paper value: drop `paper` or pick a rule"
                .into(),
        ),
        (r, None) => Err(format!("rule '{}' needs a `paper` value", rule_name(r))),
        (r, Some(p)) => Err(format!(
            "rule '{}' cannot take the paper value {}: {}",
            rule_name(r),
            match p {
                Paper::Value(v) => format!("{v}"),
                Paper::Range(a, b) => format!("[{a}, {b}]"),
                Paper::List(l) => format!("{l:?}"),
            },
            match r {
                Rule::Inside => "give [lo, hi]",
                Rule::Order => "give one number per `ours` expression",
                _ => "give one number",
            }
        )),
    }
}

fn rule_name(r: Rule) -> &'static str {
    match r {
        Rule::Exact => "exact",
        Rule::Within => "within",
        Rule::Inside => "inside",
        Rule::AtMost => "at_most",
        Rule::AtLeast => "at_least",
        Rule::Order => "order",
        Rule::Band => "band",
        Rule::ByConstruction => "by_construction",
        Rule::Report => "report",
    }
}

/// Checks that `band` is given exactly for rule `band`, ordered and not NaN.
pub fn check_band(rule: Rule, band: Option<(f64, f64)>) -> Result<(), String> {
    match (rule, band) {
        (Rule::Band, Some((lo, hi))) if lo <= hi => Ok(()),
        (Rule::Band, Some((lo, hi))) => Err(format!("band [{lo}, {hi}] is reversed or NaN")),
        (Rule::Band, None) => Err(
            "rule 'band' needs `band = [lo, hi]` (`inf` for no upper bound) and `band_reason`"
                .into(),
        ),
        (_, Some(_)) => Err(format!(
            "`band` belongs to rule 'band' only, not '{}'",
            rule_name(rule)
        )),
        (_, None) => Ok(()),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn j(rule: Rule, paper: Paper, ours: &[f64], tol: Option<f64>) -> Verdict {
        judge(rule, Some(&paper), ours, tol, None).unwrap()
    }

    #[test]
    fn bands_fail_outside_and_by_construction_is_no_verdict() {
        let b = |ours, band| {
            judge(
                Rule::Band,
                Some(&Paper::Value(1.10)),
                &[ours],
                None,
                Some(band),
            )
            .unwrap()
        };
        // LPC's "up to 10 % more points than QSplat": [0.95, 1.15].
        assert_eq!(b(1.0, (0.95, 1.15)), Verdict::Holds);
        assert_eq!(b(1.15, (0.95, 1.15)), Verdict::Holds);
        assert_eq!(
            b(0.24, (0.95, 1.15)),
            Verdict::Differs,
            "0.24× QSplat's points"
        );
        assert_eq!(b(1.2, (0.95, 1.15)), Verdict::Differs);
        assert_eq!(b(f64::NAN, (0.95, 1.15)), Verdict::Differs);
        // One-sided: "an order of magnitude faster", at least 8.3×.
        assert_eq!(b(100.0, (8.3, f64::INFINITY)), Verdict::Holds);
        assert_eq!(b(8.2, (8.3, f64::INFINITY)), Verdict::Differs);
        assert!(judge(Rule::Band, Some(&Paper::Value(1.0)), &[1.0], None, None).is_err());
        assert!(
            judge(
                Rule::Band,
                Some(&Paper::Value(1.0)),
                &[1.0],
                None,
                Some((2.0, 1.0))
            )
            .is_err()
        );
        assert!(
            judge(
                Rule::AtMost,
                Some(&Paper::Value(1.0)),
                &[1.0],
                None,
                Some((0.0, 2.0))
            )
            .is_err()
        );
        let c = judge(
            Rule::ByConstruction,
            Some(&Paper::Value(4.0)),
            &[4.0],
            None,
            None,
        )
        .unwrap();
        assert_eq!(c, Verdict::ByConstruction);
        assert!(!c.is_verdict());
        assert_eq!(
            Verdict::of_table(&[c, Verdict::OursOnly]),
            Verdict::OursOnly
        );
        assert_eq!(
            Verdict::of_table(&[Verdict::NoVerdictCpu, Verdict::OursOnly]),
            Verdict::NoVerdictCpu
        );
    }

    #[test]
    fn within_holds_at_the_boundary_and_differs_past_it() {
        let v = |ours| j(Rule::Within, Paper::Value(2.0), &[ours], Some(0.15));
        assert_eq!(v(2.3), Verdict::Holds); // +15 % exactly
        assert_eq!(v(1.7), Verdict::Holds); // −15 % exactly
        assert_eq!(v(2.0), Verdict::Holds);
        assert_eq!(v(2.3001), Verdict::Differs);
        assert_eq!(v(1.6999), Verdict::Differs);
        assert_eq!(
            j(Rule::Within, Paper::Value(1.0), &[1.0], Some(0.0)),
            Verdict::Holds
        );
    }

    #[test]
    fn exact_inside_and_one_sided_bounds() {
        assert_eq!(
            j(Rule::Exact, Paper::Value(55987.0), &[55987.0], None),
            Verdict::Holds
        );
        assert_eq!(
            j(Rule::Exact, Paper::Value(55987.0), &[55986.0], None),
            Verdict::Differs
        );
        let inside = |v| j(Rule::Inside, Paper::Range(0.40, 0.49), &[v], None);
        assert_eq!(inside(0.40), Verdict::Holds);
        assert_eq!(inside(0.49), Verdict::Holds);
        assert_eq!(inside(0.3999), Verdict::Differs);
        assert_eq!(inside(0.4901), Verdict::Differs);
        assert_eq!(
            j(Rule::AtMost, Paper::Value(1.10), &[1.10], None),
            Verdict::Holds
        );
        assert_eq!(
            j(Rule::AtMost, Paper::Value(1.10), &[1.1001], None),
            Verdict::Differs
        );
        assert_eq!(
            j(Rule::AtLeast, Paper::Value(40e3), &[40e3], None),
            Verdict::Holds
        );
        assert_eq!(
            j(Rule::AtLeast, Paper::Value(40e3), &[39_999.0], None),
            Verdict::Differs
        );
    }

    #[test]
    fn order_compares_every_pair_and_ignores_paper_ties() {
        let p = Paper::List(vec![118.0, 203.0, 229.0]);
        assert_eq!(
            j(Rule::Order, p.clone(), &[1.0, 2.0, 3.0], None),
            Verdict::Holds
        );
        assert_eq!(
            j(Rule::Order, p.clone(), &[1.0, 3.0, 2.0], None),
            Verdict::Differs
        );
        assert_eq!(
            j(Rule::Order, p.clone(), &[1.0, 2.0, 2.0], None),
            Verdict::Differs
        );
        let tied = Paper::List(vec![224.0, 224.0, 251.0]);
        assert_eq!(
            j(Rule::Order, tied.clone(), &[2.0, 1.0, 3.0], None),
            Verdict::Holds
        );
        assert_eq!(
            j(Rule::Order, tied, &[2.0, 4.0, 3.0], None),
            Verdict::Differs
        );
    }

    #[test]
    fn shapes_are_checked() {
        let e = |r, p: Option<Paper>, n, t| check_shape(r, p.as_ref(), n, t).unwrap_err();
        assert!(e(Rule::Within, Some(Paper::Value(1.0)), 1, None).contains("tolerance"));
        assert!(e(Rule::Within, Some(Paper::Value(1.0)), 1, Some(-0.1)).contains("≥ 0"));
        assert!(e(Rule::Exact, Some(Paper::Value(1.0)), 1, Some(0.1)).contains("'within' only"));
        assert!(e(Rule::Inside, Some(Paper::Value(1.0)), 1, None).contains("[lo, hi]"));
        assert!(e(Rule::Inside, Some(Paper::Range(2.0, 1.0)), 1, None).contains("reversed"));
        assert!(e(Rule::Order, Some(Paper::List(vec![1.0, 2.0])), 3, None).contains("as many"));
        assert!(e(Rule::Report, Some(Paper::Value(1.0)), 1, None).contains("drop `paper`"));
        assert!(e(Rule::AtMost, None, 1, None).contains("needs a `paper`"));
        assert!(e(Rule::Exact, Some(Paper::Value(1.0)), 2, None).contains("one `ours`"));
        assert_eq!(
            judge(Rule::Report, None, &[3.0], None, None).unwrap(),
            Verdict::OursOnly
        );
    }

    #[test]
    fn a_table_takes_its_worst_row() {
        use Verdict::*;
        assert_eq!(Verdict::of_table(&[Holds, Differs, NeedsGpu]), Differs);
        assert_eq!(Verdict::of_table(&[Holds, NeedsGpu, OursOnly]), Holds);
        assert_eq!(Verdict::of_table(&[NeedsGpu, OursOnly]), NeedsGpu);
        assert_eq!(Verdict::of_table(&[OursOnly]), OursOnly);
        assert_eq!(
            Verdict::of_table(&[Holds, Failed("x".into())]),
            Failed("x".into())
        );
    }
}
