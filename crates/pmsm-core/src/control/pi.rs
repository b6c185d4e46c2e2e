//! Fixed-point PI controller with feed-forward, symmetric output clamp and anti-windup
//! (docs/khlaief2012.md §6–7): the current loops' controller.
//!
//! ```text
//! u_raw = ff + K_p e + I                              output before the clamp
//! I ← I + K_i T_s e + k_t (clamp(u_raw) − u_raw),     k_t = min(1, K_i T_s/K_p)
//! hold:     no integration that pushes |u_raw| further out
//! I ← clamp(I, −m − ff, m − ff)
//! u = clamp(ff + K_p e + I, −m, m)
//! saturated = u_raw ∉ [−m, m], or on a limit with e pushing into it, or I clamped
//! ```
//!
//! # Anti-windup
//!
//! **Back-calculation** with the tracking time equal to the integral time, `T_t = K_p/K_i`.
//! In saturation the two integrator terms combine into `I ← (1 − k_t) I + k_t (limit − ff)`:
//! the integrator relaxes toward the value that alone would put the output on the limit. For a
//! current loop designed by pole–zero cancellation (`K_i/K_p = R/L`) that value, once the
//! current has settled on the limit, is exactly the resistive drop `R i` the linear loop
//! would hold for that current: the loop leaves saturation in the state of a linear response
//! and shows the designed first-order recovery. (Conditional integration alone would freeze
//! the integrator wherever it was when the proportional term first saturated, and the error
//! would then decay with the slow electrical time constant `L/R` instead.)
//!
//! It adds **integrator clamping**: `ff + I` alone never leaves the limits, which discharges
//! the integrator at once when the limits move inward (the voltage circle shrinks with the bus,
//! the decoupling feed-forward grows with speed). `hold` lets a downstream stage that
//! saturates on its own (the SVPWM circle) stop the outward integration. The limit is given
//! at every step, so a caller can apply a time-varying or vector (circle) limit one axis at a
//! time ([`super::current`]). The IP speed loop has its own integrator ([`super::speed`]).
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | `e`, `ff`, `u`, `m`, `u_raw` | [`Pu`] Q8.24 | ±128 |
//! | `K_p` | [`Coef<17>`](Coef) | [2⁻⁹, 2¹⁴), resolution 2⁻¹⁷ (≥ 8 significant bits) |
//! | `K_i T_s` | [`Coef<32>`](Coef) | 0 or [2⁻²⁴, ½) |
//! | `k_t` | [`Coef<30>`](Coef) | [0, 1] |
//! | `I` | Q8.56 in `i64` (LSB = that of `K_i T_s · e` exact; high word = [`Pu`]) | clamped into `[−m − ff, m − ff]` ⊂ ±128 |
//!
//! `u_raw = (ff + K_p e) + I` is formed in 32 bits with `QADD`s: `K_p e` is rounded once from
//! the exact product (½ LSB) and `I` to the nearest LSB (½ LSB), so `u_raw` is within 1 LSB
//! of the exact sum, and it saturates at ±128 (the limits are inside, so the clamp and the
//! flags are unaffected).
//! Increments `K_i T_s e` and `k_t (clamp(u_raw) − u_raw)` are exact products in the
//! integrator's LSB (one `SMLAL` each on a Cortex-M4), so an increment of 10⁻⁵ LSB is not
//! lost. The sum `I + increment` saturates its high word (cheaper than a 64-bit saturating
//! add, and exact up to the clamp that follows), and the clamp compares high words only. The
//! back-calculation's excess is bounded to ±32 per unit (far beyond any drive's voltage
//! error) so that the increment itself cannot overflow. A few tens of instructions per step
//! on a Cortex-M4 (`docs/PERFORMANCE.md`, `current_loops`).

use crate::error::ConfigError;
use crate::num::{Coef, Pu};

/// Fractional bits of [`Pi`]'s `K_p`: up to 2¹⁴, the largest `L/(T_s Z_b)` of the
/// per-unit envelope ([`crate::units`]), i.e. a deadbeat current loop on its fastest motor.
pub const KP_FRAC: u32 = 17;
/// Fractional bits of [`Pi`]'s `K_i T_s` (below ½): the integrator's LSB is the exact
/// product's, 2⁻⁵⁶, so the high word of the Q8.56 integrator is a [`Pu`].
pub const KI_FRAC: u32 = 32;
/// Fractional bits of [`Pi`]'s `k_t` (at most 1).
pub const KT_FRAC: u32 = 30;
/// Smallest non-zero `K_p` of a [`Pi`]: 2⁻⁹, eight significant bits at `KP_FRAC`.
pub const KP_MIN: f64 = 1.0 / 512.0;
/// Smallest non-zero `K_i T_s` of a [`Pi`]: 2⁻²⁴, eight significant bits at `KI_FRAC`.
pub const KI_TS_MIN: f64 = 1.0 / 16_777_216.0;
/// Largest `K_i T_s` of a [`Pi`] (exclusive): ½ (a current loop's default is
/// `0.05 R/Z_b`, below 0.01 for the motors of the envelope's tests).
pub const KI_TS_MAX: f64 = 0.5;

/// Shift from a [`Pu`] value to the Q8.56 integrator (`KI_FRAC`).
const I_SHIFT: u32 = KI_FRAC;
/// Bound of the back-calculation's excess, ±2²⁹ LSB (±32 pu): `|K_i T_s e| < 2⁶²` and
/// `|4 k_t excess| ≤ 2⁶¹`, so the increment cannot overflow.
const EXCESS_BOUND: i32 = 1 << 29;

/// `value` (per unit) as a `Coef<F>`: zero (when `zero_ok`) or within `[min, max]`, `max`
/// at most the largest value a `Coef<F>` holds, `(2³¹ − 1) 2^−F`; the error reports
/// `value · si_per_pu` and the range in the same (SI) unit.
pub(crate) fn coef_in<const F: u32>(
    key: &'static str,
    value: f64,
    range: (f64, f64),
    zero_ok: bool,
    si_per_pu: f64,
) -> Result<Coef<F>, ConfigError> {
    coef_bits_in(key, value, range, zero_ok, si_per_pu, F).map(Coef::from_bits)
}

/// [`coef_in`] at the binary point `frac`, as bits: one copy for every format, out of line as
/// [`crate::num::coef_bits`] is and for the same reasons.
#[cfg_attr(target_has_atomic = "ptr", inline(never))]
#[cfg_attr(not(target_has_atomic = "ptr"), inline(always))]
fn coef_bits_in(
    key: &'static str,
    value: f64,
    (min, max): (f64, f64),
    zero_ok: bool,
    si_per_pu: f64,
    frac: u32,
) -> Result<i32, ConfigError> {
    // The largest value a Coef<frac> holds.
    let max = max.min(libm::ldexp(i32::MAX as f64, -(frac as i32)));
    let ok = value.is_finite() && ((zero_ok && value == 0.0) || (min..=max).contains(&value));
    match crate::num::coef_bits(value, frac) {
        Some(bits) if ok => Ok(bits),
        _ => Err(ConfigError::Gain {
            key,
            value: value * si_per_pu,
            min: if zero_ok { 0.0 } else { min * si_per_pu },
            max: max * si_per_pu,
        }),
    }
}

/// Output of one [`Pi::step`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PiOutput {
    /// Clamped output, per unit.
    pub u: Pu,
    /// The output before the clamp was outside the limits, or on a limit with the error
    /// pushing into it, or the integrator was clamped.
    pub saturated: bool,
}

/// The terms of a [`Pi`] step that do not depend on its limits ([`Pi::prepare`]), bits of
/// [`Pu`] and the integrator's increment `K_i T_s e` (Q8.56).
#[derive(Clone, Copy, Debug)]
pub(crate) struct PiTerms {
    e: i32,
    ff: i32,
    /// `ff + K_p e`.
    pf: i32,
    /// `u_raw = ff + K_p e + I`.
    raw: i32,
    inc: i64,
}

impl PiTerms {
    /// `|u_raw|`, the output before the limits and before this step's integration: a caller
    /// tells from it, without a [`Pi::finish`], whether a limit can be far.
    #[inline(always)]
    pub(crate) fn raw_abs(&self) -> u32 {
        self.raw.unsigned_abs()
    }
}

/// Gains of a [`Pi`], per unit (back-calculation; `K_p > 0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, crate::image::Words)]
pub struct PiConfig {
    kp: Coef<KP_FRAC>,
    ki_ts: Coef<KI_FRAC>,
    /// `min(K_i T_s/K_p, 1)` of the stored gains.
    kt: Coef<KT_FRAC>,
}

impl PiConfig {
    /// PI with proportional gain `kp` in `[2⁻⁹, 2¹⁴)` and integral gain per sample `ki_ts`
    /// (0 or in `[2⁻²⁴, ½)`), per unit. Errors name `keys[0]` or `keys[1]` and give the value
    /// and range times `si_per_pu` (the caller's unit).
    pub fn new(
        kp: f64,
        ki_ts: f64,
        keys: [&'static str; 2],
        si_per_pu: [f64; 2],
    ) -> Result<Self, ConfigError> {
        let kp = coef_in::<KP_FRAC>(keys[0], kp, (KP_MIN, f64::MAX), false, si_per_pu[0])?;
        let max_ki = KI_TS_MAX - libm::ldexp(1.0, -(KI_FRAC as i32));
        let ki_ts = coef_in::<KI_FRAC>(keys[1], ki_ts, (KI_TS_MIN, max_ki), true, si_per_pu[1])?;
        // From the stored values, so that an f64 model with the same constants is exact (up
        // to the 2⁻³¹ rounding of k_t). kp ≥ 2⁻⁹ > 0; k_t ≤ 1 = 2³⁰ LSB fits.
        let kt = (ki_ts.to_f64() / kp.to_f64()).min(1.0);
        let kt = Coef::new(kt).unwrap_or(Coef::ZERO);
        Ok(Self { kp, ki_ts, kt })
    }

    /// `K_p` as stored.
    pub fn kp(&self) -> f64 {
        self.kp.to_f64()
    }

    /// `K_i T_s` as stored.
    pub fn ki_ts(&self) -> f64 {
        self.ki_ts.to_f64()
    }

    /// Back-calculation gain `k_t` as stored.
    pub fn kt(&self) -> f64 {
        self.kt.to_f64()
    }
}

/// The PI of the current loops: the algorithm of this module's docs with back-calculation
/// and symmetric limits `[−m, m]`, in the formats of its table. Integer only, never panics,
/// never wraps.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Pi {
    config: PiConfig,
    /// Integral state, Q8.56 (high word: [`Pu`]); at the end of every step a multiple of
    /// 2³² or within `(lo − ff, hi − ff)`.
    integ: i64,
}

impl Pi {
    /// A controller with zero integral state.
    pub fn new(config: PiConfig) -> Self {
        Self { config, integ: 0 }
    }

    /// The gains.
    pub fn config(&self) -> &PiConfig {
        &self.config
    }

    /// Sets the integral state.
    pub fn reset(&mut self, integral: Pu) {
        self.integ = (integral.to_bits() as i64) << I_SHIFT;
    }

    /// The integral state, rounded to [`Pu`].
    pub fn integral(&self) -> Pu {
        Pu::from_bits(integ_to_pu(self.integ))
    }

    /// One step: error `e`, feed-forward `ff`, output limits `±max` (`|max|` is used), and
    /// `hold` (a later stage saturated: do not integrate outward).
    #[inline(always)]
    pub fn step(&mut self, e: Pu, ff: Pu, max: Pu, hold: bool) -> PiOutput {
        let (out, _, integ) = self.eval(e, ff, max.saturating_abs(), hold);
        self.integ = integ;
        out
    }

    /// The step without its state update, for limits `±m` with `m ≥ 0` (a negative `m` acts
    /// as 0): the output, whether no limit took part (then the step is bit for bit the same
    /// for any wider limits), and the new integral state (for [`Pi::commit`]).
    #[inline(always)]
    pub(crate) fn eval(&self, e: Pu, ff: Pu, m: Pu, hold: bool) -> (PiOutput, bool, i64) {
        self.finish(&self.prepare(e, ff), m, hold)
    }

    /// The part of a step that does not depend on the limits: a caller with a costly exact
    /// limit [`Pi::finish`]es with a cheap inner bound first, and again with the exact limit
    /// only when a limit took part, without forming the products twice.
    #[inline(always)]
    pub(crate) fn prepare(&self, e: Pu, ff: Pu) -> PiTerms {
        let c = self.config;
        let (e, ff) = (e.to_bits(), ff.to_bits());
        // ff + K_p e (one rounding of the exact product, saturated), then + I rounded: two
        // roundings, within 1 LSB of the exact sum (f64 tests: drive_parts_loops).
        let pf = c.kp.apply_bits(e).saturating_add(ff);
        PiTerms {
            e,
            ff,
            pf,
            raw: pf.saturating_add(integ_to_pu(self.integ)),
            // |K_i T_s e| < 2⁶² (K_i T_s < ½).
            inc: c.ki_ts.wide(e),
        }
    }

    /// [`Pi::eval`] from the terms of [`Pi::prepare`].
    #[inline(always)]
    pub(crate) fn finish(&self, t: &PiTerms, m: Pu, hold: bool) -> (PiOutput, bool, i64) {
        let c = self.config;
        let PiTerms {
            e: eb,
            ff: ffb,
            pf,
            raw,
            mut inc,
        } = *t;
        let hi = m.to_bits().max(0);
        let lo = -hi;
        // lo < raw < hi, with |raw| taken without overflow.
        let raw_inside = raw.unsigned_abs() < hi as u32;
        let (up, down) = (eb > 0, eb < 0);
        if !raw_inside {
            // Back-calculation k_t (clamp(u_raw) − u_raw), bounded to ±32 pu so that
            // |4 k_t excess| ≤ 2⁶¹ (k_t ≤ 1) and the sum stays below 2⁶³; zero inside the
            // limits (the common case), where the product is skipped.
            let excess = raw.max(lo).min(hi).saturating_sub(raw);
            let excess = excess.clamp(-EXCESS_BOUND, EXCESS_BOUND);
            inc += c.kt.wide(excess) << (KI_FRAC - KT_FRAC);
        }
        if hold && ((raw > 0 && up) || (raw < 0 && down)) {
            inc = 0;
        }
        // I + inc with the high word saturated (the clamp below brings it back), then the
        // clamp to [lo − ff, hi − ff] on the high word: I < i_lo 2³² ⟺ high < i_lo, and
        // I ≥ i_hi 2³² ⟺ high ≥ i_hi (clamped unless exactly on the bound).
        let (low, carry) = (self.integ as u32).overflowing_add(inc as u32);
        let high = ((self.integ >> 32) as i32)
            .saturating_add((inc >> 32) as i32)
            .saturating_add(carry as i32);
        let i_lo = lo.saturating_sub(ffb);
        let i_hi = hi.saturating_sub(ffb);
        let (integ, clamped) = if high >= i_hi {
            ((i_hi as i64) << 32, high != i_hi || low != 0)
        } else if high < i_lo {
            ((i_lo as i64) << 32, true)
        } else {
            (((high as i64) << 32) | low as i64, false)
        };
        let raw2 = pf.saturating_add(integ_to_pu(integ));
        // On a limit with the error pushing into it counts as saturated: raw2 ≥ hi when
        // e > 0, raw2 > hi otherwise (hi − 1 and lo + 1 cannot overflow as hi ≥ 0).
        let out = PiOutput {
            u: Pu::from_bits(raw2.max(lo).min(hi)),
            saturated: clamped || raw2 > hi - up as i32 || raw2 < lo + down as i32,
        };
        let inside = !clamped && raw_inside && raw2.unsigned_abs() < hi as u32;
        (out, inside, integ)
    }

    /// Stores a new integral state returned by [`Pi::eval`].
    #[inline(always)]
    pub(crate) fn commit(&mut self, integ: i64) {
        self.integ = integ;
    }
}

/// A Q8.56 integral state rounded to [`Pu`] bits: the high word plus the rounding bit,
/// saturated.
#[inline(always)]
fn integ_to_pu(integ: i64) -> i32 {
    ((integ >> I_SHIFT) as i32).saturating_add(((integ as u32) >> (I_SHIFT - 1)) as i32)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::num::pu_from_f64;

    fn pi(kp: f64, ki_ts: f64) -> Pi {
        Pi::new(PiConfig::new(kp, ki_ts, ["kp", "ki"], [1.0, 1.0]).unwrap())
    }

    #[test]
    fn bad_gains_are_named() {
        assert!(matches!(
            PiConfig::new(-1.0, 0.1, ["a.kp", "a.ki"], [1.0, 1.0]),
            Err(ConfigError::Gain { key: "a.kp", .. })
        ));
        assert!(matches!(
            PiConfig::new(1.0, f64::NAN, ["a.kp", "a.ki"], [1.0, 1.0]),
            Err(ConfigError::Gain { key: "a.ki", .. })
        ));
        assert!(matches!(
            PiConfig::new(1.0, 2.0, ["a.kp", "a.ki"], [1.0, 1.0]),
            Err(ConfigError::Gain { key: "a.ki", max, .. }) if max < KI_TS_MAX
        ));
    }

    #[test]
    fn integrates_sub_lsb_increments() {
        // K_i T_s e = 1e-3 LSB per step: after 1e6 steps the integral is 1000 LSB (±1); the
        // smallest K_p times a 1-LSB error rounds to zero.
        let mut c = pi(KP_MIN, 1e-3);
        let e = Pu::from_bits(1);
        let mut out = PiOutput::default();
        for _ in 0..1_000_000 {
            out = c.step(e, Pu::ZERO, Pu::from_num(1), false);
        }
        assert!((out.u.to_bits() - 1000).abs() <= 1, "{}", out.u.to_bits());
    }

    #[test]
    fn clamps_and_recovers_at_once() {
        let one = Pu::from_num(1);
        let mut c = pi(KP_MIN, 0.01);
        for k in 0..10_000 {
            let o = c.step(Pu::from_num(5), Pu::ZERO, one, false);
            if k >= 20 {
                assert_eq!(o.u, one);
                assert!(o.saturated);
            }
        }
        // The integrator was held at the limit: a small negative error leaves saturation
        // within one step (a wound-up integrator would need 10 000).
        assert!(c.integral() <= one);
        let o = c.step(pu_from_f64(-0.1), Pu::ZERO, one, false);
        assert!(!o.saturated && o.u < one);
        // Back-calculation: in saturation I relaxes to the limit at k_t per step.
        let mut c = pi(1.0, 0.01);
        for _ in 0..2000 {
            let o = c.step(Pu::from_num(5), Pu::ZERO, one, false);
            assert_eq!(o.u, one);
        }
        assert!(
            (c.integral().to_bits() - (1 << 24)).abs() <= 1,
            "{}",
            c.integral()
        );
        // Extreme inputs saturate, never wrap or panic.
        let o = c.step(Pu::MAX, Pu::MAX, Pu::MAX, true);
        assert_eq!(o.u, Pu::MAX);
        let o = c.step(Pu::MIN, Pu::MIN, Pu::MIN, true);
        assert_eq!(o.u, -Pu::MAX);
    }
}
