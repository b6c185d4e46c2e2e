//! MRAS: Tomita's adaptive speed estimator on the AO (Solsona, Valla, Muravchik (2000) eq. 27–29, docs/solsona2000.md §5).
//!
//! An adjustable EMF model `ẽ` turns at the adapted speed `ω̂_Ad` and is pulled toward the
//! AO's estimate `ê_AO`:
//!
//! ```text
//! dẽ/dt = ω̂_Ad J ẽ + (ω̂_AO/c3)(ê_AO − ẽ)
//! ε = (ê_AO,β − ẽ_β) ẽ_α − (ê_AO,α − ẽ_α) ẽ_β
//! ω̂_Ad = (c1/ω̂_AO) ε + (c2/ω̂_AO) ∫ ε dt,     ω̂_AO = |ê_AO|/ψ
//! ```
//!
//! The constants are the paper's, in SI electrical units (`c1 = 0.0347`, `c2 = 5208`,
//! `c3 = 0.1`); in per unit `ω̂_Ad = ψ_b² (c1 ε + (c2/ω_b) ω_b∫ε dt) / ω̂_AO` with
//! `ψ_b = V_b/ω_b`, which keeps the paper's behaviour for any base.
//!
//! # The drive's defaults
//!
//! The paper's constants suit the paper's motor only. With `E = ψ|ω|`, `ε ≈ E² Δ` for the
//! model's phase `Δ` behind `ê_AO`, and eq. 27–29 linearise to
//! `s² + |ω| (ψ² c1 + 1/c3) s + ψ² c2 |ω|` (in `Δ`, driven by the speed error), whose slow root
//! is `ψ² c2 c3` while the pull dominates the damping: 43 rad/s on motor A (ψ = 0.288 Wb), but
//! 0.1 rad/s on a 48 V motor with ψ = 0.014 Wb, whose adapted speed then does not move in a
//! whole open-loop start. [`MrasEmfConfig::default_for`] therefore designs `c2` for a slow root
//! of [`crate::tuning::MRAS_EMF_ADAPTATION_BANDWIDTH_TS`]`/T_s`, keeps the paper's `c1/c2`, raises
//! `c3` where the sample rate is too slow for it (docs/solsona2000.md §5), integrates
//! `ε/ω̂_AO` instead of `ε` ([`MrasEmfConfig::normalised_integral`]: the same at constant
//! speed, but eq. 29's division of the integral by a changing `ω̂_AO` pushes the estimate
//! against every change of speed, and the estimate lagged a rotor decelerating at the current
//! limit), and runs the AO with its lag compensated ([`AoConfig::lag_compensated`]), whose turn
//! it adds to the model's angle: at constant speed the model is aligned with `ê_AO` and
//! carries the same lag.
//!
//! While the drive's open loop holds the direction ([`Estimator::hold_direction`]) the
//! estimate's speed is the AO's, signed by the held direction, and the model turns at it; at
//! the release the integral takes the value that gives that speed at zero error, so the
//! adaptation starts from a speed measured from the EMF instead of from rest (where its slow
//! root would leave it at the handover).
//!
//! Discretisation: the rotation of `ẽ` is exact (as in the NLO), the pull uses the pole
//! `1 − exp(−ω̂_AO T_s/c3)` (third-order series, exact to 1e−3 at the largest accepted step),
//! the integral is a running sum. `ω̂_AO` is kept above [`MIN_SPEED_PU`] so the division stays
//! bounded. The division is the one `i64` division of the estimators (a library call on
//! Cortex-M).

use super::ao::{Ao, AoConfig};
use super::emf::{approach, rotor_angle_from_emf};
use super::{Estimate, Estimator, ObserverInput, gain};
use crate::angle::Angle;
use crate::cordic::polar;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, rotate};
use crate::num::{Gain, Pu, mul, pu_from_f64, sat_i32};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Solsona, Valla, Muravchik's (2000) constants `c1, c2, c3` (SI, electrical).
pub const PAPER_CONSTANTS: [f64; 3] = [0.0347, 5208.0, 0.1];
/// Smallest `ω̂_AO` used in the adaptation law, per unit.
pub const MIN_SPEED_PU: f64 = 0.005;
/// The slow root of the drive's adaptation, `ψ² c2 c3`, times `T_s`
/// ([`MrasEmfConfig::default_for`]): twelve and a half times the back-EMF estimators'
/// speed-loop bandwidth (`0.002/T_s`), 500 rad/s at 20 kHz (the paper's constants give
/// 43 rad/s on its motor and 0.1 rad/s on a 48 V motor of a hundredth of its flux). Chosen on
/// the random family: 274 of 301 runs held against 272 at 0.02, 271 at 0.03, 251 at 0.06
/// (docs/solsona2000.md §5).
pub const ADAPTATION_BANDWIDTH_TS: f64 = 0.025;
/// Least damping ratio of the drive's adaptation at its handover speed
/// ([`MrasEmfConfig::damped_speed_rad_s`]).
pub const MIN_DAMPING: f64 = 0.5;

/// `c3` of [`MrasEmfConfig::default_for`]: the paper's, at least `ω_b T_s` (a pull step of at
/// most 1 at base speed; docs/solsona2000.md §5).
fn default_c3(base: &PerUnit) -> f64 {
    PAPER_CONSTANTS[2].max(base.omega_e_rad_s * base.sample_s)
}

/// Configuration of the [`MrasEmf`].
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct MrasEmfConfig {
    ao: AoConfig,
    law: Law,
    /// `c1, c2, c3` as configured.
    pub constants: [f64; 3],
}

/// The adaptation law's coefficients (the estimator keeps these, its AO its own
/// configuration: no second copy of the AO's in the state).
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
struct Law {
    /// `ω_b T_s / c3`: pull rate per unit of speed.
    pull: Gain,
    /// Rotation per sample, angle LSB per LSB of per-unit speed.
    step: Gain,
    /// `ψ_b² c1`.
    k1: Gain,
    /// `ψ_b² c2 / ω_b`.
    k2: Gain,
    /// `ω_b T_s`: integral increment per unit of ε (`ψ_b² c2 T_s` per unit of `ε/ω̂_AO` with
    /// the normalised integral).
    k_int: Gain,
    /// `1/k2`: the integral that gives a speed at zero error, per unit of `ω̂ |ω̂_AO|`
    /// (zero with `c2 = 0`).
    inv_k2: Gain,
    min_speed: Pu,
    /// The integral of `ε/ω̂_AO` instead of `ε` ([`MrasEmfConfig::normalised_integral`]):
    /// `k_int` is then `ψ_b² c2 T_s` and the integral carries the speed itself.
    normalised: bool,
}

impl MrasEmfConfig {
    /// MRAS with the paper's constants on an AO of gain `ao_gain_rad_s`.
    pub fn paper(
        motor: &MotorParams,
        base: &PerUnit,
        ao_gain_rad_s: f64,
    ) -> Result<Self, ConfigError> {
        Self::new(motor, base, ao_gain_rad_s, PAPER_CONSTANTS)
    }

    /// The drive's MRAS (module docs, "the drive's defaults"): the normalised integral
    /// ([`Self::normalised_integral`]); `c3` the paper's but at least
    /// `ω_b T_s` (a pull of one sample's worth per sample at base speed: the paper's 0.1 is
    /// below the stable least `ω_b T_s/2` for a fast motor at a slow PWM, a 320 V, 5459 r/min,
    /// 3-pole-pair motor at 13 kHz needs 0.103, and doubling the bound keeps the pull's series
    /// accurate); `c2` such that the adaptation's slow root `ψ² c2 c3` is
    /// [`crate::tuning::MRAS_EMF_ADAPTATION_BANDWIDTH_TS`]`/T_s`; `c1` in the paper's ratio to `c2`; the AO
    /// lag-compensated.
    pub fn default_for(
        motor: &MotorParams,
        base: &PerUnit,
        ao_gain_rad_s: f64,
    ) -> Result<Self, ConfigError> {
        let [c1, c2, _] = PAPER_CONSTANTS;
        let psi = crate::params::positive("flux_wb", motor.flux_wb)?;
        let c3 = default_c3(base);
        let c2_motor = ADAPTATION_BANDWIDTH_TS / base.sample_s / (psi * psi * c3);
        let mut c = Self::new(
            motor,
            base,
            ao_gain_rad_s,
            [c1 / c2 * c2_motor, c2_motor, c3],
        )?
        .normalised_integral(base)?;
        c.ao = AoConfig::lag_compensated(motor, base, ao_gain_rad_s)?;
        Ok(c)
    }

    /// The electrical speed, rad/s, above which the adaptation of [`MrasEmfConfig::default_for`]
    /// is damped at least [`MIN_DAMPING`]: its loop `s² + (|ω|/c3) s + ψ² c2 |ω|`
    /// (docs/solsona2000.md §5) has the damping ratio `ζ = √(|ω| T_s/(4 a c3))`, `a` =
    /// [`ADAPTATION_BANDWIDTH_TS`], which falls with the speed: `4 a c3 ζ²/T_s`. 35 rad/s at
    /// 14 kHz; a 320 V motor of two pole pairs rated 1055 r/min hands over at a tenth of its
    /// rated speed, 22 rad/s, where `ζ = 0.4`, and its estimate swung ±80 r/min about the
    /// rotor's at 33 Hz until the speed loop drove it through zero.
    pub fn damped_speed_rad_s(base: &PerUnit) -> f64 {
        let c3 = default_c3(base);
        4.0 * ADAPTATION_BANDWIDTH_TS * c3 * MIN_DAMPING * MIN_DAMPING / base.sample_s
    }

    /// The same constants with `ε/ω̂_AO` integrated instead of `ε` (module docs, "the drive's
    /// defaults"): `ω̂_Ad = (c1 ε)/ω̂_AO + c2 ∫ ε/ω̂_AO dt`, equal to eq. 29 at constant speed.
    pub fn normalised_integral(mut self, base: &PerUnit) -> Result<Self, ConfigError> {
        self.law.k_int = gain(
            "c2",
            base.flux_wb * base.flux_wb * self.constants[1] * base.sample_s,
        )?;
        self.law.normalised = true;
        Ok(self)
    }

    /// MRAS with constants `[c1, c2, c3]` (SI, electrical) on an AO of gain `ao_gain_rad_s`.
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        ao_gain_rad_s: f64,
        [c1, c2, c3]: [f64; 3],
    ) -> Result<Self, ConfigError> {
        let ts = base.sample_s;
        let wb = base.omega_e_rad_s;
        let check = |key, v: f64, min: f64, max: f64| {
            if v.is_finite() && v >= min && v <= max {
                Ok(v)
            } else {
                Err(ConfigError::Gain {
                    key,
                    value: v,
                    min,
                    max,
                })
            }
        };
        check("c1", c1, 1e-12, 1e15)?;
        check("c2", c2, 0.0, 1e15)?;
        // The pull must stay below 2 per sample at base speed (its series and stability).
        check("c3", c3, 0.5 * wb * ts, 1e9)?;
        let psi2 = base.flux_wb * base.flux_wb;
        let law = Law {
            pull: gain("c3", wb * ts / c3)?,
            step: gain(
                "sample_hz",
                wb * ts / (Angle::RAD_PER_LSB * (1u64 << 24) as f64),
            )?,
            k1: gain("c1", psi2 * c1)?,
            k2: if c2 == 0.0 {
                Gain::ZERO
            } else {
                gain("c2", psi2 * c2 / wb)?
            },
            k_int: gain("sample_hz", wb * ts)?,
            inv_k2: if c2 == 0.0 {
                Gain::ZERO
            } else {
                gain("c2", wb / (psi2 * c2))?
            },
            min_speed: pu_from_f64(MIN_SPEED_PU),
            normalised: false,
        };
        Ok(Self {
            ao: AoConfig::new(motor, base, ao_gain_rad_s)?,
            law,
            constants: [c1, c2, c3],
        })
    }
}

/// The MRAS estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct MrasEmf {
    law: Law,
    ao: Ao,
    model: AlphaBeta,
    /// Per unit, Q8.24: the running sum of `ω_b T_s ε` (eq. 29), or with the normalised
    /// integral the adapted speed's integral part itself (within ±128 pu, saturating).
    integral: Pu,
    last: Estimate,
    /// `| |ẽ| − ψ |ω̂| |`: the adjustable model's EMF against the adapted speed.
    consistency: Pu,
    /// From a reset or a held direction to the release: the estimate's speed is the AO's
    /// (module docs).
    following: bool,
}

impl MrasEmf {
    /// The floating-point values of the law it keeps (none: the constants stay in the
    /// configuration).
    pub(crate) const LAW_FLOATS: usize = <Law as crate::image::Words>::FLOATS;

    /// A new estimator at rest.
    pub fn new(config: MrasEmfConfig) -> Self {
        Self {
            ao: Ao::new(config.ao),
            law: config.law,
            model: AlphaBeta::default(),
            integral: Pu::ZERO,
            last: Estimate::default(),
            consistency: Pu::ZERO,
            following: false,
        }
    }

    /// The integral that gives the speed `omega` at zero error with the AO at `speed_ao`:
    /// `ω̂ = k2 ∫ / ω̂_AO` solved for `∫` (the speed itself with the normalised integral).
    fn integral_for(&self, omega: Pu, speed_ao: Pu) -> Pu {
        let c = &self.law;
        if c.normalised {
            return omega;
        }
        c.inv_k2.apply(mul(omega, speed_ao.max(c.min_speed)))
    }

    /// The AO that feeds the adaptation.
    pub fn ao(&self) -> &Ao {
        &self.ao
    }
}

/// `1 − exp(−x) ≈ x − x²/2 + x³/6` for `0 ≤ x ≤ 2`, Q8.24 in and out.
fn pull_fraction(x: Pu) -> Pu {
    let x = x.clamp(Pu::ZERO, Pu::from_num(2));
    let x2 = mul(x, x);
    let x3 = mul(x2, x);
    x - x2 / 2 + x3 / 6
}

impl Estimator for MrasEmf {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        let c = &self.law;
        let ao = self.ao.update(input);
        let reference = ao.emf;
        let speed_ao = ao.omega.saturating_abs().max(c.min_speed);
        // Adjustable model to t_k: exact rotation at the last adapted speed, then the pull
        // toward ê_AO (Solsona, Valla, Muravchik (2000) eq. 27–28).
        let turn = Angle(c.step.apply_bits(self.last.omega.to_bits()));
        let turned = rotate(self.model, turn.sin_cos());
        let pull = pull_fraction(c.pull.apply(speed_ao));
        self.model = approach(turned, reference, Gain::from_raw(pull.to_bits(), 24));
        // ε = ẽ × (ê_AO − ẽ) at the same instant (the bracket of Solsona, Valla, Muravchik (2000) eq. 29).
        let d = reference.saturating_sub(self.model);
        let eps = mul(d.beta, self.model.alpha).saturating_sub(mul(d.alpha, self.model.beta));
        let div = |num: Pu| {
            Pu::from_bits(sat_i32(
                // speed_ao ≥ MIN_SPEED_PU > 0; checked so that no panic path is linked.
                ((num.to_bits() as i64) << 24)
                    .checked_div(speed_ao.to_bits() as i64)
                    .unwrap_or(0),
            ))
        };
        let adapted = if c.normalised {
            let q = div(eps);
            self.integral = self.integral.saturating_add(c.k_int.apply(q));
            c.k1.apply(q).saturating_add(self.integral)
        } else {
            self.integral = self.integral.saturating_add(c.k_int.apply(eps));
            // ω̂_Ad = (k1 ε + k2 ∫) / ω̂_AO (Solsona, Valla, Muravchik (2000) eq. 29).
            div(c.k1.apply(eps).saturating_add(c.k2.apply(self.integral)))
        };
        // In the drive's open loop: the AO's speed (in the direction its AO holds).
        let omega = if self.following { ao.omega } else { adapted };
        let p = polar(self.model.alpha, self.model.beta);
        self.consistency = p
            .magnitude
            .saturating_sub(mul(self.ao.config().psi(), omega.saturating_abs()))
            .saturating_abs();
        // The AO's lag compensation turns the model's angle as it turns the AO's: by its
        // magnitude, in this estimate's sense of rotation.
        let turn = self.ao.lag();
        let lag = if (ao.omega >= Pu::ZERO) == (omega >= Pu::ZERO) {
            turn
        } else {
            Angle::ZERO - turn
        };
        self.last = Estimate {
            theta: rotor_angle_from_emf(p.angle, omega >= Pu::ZERO) + lag,
            omega,
            emf: self.model,
        };
        self.last
    }

    fn hold_direction(&mut self, forward: Option<bool>) {
        if self.following && forward.is_none() {
            // Released: the adaptation continues from the speed the estimate carries.
            let speed_ao = self.ao.estimate().omega.saturating_abs();
            self.integral = self.integral_for(self.last.omega, speed_ao);
        }
        self.following = forward.is_some();
        self.ao.hold_direction(forward);
    }

    fn estimate(&self) -> Estimate {
        self.last
    }

    fn health(&self) -> Pu {
        self.consistency
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        self.ao.reset(theta, omega);
        self.model = self.ao.estimate().emf;
        // The integral carries the speed at zero error: ω̂ = k2 ∫ / ω̂_AO.
        self.integral = self.integral_for(omega, omega.saturating_abs());
        self.consistency = Pu::ZERO;
        self.following = true;
        self.last = Estimate {
            theta,
            omega,
            emf: self.model,
        };
    }
}
