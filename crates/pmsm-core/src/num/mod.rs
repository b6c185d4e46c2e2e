//! Fixed-point formats of the core and the few integer kernels everything else is built on.
//!
//! # Conventions
//!
//! | type | format | range | LSB | used for |
//! |---|---|---|---|---|
//! | [`Pu`] | Q8.24 in `i32` | [−128, 128) | 2⁻²⁴ ≈ 5.96e−8 | every per-unit signal and most coefficients |
//! | [`Unit`] | Q2.30 in `i32` | [−2, 2) | 2⁻³⁰ ≈ 9.31e−10 | sin, cos, unit vectors (±1 exact) |
//! | [`Angle`](crate::angle::Angle) | `i32` turn | one turn = 2³² | 2π/2³² ≈ 1.46e−9 rad | electrical angle, wraps by design |
//!
//! Per-unit values are relative to the bases of [`crate::units::PerUnit`]; with those bases
//! a healthy drive keeps its signals within a few per-unit, so Q8.24 leaves a 30× headroom
//! for transients and intermediate sums while resolving 6e−8 of rated current or voltage
//! (the precision integrators need at 20 kHz). Products are formed in `i64`, rounded to
//! nearest (ties up) and saturated: nothing on the control path wraps, except angles.

pub use fixed::types::{I2F30, I8F24};

/// Per-unit signal: Q8.24, range [−128, 128), LSB 2⁻²⁴.
pub type Pu = I8F24;

/// Unit-range quantity (sin, cos, components of a unit vector): Q2.30, range [−2, 2), LSB 2⁻³⁰.
pub type Unit = I2F30;

mod gain;
mod wide;
pub(crate) use gain::{Gain, round_shift_var};
#[cfg(any(test, feature = "overmodulation"))]
pub(crate) use wide::umul;
pub(crate) use wide::{wmul, wmul_inline};

/// Fractional bits of [`Pu`].
pub const PU_FRAC: u32 = 24;
/// Fractional bits of [`Unit`].
pub const UNIT_FRAC: u32 = 30;

/// `1/√3` in Q1.31 (rounded), the scale of Clarke's β, of the modulator's circle and of the
/// dead-time vector.
pub(crate) const INV_SQRT3_Q31: i32 = 1_239_850_262;

/// Rounds `x / 2^shift` to nearest (ties toward +∞) and saturates to `i32`: a result beyond
/// the `i32` range comes out at the rail it passed, exactly for `shift < 16` and `shift ≥ 32`,
/// and for `shift` in 16..=31 within `2^(32−shift) − 1` LSB of it (at most 2⁻¹⁵ of full
/// scale: the high word is clamped and the low word's bits pass, [`join_clamped`]). It never
/// wraps, and a result inside the range is exact.
///
/// `shift` must be in 1..=62 and `|x| ≤ 2⁶³ − 2³²` (any product of two `i32`, or a sum of
/// two such products); these are contracts of every caller in the crate. With a constant
/// `shift` ≤ 32 (every per-sample product) the rounding half is added before the shift, and
/// the range is handled on the high word only.
#[inline(always)]
pub(crate) const fn round_shift_sat(x: i64, shift: u32) -> i32 {
    if shift <= 32 {
        shr_sat_small(x, shift)
    } else {
        let rounded = (x >> shift) + ((x >> (shift - 1)) & 1);
        sat_i32(rounded)
    }
}

/// Rounds `x / 2^shift` to nearest (ties toward +∞) for a result the caller has bounded
/// inside the `i32` range (each call site says why): no saturation to test for. `shift` in
/// 1..=32 and `|x| < 2⁶³ − 2³¹`.
#[inline(always)]
pub(crate) const fn round_shift(x: i64, shift: u32) -> i32 {
    (x.wrapping_add(1 << (shift - 1)) >> shift) as i32
}

/// The least shift whose saturation clamps the high word ([`join_clamped`]): the low bits
/// that pass are then below 2⁻¹⁵ of full scale.
const JOIN_MIN_SHIFT: u32 = 16;

/// Whether this is ARMv6-M (Cortex-M0/M0+), recognised as in [`wmul`].
const V6M: bool = cfg!(all(target_arch = "arm", not(target_has_atomic = "32")));

/// [`round_shift_sat`] for `shift` in 1..=32: `p = x + 2^(shift−1)` cannot wrap under the
/// contract on `x`. From a shift of 16 on, a Cortex-M4 clamps the high word with one `SSAT`
/// and joins it to the low word (five instructions with the rounding, against eight for a
/// test of the high word and a select: 135 fewer per drive step). ARMv6-M has no `SSAT`, and
/// its constants cost more than the test of whether the high word is all sign (then
/// `p >> shift` fits): there the clamp runs only when it does not. Both give the same bits
/// (tests).
#[inline(always)]
const fn shr_sat_small(x: i64, shift: u32) -> i32 {
    let p = x.wrapping_add(1 << (shift - 1));
    let hi = (p >> 32) as i32;
    if shift == 32 {
        return hi;
    }
    if V6M || shift < JOIN_MIN_SHIFT {
        let v = (p >> shift) as i32;
        if (hi >> (shift - 1)) == (hi >> 31) {
            return v;
        }
        if shift < JOIN_MIN_SHIFT {
            return (hi >> 31) ^ i32::MAX;
        }
        // Beyond: the clamped high word is the rail's, so `join_clamped` is the rail with its
        // low `32 − shift` bits replaced by the low word's top ones: the sign shifted up and
        // one constant for the rail's top bits, and `v` less the high word's bits for the low
        // ones (no mask for the Cortex-M0 to keep in a register across the products).
        let k = 32 - shift;
        let top = ((hi >> 31) << k) ^ (i32::MAX & !((1 << k) - 1));
        return top | (v ^ (hi << k));
    }
    join_clamped(p, shift)
}

/// `p`'s high word clamped to `[−2^(shift−1), 2^(shift−1))`, shifted up and joined to the low
/// word's top `32 − shift` bits (`shift` in 1..=31): `p >> shift` when that fits an `i32`,
/// else within `2^(32−shift)` of the rail it passed.
#[inline(always)]
const fn join_clamped(p: i64, shift: u32) -> i32 {
    let hi = (p >> 32) as i32;
    let lim = (1i32 << (shift - 1)) - 1;
    let c = if hi > lim {
        lim
    } else if hi < -lim - 1 {
        -lim - 1
    } else {
        hi
    };
    ((c as u32) << (32 - shift) | (p as u32) >> shift) as i32
}

/// `x` times the Q4.28 scale `s` (`1 << 28` is one), saturated: the dead-time calibration's
/// scale applied to a configuration's bits, and to the scale already in use.
pub(crate) fn scale_q28(x: i32, s: i32) -> i32 {
    sat_i32(wmul(x, s) >> 28)
}

/// Saturates an `i64` to the `i32` range.
#[inline(always)]
pub(crate) const fn sat_i32(x: i64) -> i32 {
    if x > i32::MAX as i64 {
        i32::MAX
    } else if x < i32::MIN as i64 {
        i32::MIN
    } else {
        x as i32
    }
}

/// `⌊x · c / 2¹⁶⌋` for a factor `c < 2¹⁶` (Q0.16): the arc's room and, shifted by three
/// more, the modulator's shrink onto its hexagon ([`mul_q19`]). On ARMv6-M two 32-bit `MULS`
/// of `x`'s halves instead of a 32×32→64 product: `x = x_h 2¹⁶ + x_l`, `|x_h c| < 2³¹ − 2¹⁶`,
/// `x_l c < 2³²`, and `⌊(x_h c 2¹⁶ + x_l c)/2¹⁶⌋ = x_h c + ⌊x_l c/2¹⁶⌋` exactly (the same bits
/// as the `i64` product; checked in the tests).
#[inline(always)]
pub(crate) fn mul_u16(x: i32, c: u32) -> i32 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        mul_u16_halves(x, c)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        ((x as i64 * (c & 0xffff) as i64) >> 16) as i32
    }
}

/// [`mul_u16`] from 16-bit halves of `x` (ARMv6-M, and the tests).
#[inline(always)]
#[allow(dead_code)] // used on ARMv6-M only, and by the tests
const fn mul_u16_halves(x: i32, c: u32) -> i32 {
    let c = c & 0xffff;
    let hi = (x >> 16).wrapping_mul(c as i32);
    let lo = ((x as u32) & 0xffff).wrapping_mul(c) >> 16;
    hi.wrapping_add(lo as i32)
}

/// `⌊x · c / 2¹⁹⌋` for `c < 2¹⁶` (Q0.19 below ⅛): the modulator's shrink onto its hexagon,
/// [`mul_u16`] shifted by three more (nested floors: the same bits).
#[inline(always)]
pub(crate) fn mul_q19(x: i32, c: u32) -> i32 {
    mul_u16(x, c) >> 3
}

/// One Newton step toward `2⁶¹/d_n` for `d_n` in `[2³⁰, 2³¹)` from `r` (at most `2³¹`, within
/// `2⁻⁷` of it): on `f(r) = 1/r − d_n/2⁶¹`, `r ← r + r (2⁶¹ − d_n r)/2⁶¹`, which squares the
/// relative error (down to the `2⁻³¹` of the arithmetic) and stays at or below `2⁶¹/d_n`. The
/// residual, below `2⁵⁵`, is taken to `2⁻²⁹` first so that the product stays in `i64`.
/// [`Reciprocal::of`]'s steps and `polar`'s reciprocal.
#[inline(always)]
pub(crate) fn reciprocal_step(dn: i32, r: i32) -> i32 {
    let e = (((1i64 << 61) - wmul(dn, r)) >> 29) as i32;
    sat_i32(r as i64 + (wmul(r, e) >> 32))
}

/// `x/d` in Q2.30 for a divisor `d > 0` known only at run time (or with too wide a range
/// for one binary point): a normalised mantissa `r ∈ [2³⁰, 2³¹)` of `2^(61 − pre)/d` and a
/// pre-shift, so that `x/d = ((x << pre) · r) >> 31`, one product and constant shifts on the
/// control path. Valid for `|x| ≤ d` (a fraction within ±1); beyond, `x << pre` saturates and
/// so does the result.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
pub(crate) struct Reciprocal {
    r: i32,
    pre: u32,
}

impl Reciprocal {
    /// Of the integer `d` (e.g. the bits of a bus reading), on the control path: a
    /// normalisation, one 32-bit division for 16 bits and two Newton steps for the rest (no
    /// 64-bit division). `d ≤ 0` gives the zero reciprocal.
    pub fn of(d: i32) -> Self {
        if d <= 0 {
            return Self::default();
        }
        let n = d.leading_zeros(); // 1..=31
        let dn = (d as u32) << (n - 1); // [2^30, 2^31)
        // q ≈ 2⁴⁸/d_n from a 32-bit division, r₀ = q·2¹³ ≈ 2⁶¹/d_n (≤ 2³¹).
        // dn >> 16 ≥ 2¹⁴; the checked form keeps a panic path out of the firmware.
        let q = u32::MAX.checked_div(dn >> 16).unwrap_or(u32::MAX);
        let mut r = ((q as i64) << 13).min(i32::MAX as i64) as i32;
        // Two Newton steps: 2⁻¹⁴ → 2⁻²⁸ → below the 2⁻³¹ of the arithmetic.
        for _ in 0..2 {
            r = reciprocal_step(dn as i32, r);
        }
        Self {
            r: r.max(0),
            pre: n - 1,
        }
    }

    /// Of a divisor given as a float in the same units as `x` (configuration time): exact to
    /// the rounding of `r`, also for a divisor that is not an integer number of LSB. `None`
    /// unless `1 ≤ d < 2³¹`.
    pub fn from_f64(d: f64) -> Option<Self> {
        if !(1.0..2_147_483_648.0).contains(&d) {
            return None;
        }
        // The largest pre-shift keeping r = 2^(61 − pre)/d at or above 2³⁰.
        let pre = (31 - log2_ceil(d)).clamp(0, 30) as u32;
        let r = libm::round(libm::ldexp(1.0, 61 - pre as i32) / d);
        Some(Self {
            r: r.min(i32::MAX as f64) as i32,
            pre,
        })
    }

    /// The zero reciprocal (of a divisor `≤ 0`, or the default).
    #[inline(always)]
    pub fn is_zero(self) -> bool {
        self.r == 0
    }

    /// `x/d` in Q2.30 (`x · 2³⁰/d`), rounded and saturated.
    #[inline(always)]
    pub fn fraction(self, x: i32) -> i32 {
        round_shift_sat(self.product(x), 31)
    }

    /// `x/d` in Q4.28 (`x · 2²⁸/d`), within one LSB (the high word of the product, halved
    /// and rounded): for `|x| ≤ d` the result is within ±2²⁸ and needs no saturation.
    #[inline(always)]
    pub fn fraction_q28(self, x: i32) -> i32 {
        (((self.product(x) >> 32) as i32) + 1) >> 1
    }

    /// [`Reciprocal::fraction`] for `|x| ≤ d`, which the caller has checked: `x << pre` then
    /// fits and the result is within ±2³⁰, so neither needs a saturation test (the same bits).
    #[inline(always)]
    pub fn fraction_within(self, x: i32) -> i32 {
        round_shift(wmul_inline(x << self.pre, self.r), 31)
    }

    /// `x/d` in Q16 for `0 ≤ x ≤ d`, rounded up, from one 32-bit product of the top bits of
    /// `x << pre` and of `r` (each rounded up): at or above the exact value, by at most
    /// 6·2⁻¹⁶ (the current loops' `|v_d|/v_DC`, where the room it indexes is a table's).
    #[inline(always)]
    pub fn fraction_q16_up(self, x: i32) -> u32 {
        // x ≤ d: x << pre < 2³¹. (x << pre)/2¹⁵ + 1 ≤ 2¹⁶ and r/2¹⁶ + 1 ≤ 2¹⁵: the product
        // stays below 2³¹, and x/d = (x << pre) r / 2⁶¹ ≤ that product / 2³⁰.
        let xs = ((x.max(0) as u32) << self.pre >> 15) + 1;
        let rs = (self.r as u32 >> 16) + 1;
        ((xs * rs) >> 14) + 1
    }

    /// `(x << pre) · r` = `x · 2⁶¹/d` (the shift saturated).
    #[inline(always)]
    fn product(self, x: i32) -> i64 {
        let a = x << self.pre;
        let a = if a >> self.pre == x {
            a
        } else {
            (x >> 31) ^ i32::MAX
        };
        wmul_inline(a, self.r)
    }
}

/// `a · b` for two [`Pu`] values, rounded to nearest and saturated.
#[inline(always)]
pub fn mul(a: Pu, b: Pu) -> Pu {
    Pu::from_bits(round_shift_sat(
        wmul_inline(a.to_bits(), b.to_bits()),
        PU_FRAC,
    ))
}

/// `a · u` for a [`Pu`] signal and a [`Unit`] factor, rounded to nearest and saturated.
#[inline(always)]
pub fn mul_unit(a: Pu, u: Unit) -> Pu {
    Pu::from_bits(round_shift_sat(
        wmul_inline(a.to_bits(), u.to_bits()),
        UNIT_FRAC,
    ))
}

/// `a · u + b · v` with a single rounding, saturated (the kernel of Park's rotation).
#[inline(always)]
pub(crate) fn dot_unit(a: Pu, u: Unit, b: Pu, v: Unit) -> Pu {
    let acc = wmul_inline(a.to_bits(), u.to_bits()) + wmul_inline(b.to_bits(), v.to_bits());
    Pu::from_bits(round_shift_sat(acc, UNIT_FRAC))
}

/// `x` (Q2.30 bits) taken down to 2⁻¹⁴, toward −∞: the low 16 bits cleared. The grid of the
/// current-model MRAS's frames (`angle::sin_cos_frame`), whose transforms carry ADC-limited
/// currents and PWM-limited voltages; on it a product is 32×16 ([`dot_frame`]).
#[inline(always)]
pub(crate) const fn on_frame_grid(x: i32) -> i32 {
    x & !((1 << FRAME_SHIFT) - 1)
}

/// `(sin, cos)` of `sc` on the frames' grid ([`on_frame_grid`]), as Q2.30 bits.
#[inline(always)]
pub(crate) fn frame_bits(sc: crate::angle::SinCos) -> (i32, i32) {
    (
        on_frame_grid(sc.sin.to_bits()),
        on_frame_grid(sc.cos.to_bits()),
    )
}

/// `a · u + b · v` with one rounding, saturated, for `u`, `v` on the frames' grid
/// ([`on_frame_grid`]; `|u| + |v| < 2`): the kernel of the transforms in the MRAS's frames.
/// On ARMv6-M half the partial products of [`dot_unit`]'s.
#[inline(always)]
pub(crate) fn dot_frame(a: Pu, u: i32, b: Pu, v: i32) -> Pu {
    Pu::from_bits(wide::dot_q14(a.to_bits(), u, b.to_bits(), v))
}

/// The bits of a [`Unit`] below the 2⁻¹⁴ that [`on_frame_grid`] keeps.
pub(crate) const FRAME_SHIFT: u32 = UNIT_FRAC - 14;

/// A constant factor with a compile-time binary point: `value = bits · 2^−F`, `F` in 1..=32.
///
/// The bits of the coefficient nearest to `value` at the binary point `frac` ([`Coef::new`]
/// for a format known only at run time), or `None` if it is not finite or outside
/// `[−2^(31−frac), 2^(31−frac))`. One copy for every format, out of line (the board's image
/// carried one per format), but inlined on ARMv6-M, where the processor-in-the-loop harness
/// designs its drives on a 16 KiB stack that an out-of-line call's frame overflowed.
#[cfg_attr(target_has_atomic = "ptr", inline(never))]
#[cfg_attr(not(target_has_atomic = "ptr"), inline(always))]
pub(crate) fn coef_bits(value: f64, frac: u32) -> Option<i32> {
    if !value.is_finite() {
        return None;
    }
    let m = libm::round(libm::ldexp(value, frac as i32));
    if !(-2_147_483_648.0..2_147_483_648.0).contains(&m) {
        return None;
    }
    Some(m as i32)
}

/// The hot path's twin of [`Gain`]: where a coefficient's range is known from the motor
/// envelope, a fixed `F` makes every product one `SMULL`, a constant shift and a high-word
/// fit test (about ten instructions on a Cortex-M4; a `Gain` takes a test of its run-time
/// shift more, [`round_shift_var`], and a few more when its shift is 32 or less). Range
/// `[−2^(31−F), 2^(31−F))`, resolution `2^−F`; constructors reject values outside the range.
/// `Coef<30>` holds gains below 2 in magnitude to 9.3e−10, `Coef<24>` below 128 to 6e−8.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
pub(crate) struct Coef<const F: u32>(i32);

impl<const F: u32> Coef<F> {
    /// Zero.
    pub const ZERO: Self = Self(0);

    /// Largest magnitude a `Coef<F>` holds (exclusive): `2^(31−F)`.
    pub const fn limit() -> f64 {
        (1u64 << (31 - F)) as f64
    }

    /// The coefficient nearest to `value`, or `None` if it is not finite or outside
    /// `[−2^(31−F), 2^(31−F))`.
    pub fn new(value: f64) -> Option<Self> {
        coef_bits(value, F).map(Self)
    }

    /// The raw bits (`value · 2^F`).
    pub const fn bits(self) -> i32 {
        self.0
    }

    /// The coefficient of the raw bits `bits` (`value = bits · 2^−F`).
    pub const fn from_bits(bits: i32) -> Self {
        Self(bits)
    }

    /// The value as a float (exact).
    pub fn to_f64(self) -> f64 {
        libm::ldexp(self.0 as f64, -(F as i32))
    }

    /// `value · x` for a signal in any Q format, in the same format; rounded, saturated.
    #[inline(always)]
    pub fn apply_bits(self, x: i32) -> i32 {
        round_shift_sat(wmul_inline(x, self.0), F)
    }

    /// `value · x` for a [`Pu`] signal, rounded to nearest and saturated.
    #[inline(always)]
    pub fn apply(self, x: Pu) -> Pu {
        Pu::from_bits(self.apply_bits(x.to_bits()))
    }

    /// The exact product `value · x · 2^F` (for accumulators that keep every bit).
    #[inline(always)]
    pub fn wide(self, x: i32) -> i64 {
        wmul_inline(x, self.0)
    }
}

/// One step of the first-order filter `y += (x − y)·2^−k`, the pole a power of two (a shift,
/// no product). The arithmetic shift rounds toward −∞: the filter settles within `2^k` LSB
/// below a constant input. `k = 0` passes the input through.
#[inline(always)]
pub(crate) fn follow(y: Pu, x: Pu, k: u32) -> Pu {
    y.saturating_add(Pu::from_bits(x.saturating_sub(y).to_bits() >> k))
}

/// The shift `k` of [`follow`] for a time constant of `tau_steps` steps: its `2^k` the power of
/// two nearest in the logarithm (`round(log2 τ)`), within 0..=20; `None` when `tau_steps` is not
/// a positive finite number.
pub(crate) fn follow_shift(tau_steps: f64) -> Option<u32> {
    (tau_steps > 0.0 && tau_steps.is_finite()).then(|| log2_round(tau_steps).clamp(0, 20) as u32)
}

/// The binary exponent and the significand in [1, 2) of a positive normal `x`, from its bits.
fn exponent_significand(x: f64) -> (i32, f64) {
    let bits = x.to_bits();
    let significand = f64::from_bits((bits & ((1 << 52) - 1)) | (1023 << 52));
    (((bits >> 52) & 0x7ff) as i32 - 1023, significand)
}

/// `round(log₂ x)` of a positive normal `x`: its exponent, plus one from a significand of √2
/// up (whose logarithm is ½). From the bits: no library logarithm in the board's image.
pub(crate) fn log2_round(x: f64) -> i32 {
    let (e, m) = exponent_significand(x);
    e + (m >= core::f64::consts::SQRT_2) as i32
}

/// `⌈log₂ x⌉` of a positive normal `x`: its exponent, plus one unless it is a power of two.
pub(crate) fn log2_ceil(x: f64) -> i32 {
    let (e, m) = exponent_significand(x);
    e + (m > 1.0) as i32
}

/// Converts a float to [`Pu`], rounding to nearest and saturating (NaN gives 0).
///
/// For configuration and host code; the control path never touches floats.
pub fn pu_from_f64(x: f64) -> Pu {
    Pu::from_bits(f64_to_bits_sat(x, PU_FRAC))
}

/// `round(x · 2^frac)` saturated to `i32`; NaN maps to 0.
pub(crate) fn f64_to_bits_sat(x: f64, frac: u32) -> i32 {
    let scaled = libm::round(x * (1u64 << frac) as f64);
    if scaled.is_nan() {
        0
    } else if scaled >= i32::MAX as f64 {
        i32::MAX
    } else if scaled <= i32::MIN as f64 {
        i32::MIN
    } else {
        scaled as i32
    }
}

#[cfg(test)]
mod tests;
