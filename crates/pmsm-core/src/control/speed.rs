//! IP speed controller of Khlaief, Boussak, Gossa (2012) (nomenclature `K_iΩ`, `K_pΩ`; docs/khlaief2012.md §6–7),
//! its PI form, and the forms between them.
//!
//! ```text
//! IP:  i_q* = K_iΩ ∫(ω* − ω̂) dt − K_pΩ ω̂,          clamped to ±I_max
//! PI:  i_q* = K_iΩ ∫(ω* − ω̂) dt + K_pΩ (ω* − ω̂),
//! b:   i_q* = K_iΩ ∫(ω* − ω̂) dt + K_pΩ (b ω* − ω̂),  b ∈ [0, 1] (IP: 0, PI: 1)
//! ```
//!
//! In the IP form the proportional action acts on the measured (estimated) speed only, so a
//! reference step does not kick the current, and the closed loop has no zero. All forms have
//! the same loop (the same response to the load and to the estimate); they differ only in how
//! they follow the reference ([`SpeedDesign::reference_weight`], the setpoint weight `b` of a
//! two-degree-of-freedom PI).
//!
//! # Gains
//!
//! With an ideal current loop the electrical speed obeys `dω/dt = K i_q − (B/J) ω − p T_L/J`,
//! `K = p K_T/J` (Khlaief, Boussak, Gossa (2012) eq. 5 with the 1.5 of docs/algorithms.md (conventions) inside `K_T`). The IP loop is
//! then
//!
//! ```text
//! ω/ω* = K K_iΩ / (s² + (K K_pΩ + B/J) s + K K_iΩ)
//! ```
//!
//! and for a natural frequency `ω_n` and damping `ζ`:
//! `K_iΩ = ω_n²/K`, `K_pΩ = (2 ζ ω_n − B/J)/K` (not below 0). With `ζ ≥ 1` both poles are real
//! and there is no zero, so the step response is monotone: no overshoot (Khlaief, Boussak, Gossa (2012) §7, Fig. 7).
//! Defaults: `ζ = 1`, `ω_n` a twentieth of the default current-loop bandwidth, `0.005/T_s`
//! (70 rad/s at 14 kHz), `I_max` = 1 pu (rated peak current).
//!
//! # Following a ramp
//!
//! On a reference ramp `dω*/dt = α` the IP loop settles `(K K_pΩ + B/J) α/(K K_iΩ) ≈ 2ζα/ω_n`
//! behind it: 730 r/min, a third of the reference, on a reversal of the random family with a
//! 36 ms mechanical time constant (docs/drive.md, "speed loop: IP or PI"), where the rotor is
//! then still turning the old way when a load that follows the reference changes sign. The
//! PI form adds `K_pΩ ω*` to the IP's output, a zero at `K_iΩ/K_pΩ = ω_n/2ζ` in `ω/ω*`: with
//! `B = 0` the loop is of type 2 and follows a ramp without lag, at the price of an overshoot
//! after a step (`1 + e⁻²`, 13.5 %, at `t = 2/ω_n` with `ζ = 1`) and at the end of a ramp
//! (`α/(e ω_n)` at `t = 1/ω_n`: 18 % of the lag the IP form would have had). A weight `b`
//! adds `b K_pΩ ω*`: the zero moves to `ω_n/(2ζb)`, the ramp is followed `(1 − b)` of the IP's
//! lag late, and the overshoot shrinks with it (the response is the IP's plus `b` times the
//! PI's difference from it, both linear in the reference).
//!
//! # Anti-windup
//!
//! The PI of [`super::pi`] with `K_p = 0` and `ff = −K_pΩ ω̂` (IP; `ff = −K_pΩ (ω̂ − b ω*)`
//! with a weight, whose reference part [`SpeedController::move_reference`] adds): conditional
//! integration (no integration while the output is at a limit and the error drives it
//! further) and an integrator clamped to `[−I_max + K_pΩ ω̂, I_max + K_pΩ ω̂]`. After a
//! saturated acceleration the integrator leaves the clamp when `K_iΩ (ω* − ω̂) < K_pΩ dω̂/dt`,
//! which is the state of the linear loop tracking a ramp; a ramp followed by a hold gives no
//! overshoot either, so a saturated step does not overshoot in the IP form (tests:
//! `drive_parts_loops`).
//!
//! # State: the unclamped output, not the integral
//!
//! The integral `I` holds `i_q* + K_pΩ ω̂`, which is far larger than `I_max` when `K_pΩ` is
//! large (108 pu of current at 1 pu of speed for motor A). The controller keeps instead
//! `s = I − K_pΩ ω̂` (the output, `s ∈ [−I_max, I_max]` after each step) and the last
//! `ff = −K_pΩ ω̂`; with `Δff` the change of `ff` since the previous sample, the step
//!
//! ```text
//! u_raw = s + Δff
//! stop  = (u_raw ≥ I_max and e > 0) or (u_raw ≤ −I_max and e < 0)
//! s     = clamp(u_raw + (stop ? 0 : K_iΩ T e), −I_max, I_max)
//! ```
//!
//! is the PI above exactly (the clamp of `I` to `[lo − ff, hi − ff]` is the clamp of `s` to
//! `[lo, hi]`): one product per step (`K_pΩ ω̂`) besides the integral's, and 32-bit
//! comparisons on the high word of `s`.
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | `ω*`, `ω̂` (of `ω_b`), `i_q*`, `I_max` (of `I_b`), `ff`, `Δff` | [`Pu`] Q8.24 | ±128 (saturated); `I_max` ≤ 64 |
//! | `−K_pΩ ω_b/I_b` | [`Coef<17>`](Coef) | (−2¹⁴, 0], resolution 2⁻¹⁷ |
//! | `K_iΩ T ω_b/I_b` (`T` the speed loop's period) | [`Coef<28>`](Coef) | 0 or [2⁻²⁰, 8) |
//! | `s` | Q8.56 in `i64` (high word: [`Pu`]; LSB that of `2 K_iΩ T e` exact) | `[−I_max, I_max]` |
//!
//! `u_raw` saturates its high word: with `|s| ≤ I_max ≤ 64` a saturated sum lies beyond the
//! limit on the same side, so the decisions and the clamp are those of the exact sum. The
//! output is `s` rounded (½ LSB).

use super::gain_in;
use super::pi::{KP_FRAC, coef_in};
use crate::error::ConfigError;
use crate::num::{Coef, Pu, pu_from_f64};
use crate::params::{MotorParams, in_range};
use crate::units::PerUnit;

/// Fractional bits of `K_iΩ T` (per unit, below 8: the task's period is several samples);
/// its exact product, shifted into the state's LSB (2⁻⁵⁶), saturates.
const KI_FRAC: u32 = 28;
/// Smallest non-zero `K_iΩ T ω_b/I_b`: 2⁻²⁰, eight significant bits.
const KI_MIN: f64 = 1.0 / 1_048_576.0;
/// Largest `K_iΩ T ω_b/I_b`: below 8 (an integrator that alone corrects eight times a unit
/// error in one step of the task, which no speed loop needs).
const KI_MAX: f64 = 8.0 - 1.0 / 268_435_456.0;

/// Default `ω_n T_s` of the speed loop (a twentieth of the current loop's default).
pub const DEFAULT_BANDWIDTH_TS: f64 = 0.005;

/// Default [`SpeedDesign::decimation`] of a speed loop on its own: every sample. The drive's
/// design takes its task period instead (`TASK_PERIOD`, the loop in the drive's task on the
/// period's mean speed: docs/drive.md, "two rates").
pub const SPEED_LOOP_DECIMATION: u32 = 1;

/// [`SpeedDesign::reference_weight`] of the IP form of Khlaief, Boussak, Gossa (2012): the
/// proportional action on the estimated speed only.
pub const IP_FORM: f64 = 0.0;
/// [`SpeedDesign::reference_weight`] of the PI form: the proportional action on the error.
pub const PI_FORM: f64 = 1.0;

/// How the speed controller is designed; [`SpeedDesign::default_for`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct SpeedDesign {
    /// Natural frequency `ω_n` of the speed loop, rad/s.
    pub bandwidth_rad_s: f64,
    /// Damping `ζ` (≥ 1: no overshoot).
    pub damping: f64,
    /// Current limit `I_max`, A peak.
    pub current_limit_a: f64,
    /// The speed loop runs once every `decimation` control samples (≥ 1; the drive's task
    /// runs it once per task period, so the drive takes `TASK_PERIOD`, docs/drive.md, "two
    /// rates"); the gains are designed for that period.
    pub decimation: u32,
    /// `(K_iΩ, K_pΩ)` in A/(rad/s · s) and A/(rad/s) of electrical speed, overriding the
    /// design from `ω_n` and `ζ`.
    pub gains: Option<(f64, f64)>,
    /// The share `b` of the reference in the proportional action, in `[0, 1]`:
    /// `i_q* = K_iΩ ∫(ω* − ω̂) dt + K_pΩ (b ω* − ω̂)` (module docs, "following a ramp"):
    /// [`IP_FORM`] (0, Khlaief, Boussak, Gossa (2012)) follows a ramp `≈ 2ζα/ω_n` late without
    /// overshoot, [`PI_FORM`] (1) without lag, overshooting its end; in between, `(1 − b)` of
    /// the lag.
    pub reference_weight: f64,
}

impl SpeedDesign {
    /// `ω_n = 0.005/T_s`, `ζ = 1`, `I_max = I_b` (rated peak), once every
    /// [`SPEED_LOOP_DECIMATION`] samples, the IP form (the drive's default for the
    /// current-model MRAS weighs the reference by a half: `DriveDesign::default_for`).
    pub fn default_for(base: &PerUnit) -> Self {
        Self {
            bandwidth_rad_s: DEFAULT_BANDWIDTH_TS / base.sample_s,
            damping: 1.0,
            current_limit_a: base.current_a,
            decimation: SPEED_LOOP_DECIMATION,
            gains: None,
            reference_weight: IP_FORM,
        }
    }
}

/// Configuration of the [`SpeedController`].
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct SpeedConfig {
    /// `K_iΩ T` per unit.
    ki_t: Coef<KI_FRAC>,
    /// `−K_pΩ` per unit (negated: `ff = −K_pΩ ω̂` without a negation per sample).
    neg_kp: Coef<KP_FRAC>,
    /// `−b K_pΩ` per unit: the reference's part ([`SpeedController::move_reference`]).
    neg_kp_ref: Coef<KP_FRAC>,
    /// `I_max` per unit.
    i_max: Pu,
    /// Gains used, SI: `(K_iΩ, K_pΩ)`.
    pub gains_si: (f64, f64),
    /// The design.
    pub design: SpeedDesign,
}

impl SpeedConfig {
    /// Designs the IP controller for `motor` and the bases `base`.
    ///
    /// Errors ([`ConfigError::Gain`]): `speed.bandwidth_rad_s` outside `(0, 0.2/T]`,
    /// `speed.damping` outside `[0.3, 10]`, `speed.ki` or `speed.kp` negative or beyond the
    /// per-unit range (`K_iΩ T ω_b/I_b` 0 or in [2⁻²³, 1), `K_pΩ ω_b/I_b` < 2¹⁴; in SI units
    /// in the error); [`ConfigError::Param`] for `speed.current_limit_a` (in `(0, 64 I_b]`)
    /// or `speed.decimation` (in 1..=1000). Out of line: the drive designs several loops.
    #[inline(never)]
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        design: SpeedDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        in_range("speed.decimation", design.decimation as f64, 1.0, 1000.0)?;
        let b = in_range("speed.reference_weight", design.reference_weight, 0.0, 1.0)?;
        let t = base.sample_s * design.decimation as f64;
        let i_max_a = in_range(
            "speed.current_limit_a",
            design.current_limit_a,
            1e-9,
            64.0 * base.current_a,
        )?;
        let k = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        let b_j = motor.b_nm_s / motor.j_kg_m2;
        let (ki, kp) = match design.gains {
            Some(g) => g,
            None => {
                let wn = gain_in(
                    "speed.bandwidth_rad_s",
                    design.bandwidth_rad_s,
                    1e-9,
                    0.2 / t,
                )?;
                let zeta = gain_in("speed.damping", design.damping, 0.3, 10.0)?;
                (wn * wn / k, ((2.0 * zeta * wn - b_j) / k).max(0.0))
            }
        };
        let (wb, ib) = (base.omega_e_rad_s, base.current_a);
        // Per-unit: i_q/I_b = K (ω/ω_b) ω_b/I_b.
        // The negation of a representable non-negative value is representable, and so is a
        // share of it (b ≤ 1; rounded toward zero).
        let neg_kp = Coef::new(
            -coef_in::<KP_FRAC>("speed.kp", kp * wb / ib, (0.0, f64::MAX), true, ib / wb)?.to_f64(),
        )
        .unwrap_or(Coef::ZERO);
        Ok(Self {
            ki_t: coef_in(
                "speed.ki",
                ki * t * wb / ib,
                (KI_MIN, KI_MAX),
                true,
                ib / (t * wb),
            )?,
            neg_kp,
            neg_kp_ref: Coef::from_bits((f64::from(neg_kp.bits()) * b) as i32),
            i_max: pu_from_f64(i_max_a / ib),
            gains_si: (ki, kp),
            design,
        })
    }
}

/// The fixed-point gains and limit of a [`SpeedConfig`], without its design: what the drive
/// keeps of the other loops it switches to ([`SpeedController::retune_gains`]).
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub(crate) struct SpeedGains {
    ki_t: Coef<KI_FRAC>,
    neg_kp: Coef<KP_FRAC>,
    neg_kp_ref: Coef<KP_FRAC>,
    i_max: Pu,
}

impl SpeedConfig {
    /// The fixed-point gains and limit.
    pub(crate) fn gains(&self) -> SpeedGains {
        SpeedGains {
            ki_t: self.ki_t,
            neg_kp: self.neg_kp,
            neg_kp_ref: self.neg_kp_ref,
            i_max: self.i_max,
        }
    }

    /// `K_pΩ ω_b/I_b` as stored (per unit; for f64 models of the fixed-point loop).
    pub fn kp_pu(&self) -> f64 {
        -self.neg_kp.to_f64()
    }

    /// `b K_pΩ ω_b/I_b` as stored: the reference's part of the proportional action.
    pub fn kp_ref_pu(&self) -> f64 {
        -self.neg_kp_ref.to_f64()
    }

    /// `K_iΩ T ω_b/I_b` as stored (per unit).
    pub fn ki_t_pu(&self) -> f64 {
        self.ki_t.to_f64()
    }

    /// `I_max` per unit.
    pub fn i_max(&self) -> Pu {
        self.i_max
    }
}

/// Output of the speed controller.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SpeedOutput {
    /// q-current reference, per unit of `I_b`, within `±I_max`.
    pub iq_ref: Pu,
    /// The reference was clamped to the current limit.
    pub saturated: bool,
}

/// The IP speed controller: configuration and state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedController {
    /// The gains in use (of the [`SpeedConfig`] it was built or retuned with; its design
    /// data, `f64`, is not kept).
    config: SpeedGains,
    /// Output of the last step, Q8.56 (high word: [`Pu`]; see the module docs).
    s: i64,
    /// `ff = −K_pΩ ω̂` of the last step.
    ff: Pu,
    /// The output's limit, `≤ I_max`: lowered by the drive to the current circle's `|i_q|`
    /// room when `i_d ≠ 0` (MTPA, field weakening), so that the integrator stops there.
    limit: Pu,
}

/// Shift from [`Pu`] to the Q8.56 state.
const S_SHIFT: u32 = 32;

impl SpeedController {
    /// Controller with zero integral state.
    pub fn new(config: SpeedConfig) -> Self {
        Self {
            s: 0,
            ff: Pu::ZERO,
            limit: config.i_max,
            config: config.gains(),
        }
    }

    /// Bumpless restart at speed `omega` with current `iq` flowing: sets the integrator to
    /// `iq + K_pΩ ω` (`iq` clamped to `±I_max`), the limit back to `I_max`.
    pub fn reset(&mut self, omega: Pu, iq: Pu) {
        let c = &self.config;
        self.ff = c.neg_kp.apply(omega);
        self.limit = c.i_max;
        self.s = (iq.max(-c.i_max).min(c.i_max).to_bits() as i64) << S_SHIFT;
    }

    /// Takes the gains of `config` without a bump: the output stays, the proportional
    /// action's memory is the new gain's at the speed `omega` it last saw, the limit at most
    /// the new `I_max`.
    pub fn retune(&mut self, config: SpeedConfig, omega: Pu) {
        self.retune_gains(config.gains(), omega);
    }

    /// [`SpeedController::retune`] to the fixed-point `gains`.
    pub(crate) fn retune_gains(&mut self, gains: SpeedGains, omega: Pu) {
        self.ff = gains.neg_kp.apply(omega);
        self.limit = self.limit.min(gains.i_max);
        self.config = gains;
    }

    /// The reference moved from `from` to `to`: adds `b K_pΩ (to − from)` to the output
    /// ([`SpeedDesign::reference_weight`]; nothing in the IP form), clamped to the limit, as a
    /// step at the reference's change would. The step itself stays the IP's, so the
    /// reference's part costs the control path nothing: it acts where the reference is set.
    pub fn move_reference(&mut self, from: Pu, to: Pu) {
        let c = &self.config;
        if c.neg_kp_ref == Coef::ZERO {
            return;
        }
        // −b K_pΩ (from − to) exact (LSB 2⁻⁴¹, |·| < 2⁶²), added to the state at that LSB
        // and its 15 lower bits kept: a reference moved in many small steps adds up to its
        // whole move (a kick rounded at every step would drift by up to ½ LSB each).
        const LOW: u32 = S_SHIFT - KP_FRAC;
        let kick = c.neg_kp_ref.wide(from.saturating_sub(to).to_bits());
        let sum = (self.s >> LOW) + kick;
        let limit = (self.limit.to_bits() as i64) << KP_FRAC;
        self.s = if sum >= limit {
            limit << LOW
        } else if sum <= -limit {
            -limit << LOW
        } else {
            (sum << LOW) | (self.s & ((1 << LOW) - 1))
        };
    }

    /// Whether the output `iq_ref` of the last step is at the limit, within 1/64 of it: a loop
    /// held against its limit hovers just inside, its proportional action moving with the
    /// speed's ripple (2.90713 A against 2.90726 on a motor of the random family).
    pub fn at_limit(&self, iq_ref: Pu) -> bool {
        let limit = self.limit.to_bits();
        iq_ref.to_bits().saturating_abs() >= limit - (limit >> 6)
    }

    /// Moves the output by `delta` (a feed-forward's change) within `±I_max`; the next step
    /// starts from it and clamps to the limit.
    pub fn shift_output(&mut self, delta: Pu) {
        let i_max = self.config.i_max.to_bits();
        let high = ((self.s >> S_SHIFT) as i32).saturating_add(delta.to_bits());
        let high = high.max(-i_max).min(i_max);
        self.s = ((high as i64) << S_SHIFT) | (self.s & 0xffff_ffff);
    }

    /// Sets the output's limit to `limit` within `[0, I_max]`; the next step clamps to it.
    pub fn set_limit(&mut self, limit: Pu) {
        self.limit = limit.min(self.config.i_max).max(Pu::ZERO);
    }

    /// One speed-loop sample (every `decimation` control samples). Integer only; never
    /// panics.
    pub fn step(&mut self, omega_ref: Pu, omega: Pu) -> SpeedOutput {
        let c = &self.config;
        let e = omega_ref.saturating_sub(omega).to_bits();
        let ff = c.neg_kp.apply(omega);
        let dff = ff.to_bits().saturating_sub(self.ff.to_bits());
        self.ff = ff;
        // u_raw = s + Δff: the high word (a Pu) saturated, the fraction unchanged. With
        // |s| ≤ I_max ≤ 64 pu a saturated sum is beyond the limits on the same side, so the
        // decisions and the clamp are the same as with the exact sum.
        let (high, low) = ((self.s >> S_SHIFT) as i32, self.s as u32);
        let high = high.saturating_add(dff);
        let (hi, lo) = (self.limit.to_bits(), -self.limit.to_bits());
        let (up, down) = (e > 0, e < 0);
        // u_raw ≥ I_max ⟺ high ≥ hi; u_raw ≤ −I_max ⟺ high < lo, or high = lo and no fraction.
        let stop = (high >= hi && up) || ((high < lo || (high == lo && low == 0)) && down);
        // K_iΩ T e, exact (|·| < 2⁶²), in the state's LSB 2⁻⁵⁶, saturated: beyond 2⁶³ it is
        // far beyond the limit, where the clamp below takes it.
        let inc = if stop {
            0
        } else {
            c.ki_t.wide(e).saturating_mul(1 << (S_SHIFT - KI_FRAC))
        };
        // u_raw + inc with the high word saturated, then the clamp on the high word.
        let (low, carry) = low.overflowing_add(inc as u32);
        let high = high
            .saturating_add((inc >> 32) as i32)
            .saturating_add(carry as i32);
        let (s, clamped) = if high >= hi {
            ((hi as i64) << S_SHIFT, high != hi || low != 0)
        } else if high < lo {
            ((lo as i64) << S_SHIFT, true)
        } else {
            (((high as i64) << S_SHIFT) | low as i64, false)
        };
        self.s = s;
        // s ∈ [−I_max, I_max]: the high word plus the rounding bit stays inside.
        let iq = (s >> S_SHIFT) as i32 + ((s as u32) >> (S_SHIFT - 1)) as i32;
        SpeedOutput {
            iq_ref: Pu::from_bits(iq),
            saturated: clamped
                || (s == (hi as i64) << S_SHIFT && up)
                || (s == (lo as i64) << S_SHIFT && down),
        }
    }
}
