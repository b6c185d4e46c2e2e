//! AO: the linear reduced-order observer of Solsona, Valla, Muravchik (2000) (eq. 21–26, docs/solsona2000.md §3).
//!
//! Continuous form: `dξ/dt = g (−R i − ê + v)`, `ê = ξ − L g i`, whose error dynamics are
//! `dê/dt = g (e − ê)`: a first-order lag of bandwidth `g` on the EMF. At constant electrical
//! speed `Ω` this leaves the errors of Solsona, Valla, Muravchik (2000) eq. 13–14, `ε_θ = atan(−Ω/g)`,
//! `ε_ω = Ω (g/√(g² + Ω²) − 1)`.
//!
//! # Discretisation
//!
//! The filter is applied to the mean EMF of each interval, [`EmfMeter`]: `ê_k = ê_{k−1} +
//! κ (ē_k − ê_{k−1})` with the matched pole `κ = 1 − exp(−g T_s)`. This reproduces eq. 13–14
//! within 0.6 % of the angle error and exactly in speed even at `g T_s = 0.25` (forward Euler,
//! `κ = g T_s`, misses the speed error by 25 % there). Speed `|ω̂| = |ê|/ψ` (eq. 25) with the
//! sign from [`Direction`]; angle from eq. 26 (`θ̂ = ∠ê ∓ 90°`).
//!
//! Signals: `ê` Q8.24 per unit of `V_b`; `κ` a [`Gain`].
//!
//! # Lag compensation (project addition, the drive's default)
//!
//! The lag of eq. 13–14 is known exactly at constant speed: the AO's EMF is the true one
//! turned back by `atan(Ω/g)` and shortened by `cos` of that, so with `y = ω̂_AO/g` (its own
//! speed over its gain, below 1 at any speed) the rotor is `asin y` ahead of it and turns at
//! `Ω = ω̂_AO/√(1 − y²)`. [`AoConfig::lag_compensated`] adds both corrections to every
//! estimate, by their series `asin y ≈ y + y³/6 + 3y⁵/40` and
//! `1/√(1 − y²) ≈ 1 + y²/2 + 3y⁴/8 + 5y⁶/16` (at `y = 0.4`, 1.3 times rated speed with the
//! default `g`: 1e−4 rad and 2e−4 of the speed; [`LagCompensation`]). Left alone, the default
//! `g` of three times the rated speed leaves 0.165 rad at half rated speed, more than a
//! drive's angle error should be; the paper's reproduction runs without it.

use super::emf::{EmfToRotor, approach};
use super::{
    Direction, EmfMeter, EmfMeterConfig, Estimate, Estimator, ObserverInput, observer_pole,
};
use crate::angle::Angle;
use crate::cordic::polar;
use crate::error::ConfigError;
use crate::frames::AlphaBeta;
use crate::num::{Gain, Pu, mul};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Configuration of the [`Ao`].
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct AoConfig {
    meter: EmfMeterConfig,
    kappa: Gain,
    rotor: EmfToRotor,
    /// The steady lag's compensation (module docs; [`LagCompensation::OFF`]: the paper's AO).
    lag: LagCompensation,
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
            rotor: EmfToRotor::new(motor, base)?,
            lag: LagCompensation::OFF,
        })
    }

    /// [`AoConfig::new`] with its steady lag compensated (module docs, "lag compensation").
    pub fn lag_compensated(
        motor: &MotorParams,
        base: &PerUnit,
        gain_rad_s: f64,
    ) -> Result<Self, ConfigError> {
        Ok(Self {
            lag: LagCompensation::new(base, gain_rad_s)?,
            ..Self::new(motor, base, gain_rad_s)?
        })
    }

    /// Whether the estimates are lag-compensated.
    pub fn is_lag_compensated(&self) -> bool {
        self.lag != LagCompensation::OFF
    }

    /// `ψ`, per unit of the flux base.
    pub(crate) fn psi(&self) -> Pu {
        self.rotor.psi()
    }
}

/// The AO's steady lag behind the rotor as a function of its own speed (module docs, "lag
/// compensation"): `y = |ω̂_AO|/g` in Q8.24 from `1/g` per unit of `ω_b`.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub(crate) struct LagCompensation {
    /// `ω_b/g` (zero: off).
    inv_g: Gain,
}

/// Radians in Q8.24 to [`Angle`] LSB: `2³²/(2π)/2²⁴ = 2⁸/(2π)`, in Q16.
const RAD_TO_ANGLE_Q16: i64 = 2_670_177; // round(2^24 / (2π))

impl LagCompensation {
    /// No compensation.
    const OFF: Self = Self { inv_g: Gain::ZERO };

    fn new(base: &PerUnit, gain_rad_s: f64) -> Result<Self, ConfigError> {
        Ok(Self {
            inv_g: super::gain("gain", base.omega_e_rad_s / gain_rad_s)?,
        })
    }

    /// The lag `asin y` as an angle and the speed factor `1/√(1 − y²)` (Q8.24) for the
    /// speed magnitude `speed` (per unit); `y` taken at most 1/2 (beyond any speed the
    /// default gain meets: the series stay within 2e−3 there).
    #[inline(always)]
    pub(crate) fn at(&self, speed: Pu) -> (Angle, Pu) {
        let y = self.inv_g.apply(speed.saturating_abs()).min(Pu::ONE / 2);
        let y2 = mul(y, y);
        let y4 = mul(y2, y2);
        // asin y = y (1 + y²/6 + 3y⁴/40); 1/√(1 − y²) = 1 + y²/2 + 3y⁴/8 + 5y⁶/16.
        let asin = mul(y, Pu::ONE + y2 / 6 + mul(y4, Pu::from_bits(1_258_291))); // 3/40
        let factor = Pu::ONE + y2 / 2 + mul(y4, Pu::from_bits(6_291_456)) // 3/8
            + mul(mul(y4, y2), Pu::from_bits(5_242_880)); // 5/16
        // `RAD_TO_ANGLE_Q16` < 2³¹: the exact product of two `i32` (`wmul`); asin < 0.53 rad,
        // so the angle fits its `i32` with room.
        let lag = (crate::num::wmul(asin.to_bits(), RAD_TO_ANGLE_Q16 as i32) >> 16) as i32;
        (Angle(lag), factor)
    }

    /// `estimate` corrected for the lag at its own speed: the angle advanced in the sense of
    /// rotation, the speed lengthened.
    #[inline(always)]
    pub(crate) fn correct(&self, estimate: Estimate) -> Estimate {
        let (lag, factor) = self.at(estimate.omega);
        let forward = estimate.omega >= Pu::ZERO;
        Estimate {
            theta: if forward {
                estimate.theta + lag
            } else {
                estimate.theta - lag
            },
            omega: mul(estimate.omega, factor),
            emf: estimate.emf,
        }
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
    /// The lag compensation's turn of the last estimate (zero without it).
    lag: Angle,
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
            lag: Angle::ZERO,
        }
    }

    /// The lag compensation's turn of the last estimate, signed in the sense of rotation
    /// (zero without the compensation): what an estimator built on the AO's EMF adds to its
    /// own angle.
    pub fn lag(&self) -> Angle {
        self.lag
    }

    /// The configuration.
    pub fn config(&self) -> &AoConfig {
        &self.config
    }
}

impl Estimator for Ao {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        if let Some(measured) = self.meter.update(&self.config.meter, input.i, input.v) {
            self.innovation = measured.saturating_sub(self.emf).l1_norm();
            self.emf = approach(self.emf, measured, self.config.kappa);
        }
        let p = polar(self.emf.alpha, self.emf.beta);
        let raw = self.config.rotor.estimate(self.emf, p, &mut self.direction);
        self.last = if self.config.is_lag_compensated() {
            self.config.lag.correct(raw)
        } else {
            raw
        };
        self.lag = self.last.theta - raw.theta;
        self.last
    }

    fn estimate(&self) -> Estimate {
        self.last
    }

    fn health(&self) -> Pu {
        self.innovation
    }

    fn hold_direction(&mut self, forward: Option<bool>) {
        self.direction.hold(forward);
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        self.emf = self.config.rotor.emf_of(theta, omega);
        self.meter.restart();
        self.innovation = Pu::ZERO;
        self.lag = Angle::ZERO;
        self.direction.reset(omega >= Pu::ZERO);
        self.last = Estimate {
            theta,
            omega,
            emf: self.emf,
        };
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{inverter_b, motor_b};
    use crate::num::pu_from_f64;

    /// The lag compensation's series against `asin y` and `1/√(1 − y²)` in f64: within
    /// 1.2e−4 rad and 2.5e−4 of the speed up to `y = 0.4` (1.3 times rated speed with the
    /// default gain), 5e−4 rad and 1.5e−3 up to its cap `y = 0.5`, plus the formats' LSB.
    #[test]
    fn lag_compensation_against_reference() {
        let base = PerUnit::new(&motor_b(), &inverter_b(), 14e3).unwrap();
        let g = 2.0 * base.omega_e_rad_s;
        let lag = LagCompensation::new(&base, g).unwrap();
        for k in 0..=100 {
            let y = 0.5 * k as f64 / 100.0;
            let speed = y * g / base.omega_e_rad_s;
            for sign in [1.0, -1.0] {
                let (turn, factor) = lag.at(pu_from_f64(sign * speed));
                let (da, df) = (
                    (turn.to_rad() - y.asin()).abs(),
                    (factor.to_num::<f64>() - 1.0 / (1.0 - y * y).sqrt()).abs(),
                );
                let (ba, bf) = if y <= 0.4 {
                    (1.2e-4, 2.5e-4)
                } else {
                    (5e-4, 1.5e-3)
                };
                assert!(da < ba + 1e-6 && df < bf + 1e-6, "y {y}: {da} rad, {df}");
            }
        }
    }
}
