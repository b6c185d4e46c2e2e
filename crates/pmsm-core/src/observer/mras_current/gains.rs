//! The adaptation gains of the current-model MRAS and their design (module docs, "Gains").

use super::DEFAULT_BANDWIDTH_TS;
use crate::params::MotorParams;
use crate::units::PerUnit;

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
    /// (the plain MRAS of Khlaief, Boussak, Gossa (2012)).
    pub kl: f64,
    /// Raise the three gains at low speed, up to four times, to hold the loop's gain where ξ's
    /// sensitivity falls (module docs, "Low-speed schedule"); `false` (the default) keeps them
    /// fixed.
    pub low_speed_schedule: bool,
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
        }
    }

    /// [`MrasCurrentGains::design`] at `ω_n = 0.02/T_s`.
    pub fn default_for(motor: &MotorParams, base: &PerUnit) -> Self {
        Self::design(motor, DEFAULT_BANDWIDTH_TS / base.sample_s)
    }
}
