//! The control loops of the drive of seed 001 (equations.md §4.4): a fixed-point PI with
//! anti-windup ([`pi`]), the dq current controllers ([`current`]) and the IP speed controller
//! ([`speed`]).
//!
//! All of them follow the crate's split: a `Config::new` that designs and checks every
//! coefficient in `f64` once, and an integer-only `step` that saturates instead of wrapping
//! and reports it. Signals are per unit ([`Pu`], Q8.24) of [`PerUnit`](crate::units::PerUnit).
//!
//! The current and speed loops run on compile-time binary points ([`Coef`](crate::num::Coef)
//! gains, integrators whose LSB is the exact product's: [`pi::Pi`], [`speed`]) and exact
//! square roots in a fixed number of steps ([`isqrt_fast`], [`circle_room`]), a few tens of
//! instructions each on a Cortex-M4.

pub mod current;
pub mod pi;
pub mod speed;

pub use current::{CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput};
pub use pi::{Pi, PiConfig, PiOutput};
pub use speed::{SpeedConfig, SpeedController, SpeedDesign, SpeedOutput};

use crate::error::ConfigError;
use crate::num::{Pu, sat_i32, wmul};

/// `⌊√x⌋` of a `u64`, bit by bit (32 iterations of shifts and compares, no division).
pub fn isqrt_u64(x: u64) -> u32 {
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
const RSQRT_SEED: [u16; 49] = [
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
pub fn isqrt_fast(x: u64) -> u32 {
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
    let (t0, t1) = match (RSQRT_SEED.get(j), RSQRT_SEED.get(j + 1)) {
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

/// `√(r² − x²)` for `|x| ≤ r`, both [`Pu`] ≥ 0 in magnitude; 0 when `|x| ≥ r` (the room left on
/// the q axis of a voltage circle of radius `r` once d takes `x`). Exact: `⌊·⌋` to the LSB.
pub fn circle_room(r: Pu, x: Pu) -> Pu {
    let r = r.to_bits().unsigned_abs();
    let x = x.to_bits().unsigned_abs();
    if x >= r {
        return Pu::ZERO;
    }
    // (r − x)(r + x): the root of a Q.48 value is Q.24. Below 2^62 when r < 2^30 (64 pu):
    // a product of two i32; beyond, in u64 (the bit-by-bit root then).
    let sq = if r < 1 << 30 {
        wmul((r - x) as i32, (r + x) as i32) as u64
    } else {
        crate::num::umul(r - x, r + x)
    };
    Pu::from_bits(sat_i32(isqrt_fast(sq) as i64))
}

/// `c · x` rounded to nearest for a coefficient `|c| < 1` ([`Coef<31>`](crate::num::Coef)):
/// `|c x| < |x|`, so the result always fits an `i32` and needs no saturation test.
#[inline(always)]
pub(crate) fn frac_mul(c: crate::num::Coef<31>, x: i32) -> i32 {
    ((crate::num::wmul_inline(x, c.bits()) + (1 << 30)) >> 31) as i32
}

/// Checks `min ≤ value ≤ max` (finite) for a gain named `key`.
pub(crate) fn gain_in(
    key: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<f64, ConfigError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(value)
    } else {
        Err(ConfigError::Gain {
            key,
            value,
            min,
            max,
        })
    }
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

    #[test]
    fn circle_room_examples() {
        let one = Pu::from_num(1);
        assert_eq!(circle_room(one, Pu::ZERO), one);
        assert_eq!(circle_room(one, one), Pu::ZERO);
        assert_eq!(circle_room(one, Pu::from_num(2)), Pu::ZERO);
        let r = circle_room(Pu::from_num(5), Pu::from_num(-3));
        assert_eq!(r, Pu::from_num(4));
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
        fn circle_room_within_one_lsb(r in 0i32..1 << 30, x in any::<i32>()) {
            let got = circle_room(Pu::from_bits(r), Pu::from_bits(x)).to_bits() as f64;
            let (rf, xf) = (r as f64, (x as f64).abs());
            let exact = if xf >= rf { 0.0 } else { (rf * rf - xf * xf).sqrt() };
            prop_assert!((got - exact).abs() <= 1.0);
        }
    }
}
