//! AO: the linear reduced-order observer of seed 000 (eq. 21–26, equations.md §3.1).
//!
//! Continuous form: `dξ/dt = g (−R i − ê + v)`, `ê = ξ − L g i`, whose error dynamics are
//! `dê/dt = g (e − ê)`: a first-order lag of bandwidth `g` on the EMF. At constant electrical
//! speed `Ω` this leaves the errors of seed 000 eq. 13–14, `ε_θ = atan(−Ω/g)`,
//! `ε_ω = Ω (g/√(g² + Ω²) − 1)`.
//!
//! # Discretisation
//!
//! The filter is applied to the mean EMF of each interval, [`EmfMeter`]: `ê_k = ê_{k−1} +
//! κ (ē_k − ê_{k−1})` with the matched pole `κ = 1 − exp(−g T_s)`. This reproduces eq. 13–14
//! within 0.6 % of the angle error and exactly in speed even at `g T_s = 0.25` (forward Euler,
//! `κ = g T_s`, misses the speed error by 25 % there). Speed `|ω̂| = |ê|/ψ` (eq. 26) with the
//! sign from [`Direction`]; angle from eq. 25 (`θ̂ = ∠ê ∓ 90°`).
//!
//! Signals: `ê` Q8.24 per unit of `V_b`; `κ` a [`Gain`].

use super::{
    Direction, DirectionConfig, EmfMeter, EmfMeterConfig, Estimate, Estimator, ObserverInput, gain,
    observer_pole, rotor_angle_from_emf,
};
use crate::angle::Angle;
use crate::cordic::polar;
use crate::error::ConfigError;
use crate::frames::AlphaBeta;
use crate::num::{Gain, Pu, mul_unit};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Configuration of the [`Ao`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AoConfig {
    meter: EmfMeterConfig,
    direction: DirectionConfig,
    kappa: Gain,
    inv_psi: Gain,
    psi_pu: Pu,
    min_emf: Pu,
    /// EMF below which the direction may flip (`FLIP_SPEED_PU` of the base speed).
    flip_emf: Pu,
    /// Observer gain `g`, rad/s.
    pub gain_rad_s: f64,
}

impl AoConfig {
    /// AO of gain `g` (rad/s) for `motor` sampled as in `base`. A surface motor uses `L`; an
    /// interior one `L_q` (its "EMF" is then the extended EMF).
    pub fn new(motor: &MotorParams, base: &PerUnit, gain_rad_s: f64) -> Result<Self, ConfigError> {
        motor.validate()?;
        let kappa = observer_pole(base, gain_rad_s)?;
        Ok(Self {
            meter: EmfMeterConfig::new(motor, base, motor.lq_h)?,
            kappa,
            inv_psi: gain("flux_wb", base.flux_wb / motor.flux_wb)?,
            psi_pu: crate::num::pu_from_f64(motor.flux_wb / base.flux_wb),
            min_emf: crate::num::pu_from_f64(super::nlo::MIN_EMF_PU),
            flip_emf: crate::num::pu_from_f64(
                super::direction::FLIP_SPEED_PU * motor.flux_wb / base.flux_wb,
            ),
            direction: DirectionConfig::new(base.sample_s, base.omega_e_rad_s),
            gain_rad_s,
        })
    }
}

/// The AO estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct Ao {
    config: AoConfig,
    meter: EmfMeter,
    direction: Direction,
    emf: AlphaBeta,
    last: Estimate,
    /// `|Δα| + |Δβ|` of the last innovation (measured EMF minus the estimate).
    innovation: Pu,
}

impl AoConfig {
    /// `ψ`, per unit of the flux base.
    pub(crate) fn psi(&self) -> Pu {
        self.psi_pu
    }
}

impl Ao {
    /// A new observer with zero EMF estimate.
    pub fn new(config: AoConfig) -> Self {
        Self {
            meter: EmfMeter::default(),
            direction: Direction::default(),
            config,
            emf: AlphaBeta::default(),
            last: Estimate::default(),
            innovation: Pu::ZERO,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &AoConfig {
        &self.config
    }
}

/// `x + κ (target − x)`, per component.
pub(crate) fn approach(x: AlphaBeta, target: AlphaBeta, kappa: Gain) -> AlphaBeta {
    approach_delta(x, target, x, kappa)
}

/// `x + κ (measured − predicted)`, per component: a correction by an innovation.
/// `|m_α − p_α| + |m_β − p_β|`: the size of an EMF innovation, per unit of `V_b` (the L1
/// norm: no product, between 1 and √2 times the Euclidean length).
#[inline]
pub(crate) fn innovation_l1(measured: AlphaBeta, predicted: AlphaBeta) -> Pu {
    measured
        .alpha
        .saturating_sub(predicted.alpha)
        .saturating_abs()
        .saturating_add(
            measured
                .beta
                .saturating_sub(predicted.beta)
                .saturating_abs(),
        )
}

pub(crate) fn approach_delta(
    x: AlphaBeta,
    measured: AlphaBeta,
    predicted: AlphaBeta,
    kappa: Gain,
) -> AlphaBeta {
    AlphaBeta {
        alpha: x
            .alpha
            .saturating_add(kappa.apply(measured.alpha.saturating_sub(predicted.alpha))),
        beta: x
            .beta
            .saturating_add(kappa.apply(measured.beta.saturating_sub(predicted.beta))),
    }
}

/// The EMF vector `ψ ω (−sin θ, cos θ)` for a rotor at `theta` turning at `omega` (per unit,
/// ψ in per unit of the base flux).
pub(crate) fn emf_of(theta: Angle, omega: Pu, psi_pu: Pu) -> AlphaBeta {
    let sc = theta.sin_cos();
    let amplitude = crate::num::mul(omega, psi_pu);
    AlphaBeta {
        alpha: mul_unit(amplitude, sc.sin.saturating_neg()),
        beta: mul_unit(amplitude, sc.cos),
    }
}

impl Estimator for Ao {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        if let Some(measured) = self.meter.update(&self.config.meter, input.i, input.v) {
            self.innovation = innovation_l1(measured, self.emf);
            self.emf = approach(self.emf, measured, self.config.kappa);
        }
        let p = polar(self.emf.alpha, self.emf.beta);
        let forward = self.direction.update(
            &self.config.direction,
            p.angle,
            p.magnitude > self.config.min_emf,
            p.magnitude < self.config.flip_emf,
        );
        let speed = self.config.inv_psi.apply(p.magnitude);
        self.last = Estimate {
            theta: rotor_angle_from_emf(p.angle, forward),
            omega: if forward {
                speed
            } else {
                speed.saturating_neg()
            },
            emf: self.emf,
        };
        self.last
    }

    fn estimate(&self) -> Estimate {
        self.last
    }

    fn health(&self) -> Pu {
        self.innovation
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        self.emf = emf_of(theta, omega, self.config.psi_pu);
        self.meter.restart();
        self.innovation = Pu::ZERO;
        self.direction.reset(omega >= Pu::ZERO);
        self.last = Estimate {
            theta,
            omega,
            emf: self.emf,
        };
    }
}
