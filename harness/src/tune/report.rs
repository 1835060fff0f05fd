//! `recommendation.md`: per target the settings ranked by error at a common cost (see
//! [`super::pareto`]), the best and the runner-up with its margin and whether that margin is
//! larger than run-to-run noise, the method's default marked; then the Pareto front.

use std::collections::BTreeMap;
use std::fmt::Write as _;

use super::pareto::{self, Ranking};
use super::{Cost, Plan, Setting, TuneRow};

/// A margin below this share of the best error is called a tie in practice, however
/// repeatable: reading errors off curves at a common cost is itself only this exact.
const TIE: f64 = 0.01;

/// Whether grid value `v` is the default `d` (as text, or as the same number).
fn same_value(v: &str, d: &str) -> bool {
    v == d
        || matches!((v.parse::<f64>(), d.parse::<f64>()), (Ok(a), Ok(b)) if a == b)
        || v.trim_matches('"') == d
}

/// The setting whose every gridded value is the method's default, if the grid has it.
fn default_setting(plan: &Plan, rows: &[TuneRow]) -> Option<usize> {
    let defaults = plan.kind().ok()?.defaults();
    rows.iter()
        .find(|r| {
            plan.grid
                .axes
                .iter()
                .zip(&r.values)
                .all(|(a, v)| defaults.get(&a.key).is_some_and(|d| same_value(v, d)))
        })
        .map(|r| r.setting)
}

fn num(v: f64) -> String {
    if v == 0.0 {
        return "0".into();
    }
    let a = v.abs();
    if a >= 1000.0 || (v.fract() == 0.0 && a < 1e15) {
        crate::reproduce::evaluate::thousands(v)
    } else {
        let digits = (3 - a.log10().floor() as i32).clamp(0, 8) as usize;
        format!("{v:.digits$}")
    }
}

/// The text of `recommendation.md` for `rows` of `plan` (ran on `adapter` at `commit`).
pub fn recommendation(
    plan: &Plan,
    rows: &[TuneRow],
    adapter: &str,
    commit: &str,
) -> anyhow::Result<String> {
    let report = Report::new(plan, rows);
    let defaults = plan.kind()?.defaults();
    let mut o = String::new();
    report.write_intro(&mut o, adapter, commit, &defaults)?;
    for t in 0..plan.targets.len() {
        report.write_target(&mut o, t)?;
    }
    report.write_front(&mut o)?;
    Ok(o)
}

/// A setting's error curve: its `(cost, error)` at each target (`None`: not measured).
type Curve = Vec<Option<(f64, f64)>>;

/// What every section of `recommendation.md` reads: the plan, its rows, the settings'
/// curves and the default setting.
struct Report<'a> {
    plan: &'a Plan,
    rows: &'a [TuneRow],
    settings: Vec<Setting>,
    /// Per setting (in grid order) its curve.
    curves: Vec<Curve>,
    /// The setting that is the method's default, if the grid has it.
    default: Option<usize>,
}

/// Where one target's settings are compared, and its ranking there.
struct TargetRanking {
    /// The target.
    t: usize,
    common: pareto::Common,
    /// "within the budget" or "at the common cost".
    at: &'static str,
    ranking: Ranking,
}

impl<'a> Report<'a> {
    fn new(plan: &'a Plan, rows: &'a [TuneRow]) -> Self {
        let settings = plan.grid.settings();
        let n_t = plan.targets.len();
        let row = |s: usize, t: usize| rows.iter().find(|r| r.setting == s && r.target == t);
        let curves = settings
            .iter()
            .map(|s| {
                (0..n_t)
                    .map(|t| {
                        row(s.index, t).and_then(|r| Some((r.cost, r.sweep.flip_mean_median?)))
                    })
                    .collect()
            })
            .collect();
        Report {
            plan,
            rows,
            settings,
            curves,
            default: default_setting(plan, rows),
        }
    }

    /// The row of setting `s` at target `t`.
    fn row(&self, s: usize, t: usize) -> Option<&'a TuneRow> {
        self.rows.iter().find(|r| r.setting == s && r.target == t)
    }

    /// The title, the command, the paragraph on grid, path, targets, cost and error, and the
    /// line on the method's default (`defaults`: the method's default parameters).
    fn write_intro(
        &self,
        o: &mut String,
        adapter: &str,
        commit: &str,
        defaults: &BTreeMap<String, String>,
    ) -> std::fmt::Result {
        let plan = self.plan;
        writeln!(o, "# Tune: {} on {}\n", plan.method, plan.scene)?;
        writeln!(o, "`{}`\n", plan.command)?;
        let axes: Vec<String> = plan
            .grid
            .axes
            .iter()
            .map(|a| {
                format!(
                    "{} ∈ {{{}}} ({})",
                    a.key,
                    a.values.join(", "),
                    if a.runtime { "runtime" } else { "build" }
                )
            })
            .collect();
        writeln!(
            o,
            "Adapter {adapter}, commit {commit}. Grid: {}{}. Path {}; targets {}. Cost: {}. \
             Error: the median over the frames of the mean FLIP against the full-resolution \
             reference. Each run was made {}: run-to-run noise is the largest change of a \
             setting's error at the common cost when a repeat replaces the run.\n",
            axes.join("; "),
            if plan.grid.fixed.is_empty() {
                String::new()
            } else {
                format!(
                    "; fixed {}",
                    plan.grid
                        .fixed
                        .iter()
                        .map(|(k, v)| format!("{k}={v}"))
                        .collect::<Vec<_>>()
                        .join(" ")
                )
            },
            plan.path,
            plan.targets
                .iter()
                .map(|t| t.label())
                .collect::<Vec<_>>()
                .join(", "),
            plan.cost.describe(),
            match plan.repeats {
                1 => "once".to_string(),
                n => format!("{n} times"),
            }
        )?;
        let default_text: Vec<String> = plan
            .grid
            .axes
            .iter()
            .map(|a| {
                format!(
                    "{}={}",
                    a.key,
                    defaults.get(&a.key).map_or("(estimated)", String::as_str)
                )
            })
            .collect();
        match self.default {
            Some(s) => writeln!(
                o,
                "The method's default ({}; the paper's choice unless its README says otherwise) \
                 is setting `{}`, marked ✓.\n",
                default_text.join(" "),
                self.settings[s].label()
            ),
            None => writeln!(
                o,
                "The method's default ({}) is not in the grid.\n",
                default_text.join(" ")
            ),
        }
    }

    /// Target `t`'s section: its heading, the recommendation, the ranking table and the
    /// settings not comparable there.
    fn write_target(&self, o: &mut String, t: usize) -> std::fmt::Result {
        let target = &self.plan.targets[t];
        writeln!(o, "## {}\n", target.label())?;
        let common = match (self.plan.cost, target.kind.as_str()) {
            (super::Cost::Points, "budget") => pareto::Common::Target(target.value),
            _ => pareto::Common::Median,
        };
        let at = match common {
            pareto::Common::Target(_) => "within the budget",
            pareto::Common::Median => "at the common cost",
        };
        let Some(ranking) = pareto::rank(&self.curves, t, common) else {
            return writeln!(o, "No setting has an error measured at this target.\n");
        };
        let tr = TargetRanking {
            t,
            common,
            at,
            ranking,
        };
        self.write_verdict(o, &tr)?;
        self.write_ranking_table(o, &tr)?;
        if !tr.ranking.unreachable.is_empty() {
            writeln!(
                o,
                "\nNot comparable at this cost (no target of theirs within {:.0} % of it): {}.",
                100.0 * pareto::REACH,
                tr.ranking
                    .unreachable
                    .iter()
                    .map(|s| self.settings[*s].label())
                    .collect::<Vec<_>>()
                    .join(", ")
            )?;
        }
        writeln!(o)
    }

    /// Run-to-run noise of setting `s` at the common cost of `tr`: the largest change of its
    /// error there when a repeat takes the place of the target's run. `None` without
    /// repeats.
    fn noise(&self, tr: &TargetRanking, s: usize) -> Option<f64> {
        let (t, cost, curves) = (tr.t, tr.ranking.cost, &self.curves);
        let r = self.row(s, t)?;
        if self.plan.repeats < 2 || r.repeats.is_empty() {
            return None;
        }
        let error = |curve: &[Option<(f64, f64)>]| match tr.common {
            pareto::Common::Target(_) => curve[t].map(|p| p.1),
            pareto::Common::Median => {
                let pts: Vec<(f64, f64)> = curve.iter().flatten().copied().collect();
                pareto::error_at(&pts, cost)
            }
        };
        let e0 = error(&curves[s])?;
        r.repeats
            .iter()
            .map(|&(c, f)| {
                let mut curve = curves[s].clone();
                curve[t] = f.map(|f| (c, f));
                error(&curve).map_or(f64::INFINITY, |e| (e - e0).abs())
            })
            .reduce(f64::max)
    }

    /// The recommendation at one target: the best setting and, if there is one, the
    /// runner-up with the margin and whether it is beyond run-to-run noise.
    fn write_verdict(&self, o: &mut String, tr: &TargetRanking) -> std::fmt::Result {
        let (settings, at, cost) = (&self.settings, tr.at, tr.ranking.cost);
        match tr.ranking.ranked.as_slice() {
            [] => writeln!(o, "No setting reaches the common cost {}.\n", num(cost)),
            [(best, e)] => writeln!(
                o,
                "**Recommended: {}**, FLIP {} {at} {} (the only setting that reaches it).\n",
                settings[*best].label(),
                num(*e),
                num(cost)
            ),
            [(best, e1), (second, e2), ..] => {
                let margin = e2 - e1;
                let (n1, n2) = (self.noise(tr, *best), self.noise(tr, *second));
                let verdict = noise_verdict(margin, n1, n2, self.plan.cost);
                let share = if *e1 > 0.0 { margin / e1 } else { 0.0 };
                writeln!(
                    o,
                    "**Recommended: {}**, FLIP {} {at} {}; runner-up {} at {}: margin {} \
                     ({:.1} %), {verdict}{}.\n",
                    settings[*best].label(),
                    num(*e1),
                    num(cost),
                    settings[*second].label(),
                    num(*e2),
                    num(margin),
                    100.0 * share,
                    if share < TIE {
                        format!(
                            "; but under {:.0} % of the error: a tie in practice",
                            100.0 * TIE
                        )
                    } else {
                        String::new()
                    }
                )
            }
        }
    }

    /// The table of the settings ranked at one target.
    fn write_ranking_table(&self, o: &mut String, tr: &TargetRanking) -> std::fmt::Result {
        let (at, cost) = (tr.at, tr.ranking.cost);
        writeln!(
            o,
            "| rank | setting | FLIP {at} {} | measured FLIP | cost | points | holes | noise | default |",
            num(cost)
        )?;
        writeln!(o, "|---|---|---|---|---|---|---|---|---|")?;
        for (i, (s, e)) in tr.ranking.ranked.iter().enumerate() {
            let Some(r) = self.row(*s, tr.t) else {
                continue;
            };
            writeln!(
                o,
                "| {} | {} | {} | {} | {} | {} | {} | {} | {} |",
                i + 1,
                self.settings[*s].label(),
                num(*e),
                r.sweep.flip_mean_median.map_or("-".into(), num),
                num(r.cost),
                num(r.sweep.points_drawn_median),
                r.sweep.hole_ratio_median.map_or("-".into(), num),
                noise_cell(self.noise(tr, *s)),
                if self.default == Some(*s) { "✓" } else { "" }
            )?;
        }
        Ok(())
    }

    /// The Pareto front over (cost, FLIP) of every setting and target, by cost.
    fn write_front(&self, o: &mut String) -> std::fmt::Result {
        writeln!(
            o,
            "## Pareto front over (cost, FLIP), every setting and target\n"
        )?;
        writeln!(o, "| setting | target | cost | FLIP | points |")?;
        writeln!(o, "|---|---|---|---|---|")?;
        let mut front: Vec<&TuneRow> = self.rows.iter().filter(|r| r.pareto).collect();
        front.sort_by(|a, b| a.cost.total_cmp(&b.cost));
        for r in front {
            writeln!(
                o,
                "| {} | {} | {} | {} | {} |",
                r.label,
                self.plan.targets[r.target].label(),
                num(r.cost),
                r.sweep.flip_mean_median.map_or("-".into(), num),
                num(r.sweep.points_drawn_median)
            )?;
        }
        Ok(())
    }
}

/// Whether a margin between the best and the runner-up is beyond their run-to-run noises
/// `n1` and `n2`, in words. An infinite noise is a repeat whose cost moved the setting's
/// curve off the common cost, so that no error could be read there: not a measured noise.
/// Where the cost is time, whose own run-to-run change is what made the comparison
/// uncertain, the words suggest `--cost points`.
fn noise_verdict(margin: f64, n1: Option<f64>, n2: Option<f64>, cost: Cost) -> String {
    let hint = match cost {
        Cost::Time => {
            "; a time cost changes between runs (a shared CPU most of all): `--cost points` \
             compares at a cost that repeats exactly"
        }
        Cost::Points => "",
    };
    if n1.is_some_and(f64::is_infinite) || n2.is_some_and(f64::is_infinite) {
        return format!(
            "run-to-run noise not measurable: a repeat's cost moved a curve off the common \
             cost{hint}"
        );
    }
    match pareto::beyond_noise(margin, n1.zip(n2)) {
        Some(true) if n1 == Some(0.0) && n2 == Some(0.0) => {
            "the repeats reproduced both exactly, so the margin is not noise".into()
        }
        Some(true) => format!(
            "larger than run-to-run noise ({} + {})",
            num(n1.unwrap_or(0.0)),
            num(n2.unwrap_or(0.0))
        ),
        Some(false) => format!(
            "**not** larger than run-to-run noise ({} + {}): the two are tied \
             within what a repeat changes{hint}",
            num(n1.unwrap_or(0.0)),
            num(n2.unwrap_or(0.0))
        ),
        None => "run-to-run noise not measured (--repeats 1)".into(),
    }
}

/// A noise for the ranking table: an infinite one (a repeat's cost off the common cost) is
/// no number.
fn noise_cell(noise: Option<f64>) -> String {
    match noise {
        None => "-".into(),
        Some(n) if n.is_infinite() => "off the common cost".into(),
        Some(n) => num(n),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plot::SweepRow;
    use crate::tune::{Grid, TargetRecord};

    fn plan(repeats: usize) -> Plan {
        let grids = vec!["m=1024,2048,4096".to_string()];
        Plan {
            method: "lpc".into(),
            scene: "statue:1000:1".into(),
            path: "orbit".into(),
            grid: Grid::parse(methods::MethodKind::Lpc, &grids, &Default::default(), false)
                .unwrap_or_else(|e| panic!("{e:#}")),
            targets: vec![
                TargetRecord::of(
                    &crate::sweep::SweepTarget::budget(1000).unwrap_or_else(|e| panic!("{e}")),
                ),
                TargetRecord::of(
                    &crate::sweep::SweepTarget::budget(2000).unwrap_or_else(|e| panic!("{e}")),
                ),
            ],
            cost: Cost::Points,
            repeats,
            scene_args: vec![],
            run_args: vec![],
            build_dir: None,
            build_url: None,
            cache: "c".into(),
            command: "splatbench tune …".into(),
        }
    }

    /// Setting `s` (m = 1024, 2048, 4096) at target `t`: `(points, FLIP)`, and its repeat's.
    fn row(s: usize, t: usize, (cost, flip): (f64, f64), repeat: Option<(f64, f64)>) -> TuneRow {
        TuneRow {
            setting: s,
            label: format!("m={}", [1024, 2048, 4096][s]),
            values: vec![[1024, 2048, 4096][s].to_string()],
            target: t,
            target_name: format!("budget-{}", [1000, 2000][t]),
            value: [1000.0, 2000.0][t],
            sweep: SweepRow {
                method: "lpc".into(),
                params: String::new(),
                scene: "s".into(),
                path: "orbit".into(),
                target: "budget".into(),
                value: [1000.0, 2000.0][t],
                frames: 2,
                points_drawn_median: cost,
                splats_per_s_median: 1.0,
                gpu_ms_median: None,
                cpu_select_ms_median: 0.1,
                flip_mean_median: Some(flip),
                flip_mean_max: Some(flip),
                hole_ratio_median: Some(0.0),
                hole_ratio_max: Some(0.0),
                psnr_db_median: None,
                popping_flip_median: None,
                popping_warped_l1_median: None,
                popping_warped_l1_p95: None,
                popping_warped_l7_median: None,
                popping_warped_l7_p95: None,
                rss_bytes_max: 0,
            },
            wall_ms_median: 1.0,
            cost,
            flip_noise: None,
            cost_noise: None,
            repeats: repeat.map(|(c, f)| vec![(c, Some(f))]).unwrap_or_default(),
            build_seconds: None,
            bytes_per_sample: None,
            build_peak_rss_bytes: None,
            peak_rss_bytes: None,
            pareto: false,
        }
    }

    #[test]
    fn the_recommendation_on_hand_made_rows() {
        // m=2048 beats m=1024 by 0.02 at both budgets.
        let rows = |noise: f64| {
            vec![
                row(0, 0, (1000.0, 0.30), Some((1000.0, 0.30 + noise))),
                row(0, 1, (2000.0, 0.20), Some((2000.0, 0.20))),
                row(1, 0, (1000.0, 0.28), Some((1000.0, 0.28))),
                row(1, 1, (2000.0, 0.18), Some((2000.0, 0.18))),
                // m=4096 leaves most of each budget unused: worse within it.
                row(2, 0, (500.0, 0.50), None),
                row(2, 1, (600.0, 0.45), None),
            ]
        };
        let text = recommendation(&plan(2), &rows(0.0), "llvmpipe (Vulkan)", "abc").unwrap();
        assert!(
            text.contains(
                "**Recommended: m=2048**, FLIP 0.2800 within the budget 1,000; runner-up \
                 m=1024 at 0.3000: margin 0.02000 (7.1 %), the repeats reproduced both exactly"
            ),
            "{text}"
        );
        assert!(
            text.contains("| 1 | m=2048 | 0.2800 | 0.2800 | 1,000 | 1,000 | 0 | 0 | ✓ |"),
            "{text}"
        );
        // Within the budget m=4096 is ranked by its own error; compared at the median cost
        // instead (--cost time), its curve does not reach the others'.
        assert!(
            text.contains("| 3 | m=4096 | 0.5000 | 0.5000 | 500 | 500 |"),
            "{text}"
        );
        assert!(!text.contains("Not comparable"), "{text}");
        let mut timed = plan(2);
        timed.cost = Cost::Time;
        let text = recommendation(&timed, &rows(0.0), "x", "abc").unwrap();
        assert!(
            text.contains("FLIP 0.2800 at the common cost 1,000;"),
            "{text}"
        );
        assert!(
            text.contains(
                "Not comparable at this cost (no target of theirs within 10 % of it): m=4096."
            ),
            "{text}"
        );
        // A margin under 1 % of the error is a tie in practice, however repeatable.
        let mut close = rows(0.0);
        close[2].sweep.flip_mean_median = Some(0.299);
        let text = recommendation(&plan(2), &close, "x", "abc").unwrap();
        assert!(
            text.contains("under 1 % of the error: a tie in practice"),
            "{text}"
        );
        // A repeat of m=1024 that moves by 0.03 makes the margin of 0.02 noise.
        let text = recommendation(&plan(2), &rows(0.03), "llvmpipe (Vulkan)", "abc").unwrap();
        assert!(
            text.contains(
                "margin 0.02000 (7.1 %), **not** larger than run-to-run noise (0 + 0.03000)"
            ),
            "{text}"
        );
        let text = recommendation(&plan(1), &rows(0.0), "x", "abc").unwrap();
        assert!(text.contains("noise not measured (--repeats 1)"), "{text}");
        assert!(text.contains("Each run was made once:"), "{text}");
        // A time cost whose repeat of m=1024 ran 5× slower: its curve no longer reaches the
        // common cost, so its noise is no number (the CSV's flip_noise, at the target, is 0),
        // and the words point at the noise-free cost.
        let mut slow = rows(0.0);
        slow[0].repeats = vec![(5000.0, Some(0.30))];
        let text = recommendation(&timed, &slow, "x", "abc").unwrap();
        assert!(text.contains("Each run was made 2 times:"), "{text}");
        assert!(
            text.contains(
                "run-to-run noise not measurable: a repeat's cost moved a curve off the common \
                 cost; a time cost changes between runs (a shared CPU most of all): `--cost \
                 points` compares at a cost that repeats exactly"
            ),
            "{text}"
        );
        assert!(text.contains("| off the common cost |"), "{text}");
        assert!(!text.contains("inf"), "{text}");
    }

    #[test]
    fn numbers_and_defaults() {
        assert_eq!(num(12345.6), "12,346");
        assert_eq!(num(0.041234), "0.04123");
        assert_eq!(num(12.34), "12.34");
        assert_eq!(num(500.0), "500");
        assert!(same_value("2048", "2048"));
        assert!(same_value("2", "2.0"));
        assert!(!same_value("1024", "2048"));
    }
}
