//! Numbers as the check's table prints them: whole numbers whole, a pair of different values
//! with just the digits that tell them apart.

pub(super) fn show(v: Option<f64>) -> String {
    v.map_or_else(|| "empty".into(), fmt)
}

/// Two values of one figure as the table prints them: whole numbers whole, others with the
/// fewest significant digits (at least 4) at which two different values print differently,
/// so a difference is shown at its own scale and no value at 17 digits.
pub(super) fn show_pair(a: Option<f64>, b: Option<f64>) -> (String, String) {
    let at = |v: Option<f64>, digits: usize| v.map_or_else(|| "empty".into(), |x| sig(x, digits));
    for digits in 4..=17 {
        let (sa, sb) = (at(a, digits), at(b, digits));
        if sa != sb || a == b {
            return (sa, sb);
        }
    }
    (show(a), show(b))
}

/// `v` with `digits` significant digits (whole numbers whole).
pub(super) fn sig(v: f64, digits: usize) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        return format!("{v:.0}");
    }
    let magnitude = if v == 0.0 {
        0
    } else {
        v.abs().log10().floor() as i64
    };
    let decimals = (digits as i64 - 1 - magnitude).clamp(0, 20) as usize;
    let text = format!("{v:.decimals$}");
    if v.abs() >= 1e-4 || v == 0.0 {
        text
    } else {
        format!("{v:.prec$e}", prec = digits - 1)
    }
}

/// A number as the table prints it: integers whole, others in their shortest exact text.
pub(super) fn fmt(v: f64) -> String {
    if v.fract() == 0.0 && v.abs() < 1e15 {
        format!("{v:.0}")
    } else {
        v.to_string()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pair(a: Option<f64>, b: Option<f64>) -> (String, String) {
        show_pair(a, b)
    }

    #[test]
    fn a_pair_prints_the_digits_that_tell_it_apart() {
        let s = |a: &str, b: &str| (a.to_string(), b.to_string());
        assert_eq!(
            pair(Some(0.012_345_678_9), Some(0.012_346_1)),
            s("0.0123457", "0.0123461")
        );
        assert_eq!(pair(Some(0.5), Some(0.5)), s("0.5000", "0.5000"));
        assert_eq!(pair(Some(3.0), Some(4.0)), s("3", "4"));
        assert_eq!(pair(Some(0.25), None), s("0.2500", "empty"));
        assert_eq!(pair(Some(1e-6), Some(2e-6)), s("1.000e-6", "2.000e-6"));
        // Values that differ only in the last bit print at full precision, never equal.
        let x = 0.1_f64;
        let (a, b) = pair(Some(x), Some(f64::from_bits(x.to_bits() + 1)));
        assert_ne!(a, b);
    }
}
