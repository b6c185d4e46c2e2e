//! The back-EMF that the measurements imply over each sample interval.
//!
//! From `L di/dt = −R i − e + v` (docs/algorithms.md (conventions)), integrated exactly over
//! `[t_{k−1}, t_k]`, the mean EMF over the interval is
//!
//! ```text
//! ē_k = v̄_k − R (i_{k−1} + i_k)/2 − (L/T_s) (i_k − i_{k−1})
//! ```
//!
//! `v̄_k` is the mean voltage over the interval (what the inverter applied), the current term is
//! exact, and only `∫ R i` is approximated (trapezoid, error `R T_s² i''/12`). No derivative of
//! a measurement is taken: `L (i_k − i_{k−1})` is the exact volt-seconds stored in the
//! inductance. Every estimator of Solsona, Valla, Muravchik (2000) is a filter of this
//! quantity, and all of them read the rotor from their EMF estimate the same way
//! ([`EmfToRotor`]): angle from eq. 11 and 25, speed from eq. 12 and 26, the sign from the
//! sense of rotation ([`Direction`]).

use super::direction::{Direction, DirectionConfig, FLIP_SPEED_PU};
use super::{Estimate, gain};
use crate::angle::Angle;
use crate::cordic::Polar;
use crate::error::ConfigError;
use crate::frames::AlphaBeta;
use crate::num::{Gain, Pu, mul, mul_unit, pu_from_f64};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Below this EMF magnitude (per unit) the direction `û` of the last estimate is used, and the
/// angle of the estimate does not count as evidence of the direction of rotation.
pub const MIN_EMF_PU: f64 = 1e-4;

/// The coefficients of the interval-mean EMF: `R/2` and `L/T_s` in per unit.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub(crate) struct EmfMeterConfig {
    /// `R/Z_b / 2`.
    half_r: Gain,
    /// `L I_b / (V_b T_s)`: per-unit volts per per-unit current change in one sample.
    l_over_ts: Gain,
}

impl EmfMeterConfig {
    /// Coefficients for `motor` with inductance `l_h` (the surface motor's `L`, or `L_q`).
    pub fn new(motor: &MotorParams, base: &PerUnit, l_h: f64) -> Result<Self, ConfigError> {
        let l_h = crate::params::positive("ld_h", l_h)?;
        Ok(Self {
            half_r: gain("rs_ohm", 0.5 * motor.rs_ohm / base.impedance_ohm)?,
            l_over_ts: gain(
                "ld_h",
                l_h * base.current_a / (base.voltage_v * base.sample_s),
            )?,
        })
    }
}

/// Measured mean EMF over each interval: the state is the previous current sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct EmfMeter {
    previous_i: Option<AlphaBeta>,
}

impl EmfMeter {
    /// `ē_k` from the current at `t_k` and the mean voltage over `[t_{k−1}, t_k]`; `None` at
    /// the first sample (no interval yet).
    #[inline(always)]
    pub fn update(&mut self, c: &EmfMeterConfig, i: AlphaBeta, v: AlphaBeta) -> Option<AlphaBeta> {
        let prev = self.previous_i.replace(i)?;
        let component = |v: Pu, i0: Pu, i1: Pu| {
            let drop = c.half_r.apply(i0.saturating_add(i1));
            let stored = c.l_over_ts.apply(i1.saturating_sub(i0));
            v.saturating_sub(drop).saturating_sub(stored)
        };
        Some(AlphaBeta {
            alpha: component(v.alpha, prev.alpha, i.alpha),
            beta: component(v.beta, prev.beta, i.beta),
        })
    }

    /// Forgets the previous current (after a gap in the samples).
    pub fn restart(&mut self) {
        self.previous_i = None;
    }
}

/// The coefficients that turn an EMF estimate into the rotor's angle and speed, shared by the
/// NLO, the AO and (through its AO) the MRAS on the AO.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub(crate) struct EmfToRotor {
    direction: DirectionConfig,
    /// `ψ_b/ψ`: per-unit speed per per-unit EMF magnitude.
    inv_psi: Gain,
    /// `ψ`, per unit of the flux base.
    psi_pu: Pu,
    /// [`MIN_EMF_PU`].
    min_emf: Pu,
    /// EMF below which the direction may flip ([`FLIP_SPEED_PU`] of the base speed).
    flip_emf: Pu,
}

impl EmfToRotor {
    /// For `motor` (its flux) sampled as in `base`.
    pub(crate) fn new(motor: &MotorParams, base: &PerUnit) -> Result<Self, ConfigError> {
        Ok(Self {
            direction: DirectionConfig::new(base.sample_s, base.omega_e_rad_s),
            inv_psi: gain("flux_wb", base.flux_wb / motor.flux_wb)?,
            psi_pu: pu_from_f64(motor.flux_wb / base.flux_wb),
            min_emf: pu_from_f64(MIN_EMF_PU),
            flip_emf: pu_from_f64(FLIP_SPEED_PU * motor.flux_wb / base.flux_wb),
        })
    }

    /// `ψ`, per unit of the flux base.
    pub(crate) fn psi(&self) -> Pu {
        self.psi_pu
    }

    /// Whether an EMF vector of polar form `p` is large enough for its angle to mean anything.
    #[inline(always)]
    pub(crate) fn has_angle(&self, p: &Polar) -> bool {
        p.magnitude > self.min_emf
    }

    /// The estimate from the EMF estimate `emf` of polar form `p`: `|ω̂| = |ê|/ψ`, its sign
    /// from `direction` (updated here), `θ̂ = ∠ê ∓ 90°`.
    #[inline(always)]
    pub(crate) fn estimate(&self, emf: AlphaBeta, p: Polar, direction: &mut Direction) -> Estimate {
        let speed = self.inv_psi.apply(p.magnitude);
        let forward = direction.update(
            &self.direction,
            p.angle,
            self.has_angle(&p),
            p.magnitude < self.flip_emf,
            speed,
        );
        Estimate {
            theta: rotor_angle_from_emf(p.angle, forward),
            omega: if forward {
                speed
            } else {
                speed.saturating_neg()
            },
            emf,
        }
    }

    /// The EMF vector `ψ ω (−sin θ, cos θ)` of a rotor at `theta` turning at `omega`.
    pub(crate) fn emf_of(&self, theta: Angle, omega: Pu) -> AlphaBeta {
        let sc = theta.sin_cos();
        let amplitude = mul(omega, self.psi_pu);
        AlphaBeta {
            alpha: mul_unit(amplitude, sc.sin.saturating_neg()),
            beta: mul_unit(amplitude, sc.cos),
        }
    }
}

/// The angle of the rotor d axis from the angle `phi` of a back-EMF vector: the EMF leads d by
/// +90° when turning forwards (`ψ ω (−sin θ, cos θ)`) and lags it by 90° backwards
/// (Solsona, Valla, Muravchik (2000), eq. 11, 20: `θ̂ = atan2(−ê_α/s, ê_β/s)`).
#[inline(always)]
pub(crate) fn rotor_angle_from_emf(phi: Angle, forward: bool) -> Angle {
    if forward {
        phi - Angle::HALF_PI
    } else {
        phi + Angle::HALF_PI
    }
}

/// `x + κ (target − x)`, per component.
#[inline(always)]
pub(crate) fn approach(x: AlphaBeta, target: AlphaBeta, kappa: Gain) -> AlphaBeta {
    correct(x, target, x, kappa)
}

/// `x + κ (measured − predicted)`, per component: a correction by an innovation.
#[inline(always)]
pub(crate) fn correct(
    x: AlphaBeta,
    measured: AlphaBeta,
    predicted: AlphaBeta,
    kappa: Gain,
) -> AlphaBeta {
    let innovation = measured.saturating_sub(predicted);
    x.saturating_add(AlphaBeta {
        alpha: kappa.apply(innovation.alpha),
        beta: kappa.apply(innovation.beta),
    })
}
