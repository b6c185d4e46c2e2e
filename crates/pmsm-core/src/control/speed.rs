//! IP speed controller of seed 001 (nomenclature `K_iΩ`, `K_pΩ`; equations.md §4.4).
//!
//! ```text
//! i_q* = K_iΩ ∫(ω* − ω̂) dt − K_pΩ ω̂,   clamped to ±I_max
//! ```
//!
//! The proportional action acts on the measured (estimated) speed only, so a reference step
//! does not kick the current, and the closed loop has no zero.
//!
//! # Gains
//!
//! With an ideal current loop the electrical speed obeys `dω/dt = K i_q − (B/J) ω − p T_L/J`,
//! `K = p K_T/J` (seed 001 eq. 5 with the 1.5 of equations.md §1 inside `K_T`). The IP loop is
//! then
//!
//! ```text
//! ω/ω* = K K_iΩ / (s² + (K K_pΩ + B/J) s + K K_iΩ)
//! ```
//!
//! and for a natural frequency `ω_n` and damping `ζ`:
//! `K_iΩ = ω_n²/K`, `K_pΩ = (2 ζ ω_n − B/J)/K` (not below 0). With `ζ ≥ 1` both poles are real
//! and there is no zero, so the step response is monotone: no overshoot (seed 001 §7, Fig. 7).
//! Defaults: `ζ = 1`, `ω_n` a tenth of the default current-loop bandwidth, `0.005/T_s`
//! (70 rad/s at 14 kHz), `I_max` = 1 pu (rated peak current).
//!
//! # Anti-windup
//!
//! [`Pi`] with `K_p = 0` and `−K_pΩ ω̂` as feed-forward: conditional integration and an
//! integrator clamped to `[−I_max + K_pΩ ω̂, I_max + K_pΩ ω̂]`. After a saturated acceleration
//! the integrator leaves the clamp when `K_iΩ (ω* − ω̂) < K_pΩ dω̂/dt`, which is the state of
//! the linear loop tracking a ramp; a ramp followed by a hold gives no overshoot either, so a
//! saturated step does not overshoot (tests: `drive_parts_loops`).
//!
//! # Formats
//!
//! `ω*`, `ω̂` per unit of `ω_b`, `i_q*` per unit of `I_b`: [`Pu`]. Gains: [`WideGain`] per unit
//! (`K_pΩ ω_b/I_b`, `K_iΩ T ω_b/I_b` with `T` the speed loop's period).

use super::pi::{Limits, Pi, PiConfig};
use super::{WideGain, gain_in, wide_gain};
use crate::error::ConfigError;
use crate::num::{Pu, pu_from_f64};
use crate::params::{MotorParams, in_range};
use crate::units::PerUnit;

/// Default `ω_n T_s` of the speed loop (a tenth of the current loop's default).
pub const DEFAULT_BANDWIDTH_TS: f64 = 0.005;

/// How the speed controller is designed; [`SpeedDesign::default_for`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedDesign {
    /// Natural frequency `ω_n` of the speed loop, rad/s.
    pub bandwidth_rad_s: f64,
    /// Damping `ζ` (≥ 1: no overshoot).
    pub damping: f64,
    /// Current limit `I_max`, A peak.
    pub current_limit_a: f64,
    /// The speed loop runs once every `decimation` control samples (≥ 1).
    pub decimation: u32,
    /// `(K_iΩ, K_pΩ)` in A/(rad/s · s) and A/(rad/s) of electrical speed, overriding the
    /// design from `ω_n` and `ζ`.
    pub gains: Option<(f64, f64)>,
}

impl SpeedDesign {
    /// `ω_n = 0.005/T_s`, `ζ = 1`, `I_max = I_b` (rated peak), every sample.
    pub fn default_for(base: &PerUnit) -> Self {
        Self {
            bandwidth_rad_s: DEFAULT_BANDWIDTH_TS / base.sample_s,
            damping: 1.0,
            current_limit_a: base.current_a,
            decimation: 1,
            gains: None,
        }
    }
}

/// Configuration of the [`SpeedController`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpeedConfig {
    pi: PiConfig,
    /// `K_pΩ` per unit.
    kp: WideGain,
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
    /// per-unit range; [`ConfigError::Param`] for `speed.current_limit_a` (in `(0, 64 I_b]`)
    /// or `speed.decimation` (in 1..=1000).
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        design: SpeedDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        in_range("speed.decimation", design.decimation as f64, 1.0, 1000.0)?;
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
        let max_ki = super::pi::MAX_KI_TS * ib / (t * wb);
        let max_kp = super::pi::MAX_KP * ib / wb;
        gain_in("speed.ki", ki, 0.0, max_ki)?;
        gain_in("speed.kp", kp, 0.0, max_kp)?;
        Ok(Self {
            pi: PiConfig::new(0.0, ki * t * wb / ib, ["speed.kp", "speed.ki"])?,
            kp: wide_gain("speed.kp", kp * wb / ib, max_kp)?,
            i_max: pu_from_f64(i_max_a / ib),
            gains_si: (ki, kp),
            design,
        })
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
    config: SpeedConfig,
    pi: Pi,
}

impl SpeedController {
    /// Controller with zero integral state.
    pub fn new(config: SpeedConfig) -> Self {
        Self {
            pi: Pi::new(config.pi),
            config,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &SpeedConfig {
        &self.config
    }

    /// Bumpless restart at speed `omega` with current `iq` flowing: sets the integrator to
    /// `iq + K_pΩ ω`.
    pub fn reset(&mut self, omega: Pu, iq: Pu) {
        let i = iq.saturating_add(self.config.kp.apply(omega));
        self.pi.reset(i);
    }

    /// One speed-loop sample (every `decimation` control samples). Integer only.
    pub fn step(&mut self, omega_ref: Pu, omega: Pu) -> SpeedOutput {
        let c = &self.config;
        let e = omega_ref.saturating_sub(omega);
        let ff = c.kp.apply(omega).saturating_neg();
        let o = self.pi.step(e, ff, Limits::symmetric(c.i_max), false);
        SpeedOutput {
            iq_ref: o.u,
            saturated: o.saturated,
        }
    }
}
