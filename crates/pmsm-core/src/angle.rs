//! Electrical angle as a wrapping integer turn, and its sine and cosine.
//!
//! One turn is 2³² counts of an `i32`, so the representable range is [−π, π) and
//! `wrapping_add` is exactly addition modulo 2π: angles are the one quantity of the core that
//! wraps, on purpose. The difference of two angles is again an [`Angle`], the signed error in
//! [−π, π).
//!
//! # sin/cos
//!
//! A quarter-wave table of 257 `Q2.30` values (1028 bytes of flash, computed at compile time)
//! gives `sin a` and `cos a` at the nearest of 1024 points per turn; the remainder
//! `δ ∈ [−π/1024, π/1024]` is applied by the angle-sum identity with `sin δ ≈ δ − δ³/6`,
//! `cos δ ≈ 1 − δ²/2`, whose truncation (`δ⁴/24 ≈ 2e−11`) is below half an LSB of Q2.30.
//! Cost: one table read pair, three 32×32→64 multiplies (`δ` and the two `sin δ` terms) and
//! four 32-bit ones (the `δ²` and `δ³` terms need only a few bits of `δ`).
//!
//! Measured error against f64 over the whole input range: see `docs/PERFORMANCE.md`; the
//! tests bound it at 3 LSB of Q2.30 (2.8e−9).

use crate::num::{UNIT_FRAC, Unit, on_frame_grid, round_shift, round_shift_sat, wmul, wmul_inline};
use core::ops::{Add, Neg, Sub};

/// Electrical angle, one turn = 2³² (LSB = 2π/2³² ≈ 1.46e−9 rad), range [−π, π), wrapping.
#[derive(
    Clone, Copy, Debug, Default, PartialEq, Eq, Hash, PartialOrd, Ord, crate::image::Words,
)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Angle(pub i32);

/// Sine and cosine of an angle, both Q2.30.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SinCos {
    /// `sin θ`, Q2.30.
    pub sin: Unit,
    /// `cos θ`, Q2.30.
    pub cos: Unit,
}

impl Angle {
    /// Zero.
    pub const ZERO: Self = Self(0);
    /// Half a turn, π (the most negative value: −π and π are the same angle).
    pub const PI: Self = Self(i32::MIN);
    /// A quarter turn, π/2.
    pub const HALF_PI: Self = Self(1 << 30);

    /// Radians per count, 2π/2³².
    pub const RAD_PER_LSB: f64 = core::f64::consts::TAU / 4_294_967_296.0;

    /// From radians (any finite value; wraps to [−π, π)). NaN gives zero.
    pub fn from_rad(rad: f64) -> Self {
        let turns = rad / core::f64::consts::TAU;
        let frac = turns - libm::floor(turns); // [0, 1)
        if frac.is_nan() {
            return Self::ZERO;
        }
        // Round to nearest count; 2^32 wraps to 0 through the u64 → u32 cast.
        Self(libm::round(frac * 4_294_967_296.0) as u64 as u32 as i32)
    }

    /// From degrees (wraps).
    pub fn from_deg(deg: f64) -> Self {
        Self::from_rad(deg.to_radians())
    }

    /// In radians, [−π, π).
    pub fn to_rad(self) -> f64 {
        self.0 as f64 * Self::RAD_PER_LSB
    }

    /// In degrees, [−180, 180).
    pub fn to_deg(self) -> f64 {
        self.to_rad().to_degrees()
    }

    /// The angle in radians as Q2.30, for small angles (|θ| < 2 rad; saturates beyond).
    pub fn to_rad_unit(self) -> Unit {
        // rad = counts · 2π/2^32, so Q2.30 bits = counts · π/2.
        // `HALF_PI_Q30` < 2³¹: the exact product of two `i32` (no general 64-bit multiply on
        // ARMv6-M).
        Unit::from_bits(round_shift_sat(wmul(self.0, HALF_PI_Q30 as i32), UNIT_FRAC))
    }

    /// Sine and cosine, each within 3 LSB of Q2.30.
    pub fn sin_cos(self) -> SinCos {
        sin_cos(self)
    }
}

impl Add for Angle {
    type Output = Angle;
    /// Addition modulo one turn.
    #[inline(always)]
    fn add(self, rhs: Angle) -> Angle {
        Angle(self.0.wrapping_add(rhs.0))
    }
}

impl Sub for Angle {
    type Output = Angle;
    /// Signed difference in [−π, π) (modulo one turn).
    #[inline(always)]
    fn sub(self, rhs: Angle) -> Angle {
        Angle(self.0.wrapping_sub(rhs.0))
    }
}

impl Neg for Angle {
    type Output = Angle;
    /// The opposite angle modulo one turn (−(−π) = −π).
    #[inline(always)]
    fn neg(self) -> Angle {
        Angle(self.0.wrapping_neg())
    }
}

/// π/2 in Q2.30 (rounded): radians per angle count, times 2^30 · 2^32 / 2^32.
const HALF_PI_Q30: i64 = 1_686_629_713;

/// Table points per quarter turn.
const QUARTER_POINTS: usize = 256;
/// Bits of the angle below the table index (32 − 2 quadrant bits − 8 index bits).
const REM_BITS: u32 = 22;

/// `sin(k · π/512)` for k = 0..=256 in Q2.30, computed at compile time.
static SIN_TABLE: [i32; QUARTER_POINTS + 1] = sin_table();

// Evaluated at compile time: a bad index would fail the build, it cannot panic at run time.
#[allow(clippy::indexing_slicing)]
const fn sin_table() -> [i32; QUARTER_POINTS + 1] {
    let mut t = [0i32; QUARTER_POINTS + 1];
    let mut k = 0;
    while k <= QUARTER_POINTS {
        let x = k as f64 * (core::f64::consts::FRAC_PI_2 / QUARTER_POINTS as f64);
        let s = const_sin(x) * (1u64 << UNIT_FRAC) as f64;
        // Round half up; s ≥ 0 here.
        t[k] = (s + 0.5) as i32;
        k += 1;
    }
    t
}

/// Taylor series of sin for 0 ≤ x ≤ π/2, accurate to f64 rounding (compile time only).
const fn const_sin(x: f64) -> f64 {
    let x2 = x * x;
    let mut term = x;
    let mut sum = x;
    let mut n = 1.0;
    while n < 40.0 {
        term = -term * x2 / ((n + 1.0) * (n + 2.0));
        sum += term;
        n += 2.0;
    }
    sum
}

/// Table entry, clamped into range so the lookup can never panic.
#[inline(always)]
fn table(k: u32) -> i64 {
    let k = if k as usize > QUARTER_POINTS {
        QUARTER_POINTS
    } else {
        k as usize
    };
    match SIN_TABLE.get(k) {
        Some(v) => *v as i64,
        None => 0,
    }
}

/// The nearest of 1024 points per turn to `angle`: the signed remainder `angle − a` in
/// [−2²¹, 2²¹) counts, and `sin a`, `cos a` from the table (Q2.30).
#[inline(always)]
fn table_point(angle: Angle) -> (i32, i32, i32) {
    let turn = angle.0 as u32;
    let nearest = turn.wrapping_add(1 << (REM_BITS - 1)) >> REM_BITS; // 0..1024 (wraps)
    let rem = turn.wrapping_sub(nearest << REM_BITS) as i32;
    let quadrant = (nearest >> 8) & 3;
    let k = nearest & 0xff;
    // sin and cos of the table point within its quadrant, then rotate to the quadrant.
    // Table values are within [0, 2³⁰]: as i32 their negations cannot wrap.
    let (s0, c0) = (table(k) as i32, table(QUARTER_POINTS as u32 - k) as i32);
    let (s_a, c_a) = match quadrant {
        0 => (s0, c0),
        1 => (c0, -s0),
        2 => (-s0, -c0),
        _ => (-c0, s0),
    };
    (rem, s_a, c_a)
}

/// Sine and cosine of `angle` (see the module docs for the method and its error).
pub fn sin_cos(angle: Angle) -> SinCos {
    let (rem, s_a, c_a) = table_point(angle);
    // δ in radians, Q2.30: rem · 2π/2^32 · 2^30 = rem · π/2; |δ| ≤ π/1024 < 2^21.7 LSB. The
    // one product that needs all its bits is a 32×32→64 one (`wmul`).
    let delta = round_shift(wmul_inline(rem, HALF_PI_Q30 as i32), UNIT_FRAC);
    // The small terms fit 32-bit products (one `MULS` each on every core): δ²/2 is below
    // 2^12.4 LSB and δ³/6 below 6 LSB, so a few bits of δ are all they need.
    let t = (delta + (1 << 6)) >> 7; // δ/2⁷, |t| < 2^14.7
    let d2 = (t * t + (1 << 15)) >> 16; // δ² in Q2.30, within 0.4 LSB
    let d3 = d2 * (delta >> 10); // δ³ in Q.50, |d3| < 2^25.1
    const SIXTH_Q16: i32 = 10_923; // 1/6 in Q0.16
    let sin_d = delta - (((d3 >> 8) * SIXTH_Q16 + (1 << 27)) >> 28); // δ − δ³/6
    // x·(1 − cos δ) = x·δ²/2 for a table value |x| ≤ 2^30: x to 2^15 steps (0.1 LSB).
    let half_d2 = |x: i32| (((x + (1 << 14)) >> 15) * d2 + (1 << 15)) >> 16;
    // sin(a+δ) = sin a − sin a (1 − cos δ) + cos a sin δ; cos(a+δ) likewise (|sin δ| < 2²²
    // times a table value ≤ 2³⁰: the products' roundings fit an i32).
    let sin = (s_a - half_d2(s_a)).saturating_add(round_shift(wmul_inline(c_a, sin_d), UNIT_FRAC));
    let cos = (c_a - half_d2(c_a)).saturating_sub(round_shift(wmul_inline(s_a, sin_d), UNIT_FRAC));
    SinCos {
        sin: Unit::from_bits(sin),
        cos: Unit::from_bits(cos),
    }
}

/// Sine and cosine of `angle` taken down to 2⁻¹⁴, as the transforms in the current-model
/// MRAS's frames take them (`num::frame_bits`): the table of [`sin_cos`], the remainder applied with 32-bit products
/// only (its terms need 2⁻²⁰, not 2⁻³⁰), so no 32×32→64 product on any core. Within 2⁻²² of
/// the exact value before it is taken down (tests), so each is the exact value's step of the
/// grid or, within 2⁻²² of a step, its neighbour.
// Out of line: inlined into the MRAS's update it is no shorter (`scripts/pil.sh`).
#[inline(never)]
pub(crate) fn sin_cos_frame(angle: Angle) -> SinCos {
    let (rem, s_a, c_a) = table_point(angle);
    // δ in Q8.24 radians: rem · 2π/2³² · 2²⁴ = rem π/2⁷, as (rem/4) · round(π/2⁶ · 2¹⁶) / 2¹⁵
    // (below 2³¹ before the shift); |δ| < 51 473.
    const PI_Q16_64: i32 = 3217;
    let delta = ((rem >> 2) * PI_Q16_64) >> 15;
    // δ²: a few bits of δ suffice (Q.32, below 40 402).
    let t = delta >> 8;
    let d2 = t * t;
    let (s15, c15) = (s_a >> 15, c_a >> 15); // |·| ≤ 2¹⁵
    // x δ: Q15 · Q24 = Q39, to Q30; x δ²/2: Q15 · Q32 = Q47, halved to Q30. Every product is
    // below 2³¹ (2¹⁵ · 51 473 and 2¹⁵ · 40 402).
    let sin = s_a - ((s15 * d2) >> 18) + ((c15 * delta) >> 9);
    let cos = c_a - ((c15 * d2) >> 18) - ((s15 * delta) >> 9);
    SinCos {
        sin: Unit::from_bits(on_frame_grid(sin)),
        cos: Unit::from_bits(on_frame_grid(cos)),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    const LSB: f64 = 1.0 / (1u64 << UNIT_FRAC) as f64;

    fn err_lsb(a: Angle) -> f64 {
        let sc = sin_cos(a);
        let x = a.to_rad();
        let es = (sc.sin.to_bits() as f64 * LSB - libm::sin(x)).abs();
        let ec = (sc.cos.to_bits() as f64 * LSB - libm::cos(x)).abs();
        es.max(ec) / LSB
    }

    #[test]
    fn table_endpoints_are_exact() {
        assert_eq!(SIN_TABLE[0], 0);
        assert_eq!(SIN_TABLE[QUARTER_POINTS], 1 << UNIT_FRAC);
        assert_eq!(SIN_TABLE[QUARTER_POINTS / 2], 759_250_125); // round(2^30 / √2)
    }

    #[test]
    fn cardinal_angles_are_exact() {
        let one = Unit::from_bits(1 << UNIT_FRAC);
        assert_eq!(
            sin_cos(Angle::ZERO),
            SinCos {
                sin: Unit::ZERO,
                cos: one
            }
        );
        assert_eq!(
            sin_cos(Angle::HALF_PI),
            SinCos {
                sin: one,
                cos: Unit::ZERO
            }
        );
        assert_eq!(
            sin_cos(Angle::PI),
            SinCos {
                sin: Unit::ZERO,
                cos: -one
            }
        );
        assert_eq!(
            sin_cos(-Angle::HALF_PI),
            SinCos {
                sin: -one,
                cos: Unit::ZERO
            }
        );
    }

    #[test]
    fn dense_sweep_within_three_lsb() {
        // Every 2^12-th angle (2^20 points) plus the neighbours of every table boundary.
        let mut worst: f64 = 0.0;
        for k in 0..(1u32 << 20) {
            worst = worst.max(err_lsb(Angle((k << 12) as i32)));
        }
        for k in 0..1024u32 {
            for off in [-1i64, 0, 1] {
                let t = ((k as i64) << REM_BITS) + (1 << (REM_BITS - 1)) + off;
                worst = worst.max(err_lsb(Angle(t as u32 as i32)));
            }
        }
        assert!(worst <= 3.0, "worst {worst} LSB");
    }

    /// Before it is taken down to 2⁻¹⁴, the frame's sin/cos is within 2⁻²² of the exact one:
    /// the step it gives is the exact value's, or a neighbour within 2⁻²² of the boundary.
    #[test]
    fn frame_sin_cos_is_the_exact_values_step() {
        let step = 1.0 / (1u64 << 14) as f64;
        let mut worst: f64 = 0.0;
        let mut check = |a: Angle| {
            let sc = sin_cos_frame(a);
            let x = a.to_rad();
            for (got, exact) in [(sc.sin, libm::sin(x)), (sc.cos, libm::cos(x))] {
                assert_eq!(got.to_bits() & 0xffff, 0, "{a:?}");
                let got = got.to_bits() as f64 * LSB;
                // got = floor(v) for a v within 2⁻²² of exact: exact − got in (−2⁻²², step + 2⁻²²).
                let below = exact - got;
                worst = worst.max((-below).max(below - step));
                assert!(got <= 1.0 && got >= -1.0 - step, "{a:?}: {got}");
            }
        };
        for k in 0..(1u32 << 20) {
            check(Angle((k << 12) as i32 ^ 0x5a5));
        }
        for k in 0..1024u32 {
            for off in [-1i64, 0, 1] {
                let t = ((k as i64) << REM_BITS) + (1 << (REM_BITS - 1)) + off;
                check(Angle(t as u32 as i32));
            }
        }
        assert!(worst < 1.0 / (1u64 << 22) as f64, "{worst:e}");
    }

    #[test]
    fn radians_round_trip() {
        for deg in [
            -720.0, -180.0, -90.0, -1.0, 0.0, 0.001, 45.0, 179.999, 180.0, 1e6,
        ] {
            let a = Angle::from_deg(deg);
            let back = a.to_deg();
            let diff = (back - deg).rem_euclid(360.0);
            let diff = diff.min(360.0 - diff);
            assert!(diff < 1e-6, "{deg} -> {back}");
        }
        assert_eq!(Angle::from_rad(f64::NAN), Angle::ZERO);
        assert_eq!(Angle::from_rad(f64::INFINITY), Angle::ZERO);
    }

    #[test]
    fn difference_is_signed_and_wraps() {
        let a = Angle::from_deg(170.0);
        let b = Angle::from_deg(-170.0);
        assert!(((b - a).to_deg() - 20.0).abs() < 1e-6);
        assert!(((a - b).to_deg() + 20.0).abs() < 1e-6);
    }

    proptest! {
        #[test]
        fn sin_cos_within_three_lsb(t in any::<i32>()) {
            let e = err_lsb(Angle(t));
            prop_assert!(e <= 3.0, "angle {} error {} LSB", t, e);
        }
    }
}
