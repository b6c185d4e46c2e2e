//! Reference frames as types, and the transforms between them (docs/algorithms.md (conventions)).
//!
//! - [`Abc`]: phase quantities.
//! - [`AlphaBeta`]: stationary two-phase frame, amplitude-invariant (peak phase = |αβ|).
//! - [`Dq`]: rotor frame, d along the magnet's north pole at electrical angle θ.
//!
//! All components are [`Pu`] (Q8.24). Every transform forms its sums of products in `i64`,
//! rounds once and saturates, so no input can make it wrap.

use crate::angle::SinCos;
use crate::num::{
    INV_SQRT3_Q31, Pu, dot_frame, dot_unit, frame_bits, round_shift, round_shift_sat, wmul,
};

/// Three phase quantities, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Abc {
    /// Phase a.
    pub a: Pu,
    /// Phase b.
    pub b: Pu,
    /// Phase c.
    pub c: Pu,
}

/// A vector in the stationary αβ frame, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct AlphaBeta {
    /// α component (along phase a).
    pub alpha: Pu,
    /// β component (90° ahead of α).
    pub beta: Pu,
}

/// A vector in the rotor dq frame, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Dq {
    /// d component (along the magnet flux).
    pub d: Pu,
    /// q component (90° ahead of d).
    pub q: Pu,
}

impl AlphaBeta {
    /// `self + other` per component, saturating at the [`Pu`] range.
    #[inline(always)]
    pub fn saturating_add(self, other: Self) -> Self {
        Self {
            alpha: self.alpha.saturating_add(other.alpha),
            beta: self.beta.saturating_add(other.beta),
        }
    }

    /// `self − other` per component, saturating at the [`Pu`] range.
    #[inline(always)]
    pub fn saturating_sub(self, other: Self) -> Self {
        Self {
            alpha: self.alpha.saturating_sub(other.alpha),
            beta: self.beta.saturating_sub(other.beta),
        }
    }

    /// `|α| + |β|` (the L1 norm: no product, between 1 and √2 times the Euclidean length),
    /// saturating.
    #[inline(always)]
    pub fn l1_norm(self) -> Pu {
        self.alpha
            .saturating_abs()
            .saturating_add(self.beta.saturating_abs())
    }
}

impl Dq {
    /// `self + other` per component, saturating at the [`Pu`] range.
    #[inline(always)]
    pub fn saturating_add(self, other: Self) -> Self {
        Self {
            d: self.d.saturating_add(other.d),
            q: self.q.saturating_add(other.q),
        }
    }

    /// `self − other` per component, saturating at the [`Pu`] range.
    #[inline(always)]
    pub fn saturating_sub(self, other: Self) -> Self {
        Self {
            d: self.d.saturating_sub(other.d),
            q: self.q.saturating_sub(other.q),
        }
    }
}

/// 1/3 in Q1.31 (rounded).
const ONE_THIRD_Q31: i32 = 715_827_883;
/// √3/2 in Q1.31 (rounded).
const SQRT3_2_Q31: i32 = 1_859_775_393;

/// Amplitude-invariant Clarke transform: `α = (2a − b − c)/3`, `β = (b − c)/√3`.
///
/// Within ½ LSB of exact while the sums `(a − b) + (a − c)` and `b − c` stay within the
/// range of [`Pu`] (any phase values within ±32 pu); beyond, the sums saturate and so do the
/// results (`α` at ±42.7 pu, `β` at ±73.9 pu), never wrapping.
// Called, not inlined, on the Cortex-M0: inlined into the drive step, its registers spilled
// around it (`scripts/pil.sh`: the step 9 instructions dearer with both transforms inlined).
#[cfg_attr(all(target_arch = "arm", not(target_has_atomic = "32")), inline(never))]
pub fn clarke(x: Abc) -> AlphaBeta {
    let (a, b, c) = (x.a.to_bits(), x.b.to_bits(), x.c.to_bits());
    let two_a = a.saturating_sub(b).saturating_add(a.saturating_sub(c));
    // |two_a|, |b − c| ≤ 2³¹ (saturated) times 1/3 and 1/√3: both results fit an i32.
    AlphaBeta {
        alpha: Pu::from_bits(round_shift(wmul(two_a, ONE_THIRD_Q31), 31)),
        beta: Pu::from_bits(round_shift(wmul(b.saturating_sub(c), INV_SQRT3_Q31), 31)),
    }
}

/// Inverse Clarke transform: `a = α`, `b = −α/2 + (√3/2) β`, `c = −α/2 − (√3/2) β`.
pub fn inverse_clarke(v: AlphaBeta) -> Abc {
    let (al, be) = (v.alpha.to_bits() as i64, v.beta.to_bits() as i64);
    // Work in Q.31 of the input: −α/2 is exact there.
    let half_alpha = -(al << 30);
    let beta_term = wmul(be as i32, SQRT3_2_Q31);
    Abc {
        a: v.alpha,
        b: Pu::from_bits(round_shift_sat(half_alpha + beta_term, 31)),
        c: Pu::from_bits(round_shift_sat(half_alpha - beta_term, 31)),
    }
}

/// Park transform to the frame at angle θ: `d = α cos θ + β sin θ`, `q = −α sin θ + β cos θ`.
pub fn park(v: AlphaBeta, sc: SinCos) -> Dq {
    Dq {
        d: dot_unit(v.alpha, sc.cos, v.beta, sc.sin),
        q: dot_unit(v.beta, sc.cos, v.alpha, sc.sin.saturating_neg()),
    }
}

/// Inverse Park transform: `α = d cos θ − q sin θ`, `β = d sin θ + q cos θ`.
// Called on the Cortex-M0, as `clarke`.
#[cfg_attr(all(target_arch = "arm", not(target_has_atomic = "32")), inline(never))]
pub fn inverse_park(v: Dq, sc: SinCos) -> AlphaBeta {
    AlphaBeta {
        alpha: dot_unit(v.d, sc.cos, v.q, sc.sin.saturating_neg()),
        beta: dot_unit(v.d, sc.sin, v.q, sc.cos),
    }
}

/// [`park`] in the drive's frames: sin and cos taken to 2⁻¹⁴ ([`frame_bits`]), so within
/// 2⁻¹³ of the exact rotation (2 LSB of a 12-bit converter's full scale are 5e−4), in half the
/// Cortex-M0's products; tested against `f64`. The current-model MRAS keeps its frames on the
/// grid and calls [`park_on_grid`] itself; the drive's step takes the other estimators' and
/// the open loop's frames with this.
#[cfg_attr(all(target_arch = "arm", not(target_has_atomic = "32")), inline(never))]
pub(crate) fn park_frame(v: AlphaBeta, sc: SinCos) -> Dq {
    let (s, c) = frame_bits(sc);
    park_on_grid(v, s, c)
}

/// [`park`] at the frame whose sin and cos, Q2.30 bits, are `s` and `c` on the grid of
/// [`crate::num::on_frame_grid`].
#[inline(always)]
pub(crate) fn park_on_grid(v: AlphaBeta, s: i32, c: i32) -> Dq {
    Dq {
        d: dot_frame(v.alpha, c, v.beta, s),
        // |s| ≤ 1: its negation cannot wrap.
        q: dot_frame(v.beta, c, v.alpha, s.wrapping_neg()),
    }
}

/// [`inverse_park`] in the drive's frames, taken to 2⁻¹⁴ ([`frame_bits`]): the drive turns
/// its voltage into the phases' frame with it.
#[cfg_attr(all(target_arch = "arm", not(target_has_atomic = "32")), inline(never))]
pub(crate) fn inverse_park_frame(v: Dq, sc: SinCos) -> AlphaBeta {
    let (s, c) = frame_bits(sc);
    AlphaBeta {
        alpha: dot_frame(v.d, c, v.q, s.wrapping_neg()),
        beta: dot_frame(v.d, s, v.q, c),
    }
}

/// Rotates a stationary vector by the angle of `sc` (counter-clockwise).
#[inline]
pub fn rotate(v: AlphaBeta, sc: SinCos) -> AlphaBeta {
    let r = inverse_park(
        Dq {
            d: v.alpha,
            q: v.beta,
        },
        sc,
    );
    AlphaBeta {
        alpha: r.alpha,
        beta: r.beta,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::angle::Angle;
    use crate::units::to_f64;
    use proptest::prelude::*;

    const LSB: f64 = 1.0 / (1u64 << 24) as f64;

    fn pu(bits: i32) -> Pu {
        Pu::from_bits(bits)
    }

    fn lsb_err(got: Pu, exact: f64) -> f64 {
        let clamped = exact.clamp(to_f64(Pu::MIN), to_f64(Pu::MAX));
        (to_f64(got) - clamped).abs() / LSB
    }

    /// Whether `park` and `inverse_park` of `(x, y)` (bits of Pu) at the angle `t` are each
    /// within `bound(|x| + |y|)` LSB of the f64 transforms with the exact sin/cos.
    fn pair_within(
        x: i32,
        y: i32,
        t: i32,
        bound: impl Fn(f64) -> f64,
        park: fn(AlphaBeta, SinCos) -> Dq,
        inverse_park: fn(Dq, SinCos) -> AlphaBeta,
    ) -> bool {
        let (xf, yf) = (to_f64(pu(x)), to_f64(pu(y)));
        let th = Angle(t).to_rad();
        let (s, c) = (libm::sin(th), libm::cos(th));
        let sc = Angle(t).sin_cos();
        let b = bound(xf.abs() + yf.abs());
        let dq = park(
            AlphaBeta {
                alpha: pu(x),
                beta: pu(y),
            },
            sc,
        );
        let ab = inverse_park(Dq { d: pu(x), q: pu(y) }, sc);
        lsb_err(dq.d, xf * c + yf * s) <= b
            && lsb_err(dq.q, -xf * s + yf * c) <= b
            && lsb_err(ab.alpha, xf * c - yf * s) <= b
            && lsb_err(ab.beta, xf * s + yf * c) <= b
    }

    proptest! {
        /// Half an LSB of rounding plus the constant's error (1.6e−10 relative) times the
        /// input, in LSB: at most 1.9 LSB over the whole range, 0.6 LSB within ±8 pu. Over
        /// the whole range against the documented saturation of the sums, within ±32 pu
        /// against the plain formula.
        #[test]
        fn clarke_against_f64(a in any::<i32>(), b in any::<i32>(), c in any::<i32>()) {
            let v = clarke(Abc { a: pu(a), b: pu(b), c: pu(c) });
            let sat = |x: i64| x.clamp(i32::MIN as i64, i32::MAX as i64) as f64;
            let (ai, bi, ci) = (a as i64, b as i64, c as i64);
            let two_a = sat(sat(ai - bi) as i64 + sat(ai - ci) as i64);
            let diff = sat(bi - ci);
            let lsb = 1.0 / (1u64 << 24) as f64;
            prop_assert!(lsb_err(v.alpha, two_a * lsb / 3.0) <= 0.5 + 1.6e-10 * two_a.abs());
            prop_assert!(lsb_err(v.beta, diff * lsb / 3f64.sqrt()) <= 0.5 + 1.6e-10 * diff.abs());
            let (a, b, c) = (a >> 3, b >> 3, c >> 3); // within ±16 pu
            let (af, bf, cf) = (to_f64(pu(a)), to_f64(pu(b)), to_f64(pu(c)));
            let v = clarke(Abc { a: pu(a), b: pu(b), c: pu(c) });
            let sum = (2.0 * a as f64 - b as f64 - c as f64).abs();
            prop_assert!(lsb_err(v.alpha, (2.0 * af - bf - cf) / 3.0) <= 0.5 + 1.6e-10 * sum);
            let diff = (b as f64 - c as f64).abs();
            prop_assert!(lsb_err(v.beta, (bf - cf) / 3f64.sqrt()) <= 0.5 + 1.6e-10 * diff);
        }

        /// Half an LSB plus the error of √3/2 in Q1.31 (2.1e−10 relative): below 1 LSB.
        #[test]
        fn inverse_clarke_within_one_lsb(al in any::<i32>(), be in any::<i32>()) {
            let (x, y) = (to_f64(pu(al)), to_f64(pu(be)));
            let v = inverse_clarke(AlphaBeta { alpha: pu(al), beta: pu(be) });
            let k = 3f64.sqrt() / 2.0;
            prop_assert_eq!(v.a, pu(al));
            let bound = 0.5 + 2.1e-10 * (be as f64).abs();
            // Saturated, the rail within the 1 LSB a shift by 31 lets pass.
            let beyond = |e: f64| e < to_f64(Pu::MIN) || e > to_f64(Pu::MAX);
            let rail = |e: f64| f64::from(u8::from(beyond(e)));
            let (eb, ec) = (-x / 2.0 + k * y, -x / 2.0 - k * y);
            prop_assert!(lsb_err(v.b, eb) <= bound + rail(eb));
            prop_assert!(lsb_err(v.c, ec) <= bound + rail(ec));
        }

        /// Park and inverse Park against f64 with the exact sin/cos of the angle: the bound is
        /// half an LSB of rounding plus the sin/cos error (3 LSB of Q2.30) times |v|.
        #[test]
        fn park_pair_against_f64(x in any::<i32>(), y in any::<i32>(), t in any::<i32>()) {
            let bound = |v: f64| 0.5 + 1e-6 + 2.0 * 3.0 * v / 64.0;
            prop_assert!(pair_within(x, y, t, bound, park, inverse_park));
        }

        /// The pair in the MRAS's frames against f64 with the exact sin/cos: half an LSB of
        /// rounding plus sin/cos taken to 2⁻¹⁴ (below 2⁻¹⁴ each) times |v|, for signals within
        /// ±32 pu.
        #[test]
        fn frame_park_pair_against_f64(x in -1i32 << 29..1 << 29, y in -1i32 << 29..1 << 29, t in any::<i32>()) {
            let bound = |v: f64| 0.5 + v * 1024.0;
            prop_assert!(pair_within(x, y, t, bound, park_frame, inverse_park_frame));
        }

        /// Park then inverse Park returns the vector within 2 LSB for signals up to 8 pu.
        #[test]
        fn park_round_trip(x in -1i32 << 27..1 << 27, y in -1i32 << 27..1 << 27, t in any::<i32>()) {
            let sc = Angle(t).sin_cos();
            let v = AlphaBeta { alpha: pu(x), beta: pu(y) };
            let back = inverse_park(park(v, sc), sc);
            prop_assert!((back.alpha.to_bits() - x).abs() <= 2);
            prop_assert!((back.beta.to_bits() - y).abs() <= 2);
        }
    }
}
