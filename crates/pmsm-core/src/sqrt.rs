//! Integer square roots of the control path: `⌊√x⌋` for the current loops' voltage circle
//! ([`isqrt_fast`]) and `1/√X` for the modulator's circle limit ([`rsqrt`]).
//!
//! Each is seeded from its own small table: `isqrt_fast` must be exact to the unit over 62
//! bits (an interpolated seed, Newton steps, then exact squares), `rsqrt` only within a few
//! LSB of Q2.30 over one octave (a step seed and three Newton steps, no table lookup between
//! them); one shared table would cost one of them instructions or bits.

use crate::num::{sat_i32, umul, wmul};

/// `⌊√x⌋` of a `u64`, bit by bit (32 iterations of shifts and compares, no division).
pub(crate) fn isqrt_u64(x: u64) -> u32 {
    let mut rem = x;
    let mut root: u64 = 0;
    let mut bit: u64 = 1 << 62;
    while bit > rem {
        bit >>= 2;
    }
    while bit != 0 {
        if rem >= root + bit {
            rem -= root + bit;
            root = (root >> 1) + bit;
        } else {
            root >>= 1;
        }
        bit >>= 2;
    }
    root as u32
}

/// `(1/√a − 1) · 2¹⁵` at `a = j/64`, `j = 16..=64`: the seed of [`isqrt_fast`] (98 bytes).
const ISQRT_SEED: [u16; 49] = [
    32768, 30811, 29020, 27372, 25849, 24437, 23121, 21893, 20742, 19661, 18643, 17682, 16773,
    15911, 15093, 14314, 13573, 12865, 12189, 11542, 10923, 10328, 9757, 9209, 8681, 8172, 7682,
    7209, 6752, 6310, 5883, 5470, 5069, 4681, 4305, 3940, 3585, 3240, 2905, 2579, 2262, 1954, 1653,
    1360, 1075, 796, 524, 259, 0,
];

/// `⌊√x⌋` for `x < 2⁶²`, exact, in a fixed number of steps (no loop over the bits): about 60
/// instructions on a Cortex-M4 against about 400 for [`isqrt_u64`].
///
/// `x` is normalised to `n = x·4^k ∈ [2⁶⁰, 2⁶²)`, `a = ⌊n/2³¹⌋/2³¹ ∈ [¼, 1)`. `1/√a` is
/// interpolated in a 48-interval table (relative error ≤ 4e−4), refined by one Newton step
/// `y ← y (3 − a y²)/2` (error ≤ 3e−7), which gives `R₀ = a y 2³¹ ≈ √n` within a few hundred
/// units; one Newton step on the root, `R₁ = R₀ + (n − R₀²) y/2³²`, brings it within one
/// unit, and comparisons of the exact squares with `n` finish. Every product is of two
/// `i32` (one `SMULL` on a Cortex-M4).
pub(crate) fn isqrt_fast(x: u64) -> u32 {
    if x == 0 || x >= 1 << 62 {
        // Out of contract: the bit-by-bit root (exact, slow).
        return isqrt_u64(x);
    }
    let k = (x.leading_zeros() - 2) / 2;
    let n = (x << (2 * k)) as i64; // [2^60, 2^62)
    let h = (n >> 31) as i32; // [2^29, 2^31): a = h/2^31
    // Seed: linear interpolation in the table, y in Q2.29 (y ∈ (1, 2]).
    let j = (h >> 25) as usize - 16; // 0..=47
    let frac = (h >> 9) & 0xffff;
    let (t0, t1) = match (ISQRT_SEED.get(j), ISQRT_SEED.get(j + 1)) {
        (Some(&a), Some(&b)) => (a as i32, b as i32),
        _ => (0, 0),
    };
    let yq = t0 + (((t1 - t0) * frac) >> 16); // (y − 1) 2^15
    let y = (yq + (1 << 15)) << 14; // Q.29, ≤ 2^30
    // Newton on 1/√a: u = a y (Q.29, ≈ √a ≤ 1), t = u y (≈ 1), y ← y (3 − t)/2.
    let u = (wmul(h, y) >> 31) as i32;
    let t = (wmul(u, y) >> 29) as i32;
    let y = (wmul(y, (3 << 29) - t) >> 30) as i32;
    // R0 = a y 2^31 = h y/2^29 < 2^31 (within the error of y).
    let r0 = sat_i32(wmul(h, y) >> 29).max(1 << 29);
    // Residual n − R0² (|·| < 2^43 for the errors above), then R1 = R0 + res·y/2^32.
    let res = sat_i32((n - wmul(r0, r0)) >> 12);
    let mut r = sat_i32(r0 as i64 + (wmul(res, y) >> 49)).max(0);
    // Within one unit: settle on ⌊√n⌋ with the exact squares (|r| < 2^31).
    if wmul(r, r) > n {
        r -= 1;
    }
    if r < i32::MAX && wmul(r + 1, r + 1) <= n {
        r += 1;
    }
    (r as u32) >> k
}

/// `1/√X` in Q2.30 at the centres of 24 intervals of `X ∈ [1/4, 1)` (seed of [`rsqrt`]).
const RSQRT_SEED: [u32; 24] = [
    2083365155, 1970666148, 1874477404, 1791125178, 1717986918, 1653133683, 1595110809, 1542797797,
    1495315679, 1451963954, 1412176548, 1375490368, 1341522400, 1309952745, 1280511845, 1252970736,
    1227133513, 1202831433, 1179918260, 1158266544, 1137764631, 1118314230, 1099828424, 1082230034,
];

/// `2³⁰/√X` for `x = X·2³²`, `x ∈ [2³⁰, 2³²)`: a table seed within 3 %, then three Newton
/// steps `y ← y (3 − X y²)/2`, each squaring the relative error (3 % → 1.4e−3 → 2.7e−6 →
/// the 2⁻³⁰ of the arithmetic). Newton from either side ends below `1/√X`, so the result
/// never exceeds it by more than the seed's rounding.
#[inline]
pub(crate) fn rsqrt(x: u32) -> u32 {
    let k = ((x >> 27) as usize).saturating_sub(8);
    let mut y = RSQRT_SEED.get(k).copied().unwrap_or(1 << 30);
    for _ in 0..3 {
        // X y² in Q2.30 (y² in Q3.29 first: y ≤ 2.02 · 2³⁰).
        let y2 = (umul(y, y) >> 31) as u32;
        let xy2 = (umul(x, y2) >> 31) as u32;
        let f = (3u32 << 30).saturating_sub(xy2);
        y = (umul(y, f) >> 31) as u32;
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn isqrt_exact_on_squares_and_neighbours() {
        for r in [0u64, 1, 2, 3, 1000, 65535, 1 << 31, (1 << 32) - 1] {
            let sq = r * r;
            assert_eq!(isqrt_u64(sq) as u64, r);
            if r > 0 {
                assert_eq!(isqrt_u64(sq - 1) as u64, r - 1);
            }
        }
        assert_eq!(isqrt_u64(u64::MAX), u32::MAX);
    }

    #[test]
    fn isqrt_fast_exact_on_squares_and_neighbours() {
        // Every interval of the seed table, its ends, and the normalisation corners.
        for r in (1u64..(1 << 31))
            .step_by(9_973)
            .chain([1, 2, 3, 1 << 15, (1 << 31) - 1])
        {
            for v in [r * r - 1, r * r, r * r + 1, r * r + 2 * r] {
                if v < 1 << 62 {
                    assert_eq!(isqrt_fast(v), isqrt_u64(v), "{v}");
                }
            }
        }
        for e in 0..62 {
            for v in [1u64 << e, (1u64 << e) - 1, (1u64 << e) + 1] {
                if v < 1 << 62 {
                    assert_eq!(isqrt_fast(v), isqrt_u64(v), "{v}");
                }
            }
        }
        assert_eq!(isqrt_fast((1 << 62) - 1), (1 << 31) - 1);
        assert_eq!(isqrt_fast(u64::MAX), u32::MAX);
    }

    proptest! {
        #[test]
        fn isqrt_is_floor_sqrt(x in any::<u64>()) {
            let r = isqrt_u64(x) as u128;
            prop_assert!(r * r <= x as u128);
            prop_assert!((r + 1) * (r + 1) > x as u128);
        }

        /// Within half an LSB of Q16.48 plus the gain's 2⁻²⁹ relative rounding.
        #[test]
        fn isqrt_fast_is_floor_sqrt(x in 0u64..1 << 62, sh in 0u32..62) {
            for v in [x, x >> sh, (x >> sh) | 1 << 61] {
                prop_assert_eq!(isqrt_fast(v), isqrt_u64(v), "{}", v);
            }
        }

        #[test]
        fn rsqrt_within_four_lsb(x in (1u32 << 30)..=u32::MAX) {
            let exact = (1u64 << 30) as f64 / (x as f64 / 4_294_967_296.0).sqrt();
            let got = rsqrt(x) as f64;
            prop_assert!((got - exact).abs() <= 4.0, "{} {}", got, exact);
        }

    }
}
