//! Morton (Z-order) codes: bit interleaving shared by the methods' spatial sorts (SPT's
//! octree, LPC's cloud order and repository order, MWKD's cell lists).

/// Spreads the low 21 bits of `v` so that bit `i` lands on bit `3i`.
#[inline]
pub fn spread21(v: u32) -> u64 {
    let mut x = v as u64 & 0x1f_ffff;
    x = (x | x << 32) & 0x1f_0000_0000_ffff;
    x = (x | x << 16) & 0x1f_0000_ff00_00ff;
    x = (x | x << 8) & 0x100f_00f0_0f00_f00f;
    x = (x | x << 4) & 0x10c3_0c30_c30c_30c3;
    x = (x | x << 2) & 0x1249_2492_4924_9249;
    x
}

/// Inverse of [`spread21`]: gathers bits `0, 3, 6, …` of `v`.
#[inline]
pub fn compact21(v: u64) -> u32 {
    let mut x = v & 0x1249_2492_4924_9249;
    x = (x | x >> 2) & 0x10c3_0c30_c30c_30c3;
    x = (x | x >> 4) & 0x100f_00f0_0f00_f00f;
    x = (x | x >> 8) & 0x1f_0000_ff00_00ff;
    x = (x | x >> 16) & 0x1f_0000_0000_ffff;
    x = (x | x >> 32) & 0x1f_ffff;
    x as u32
}

/// Morton code of three coordinates of up to 21 bits (x in the lowest bit).
#[inline]
pub fn morton63(q: [u32; 3]) -> u64 {
    spread21(q[0]) | spread21(q[1]) << 1 | spread21(q[2]) << 2
}

/// Spreads a 32-bit value so that bit `i` lands on bit `3i` of a `u128`.
#[inline]
fn spread32(v: u32) -> u128 {
    spread21(v & 0x1f_ffff) as u128 | (spread21(v >> 21) as u128) << 63
}

#[inline]
fn compact32(v: u128) -> u64 {
    compact21(v as u64 & ((1 << 63) - 1)) as u64 | (compact21((v >> 63) as u64) as u64) << 21
}

/// Morton code of three (up to) 32-bit coordinates.
#[inline]
pub fn morton96(q: [u32; 3]) -> u128 {
    spread32(q[0]) | spread32(q[1]) << 1 | spread32(q[2]) << 2
}

/// Inverse of [`morton96`] (values above 32 bits come back as such, for validation).
#[inline]
pub fn demorton96(code: u128) -> [u64; 3] {
    [compact32(code), compact32(code >> 1), compact32(code >> 2)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trips_and_agrees_across_widths() {
        for q in [
            [0, 0, 0],
            [1, 2, 3],
            [0x1f_ffff, 0, 0x15_5555],
            [1023, 512, 7],
        ] {
            assert_eq!(demorton96(morton96(q)), q.map(u64::from));
            assert_eq!(morton96(q), morton63(q) as u128, "{q:?}");
            assert_eq!(compact21(spread21(q[0])), q[0]);
        }
        let q = [u32::MAX, 0x8000_0000, 12345];
        assert_eq!(demorton96(morton96(q)), q.map(u64::from));
        assert_eq!(morton63([1, 0, 0]), 1);
        assert_eq!(morton63([0, 1, 0]), 2);
        assert_eq!(morton63([0, 0, 1]), 4);
    }
}
