//! Fixed-point PI controller with feed-forward, output clamp and anti-windup (equations.md §4.4).
//!
//! ```text
//! u_raw = ff + K_p e + I                              output before the clamp
//! K_p > 0:  I ← I + K_i T_s e + k_t (clamp(u_raw) − u_raw),   k_t = min(1, K_i T_s/K_p)
//! K_p = 0:  I ← I + K_i T_s e   unless u_raw is at a limit and e pushes further
//! hold:     no integration that pushes |u_raw| further out
//! I ← clamp(I, lo − ff, hi − ff)
//! u = clamp(ff + K_p e + I, lo, hi)
//! saturated = ff + K_p e + I ∉ [lo, hi], or on a limit with e pushing into it, or I clamped
//! ```
//!
//! # Anti-windup
//!
//! **Back-calculation** with the tracking time equal to the integral time, `T_t = K_p/K_i`,
//! when there is a proportional gain. In saturation the two integrator terms combine into
//! `I ← (1 − k_t) I + k_t (limit − ff)`: the integrator relaxes toward the value that alone
//! would put the output on the limit. For a current loop designed by pole–zero cancellation
//! (`K_i/K_p = R/L`) that value, once the current has settled on the limit, is exactly the
//! resistive drop `R i` the linear loop would hold for that current: the loop leaves
//! saturation in the state of a linear response and shows the designed first-order
//! recovery. (Conditional integration alone would freeze the integrator wherever it was when
//! the proportional term first saturated, and the error would then decay with the slow
//! electrical time constant `L/R` instead.)
//!
//! **Conditional integration** when `K_p = 0`: the IP speed loop ([`super::speed`]), whose
//! proportional action on the measurement is passed as `ff`. The integrator stops while the
//! output is at a limit and the error drives it further.
//!
//! Both add **integrator clamping**: `ff + I` alone never leaves the limits, which discharges
//! the integrator at once when the limits move inward (the voltage circle shrinks with the bus,
//! the decoupling feed-forward grows with speed). `hold` lets a downstream stage that
//! saturates on its own (the SVPWM circle) stop the outward integration. The limits are
//! given at every step, so a caller can apply a time-varying or vector (circle) limit one axis
//! at a time ([`super::current`]).
//!
//! # Formats of [`Pi`]
//!
//! | signal | format | range |
//! |---|---|---|
//! | `e`, `ff`, `u`, `lo`, `hi` | [`Pu`] Q8.24 | ±128 |
//! | `I` | Q16.48 in `i64` ([`super::WIDE_FRAC`]) | clamped into `[lo − ff, hi − ff]` ⊂ ±256 |
//! | `K_p`, `K_i T_s`, `k_t` | [`WideGain`] (30 significant bits) | `K_p` ≤ 2²⁰, `K_i T_s` ≤ 1, `k_t` ≤ 1 |
//!
//! The proportional term is also formed in Q16.48, so the only rounding of `u` is the final
//! one (½ LSB), and `I` resolves 2⁻²⁴ of an LSB: an increment `K_i T_s e` of 10⁻⁴ LSB is not
//! lost.
//!
//! # Two implementations
//!
//! [`FastPi`] is the one the current loops run: compile-time binary points ([`Coef`]) and
//! 32-bit logic, a few tens of instructions per step on a Cortex-M4. [`Pi`] is the general
//! one (any gain from 2⁻⁴⁰ to 2²⁰, `K_p = 0` for conditional integration) still used by the
//! current-model MRAS; it costs about ten times as much.
//!
//! # Formats of [`FastPi`]
//!
//! | signal | format | range |
//! |---|---|---|
//! | `e`, `ff`, `u`, `lo`, `hi`, `u_raw` | [`Pu`] Q8.24 | ±128 |
//! | `K_p` | [`Coef<17>`](Coef) | [2⁻⁹, 2¹⁴), resolution 2⁻¹⁷ (≥ 8 significant bits) |
//! | `K_i T_s` | [`Coef<32>`](Coef) | 0 or [2⁻²⁴, ½) |
//! | `k_t` | [`Coef<30>`](Coef) | [0, 1] |
//! | `I` | Q8.56 in `i64` (LSB = that of `K_i T_s · e` exact; high word = [`Pu`]) | clamped into `[lo − ff, hi − ff]` ⊂ ±128 |
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
//! error) so that the increment itself cannot overflow. [`FastPi`] takes symmetric limits
//! `±m`, all the current loops need.

use super::{WIDE_LIMIT, WideGain, gain_in, pu_to_wide, wide_gain, wide_to_pu};
use crate::error::ConfigError;
use crate::num::{Coef, Pu};

/// Largest accepted `K_p` (per unit of output per unit of error).
pub const MAX_KP: f64 = 1_048_576.0;
/// Largest accepted `K_i T_s`: above 1 the integrator alone over-corrects a unit error in one
/// sample, which no loop here needs.
pub const MAX_KI_TS: f64 = 1.0;

/// Output limits `[lo, hi]`, per unit. If `lo > hi` they are swapped.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    /// Lower limit.
    pub lo: Pu,
    /// Upper limit.
    pub hi: Pu,
}

impl Limits {
    /// `[−max, max]` (with `max` taken as `|max|`).
    pub fn symmetric(max: Pu) -> Self {
        let m = max.saturating_abs();
        Self { lo: -m, hi: m }
    }

    /// The limits in order.
    fn ordered(self) -> (Pu, Pu) {
        if self.lo <= self.hi {
            (self.lo, self.hi)
        } else {
            (self.hi, self.lo)
        }
    }
}

/// Gains of a [`Pi`], per unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PiConfig {
    kp: WideGain,
    ki_ts: WideGain,
    /// Back-calculation gain `min(1, K_i T_s/K_p)`; zero selects conditional integration.
    kt: WideGain,
}

impl PiConfig {
    /// PI with proportional gain `kp` and integral gain per sample `ki_ts` (`K_i T_s`), both per
    /// unit and non-negative. Errors name `keys[0]` or `keys[1]`.
    pub fn new(kp: f64, ki_ts: f64, keys: [&'static str; 2]) -> Result<Self, ConfigError> {
        let [kp_key, ki_key] = keys;
        gain_in(kp_key, kp, 0.0, MAX_KP)?;
        gain_in(ki_key, ki_ts, 0.0, MAX_KI_TS)?;
        let kp = wide_gain(kp_key, kp, MAX_KP)?;
        let ki_ts = wide_gain(ki_key, ki_ts, MAX_KI_TS)?;
        // From the stored values, so that an f64 model with the same constants is exact.
        let kt = if kp.to_f64() > 0.0 {
            wide_gain(ki_key, (ki_ts.to_f64() / kp.to_f64()).min(1.0), MAX_KI_TS)?
        } else {
            WideGain::ZERO
        };
        Ok(Self { kp, ki_ts, kt })
    }

    /// `K_p` as stored (exact value of the fixed-point constant).
    pub fn kp(&self) -> f64 {
        self.kp.to_f64()
    }

    /// `K_i T_s` as stored.
    pub fn ki_ts(&self) -> f64 {
        self.ki_ts.to_f64()
    }

    /// Back-calculation gain `k_t` as stored (0: conditional integration).
    pub fn kt(&self) -> f64 {
        self.kt.to_f64()
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

/// A PI controller: gains and integral state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pi {
    config: PiConfig,
    /// Integral state, Q16.48.
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

    /// Sets the integral state (bumpless start from a known output).
    pub fn reset(&mut self, integral: Pu) {
        self.integ = pu_to_wide(integral);
    }

    /// Adds `delta` (Q16.48, as [`WideGain::apply_wide`] returns) to the integral state: a
    /// feed-forward into the integrator, saturating.
    pub fn add_to_integral(&mut self, delta: i64) {
        self.integ = self.integ.saturating_add(delta);
    }

    /// The integral state, rounded to [`Pu`].
    pub fn integral(&self) -> Pu {
        wide_to_pu(self.integ)
    }

    /// One step: error `e`, feed-forward `ff`, output limits, and `hold` (a later stage
    /// saturated: do not integrate outward). Integer only; never panics.
    pub fn step(&mut self, e: Pu, ff: Pu, limits: Limits, hold: bool) -> PiOutput {
        self.step_inside(e, ff, limits, hold).0
    }

    /// [`Pi::step`], and whether no limit took part: the output before the clamp strictly
    /// inside `(lo, hi)` both before and after the integration, and the integrator not clamped.
    /// When it is true, the step (state and output) is bit for bit the same for any wider
    /// limits, so a caller whose exact limit is costly can step with a cheap inner bound
    /// first, and step again (from the saved state) with the exact limit only when this is
    /// false.
    pub fn step_inside(&mut self, e: Pu, ff: Pu, limits: Limits, hold: bool) -> (PiOutput, bool) {
        let (lo, hi) = limits.ordered();
        let (lo, hi) = (pu_to_wide(lo), pu_to_wide(hi));
        let ff = pu_to_wide(ff);
        let p = self.config.kp.apply_wide(e);
        // Each term is below 2^62 in magnitude; saturating adds keep the sums honest.
        let raw = ff.saturating_add(p).saturating_add(self.integ);
        let raw_inside = lo < raw && raw < hi;
        let up = e > Pu::ZERO;
        let down = e < Pu::ZERO;
        let outward = hold && ((raw > 0 && up) || (raw < 0 && down));
        let back_calc = self.config.kt != WideGain::ZERO;
        let stop = outward || (!back_calc && ((raw >= hi && up) || (raw <= lo && down)));
        if !stop {
            let inc = self.config.ki_ts.apply_wide(e);
            self.integ = self.integ.saturating_add(inc);
        }
        if back_calc && !outward {
            // k_t (clamp(u_raw) − u_raw): pulls I toward the value that puts u on the limit.
            // Zero inside the limits (the common case): skip the i128 product, whose result
            // would be exactly 0.
            let excess = raw.max(lo).min(hi).saturating_sub(raw);
            if excess != 0 {
                self.integ = self.integ.saturating_add(self.config.kt.apply_i64(excess));
            }
        }
        // Clamp the integrator so that ff + I alone stays within the limits.
        let i_lo = lo.saturating_sub(ff).clamp(-WIDE_LIMIT, WIDE_LIMIT);
        let i_hi = hi.saturating_sub(ff).clamp(-WIDE_LIMIT, WIDE_LIMIT);
        let unclamped = self.integ;
        // max/min rather than clamp: no assertion, hence no panic path, when i_lo > i_hi.
        self.integ = self.integ.max(i_lo).min(i_hi.max(i_lo));
        let raw = ff.saturating_add(p).saturating_add(self.integ);
        let inside = raw_inside && unclamped == self.integ && lo < raw && raw < hi;
        let out = PiOutput {
            u: wide_to_pu(raw.max(lo).min(hi)),
            saturated: raw > hi
                || raw < lo
                || (raw == hi && up)
                || (raw == lo && down)
                || unclamped != self.integ,
        };
        (out, inside)
    }
}

/// Fractional bits of [`FastPi`]'s `K_p`: up to 2¹⁴, the largest `L/(T_s Z_b)` of the
/// per-unit envelope ([`crate::units`]), i.e. a deadbeat current loop on its fastest motor.
pub const KP_FRAC: u32 = 17;
/// Fractional bits of [`FastPi`]'s `K_i T_s` (below ½): the integrator's LSB is the exact
/// product's, 2⁻⁵⁶, so the high word of the Q8.56 integrator is a [`Pu`].
pub const KI_FRAC: u32 = 32;
/// Fractional bits of [`FastPi`]'s `k_t` (at most 1).
pub const KT_FRAC: u32 = 30;
/// Smallest non-zero `K_p` of a [`FastPi`]: 2⁻⁹, eight significant bits at `KP_FRAC`.
pub const FAST_KP_MIN: f64 = 1.0 / 512.0;
/// Smallest non-zero `K_i T_s` of a [`FastPi`]: 2⁻²⁴, eight significant bits at `KI_FRAC`.
pub const FAST_KI_TS_MIN: f64 = 1.0 / 16_777_216.0;
/// Largest `K_i T_s` of a [`FastPi`] (exclusive): ½ (a current loop's default is
/// `0.05 R/Z_b`, below 0.01 for the motors of the envelope's tests).
pub const FAST_KI_TS_MAX: f64 = 0.5;

/// Shift from a [`Pu`] value to the Q8.56 integrator (`KI_FRAC`).
const I_SHIFT: u32 = KI_FRAC;
/// Bound of the back-calculation's excess, ±2²⁹ LSB (±32 pu): `|K_i T_s e| < 2⁶²` and
/// `|4 k_t excess| ≤ 2⁶¹`, so the increment cannot overflow.
const EXCESS_BOUND: i32 = 1 << 29;

/// Largest value a `Coef<F>` holds: `(2³¹ − 1) 2^−F`.
pub(crate) fn coef_max<const F: u32>() -> f64 {
    libm::ldexp(i32::MAX as f64, -(F as i32))
}

/// `value` (per unit) as a `Coef<F>`: zero (when `zero_ok`) or within `[min, max]`, `max`
/// at most [`coef_max`]; the error reports `value · si_per_pu` and the range in the same (SI)
/// unit.
pub(crate) fn coef_in<const F: u32>(
    key: &'static str,
    value: f64,
    (min, max): (f64, f64),
    zero_ok: bool,
    si_per_pu: f64,
) -> Result<Coef<F>, ConfigError> {
    let max = max.min(coef_max::<F>());
    let ok = value.is_finite() && ((zero_ok && value == 0.0) || (min..=max).contains(&value));
    match Coef::<F>::new(value) {
        Some(c) if ok => Ok(c),
        _ => Err(ConfigError::Gain {
            key,
            value: value * si_per_pu,
            min: if zero_ok { 0.0 } else { min * si_per_pu },
            max: max * si_per_pu,
        }),
    }
}

/// Gains of a [`FastPi`], per unit (back-calculation; `K_p > 0`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FastPiConfig {
    kp: Coef<KP_FRAC>,
    ki_ts: Coef<KI_FRAC>,
    /// `min(K_i T_s/K_p, 1)` of the stored gains.
    kt: Coef<KT_FRAC>,
}

impl FastPiConfig {
    /// PI with proportional gain `kp` in `[2⁻⁹, 2¹⁴)` and integral gain per sample `ki_ts`
    /// (0 or in `[2⁻²⁴, ½)`), per unit. Errors name `keys[0]` or `keys[1]` and give the value
    /// and range times `si_per_pu` (the caller's unit).
    pub fn new(
        kp: f64,
        ki_ts: f64,
        keys: [&'static str; 2],
        si_per_pu: [f64; 2],
    ) -> Result<Self, ConfigError> {
        let kp = coef_in::<KP_FRAC>(keys[0], kp, (FAST_KP_MIN, f64::MAX), false, si_per_pu[0])?;
        let max_ki = FAST_KI_TS_MAX - libm::ldexp(1.0, -(KI_FRAC as i32));
        let ki_ts =
            coef_in::<KI_FRAC>(keys[1], ki_ts, (FAST_KI_TS_MIN, max_ki), true, si_per_pu[1])?;
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
pub struct FastPi {
    config: FastPiConfig,
    /// Integral state, Q8.56 (high word: [`Pu`]); at the end of every step a multiple of
    /// 2³² or within `(lo − ff, hi − ff)`.
    integ: i64,
}

impl FastPi {
    /// A controller with zero integral state.
    pub fn new(config: FastPiConfig) -> Self {
        Self { config, integ: 0 }
    }

    /// The gains.
    pub fn config(&self) -> &FastPiConfig {
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
    /// as 0): the output, whether no limit took part (see [`Pi::step_inside`]: then the step
    /// is bit for bit the same for any wider limits), and the new integral state (for
    /// [`FastPi::commit`]). A caller with a costly exact limit evaluates with a cheap inner
    /// bound first, and again with the exact limit only when the second value is false.
    #[inline(always)]
    pub fn eval(&self, e: Pu, ff: Pu, m: Pu, hold: bool) -> (PiOutput, bool, i64) {
        let c = self.config;
        let (eb, ffb) = (e.to_bits(), ff.to_bits());
        let hi = m.to_bits().max(0);
        let lo = -hi;
        // ff + K_p e (one rounding of the exact product, saturated), then + I rounded: two
        // roundings, within 1 LSB of the exact sum (f64 tests: drive_parts_loops).
        let pf = c.kp.apply_bits(eb).saturating_add(ffb);
        let raw = pf.saturating_add(integ_to_pu(self.integ));
        // lo < raw < hi, with |raw| taken without overflow.
        let raw_inside = raw.unsigned_abs() < hi as u32;
        let (up, down) = (eb > 0, eb < 0);
        // |K_i T_s e| < 2⁶² (K_i T_s < ½).
        let mut inc = c.ki_ts.wide(eb);
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

    /// Stores a new integral state returned by [`FastPi::eval`].
    #[inline(always)]
    pub fn commit(&mut self, integ: i64) {
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
        Pi::new(PiConfig::new(kp, ki_ts, ["kp", "ki"]).unwrap())
    }

    #[test]
    fn bad_gains_are_named() {
        assert!(matches!(
            PiConfig::new(-1.0, 0.1, ["a.kp", "a.ki"]),
            Err(ConfigError::Gain { key: "a.kp", .. })
        ));
        assert!(matches!(
            PiConfig::new(1.0, f64::NAN, ["a.kp", "a.ki"]),
            Err(ConfigError::Gain { key: "a.ki", .. })
        ));
        assert!(matches!(
            PiConfig::new(1.0, 2.0, ["a.kp", "a.ki"]),
            Err(ConfigError::Gain { key: "a.ki", max, .. }) if max == MAX_KI_TS
        ));
    }

    #[test]
    fn integrates_sub_lsb_increments() {
        // K_i T_s e = 1e-3 LSB per step: after 1e6 steps the integral is 1000 LSB (±1).
        let mut c = pi(0.0, 1e-3);
        let e = Pu::from_bits(1);
        let lim = Limits::symmetric(Pu::from_num(1));
        let mut out = PiOutput::default();
        for _ in 0..1_000_000 {
            out = c.step(e, Pu::ZERO, lim, false);
        }
        assert!((out.u.to_bits() - 1000).abs() <= 1, "{}", out.u.to_bits());
    }

    #[test]
    fn clamps_and_recovers_at_once() {
        let mut c = pi(0.0, 0.01);
        let lim = Limits::symmetric(Pu::from_num(1));
        for k in 0..10_000 {
            let o = c.step(Pu::from_num(5), Pu::ZERO, lim, false);
            if k >= 20 {
                assert_eq!(o.u, Pu::from_num(1));
                assert!(o.saturated);
            }
        }
        // The integrator was held at the limit: a small negative error leaves saturation
        // within one step (a wound-up integrator would need 10 000).
        assert!(c.integral() <= Pu::from_num(1));
        let o = c.step(pu_from_f64(-0.1), Pu::ZERO, lim, false);
        assert!(!o.saturated && o.u < Pu::from_num(1));
        // Back-calculation: in saturation I relaxes to the limit at k_t per step.
        let mut c = pi(1.0, 0.01);
        for _ in 0..2000 {
            let o = c.step(Pu::from_num(5), Pu::ZERO, lim, false);
            assert_eq!(o.u, Pu::from_num(1));
        }
        assert!(
            (c.integral().to_bits() - (1 << 24)).abs() <= 1,
            "{}",
            c.integral()
        );
        // Extreme inputs saturate, never wrap or panic.
        let o = c.step(
            Pu::MAX,
            Pu::MAX,
            Limits {
                lo: Pu::MAX,
                hi: Pu::MIN,
            },
            true,
        );
        assert_eq!(o.u, Pu::MAX);
    }
}
