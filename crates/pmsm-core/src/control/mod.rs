//! The control loops of the drive of seed 001 (equations.md §4.4): a fixed-point PI with
//! anti-windup ([`pi`]), the dq current controllers ([`current`]) and the IP speed controller
//! ([`speed`]).
//!
//! All of them follow the crate's split: a `Config::new` that designs and checks every
//! coefficient in `f64` once, and an integer-only `step` that saturates instead of wrapping
//! and reports it. Signals are per unit ([`Pu`], Q8.24) of [`PerUnit`](crate::units::PerUnit).
//!
//! The current and speed loops run on compile-time binary points ([`Coef`](crate::num::Coef)
//! gains, integrators whose LSB is the exact product's: [`pi::FastPi`], [`speed`]) and
//! exact square roots in a fixed number of steps ([`isqrt_fast`], [`circle_room`]), a few
//! tens of instructions each on a Cortex-M4. This module also keeps [`WideGain`], a
//! configuration constant (30 significant bits at any magnitude, variable shift) whose
//! product keeps 24 bits below the [`Pu`] LSB, for the general [`pi::Pi`] of the
//! current-model MRAS and the initial position detection and dead-time compensation.

pub mod current;
pub mod pi;
pub mod speed;

pub use current::{CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput};
pub use pi::{Limits, Pi, PiConfig, PiOutput};
pub use speed::{SpeedConfig, SpeedController, SpeedDesign, SpeedOutput};

use crate::error::ConfigError;
use crate::num::{PU_FRAC, Pu, round_shift_sat, sat_i32, wmul};

/// Fractional bits of the wide accumulators (integrators): Q16.48 in `i64`, range ±32768,
/// LSB 2⁻⁴⁸ ≈ 3.6e−15, i.e. 2²⁴ steps per LSB of [`Pu`].
pub const WIDE_FRAC: u32 = 48;

/// Extra fractional bits of a wide value over [`Pu`].
const EXTRA: u32 = WIDE_FRAC - PU_FRAC;

/// A constant factor `mantissa · 2^−shift` (30–31 significant bits at any magnitude, like
/// [`crate::num::Gain`]) whose product with a [`Pu`] signal is returned in Q16.48, so that an
/// integrator can accumulate increments far below one LSB of [`Pu`] without bias.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct WideGain {
    mantissa: i32,
    shift: u32,
}

impl WideGain {
    /// Zero.
    pub const ZERO: Self = Self {
        mantissa: 0,
        shift: 30,
    };

    /// The factor closest to `value`, or `None` if it is not finite or `|value|` is outside
    /// [2⁻⁴⁰, 2²⁰] (zero is accepted).
    pub fn new(value: f64) -> Option<Self> {
        if !value.is_finite() {
            return None;
        }
        if value == 0.0 {
            return Some(Self::ZERO);
        }
        let mag = libm::fabs(value);
        if !(libm::ldexp(1.0, -40)..=libm::ldexp(1.0, 20)).contains(&mag) {
            return None;
        }
        // mag in [2^e, 2^(e+1)): mantissa in [2^29, 2^30] after the shift.
        let e = libm::ilogb(mag);
        let shift = (29 - e) as u32; // 9..=69 for the accepted range
        let m = libm::round(libm::ldexp(value, shift as i32));
        if m > i32::MAX as f64 || m < i32::MIN as f64 {
            return None;
        }
        Some(Self {
            mantissa: m as i32,
            shift,
        })
    }

    /// The factor as a float (exact).
    pub fn to_f64(self) -> f64 {
        libm::ldexp(self.mantissa as f64, -(self.shift as i32))
    }

    /// `factor · x` in Q16.48 (rounded to nearest, saturated to ±2⁶² so that a few such terms
    /// can be added without overflow).
    #[inline]
    pub fn apply_wide(self, x: Pu) -> i64 {
        // |x · m| < 2^62. Its value is prod · 2^−(shift + 24), so in Q.48 it is
        // prod · 2^(24 − shift): a rounding right shift or a saturating left shift.
        let prod = wmul(x.to_bits(), self.mantissa);
        let out = if self.shift > EXTRA {
            // 1 ≤ s ≤ 45 for the accepted range; round half up like `round_shift_sat`.
            let s = self.shift - EXTRA;
            (prod >> s) + ((prod >> (s - 1)) & 1)
        } else {
            let s = EXTRA - self.shift;
            sat_shl(prod, s)
        };
        out.clamp(-WIDE_LIMIT, WIDE_LIMIT)
    }

    /// `factor · x` for a wide value `x` in any format, in the same format (rounded to
    /// nearest, saturated to ±2⁶²); the product is formed in `i128`.
    #[inline]
    pub fn apply_i64(self, x: i64) -> i64 {
        let prod = x as i128 * self.mantissa as i128;
        // shift is 9..=69: a rounding right shift of a value below 2^94.
        let s = self.shift;
        let r = (prod >> s) + ((prod >> (s - 1)) & 1);
        r.clamp(-(WIDE_LIMIT as i128), WIDE_LIMIT as i128) as i64
    }

    /// `factor · u` for a [`Unit`](crate::num::Unit) (Q2.30) factor `u`, rounded to [`Pu`]
    /// (one rounding of the exact product), saturated.
    #[inline]
    pub fn apply_unit(self, u: crate::num::Unit) -> Pu {
        // Value u · 2^−30 · m · 2^−shift; in Q8.24 bits prod · 2^−(shift + 6).
        let prod = wmul(u.to_bits(), self.mantissa);
        let s = self.shift + (crate::num::UNIT_FRAC - PU_FRAC);
        if s > 62 {
            Pu::ZERO
        } else {
            Pu::from_bits(round_shift_sat(prod, s))
        }
    }

    /// `factor · x` rounded to [`Pu`], saturated: one rounding of the exact product (not
    /// through Q16.48), within half an LSB.
    #[inline]
    pub fn apply(self, x: Pu) -> Pu {
        // The product's value is prod · 2^−(shift + 24): in Q8.24 bits, prod · 2^−shift.
        // |prod| ≤ 2^61 (|mantissa| ≤ 2^30), so beyond a shift of 62 it rounds to zero.
        let prod = wmul(x.to_bits(), self.mantissa);
        if self.shift > 62 {
            Pu::ZERO
        } else {
            Pu::from_bits(round_shift_sat(prod, self.shift))
        }
    }
}

/// Largest magnitude of the wide values (±2⁶²), so that two can be added without overflow.
pub const WIDE_LIMIT: i64 = 1 << 62;

/// `x << s`, saturated to ±2⁶².
#[inline]
fn sat_shl(x: i64, s: u32) -> i64 {
    if x == 0 {
        0
    } else if s >= 62 || x.unsigned_abs().leading_zeros() <= s + 1 {
        if x > 0 { WIDE_LIMIT } else { -WIDE_LIMIT }
    } else {
        x << s
    }
}

/// A [`Pu`] value in Q16.48 (exact).
#[inline(always)]
pub const fn pu_to_wide(x: Pu) -> i64 {
    (x.to_bits() as i64) << EXTRA
}

/// A Q16.48 value rounded to nearest [`Pu`], saturated.
#[inline(always)]
pub fn wide_to_pu(x: i64) -> Pu {
    // (x >> 23) then round: same as round_shift_sat but written out to keep it const-free.
    let r = (x >> EXTRA) + ((x >> (EXTRA - 1)) & 1);
    Pu::from_bits(sat_i32(r))
}

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

/// A gain as a [`WideGain`], or the typed error naming its key; `max` is the largest value the
/// caller accepts (for the error message), already checked by the caller.
pub(crate) fn wide_gain(key: &'static str, value: f64, max: f64) -> Result<WideGain, ConfigError> {
    WideGain::new(value).ok_or(ConfigError::Gain {
        key,
        value,
        min: 0.0,
        max,
    })
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
    use crate::units::to_f64;
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
        fn wide_gain_against_f64(v in -1e5f64..1e5, x in any::<i32>()) {
            prop_assume!(v.abs() > 1e-12);
            let g = WideGain::new(v).unwrap();
            prop_assert!(((g.to_f64() - v) / v).abs() <= 1.0 / (1u64 << 29) as f64);
            let exact = to_f64(Pu::from_bits(x)) * g.to_f64() * (1u64 << WIDE_FRAC) as f64;
            let got = g.apply_wide(Pu::from_bits(x)) as f64;
            if exact.abs() < WIDE_LIMIT as f64 {
                prop_assert!((got - exact).abs() <= 0.5 + exact.abs() * 1e-15);
            } else {
                prop_assert_eq!(g.apply_wide(Pu::from_bits(x)).abs(), WIDE_LIMIT);
            }
        }

        #[test]
        fn wide_gain_i64_against_f64(v in 0.0f64..1.0, x in -(1i64 << 58)..(1i64 << 58)) {
            prop_assume!(v > 1e-9);
            let g = WideGain::new(v).unwrap();
            let exact = x as f64 * g.to_f64();
            let got = g.apply_i64(x) as f64;
            prop_assert!((got - exact).abs() <= 0.5 + exact.abs() * 1e-15);
        }

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
