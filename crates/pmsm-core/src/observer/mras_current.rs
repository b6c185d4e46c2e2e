//! Current-model MRAS speed and position estimator of seed 001 (eq. 14–23, equations.md §4.1).
//!
//! The measured currents are taken to the **estimated** rotor frame (`θ̂`) and compared with
//! an adjustable model of the motor run in that frame at the estimated speed:
//!
//! ```text
//! dî_d/dt = −(R/L_d) î_d + (L_q/L_d) ω̂ î_q + v_d/L_d                      (eq. 15)
//! dî_q/dt = −(R/L_q) î_q − (L_d/L_q) ω̂ î_d − (ψ/L_q) ω̂ + v_q/L_q
//! ε_d = i_d − î_d,   ε_q = i_q − î_q                                          (eq. 16)
//! ξ = (L_q/L_d) i_q ε_d − (L_d/L_q) i_d ε_q − (ψ/L_q) ε_q                     (eq. 21–22)
//! ω̂ = K_i ∫ξ dt + K_p ξ,   θ̂ = ∫ω̂ dt + θ_0                                   (eq. 22–23)
//! ```
//!
//! The estimator works with `ξ̃ = (L_q/L_d) ξ = (L_q/L_d)² i_q ε_d − (i_d + ψ/L_d) ε_q` (one
//! weight fewer), with `K_p`, `K_i` and the load gain rescaled to match: the same eq. 22.
//!
//! # Sign of ξ
//!
//! With `ε = i − î`, a rotor ahead of the estimate (`δ = θ − θ̂ > 0`) or faster than it
//! (`ω > ω̂`) gives `ξ > 0` at any speed away from zero: the back-EMF error they cause,
//! `ψ ω (−sin δ, cos δ) − ψ ω̂ (0, 1)`, drives `ε_q < 0` through the q inductance, and
//! `−(ψ/L_q) ε_q` dominates ξ. So `ω̂` grows and `θ̂` catches up: the stated sign is the
//! stable one. Checked against the plant (`tests/drive_parts_mras.rs`: the estimate converges
//! from ±20° at ±800 r/min, motoring and generating).
//!
//! # Discretisation
//!
//! In flux coordinates, `λ = (L_d î_d + ψ, L_q î_q)`, the model is a decay through `R`, a drive
//! by `v`, and a pure rotation by `−ω̂ t` (the frame turning under a fixed flux):
//! `dλ/dt = −R î + v + ω̂ (λ_q, −λ_d)`. One sample is a Strang splitting of the two parts, each
//! solved exactly:
//!
//! 1. half an R–L step in the frame at `θ̂_{k−1}`: `î ← a î + g v_dq(θ̂_{k−1})`,
//!    `a = e^{−R T_s/(2L)}`, `g = (1 − a)/R` (zero-order hold: matched pole, exact for a held
//!    voltage);
//! 2. the exact rotation of `λ` by `−Δ`, `Δ = ω̂ T_s`, written in currents:
//!    `î_d ← c î_d + s (L_q/L_d) î_q − (1 − c) ψ/L_d`, `î_q ← c î_q − s (L_d/L_q) î_d − s ψ/L_q`
//!    (`s, c = sin Δ, cos Δ`);
//! 3. half an R–L step in the frame at `θ̂_k = θ̂_{k−1} + Δ`.
//!
//! The three maps are affine, and the voltage of step 3 is that of step 1 turned by the same
//! `Δ` (`v_dq(θ̂_k) = (c v_d + s v_q, c v_q − s v_d)` with `v = v_dq(θ̂_{k−1})`), so one sample
//! is computed as their composition, exactly (with `ρ = L_q/L_d`, `Ψ_d = a_d ψ/L_d`,
//! `Ψ_q = a_q ψ/L_q`):
//!
//! ```text
//! X_d = a_d² î_d + (1 + a_d) g_d v_d + Ψ_d      X_q = a_d a_q ρ î_q + (a_d ρ g_q + g_d) v_q
//! Y_q = a_q² î_q + (1 + a_q) g_q v_q            Y_d = (a_q a_d/ρ) î_d + (a_q g_d/ρ + g_q) v_d + Ψ_q
//! î_d ← c X_d + s X_q − Ψ_d                     î_q ← c Y_q − s Y_d
//! ```
//!
//! (expand `a (rotation of (a î + g v)) + g v_dq(θ̂_k)` and collect `c` and `s`): one Park
//! transform of `v` instead of two, and eight weights, each applied once with one rounding
//! per pair, instead of the twenty-odd products of the three steps done one after the other.
//!
//! The splitting error is third order per step; forward Euler on eq. 15 would instead inflate
//! the model's EMF by `√(1 + Δ²)` and mis-damp it by `R T_s/L`, both of which the adaptation
//! reads as a speed and position error. The f64 reference of this scheme (in
//! `tests/support/drive_ref.rs`) settles within 0.004° at 800 r/min on motor B.
//!
//! The voltage of the input was applied over `[t_{k−1}, t_k)` (see [`super`]'s timing
//! convention) and is constant in the stationary frame: its rotor-frame value is taken at the
//! frame angle of each half step. `θ̂` advances with the `ω̂` held over the same interval, so
//! the model frame and the estimate are the same frame.
//!
//! # Gains
//!
//! Near `δ = 0` and away from zero speed, `ξ ≈ k_δ δ + k_ω (ω − ω̂)`; at high speed
//! `k_δ → k_∞ = (ψ/L_q)²` (A²/rad). The PI on ξ closes a phase-locked loop on `θ`; at high
//! speed its characteristic polynomial is `s² + K_p k_∞ s + K_i k_∞`, so for a natural
//! frequency `ω_n` and damping 1:
//!
//! ```text
//! K_p = 2 ω_n / k_∞,   K_i = ω_n² / k_∞,   k_∞ = (ψ/L_q)²
//! ```
//!
//! Default `ω_n = 0.02/T_s` (280 rad/s at 14 kHz). At low speed `k_δ` falls roughly as
//! `ω² L_q²/(R² + ω² L_q²)` and the loop slows (the slowest mode tends to `ω² L_q/R` as the
//! gains grow), which is the MRAS's known weakness near standstill; the position error at
//! steady state is still zero with exact parameters. Accepted range:
//! `K_p ∈ [0, 1/(k_∞ T_s)]`, `K_i ∈ [0, 0.25/(k_∞ T_s²)]`, and within the formats of their
//! per-unit values ("Formats").
//!
//! The PI is the estimator's own: `ω̂ = clamp(K_p ξ + I, ±ω_max)`, the feed-forward of the
//! mechanical model and `K_i T_s ξ` added to `I` every sample, `I` clamped to `±ω_max`. While
//! `K_p ξ + I` (before the integration) is on or beyond a limit, the integrator is
//! back-calculated, `I ← I + K_i T_s ξ + k_t (clamp − (K_p ξ + I))`, `k_t = min(1, K_i T_s/K_p)`
//! (with `K_p = 0`: no integration that pushes further out).
//!
//! # Through zero speed
//!
//! Near standstill ξ carries almost no information on the position (the EMF error vanishes
//! with ω), and a speed that changes sign under load drags the estimate away. The mechanical
//! model knows how the speed changes: the measured torque current accelerates the rotor by
//! `a (i_q − i_L) − (B/J) ω̂`, `a = p K_T/J` (equations.md §1), where `i_L` is the load seen as
//! a current. Every sample that acceleration is added to the speed integrator, and the load
//! estimate follows `dî_L/dt = −K_L ξ` (a rotor ahead of the estimate means less load than
//! assumed). Linearised, `ξ ≈ k δ`, the position error obeys
//! `δ‴ + K_p k δ″ + K_i k δ′ + a K_L k δ = 0`; [`MrasCurrentGains::design`] places its poles.
//! Through zero speed `k → 0`: the loop opens, and the model carries the estimate with the load
//! learned before, so a reversal under a load that does not reverse with it keeps its lock.
//! `K_L = 0` gives the plain MRAS of seed 001.
//!
//! # Formats
//!
//! Every per-sample product has a compile-time binary point ([`Coef`]): one multiply, a
//! constant shift and a high-word fit test. The coefficient groups and their ranges (checked
//! by [`MrasCurrentConfig::new`], which names the motor parameter or gain of a coefficient
//! that does not fit; the motor family of [`crate::units`] spans the "family" column):
//!
//! | signal or coefficient | format | range accepted | family |
//! |---|---|---|---|
//! | `î`, `i`, `v`, `ε`, `X`, `Y` | [`Pu`] Q8.24 | ±128 | per unit of `I_b`, `V_b` |
//! | sin/cos of `θ̂` and of `Δ` | [`Unit`] Q2.30 | ±1 | |
//! | model weights `a_d²`, `(1 + a_d) g_d`, `a_d a_q ρ`, `a_d ρ g_q + g_d`, `a_q²`, `(1 + a_q) g_q`, `a_q a_d/ρ`, `a_q g_d/ρ + g_q` | `Coef<28>` (LSB 3.7e−9) | [0, 4] (so `L_q/L_d` within about [¼, 4]) | [0.016, 1.66] |
//! | offsets `a_d ψ/L_d`, `a_q ψ/L_q`; `ψ/L_d` of ξ̃ | [`Pu`] Q8.24 | [0, 32] | [0.047, 7.1] |
//! | `ρ² = (L_q/L_d)²` | `Coef<26>` | [0, 16] | [1, 2.8] |
//! | `ξ̃ = (L_q/L_d) ξ` | [`Pu`] Q8.24 | ±128 | per unit of `I_b²` |
//! | `K_p` on ξ̃ | `Coef<24>` | [0, 128) | default [0.033, 58] |
//! | `K_i T_s`, `T_s a`, `T_s B/J` on ξ̃, `i_q − i_L`, `ω̂` | `Coef<31>`, exact products | `K_i T_s` [0, 1), the other two [0, 1/16] | [4.4e−4, 0.78], [5.6e−5, 0.014], [1e−6, 4.6e−5] |
//! | speed integrator `I` | `i64` Q9.55 (LSB = the exact product's) | clamped to `±ω_max` (≤ 4 pu) | |
//! | `T_s K_L I_b/ρ` (load estimate) | `Coef<27>` | [0, 16) | default [0.001, 0.58] |
//! | `i_L` | [`Pu`] Q8.24 | ±128 | |
//! | `ω̂` | [`Pu`] Q8.24 | `±ω_max` | per unit of `ω_b` |
//! | `θ̂` | `u64` turn, 2⁶⁴ per turn | wraps | the top 32 bits are the [`Angle`] |
//! | `ω_b T_s 2³³/(2π)` (angle step per unit of speed, ×2⁷) | `i32` | `ω_b T_s ≤ 1` rad | |
//!
//! Overflow: every weight above is at most 2³⁰ in bits, so a sum of two products and an
//! offset stays below 2⁶² (the rounding kernel's contract is 2⁶³ − 2³²); the bounds of the
//! integrator are given beside the code.

use super::{Estimate, Estimator, ObserverInput};
use crate::angle::{Angle, SinCos};
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, Dq};
use crate::num::{Coef, PU_FRAC, Pu, UNIT_FRAC, Unit, pu_from_f64, round_shift_sat, wmul_inline};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Default `ω_n T_s` of the adaptation loop.
pub const DEFAULT_BANDWIDTH_TS: f64 = 0.02;

/// Largest estimated speed, per unit of `ω_b` (also at most 1 rad per sample).
pub const MAX_SPEED_PU: f64 = 4.0;

/// Binary point of the model weights (module docs, "Formats").
const MODEL_FRAC: u32 = 28;
/// Largest model weight.
const MODEL_MAX: f64 = 4.0;
/// Largest offset `ψ/L` (per unit): with the signals below 4 pu, `X_d`, `Y_d` and
/// `i_d + ψ/L_d` stay far inside Q8.24.
const OFFSET_MAX: f64 = 32.0;
/// Fractional bits of the speed integrator (Q9.55): the LSB of a `Coef<31>` times a [`Pu`].
const INTEG_FRAC: u32 = 55;
/// Extra fractional bits of the integrator over [`Pu`].
const INTEG_EXTRA: u32 = INTEG_FRAC - PU_FRAC;
/// Largest `T_s a` and `T_s B/J`: keeps the feed-forward below 2⁵⁸ (see `update`).
const MECH_MAX: f64 = 1.0 / 16.0;
/// The angle step is `ω · turn_per_speed · 2^TURN_SHIFT` (2⁻⁶⁴ turn).
const TURN_SHIFT: u32 = 7;

/// Adaptation gains of eq. 22 in SI units (ξ in A²): `K_p` in (rad/s)/A², `K_i` in
/// (rad/s²)/A², electrical speed; and the gain of the load-current estimate of the mechanical
/// model (module docs, "Through zero speed").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrasCurrentGains {
    /// Proportional gain `K_pω_r-est`.
    pub kp: f64,
    /// Integral gain `K_iω_r-est`.
    pub ki: f64,
    /// Gain `K_L` of the load-current estimate, A/(A²·s); zero turns the mechanical model off
    /// (the plain MRAS of seed 001).
    pub kl: f64,
}

impl MrasCurrentGains {
    /// High-speed sensitivity of ξ to the position error, `k_∞ = (ψ/L_q)²`, A²/rad.
    pub fn k_inf(motor: &MotorParams) -> f64 {
        let r = motor.flux_wb / motor.lq_h;
        r * r
    }

    /// Design for natural frequency `ω_n = bandwidth_rad_s` (module docs): a critically damped
    /// pair at `ω_n` and the load estimate's pole at `ω_L = ω_n/4`,
    /// `(s² + 2ω_n s + ω_n²)(s + ω_L)`, with `a = p K_T/J`:
    /// `K_p = (2ω_n + ω_L)/k_∞`, `K_i = (ω_n² + 2ω_n ω_L)/k_∞`, `K_L = ω_n² ω_L/(a k_∞)`.
    pub fn design(motor: &MotorParams, bandwidth_rad_s: f64) -> Self {
        let k = Self::k_inf(motor);
        let (wn, wl) = (bandwidth_rad_s, 0.25 * bandwidth_rad_s);
        let a = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        Self {
            kp: (2.0 * wn + wl) / k,
            ki: (wn * wn + 2.0 * wn * wl) / k,
            kl: wn * wn * wl / (a * k),
        }
    }

    /// [`MrasCurrentGains::design`] at `ω_n = 0.02/T_s`.
    pub fn default_for(motor: &MotorParams, base: &PerUnit) -> Self {
        Self::design(motor, DEFAULT_BANDWIDTH_TS / base.sample_s)
    }
}

/// Configuration of the [`MrasCurrent`] estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrasCurrentConfig {
    /// Weights of the composed Strang step (module docs, "Discretisation"):
    /// `X_d = xd_i î_d + xd_v v_d + Ψ_d`, `X_q = xq_i î_q + xq_v v_q`,
    /// `Y_q = yq_i î_q + yq_v v_q`, `Y_d = yd_i î_d + yd_v v_d + Ψ_q`.
    xd_i: Coef<MODEL_FRAC>,
    xd_v: Coef<MODEL_FRAC>,
    xq_i: Coef<MODEL_FRAC>,
    xq_v: Coef<MODEL_FRAC>,
    yq_i: Coef<MODEL_FRAC>,
    yq_v: Coef<MODEL_FRAC>,
    yd_i: Coef<MODEL_FRAC>,
    yd_v: Coef<MODEL_FRAC>,
    /// `Ψ_d = a_d ψ/L_d` in Q8.24, and the same in the weights' accumulator (`× 2^MODEL_FRAC`).
    off_d: Pu,
    off_d_acc: i64,
    /// `Ψ_q = a_q ψ/L_q` in the weights' accumulator.
    off_q_acc: i64,
    /// `ρ² = (L_q/L_d)²` and `ψ/L_d` of ξ̃ (eq. 22 × L_q/L_d).
    rho2: Coef<26>,
    psi_ld: Pu,
    /// `ξ' = (L_d/ψ) ξ̃`, for [`MrasCurrent::xi`] only.
    xi_scale: Coef<24>,
    /// Angle step per unit of speed: `ω_b T_s 2³³/(2π)`; times `2^TURN_SHIFT` gives 2⁻⁶⁴ turns.
    turn_per_speed: i32,
    /// Speed integrator (Q9.55 increments): `K_i T_s`, `T_s p K_T I_b/(J ω_b)`, `T_s B/J`.
    ki_ts: Coef<31>,
    accel: Coef<31>,
    friction: Coef<31>,
    /// Proportional gain on ξ̃, and the back-calculation gain `min(1, K_i T_s/K_p)` (zero:
    /// `K_p = 0`, conditional integration).
    kp: Coef<24>,
    kt: Coef<30>,
    /// Load-current estimate change per sample per unit of ξ̃, `T_s K_L I_b/ρ` (per unit).
    load_gain: Coef<27>,
    /// Speed clamp, per unit, and in Q9.55.
    omega_max: Pu,
    omega_max_wide: i64,
    /// Gains it was built with.
    pub gains: MrasCurrentGains,
}

/// `value` as a `Coef<F>` if it is in `[min, max]` and representable, else the typed error
/// naming `key` (the motor parameter or gain the coefficient comes from).
fn coef<const F: u32>(
    key: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<Coef<F>, ConfigError> {
    let err = ConfigError::Gain {
        key,
        value,
        min,
        max,
    };
    if !(value >= min && value <= max) {
        return Err(err);
    }
    Coef::new(value).ok_or(err)
}

/// A per-unit constant in `[min, max]` as [`Pu`], else the typed error naming `key`.
fn pu_in(key: &'static str, value: f64, min: f64, max: f64) -> Result<Pu, ConfigError> {
    if value >= min && value <= max {
        Ok(pu_from_f64(value))
    } else {
        Err(ConfigError::Gain {
            key,
            value,
            min,
            max,
        })
    }
}

impl MrasCurrentConfig {
    /// Estimator for `motor` sampled as in `base`, with adaptation gains `gains`
    /// ([`MrasCurrentGains::default_for`] for the defaults).
    ///
    /// Errors: [`ConfigError::Param`] for a bad motor parameter; [`ConfigError::Gain`] naming
    /// `mras_current.kp`, `mras_current.ki` or `mras_current.kl` outside the ranges of the
    /// module docs, or naming the motor parameter (`ld_h`, `lq_h`, `j_kg_m2`, `b_nm_s`,
    /// `sample_hz`) of a coefficient outside its format (module docs, "Formats").
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        gains: MrasCurrentGains,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let ts = base.sample_s;
        let k_inf = MrasCurrentGains::k_inf(motor);
        let kp_max = 1.0 / (k_inf * ts);
        let ki_max = 0.25 / (k_inf * ts * ts);
        let a = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        let kl_max = 0.1 / (a * k_inf * ts * ts * ts);
        for (key, v, max) in [
            ("mras_current.kp", gains.kp, kp_max),
            ("mras_current.ki", gains.ki, ki_max),
            ("mras_current.kl", gains.kl, kl_max),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(ConfigError::Gain {
                    key,
                    value: v,
                    min: 0.0,
                    max,
                });
            }
        }
        let mech = gains.kl > 0.0;
        let (r, ld, lq, psi) = (
            motor.rs_ohm / base.impedance_ohm,
            motor.ld_h / base.inductance_h,
            motor.lq_h / base.inductance_h,
            motor.flux_wb / base.flux_wb,
        );
        let rho = lq / ld;
        let a_d = libm::exp(-0.5 * motor.rs_ohm * ts / motor.ld_h);
        let a_q = libm::exp(-0.5 * motor.rs_ohm * ts / motor.lq_h);
        let (g_d, g_q) = ((1.0 - a_d) / r, (1.0 - a_q) / r);
        let (psi_d, psi_q) = (psi / ld, psi / lq);
        let m = |key, v| coef::<MODEL_FRAC>(key, v, 0.0, MODEL_MAX);
        let off_d = pu_in("ld_h", a_d * psi_d, 0.0, OFFSET_MAX)?;
        let off_q = pu_in("lq_h", a_q * psi_q, 0.0, OFFSET_MAX)?;
        // ξ̃ = (L_q/L_d) ξ: gains on ξ̃ are the SI gains times I_b²/(ρ ω_b) (ξ in A², ω in pu).
        let scale = base.current_a * base.current_a / (rho * base.omega_e_rad_s);
        let omega_max = MAX_SPEED_PU.min(1.0 / (base.omega_e_rad_s * ts));
        // The per-unit formats bound the SI gains too (errors in SI units, as given).
        let kp = Coef::<24>::new(gains.kp * scale).ok_or(gain_err(
            "mras_current.kp",
            gains.kp,
            Coef::<24>::limit() / scale,
        ))?;
        let ki_ts = Coef::<31>::new(gains.ki * ts * scale).ok_or(gain_err(
            "mras_current.ki",
            gains.ki,
            Coef::<31>::limit() / (ts * scale),
        ))?;
        let load_scale = ts * base.current_a / rho;
        let load_gain = Coef::<27>::new(gains.kl * load_scale).ok_or(gain_err(
            "mras_current.kl",
            gains.kl,
            Coef::<27>::limit() / load_scale,
        ))?;
        // Back-calculation gain from the stored values (as the f64 model of a PI would).
        let kt = if kp.bits() > 0 {
            Coef::new((ki_ts.to_f64() / kp.to_f64()).min(1.0)).unwrap_or(Coef::ZERO)
        } else {
            Coef::ZERO
        };
        let accel = if mech {
            ts * motor.p() * motor.kt_nm_per_a * base.current_a
                / (motor.j_kg_m2 * base.omega_e_rad_s)
        } else {
            0.0
        };
        let friction = if mech {
            ts * motor.b_nm_s / motor.j_kg_m2
        } else {
            0.0
        };
        // ω_b T_s ≤ 1 rad (the envelope of `PerUnit`) keeps this below 2^31.
        let turn =
            libm::round(base.omega_e_rad_s * ts * libm::ldexp(1.0, 33) / core::f64::consts::TAU);
        let turn_max = i32::MAX as f64;
        if !(turn >= 0.0 && turn <= turn_max) {
            return Err(ConfigError::Gain {
                key: "sample_hz",
                value: 1.0 / ts,
                min: base.omega_e_rad_s * libm::ldexp(1.0, 33)
                    / (core::f64::consts::TAU * turn_max),
                max: f64::INFINITY,
            });
        }
        let turn_per_speed = turn as i32;
        Ok(Self {
            xd_i: m("ld_h", a_d * a_d)?,
            xd_v: m("ld_h", (1.0 + a_d) * g_d)?,
            xq_i: m("lq_h", a_d * a_q * rho)?,
            xq_v: m("lq_h", a_d * rho * g_q + g_d)?,
            yq_i: m("lq_h", a_q * a_q)?,
            yq_v: m("lq_h", (1.0 + a_q) * g_q)?,
            yd_i: m("ld_h", a_q * a_d / rho)?,
            yd_v: m("ld_h", a_q * g_d / rho + g_q)?,
            off_d,
            off_d_acc: (off_d.to_bits() as i64) << MODEL_FRAC,
            off_q_acc: (off_q.to_bits() as i64) << MODEL_FRAC,
            rho2: coef("lq_h", rho * rho, 0.0, 16.0)?,
            psi_ld: pu_in("ld_h", psi_d, 0.0, OFFSET_MAX)?,
            xi_scale: coef("ld_h", ld / psi, 0.0, Coef::<24>::limit())?,
            turn_per_speed,
            ki_ts,
            accel: coef("j_kg_m2", accel, 0.0, MECH_MAX)?,
            friction: coef("b_nm_s", friction, 0.0, MECH_MAX)?,
            kp,
            kt,
            load_gain,
            omega_max: pu_from_f64(omega_max),
            omega_max_wide: (pu_from_f64(omega_max).to_bits() as i64) << INTEG_EXTRA,
            gains,
        })
    }
}

/// The error for an SI gain whose per-unit coefficient does not fit its format.
fn gain_err(key: &'static str, value: f64, max: f64) -> ConfigError {
    ConfigError::Gain {
        key,
        value,
        min: 0.0,
        max,
    }
}

/// The current-model MRAS estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct MrasCurrent {
    config: MrasCurrentConfig,
    /// Adjustable-model current in the estimated frame.
    i_hat: Dq,
    /// Estimated angle of the last update, 2⁶⁴ per turn.
    theta: u64,
    /// sin/cos of the angle of the last update (the frame of `i_hat`).
    sc: SinCos,
    /// The angle of the next update, `θ̂ + ω̂ T_s` (eq. 23 with the speed held over the
    /// coming period), 2⁶⁴ per turn, and its sin/cos: computed at the end of an update, so
    /// that the drive turns its voltage to the coming period's mid angle from the two frames
    /// without a sin/cos of its own (see [`MrasCurrent::next_frame`]).
    theta_next: u64,
    sc_next: SinCos,
    /// The measured current of the last update in that frame (`park(i, sc)`).
    i_dq: Dq,
    /// Speed integrator `I`, Q9.55, within `±ω_max`.
    integ: i64,
    /// Adaptation signal ξ̃ = (L_q/L_d) ξ of the last update.
    xi: Pu,
    /// Load-current estimate of the mechanical model, per unit of `I_b`.
    i_load: Pu,
    /// The next update seeds the model with the measured current (after a reset).
    seed: bool,
    last: Estimate,
}

impl MrasCurrent {
    /// Estimator at `θ̂ = 0`, `ω̂ = 0`; call [`Estimator::reset`] with the initial position.
    pub fn new(config: MrasCurrentConfig) -> Self {
        let mut s = Self {
            config,
            i_hat: Dq::default(),
            theta: 0,
            sc: Angle::ZERO.sin_cos(),
            theta_next: 0,
            sc_next: Angle::ZERO.sin_cos(),
            i_dq: Dq::default(),
            integ: 0,
            xi: Pu::ZERO,
            i_load: Pu::ZERO,
            seed: true,
            last: Estimate::default(),
        };
        s.reset(Angle::ZERO, Pu::ZERO);
        s
    }

    /// The configuration.
    pub fn config(&self) -> &MrasCurrentConfig {
        &self.config
    }

    /// The adaptation signal of the last update, `ξ' = (L_q/ψ) ξ`, per unit of `I_b`
    /// (rounded from the ξ̃ the update works with).
    pub fn xi(&self) -> Pu {
        self.config.xi_scale.apply(self.xi)
    }

    /// The frame of the last estimate: `sin_cos(θ̂)` of [`Estimator::estimate`]'s angle (bit for
    /// bit what `estimate().theta.sin_cos()` gives) and the measured current of the last
    /// update rotated into it (bit for bit `park(i, sin_cos(θ̂))`; zero after a reset). The
    /// drive reuses both instead of computing them again.
    pub(crate) fn frame(&self) -> (SinCos, Dq) {
        (self.sc, self.i_dq)
    }

    /// sin/cos of the next update's frame angle, `θ̂ + ω̂ T_s` with the last estimate: the
    /// rotor frame at the end of the coming PWM period.
    pub(crate) fn next_frame(&self) -> SinCos {
        self.sc_next
    }

    /// Advances the next frame from the last update's angle by the speed `omega` held over the
    /// coming period.
    #[inline(always)]
    fn prepare_next(&mut self, omega: Pu) {
        let step = (wide(omega.to_bits(), self.config.turn_per_speed) as u64) << TURN_SHIFT;
        self.theta_next = self.theta.wrapping_add(step);
        self.sc_next = angle_of(self.theta_next).sin_cos();
    }

    fn angle(&self) -> Angle {
        angle_of(self.theta)
    }

    /// The estimate: angle and speed. The EMF is left at zero (the model does not estimate it;
    /// it is `ψ ω̂ (−sin θ̂, cos θ̂)` of these, for a caller that wants it).
    #[inline(always)]
    fn make_estimate(&self, omega: Pu) -> Estimate {
        Estimate {
            theta: self.angle(),
            omega,
            emf: AlphaBeta::default(),
        }
    }
}

/// The 2⁻⁶⁴ turn rounded to the nearest 2⁻³² turn.
#[inline(always)]
fn angle_of(theta: u64) -> Angle {
    Angle((theta.wrapping_add(1 << 31) >> 32) as u32 as i32)
}

// The products of one update, all inlined (also on ARMv6-M, where `wmul_inline` is the
// 16-bit-halves product: measured, calls to out-of-line kernels cost more than they save in
// register spills).

/// `x y`, exact.
#[inline(always)]
fn wide(x: i32, y: i32) -> i64 {
    wmul_inline(x, y)
}

/// `c x` rounded to nearest and saturated (a [`Coef`] times a [`Pu`] signal, in bits).
#[inline(always)]
fn apply<const F: u32>(c: i32, x: i32) -> i32 {
    round_shift_sat(wmul_inline(x, c), F)
}

/// `a x + b y + offset`, one rounding (`offset` in the accumulator's LSB, `2^−(24+F)`).
#[inline(always)]
fn mac<const F: u32>(a: i32, x: i32, b: i32, y: i32, offset: i64) -> i32 {
    // |a|, |b| ≤ 2^30 and |offset| ≤ 2^57 (module docs): the sum is below 2^62.
    round_shift_sat(wmul_inline(x, a) + wmul_inline(y, b) + offset, F)
}

/// `a u + b v` rounded by 2³⁰: a signal (or sin/cos) times sin/cos, whose magnitude is at
/// most 2³⁰ + 2²² in bits, so each product is below 2⁶¹.
#[inline(always)]
fn dot30(a: i32, u: i32, b: i32, v: i32) -> i32 {
    round_shift_sat(wmul_inline(a, u) + wmul_inline(b, v), UNIT_FRAC)
}

/// `−u` for a sin or cos (magnitude at most 2³⁰ + 2²² in bits: cannot wrap).
#[inline(always)]
fn neg(u: Unit) -> i32 {
    u.to_bits().wrapping_neg()
}

/// `c x` for a [`Coef`] and a [`Pu`] signal.
#[inline(always)]
fn coef_mul<const F: u32>(c: Coef<F>, x: Pu) -> Pu {
    Pu::from_bits(apply::<F>(c.bits(), x.to_bits()))
}

/// `a x + b y + offset` for two model weights.
#[inline(always)]
fn model_mac(a: Coef<MODEL_FRAC>, x: Pu, b: Coef<MODEL_FRAC>, y: Pu, offset: i64) -> Pu {
    Pu::from_bits(mac::<MODEL_FRAC>(
        a.bits(),
        x.to_bits(),
        b.bits(),
        y.to_bits(),
        offset,
    ))
}

/// Park's rotation to the frame of `sc`, as [`crate::frames::park`] (the same products and
/// rounding, so the same bits).
#[inline(always)]
fn park_in(v: AlphaBeta, sc: SinCos) -> Dq {
    let (a, b) = (v.alpha.to_bits(), v.beta.to_bits());
    let (s, c) = (sc.sin.to_bits(), sc.cos.to_bits());
    Dq {
        d: Pu::from_bits(dot30(a, c, b, s)),
        q: Pu::from_bits(dot30(b, c, a, neg(sc.sin))),
    }
}

/// sin/cos of the frame advance `Δ = θ̂_k − θ̂_{k−1}` from the sin/cos of the two frames
/// (`sin Δ = s_k c_{k−1} − c_k s_{k−1}`, `cos Δ = c_k c_{k−1} + s_k s_{k−1}`, one rounding each)
/// instead of a third `sin_cos`; exactly `(0, 1)` when the frame did not move. The two
/// products carry the sin/cos error of both frames (a few LSB of Q2.30, as `sin_cos(Δ)` has).
#[inline(always)]
fn advance(prev: SinCos, now: SinCos) -> SinCos {
    if prev == now {
        return SinCos {
            sin: Unit::ZERO,
            cos: Unit::from_bits(1 << UNIT_FRAC),
        };
    }
    let (s, c) = (now.sin.to_bits(), now.cos.to_bits());
    SinCos {
        sin: Unit::from_bits(dot30(s, prev.cos.to_bits(), c, neg(prev.sin))),
        cos: Unit::from_bits(dot30(c, prev.cos.to_bits(), s, prev.sin.to_bits())),
    }
}

/// The integrator step when the output before the clamp, `raw = K_p ξ̃ + I`, is on or beyond
/// `±ω_max` (the PI's anti-windup, module docs "Gains"): with `K_p > 0` back-calculation,
/// `I ← I + K_i T_s ξ̃ + k_t (clamp(raw) − raw)`, `k_t = min(1, K_i T_s/K_p)`; with `K_p = 0`
/// conditional integration (no integration that pushes further out). Rare, so out of line.
#[cold]
#[inline(never)]
fn integrate_saturated(c: &MrasCurrentConfig, raw: i64, integ: i64, xi: Pu) -> i64 {
    let hi = c.omega_max_wide;
    // |integ| < 2^59 and |K_i T_s ξ̃| < 2^62 (see `update`): the sum fits.
    let with_i = integ + wide(xi.to_bits(), c.ki_ts.bits());
    if c.kt.bits() == 0 {
        let pushes = (raw >= hi && xi > Pu::ZERO) || (raw <= -hi && xi < Pu::ZERO);
        if pushes { integ } else { with_i }
    } else {
        // |raw| < 2^62 + 2^59, so the excess fits; k_t ≤ 1 keeps the product below it.
        let excess = raw.max(-hi).min(hi) - raw;
        let pull = (excess as i128 * c.kt.bits() as i128 + (1 << 29)) >> 30;
        with_i.saturating_add(pull as i64)
    }
}

impl Estimator for MrasCurrent {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        let omega = self.last.omega;
        // Frame advance over [t_{k−1}, t_k) with the speed held over it (eq. 23): prepared at
        // the end of the last update (an exact product, shifted; the angle wraps by design).
        self.theta = self.theta_next;
        let sc_prev = self.sc;
        let sc = self.sc_next;
        self.sc = sc;
        let c = &self.config;
        let i = park_in(input.i, sc);
        self.i_dq = i;
        if self.seed {
            // After a reset the model starts from the measured current: no error to adapt on.
            self.seed = false;
            self.i_hat = i;
            self.xi = Pu::ZERO;
            self.last = self.make_estimate(omega);
            self.prepare_next(omega);
            return self.last;
        }
        // Model, eq. 15: the Strang step (half R–L step, exact rotation, half R–L step)
        // composed into one affine map (module docs, "Discretisation"): the weights act in
        // the frame at θ̂_{k−1}, the rotation by Δ takes them to the frame at θ̂_k.
        let v = park_in(input.v, sc_prev);
        let ih = self.i_hat;
        let xd = model_mac(c.xd_i, ih.d, c.xd_v, v.d, c.off_d_acc);
        let xq = model_mac(c.xq_i, ih.q, c.xq_v, v.q, 0);
        let yq = model_mac(c.yq_i, ih.q, c.yq_v, v.q, 0);
        let yd = model_mac(c.yd_i, ih.d, c.yd_v, v.d, c.off_q_acc);
        let r = advance(sc_prev, sc);
        let (rc, rs) = (r.cos.to_bits(), r.sin.to_bits());
        let i_hat = Dq {
            d: Pu::from_bits(dot30(xd.to_bits(), rc, xq.to_bits(), rs)).saturating_sub(c.off_d),
            q: Pu::from_bits(dot30(yq.to_bits(), rc, yd.to_bits(), neg(r.sin))),
        };
        self.i_hat = i_hat;
        // ε = i − î (eq. 16); ξ̃ = (L_q/L_d) ξ = ρ² i_q ε_d − (i_d + ψ/L_d) ε_q (eq. 21–22
        // × L_q/L_d: one weight fewer). Each product is below 2^62 in magnitude; halved, their
        // difference meets the rounding's contract (the dropped bit is 2^-25 LSB).
        let e_d = i.d.saturating_sub(i_hat.d);
        let e_q = i.q.saturating_sub(i_hat.q);
        let w_d = coef_mul(c.rho2, i.q);
        let w_q = i.d.saturating_add(c.psi_ld);
        let acc =
            (wide(w_d.to_bits(), e_d.to_bits()) >> 1) - (wide(w_q.to_bits(), e_q.to_bits()) >> 1);
        let xi = Pu::from_bits(round_shift_sat(acc, PU_FRAC - 1));
        self.xi = xi;
        // Mechanical model: the torque current less the load estimate accelerates the rotor;
        // the load estimate moves against ξ (module docs, "Through zero speed").
        let i_load = self.i_load.saturating_sub(coef_mul(c.load_gain, xi));
        self.i_load = i_load;
        let torque = i.q.saturating_sub(i_load);
        // Speed, eq. 22, in Q9.55 with exact increments: |I| ≤ 2^57 (clamped to ±4 pu),
        // |T_s a τ| < 2^58 and |T_s B/J ω̂| < 2^53 (both weights ≤ 2^27 in bits, |ω̂| ≤ 2^26),
        // |K_i T_s ξ̃| < 2^62, |K_p ξ̃| < 2^62 in Q9.55: no sum below can wrap.
        let integ = self.integ + wide(torque.to_bits(), c.accel.bits())
            - wide(omega.to_bits(), c.friction.bits());
        let p = coef_mul(c.kp, xi);
        let raw = ((p.to_bits() as i64) << INTEG_EXTRA) + integ;
        let hi = c.omega_max_wide;
        let integ = if -hi < raw && raw < hi {
            // Inside the limits: no anti-windup term.
            integ + wide(xi.to_bits(), c.ki_ts.bits())
        } else {
            integrate_saturated(c, raw, integ, xi)
        };
        let integ = integ.max(-hi).min(hi);
        self.integ = integ;
        // Rounded to Q8.24: |I| ≤ ω_max ≤ 4 pu, so the shifted value fits without a test.
        let i_pu = Pu::from_bits(((integ + (1 << (INTEG_EXTRA - 1))) >> INTEG_EXTRA) as i32);
        let omega = p.saturating_add(i_pu).max(-c.omega_max).min(c.omega_max);
        self.last = self.make_estimate(omega);
        self.prepare_next(omega);
        self.last
    }

    fn estimate(&self) -> Estimate {
        self.last
    }

    /// `|i_d − î_d| + |i_q − î_q|` of the last update (eq. 16), computed on request from the
    /// stored currents: nothing on the update's path.
    fn health(&self) -> Pu {
        let (i, m) = (self.i_dq, self.i_hat);
        i.d.saturating_sub(m.d)
            .saturating_abs()
            .saturating_add(i.q.saturating_sub(m.q).saturating_abs())
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        let omega = omega.max(-self.config.omega_max).min(self.config.omega_max);
        self.theta = (theta.0 as u32 as u64) << 32;
        self.sc = theta.sin_cos();
        self.i_dq = Dq::default();
        self.integ = (omega.to_bits() as i64) << INTEG_EXTRA;
        self.i_hat = Dq::default();
        self.xi = Pu::ZERO;
        self.i_load = Pu::ZERO;
        self.seed = true;
        self.last = self.make_estimate(omega);
        self.prepare_next(omega);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::InverterParams;

    fn motor_b() -> (MotorParams, PerUnit) {
        let mut m = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
        m.rated_current_a = Some(2.53);
        let inv = InverterParams {
            vdc_v: 540.0,
            pwm_hz: 14e3,
            dead_time_s: 2e-6,
            current_full_scale_a: 10.0,
        };
        let base = PerUnit::new(&m, &inv, 14e3).unwrap();
        (m, base)
    }

    #[test]
    fn gains_out_of_range_are_named() {
        let (m, b) = motor_b();
        let mut g = MrasCurrentGains::default_for(&m, &b);
        g.kp = -1.0;
        assert!(matches!(
            MrasCurrentConfig::new(&m, &b, g),
            Err(ConfigError::Gain {
                key: "mras_current.kp",
                ..
            })
        ));
        let mut g = MrasCurrentGains::default_for(&m, &b);
        g.ki = 1e12;
        assert!(matches!(
            MrasCurrentConfig::new(&m, &b, g),
            Err(ConfigError::Gain {
                key: "mras_current.ki",
                ..
            })
        ));
    }

    fn inverter(vdc_v: f64, full_scale_a: f64) -> InverterParams {
        InverterParams {
            vdc_v,
            pwm_hz: 20e3,
            dead_time_s: 0.5e-6,
            current_full_scale_a: full_scale_a,
        }
    }

    /// The corners of the motor family of `units` (a drone and an industrial motor, 8–20 kHz)
    /// fit every format with the default gains; a motor whose `ψ/L_d` exceeds the offsets'
    /// range (32 pu) is a named error, not a wrapped coefficient.
    #[test]
    fn family_corners_fit_and_too_small_an_inductance_is_named() {
        let mut drone = MotorParams::new(7, 0.02, 0.5e-3, 0.5e-3, 0.002, 2e-5, 1e-6);
        drone.rated_current_a = Some(60.0);
        let mut industrial = MotorParams::new(2, 4.0, 0.040, 0.048, 1.2, 0.01, 0.001);
        industrial.rated_current_a = Some(3.0);
        for hz in [8e3, 10e3, 20e3] {
            for (m, inv) in [
                (drone, inverter(24.0, 150.0)),
                (industrial, inverter(540.0, 10.0)),
            ] {
                let b = PerUnit::new(&m, &inv, hz).unwrap();
                let g = MrasCurrentGains::default_for(&m, &b);
                assert!(MrasCurrentConfig::new(&m, &b, g).is_ok(), "{m:?} {hz}");
            }
        }
        let (mut m, _) = motor_b();
        m.ld_h = 2.5e-3;
        m.lq_h = 4e-3;
        let inv = InverterParams {
            vdc_v: 540.0,
            pwm_hz: 40e3,
            dead_time_s: 2e-6,
            current_full_scale_a: 10.0,
        };
        let b = PerUnit::new(&m, &inv, 40e3).unwrap();
        let g = MrasCurrentGains::default_for(&m, &b);
        assert!(matches!(
            MrasCurrentConfig::new(&m, &b, g),
            Err(ConfigError::Gain { key: "ld_h", .. })
        ));
    }

    /// Without a proportional gain the integrator stops at the limit (conditional
    /// integration) instead of back-calculating; wild inputs still saturate, never panic.
    #[test]
    fn conditional_integration_without_kp() {
        let (m, b) = motor_b();
        let mut g = MrasCurrentGains::default_for(&m, &b);
        g.kp = 0.0;
        let cfg = MrasCurrentConfig::new(&m, &b, g).unwrap();
        let mut e = MrasCurrent::new(cfg);
        e.reset(Angle::ZERO, cfg.omega_max);
        let wild = ObserverInput {
            i: AlphaBeta {
                alpha: Pu::MIN,
                beta: Pu::MAX,
            },
            v: AlphaBeta {
                alpha: Pu::MAX,
                beta: Pu::MAX,
            },
        };
        for _ in 0..100 {
            let out = e.update(&wild);
            assert!(out.omega.abs() <= cfg.omega_max);
        }
    }

    #[test]
    fn model_at_rest_stays_at_rest_and_reset_seeds() {
        let (m, b) = motor_b();
        let cfg = MrasCurrentConfig::new(&m, &b, MrasCurrentGains::default_for(&m, &b)).unwrap();
        let mut e = MrasCurrent::new(cfg);
        e.reset(Angle::from_deg(30.0), Pu::ZERO);
        for _ in 0..1000 {
            let out = e.update(&ObserverInput::default());
            assert_eq!(out.theta, Angle::from_deg(30.0));
            assert_eq!(out.omega, Pu::ZERO);
        }
        // Wild inputs saturate, never panic.
        let wild = ObserverInput {
            i: AlphaBeta {
                alpha: Pu::MAX,
                beta: Pu::MIN,
            },
            v: AlphaBeta {
                alpha: Pu::MIN,
                beta: Pu::MAX,
            },
        };
        for _ in 0..100 {
            let out = e.update(&wild);
            assert!(out.omega.abs() <= cfg.omega_max);
        }
    }
}
