//! [`Gain`]: a constant factor with its own binary point, and the rounding by a shift known
//! only at run time that its product needs.

use super::{Pu, round_shift_sat, wmul};

/// A constant factor with its own binary point: `value = mantissa · 2^−shift`.
///
/// Coefficients of the core span many decades across the motor envelope (`Ts·R/L` can be
/// 1e−5, `L/(Ts·R)` 1e4), more than one Q format holds with precision. A `Gain` keeps 30–31
/// significant bits whatever the magnitude: [`Gain::new`] picks the shift once in the
/// configuration, and [`Gain::apply`] is one 32×32→64 multiply and a rounding shift.
#[derive(Clone, Copy, Debug, PartialEq, Eq, crate::image::Words)]
pub(crate) struct Gain {
    mantissa: i32,
    shift: u32,
}

impl Gain {
    /// Zero gain.
    pub const ZERO: Self = Self {
        mantissa: 0,
        shift: 1,
    };

    /// The gain closest to `value`, or `None` if it is not finite or its magnitude is
    /// outside [2⁻³⁰, 2³⁰) (zero is accepted).
    pub fn new(value: f64) -> Option<Self> {
        if !value.is_finite() {
            return None;
        }
        if value == 0.0 {
            return Some(Self::ZERO);
        }
        let mag = libm::fabs(value);
        if !(libm::ldexp(1.0, -30)..=libm::ldexp(1.0, 30)).contains(&mag) {
            return None;
        }
        // Largest shift that keeps |mantissa| < 2^31, capped to 62 (the product shift).
        let exponent = libm::ilogb(mag); // mag in [2^e, 2^(e+1))
        let mut shift = (30 - exponent).clamp(1, 62) as u32;
        let mut m = libm::round(libm::ldexp(value, shift as i32));
        if libm::fabs(m) >= 2_147_483_648.0 && shift > 1 {
            // Rounded up to 2^31: one bit less.
            shift -= 1;
            m = libm::round(libm::ldexp(value, shift as i32));
        }
        if m > i32::MAX as f64 || m < i32::MIN as f64 {
            return None;
        }
        Some(Self {
            mantissa: m as i32,
            shift,
        })
    }

    /// The gain `mantissa · 2^−shift` (`shift` clamped to 1..=62).
    pub(crate) const fn from_raw(mantissa: i32, shift: u32) -> Self {
        let shift = if shift < 1 {
            1
        } else if shift > 62 {
            62
        } else {
            shift
        };
        Self { mantissa, shift }
    }

    /// The gain's value as a float (exact).
    pub fn to_f64(self) -> f64 {
        libm::ldexp(self.mantissa as f64, -(self.shift as i32))
    }

    /// `gain · x` for a signal in any Q format, in the same format; rounded, saturated:
    /// bit for bit [`round_shift_sat`] of the exact product by the gain's shift, through
    /// [`round_shift_var`] (the shift is known only at run time).
    #[inline(always)]
    pub fn apply_bits(self, x: i32) -> i32 {
        round_shift_var(wmul(x, self.mantissa), self.shift)
    }

    /// `gain · x` for a [`Pu`] signal, rounded to nearest and saturated.
    #[inline(always)]
    pub fn apply(self, x: Pu) -> Pu {
        Pu::from_bits(self.apply_bits(x.to_bits()))
    }
}

/// [`round_shift_sat`] by a shift known only at run time (a [`Gain`]'s, the magnitude
/// of `polar`), bit for bit, for `shift` in 1..=62 and `|p| ≤ 2⁶²` (a product of two `i32`).
/// A 64-bit shift by a run-time amount with its saturation test is long; here the two cases
/// are taken apart:
/// - Beyond 32 (a gain below 2⁻², whose mantissa keeps 31 bits), `p` shifted is below 2³⁰:
///   nothing to saturate, and the rounding `(p + 2^(s−1)) >> s` reads the high word alone,
///   `(hi + 2^(s−33)) >> (s − 32)` (the low word adds less than one unit of the high word's,
///   which the shift drops). Three instructions.
/// - Up to 32, the rounded shift, kept when the high word shows that it fits (the common
///   case), from 32-bit shifts of the two words; the rails out of line.
#[inline(always)]
pub(crate) fn round_shift_var(p: i64, shift: u32) -> i32 {
    let s = shift;
    if s > 32 {
        // s ≤ 62: both shifts are in range; |hi| ≤ 2³⁰ and 2^(s−33) ≤ 2²⁹, no wrap.
        let hi = (p >> 32) as i32;
        (hi + (1 << ((s - 33) & 31))) >> ((s - 32) & 31)
    } else {
        // s in 1..=32 and |p| ≤ 2⁶²: the sum cannot wrap.
        let q = p + (1i64 << ((s - 1) & 31));
        let hi = (q >> 32) as i32;
        if (hi >> ((s - 1) & 31)) == (hi >> 31) {
            shr_low_word(q, hi, s)
        } else {
            rail(p, s)
        }
    }
}

/// The low word of `q >> s` for `s` in 1..=32, `hi` the high word of `q`. On ARMv6-M from
/// 32-bit shifts of the two words (a 64-bit shift by a run-time amount is a library call
/// there): `lo >> s` (by halves, so that `s = 32` gives 0) with `hi`'s low bits above it.
/// Elsewhere the 64-bit shift, which the compiler does better (the same bits).
#[inline(always)]
fn shr_low_word(q: i64, hi: i32, s: u32) -> i32 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        shr_low_word_by_words(q, hi, s)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        let _ = hi;
        (q >> (s & 63)) as i32
    }
}

/// [`shr_low_word`] from the two words (ARMv6-M, and the tests).
#[inline(always)]
#[allow(dead_code)] // used on ARMv6-M only, and by the tests
pub(crate) const fn shr_low_word_by_words(q: i64, hi: i32, s: u32) -> i32 {
    let lo = q as u32;
    (((lo >> 1) >> ((s - 1) & 31)) | ((hi as u32) << ((32 - s) & 31))) as i32
}

/// [`round_shift_var`] beyond the `i32` range: [`round_shift_sat`]'s rail.
#[cold]
#[inline(never)]
fn rail(p: i64, shift: u32) -> i32 {
    round_shift_sat(p, shift)
}
