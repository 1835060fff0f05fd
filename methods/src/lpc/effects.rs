//! LPC's known effect: the paper's splat size on samples that are not evenly spaced.
//!
//! The paper draws each cloud with squares of its spacing `r` (eqs. 1–2), the average spacing
//! between samples. On evenly spaced scans (the paper's) those squares tile the surface; on
//! irregularly spaced samples they are a Boolean model, which leaves up to `exp(−1)` = 37 %
//! of a surface bare at full resolution (README, "Spacings", "What the choice buys"). Where a
//! run's holes are that large, the result is this effect, not the traversal, and
//! `spacing_rule=cover90` (a departure) is what changes it.

use crate::{KnownEffect, Observed, Params};

use super::{LpcParams, SpacingRule, traverse::Enlarge};

/// Median hole ratio above which a run's holes are taken as the spacing rule's: 2 %, four
/// times the worst measured with `cover90` (0.5 %) and under a third of the least measured
/// with the paper's `mean` (6.8 %), on the 40 K statue orbit at 1 px (README, "What the
/// choice buys").
pub const SPACING_HOLES: f64 = 0.02;

/// The effect on a run with `params` in force that measured `observed`: the paper's spacing
/// rule (`mean`, no hand-set `spacing`, the paper's `enlarge=layers`) and median holes above
/// [`SPACING_HOLES`].
pub fn known_effect(params: &Params, observed: &Observed) -> Option<KnownEffect> {
    let p = LpcParams::from_params(params).ok()?;
    let holes = observed.hole_ratio?;
    let paper_rule =
        p.spacing.is_none() && p.spacing_rule == SpacingRule::Mean && p.enlarge == Enlarge::Layers;
    (paper_rule && holes > SPACING_HOLES).then(|| KnownEffect {
        effect: format!(
            "holes {:.1} % (median): squares of the paper's splat size, the mean sample \
             spacing r, leave Boolean-model gaps where samples are not evenly spaced (up to \
             exp(−1) = 37 % of a surface at full resolution; the paper's near-even scans leave \
             none)",
            holes * 100.0
        ),
        param: "spacing_rule=cover90".into(),
        cost: "a departure: squares of twice the 90th-percentile spacing; 0–0.5 % holes \
               measured, about twice the points at the same tolerance"
            .into(),
        doc: "methods/src/lpc/README.md, \"Spacings\"".into(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn observed(h: f64) -> Observed {
        Observed {
            hole_ratio: Some(h),
        }
    }

    #[test]
    fn the_paper_rule_with_holes_above_the_threshold_names_cover90() {
        let p = Params::default();
        let e = known_effect(&p, &observed(0.131)).expect("an effect");
        assert!(
            e.effect.starts_with("holes 13.1 % (median)"),
            "{}",
            e.effect
        );
        assert_eq!(e.param, "spacing_rule=cover90");
        assert_eq!(known_effect(&p, &observed(SPACING_HOLES)), None);
        assert_eq!(known_effect(&p, &Observed::default()), None);
    }

    #[test]
    fn a_departure_or_a_hand_set_spacing_is_not_the_paper_rule() {
        for pair in [
            "spacing_rule=cover90",
            "spacing_rule=area",
            "spacing=0.01",
            "enlarge=cloud",
        ] {
            let p = Params::parse(&[pair]).unwrap_or_else(|e| panic!("{e}"));
            assert_eq!(known_effect(&p, &observed(0.3)), None, "{pair}");
        }
    }
}
