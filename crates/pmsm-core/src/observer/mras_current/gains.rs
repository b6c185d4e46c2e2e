//! The adaptation gains of the current-model MRAS and their design (module docs, "Gains").

use super::{
    DEFAULT_BANDWIDTH_TS, DEFAULT_D_WEIGHT, KI_TS_ROOM, LOAD_GAIN_ROOM, LOAD_STEP_LAG_RAD,
    MAX_DEFAULT_BANDWIDTH_TS,
};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Adaptation gains of eq. 22 in SI units (ξ in A²): `K_p` in (rad/s)/A², `K_i` in
/// (rad/s²)/A², electrical speed; and the gain of the load-current estimate of the mechanical
/// model (module docs, "Through zero speed").
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct MrasCurrentGains {
    /// Proportional gain `K_pω_r-est`.
    pub kp: f64,
    /// Integral gain `K_iω_r-est`.
    pub ki: f64,
    /// Gain `K_L` of the load-current estimate, A/(A²·s); zero turns the mechanical model off
    /// (the plain MRAS of Khlaief, Boussak, Gossa (2012)).
    pub kl: f64,
    /// Raise the three gains at low speed, up to four times, to hold the loop's gain where ξ's
    /// sensitivity falls (module docs, "Low-speed schedule"); `false` (the default) keeps them
    /// fixed.
    pub low_speed_schedule: bool,
    /// The weight of the d-axis error in the tuning signal, relative to eq. 21's: `ξ =
    /// w (L_q/L_d) i_q ε_d − (L_d/L_q) i_d ε_q − (ψ/L_q) ε_q`, `w` in `[0, 1]` (1: the paper's;
    /// default 1/2, docs/khlaief2012.md §2 "The d-axis error's weight"). An `f32`: a weight
    /// needs no more, and it fits the struct's padding, so a drive's configuration keeps its
    /// size (the micro:bit's 16 KiB hold the Cortex-M0 PIL harness's stack).
    pub d_weight: f32,
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
            low_speed_schedule: false,
            d_weight: DEFAULT_D_WEIGHT,
        }
    }

    /// The defaults: [`MrasCurrentGains::design`] at
    /// [`MrasCurrentGains::default_bandwidth_rad_s`], the low-speed schedule off.
    #[inline(always)]
    pub fn default_for(motor: &MotorParams, base: &PerUnit) -> Self {
        Self::design(motor, Self::default_bandwidth_rad_s(motor, base))
    }

    /// The default natural frequency, rad/s: `ω_n = 0.02/T_s`, raised on a light rotor towards
    /// `√(a I_b/δ_L)`, `δ_L` = 0.15 rad (the loop's angle error after a step `α` of the
    /// acceleration is of the order of `α/ω_n²`: a rated load step then lags the estimate by
    /// about `δ_L`), at most `0.06/T_s` and as far as the gains' per-unit coefficients keep
    /// room in their formats (`K_i T_s` below ¾, the load gain below 8; module docs,
    /// "Formats").
    #[inline(always)]
    pub fn default_bandwidth_rad_s(motor: &MotorParams, base: &PerUnit) -> f64 {
        let ts = base.sample_s;
        let (k, rho) = (Self::k_inf(motor), motor.lq_h / motor.ld_h);
        let a = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        let i_b = base.current_a;
        // `K_i T_s` per unit is `1.5 ω_n² T_s c`, `K_L`'s `ω_n³ T_s I_b/(4 a k_∞ ρ)`.
        let c = i_b * i_b / (rho * base.omega_e_rad_s * k);
        let w2 = (a * i_b / LOAD_STEP_LAG_RAD).min(KI_TS_ROOM / (1.5 * ts * c));
        let wn = sqrt_below(w2, MAX_DEFAULT_BANDWIDTH_TS / ts);
        let floor = DEFAULT_BANDWIDTH_TS / ts;
        if wn * wn * wn * ts * i_b > LOAD_GAIN_ROOM * 4.0 * a * k * rho {
            floor
        } else {
            wn.max(floor)
        }
    }
}

/// `min(√x, ceiling)` by Newton's iteration from `ceiling` (decreasing; six steps reach
/// double precision from three times the root, the range the default bandwidth spans, and
/// below the floor the result is not used): a loop of a few instructions where a library
/// square root would add some hundred bytes to the board's image.
#[inline(always)]
fn sqrt_below(x: f64, ceiling: f64) -> f64 {
    if x >= ceiling * ceiling {
        return ceiling;
    }
    let mut w = ceiling;
    for _ in 0..6 {
        w = 0.5 * (w + x / w);
    }
    w
}
