//! Integer sort keys for floats, so that sorts by several float fields become one radix- or
//! parallel-sortable integer per element (shared by the methods' builds).

/// An unsigned key whose order is [`f32::total_cmp`]'s: negative values (sign bit set) have
/// all bits flipped, the others only the sign bit. So `-NaN < -∞ < … < -0.0 < 0.0 < … < ∞ <
/// NaN`, as `total_cmp` orders them; `!key` orders descending.
#[inline]
pub fn f32_total_order(x: f32) -> u32 {
    let b = x.to_bits();
    if b & 0x8000_0000 != 0 {
        !b
    } else {
        b | 0x8000_0000
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn key_order_is_total_cmp_order() {
        let values = [
            f32::NAN,
            -f32::NAN,
            f32::INFINITY,
            f32::NEG_INFINITY,
            0.0,
            -0.0,
            f32::MIN_POSITIVE,
            -f32::MIN_POSITIVE,
            1e-45,
            -1e-45,
            1.0,
            -1.0,
            1.5,
            -2.5,
            f32::MAX,
            f32::MIN,
        ];
        for &a in &values {
            for &b in &values {
                assert_eq!(
                    f32_total_order(a).cmp(&f32_total_order(b)),
                    a.total_cmp(&b),
                    "{a} vs {b}"
                );
            }
        }
    }
}
