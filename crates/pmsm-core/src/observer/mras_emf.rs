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
//! `c3 = 0.1`; [`MrasEmfConfig::default_for`] raises `c3` where the sample rate is too slow
//! for it, docs/solsona2000.md §5); in per unit `ω̂_Ad = ψ_b² (c1 ε + (c2/ω_b) ω_b∫ε dt) / ω̂_AO` with
//! `ψ_b = V_b/ω_b`, which keeps the paper's behaviour for any base.
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

/// Configuration of the [`MrasEmf`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrasEmfConfig {
    ao: AoConfig,
    /// `ω_b T_s / c3`: pull rate per unit of speed.
    pull: Gain,
    /// Rotation per sample, angle LSB per LSB of per-unit speed.
    step: Gain,
    /// `ψ_b² c1`.
    k1: Gain,
    /// `ψ_b² c2 / ω_b`.
    k2: Gain,
    /// `ω_b T_s`: integral increment per unit of ε.
    k_int: Gain,
    min_speed: Pu,
    /// `c1, c2, c3` as configured.
    pub constants: [f64; 3],
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

    /// MRAS with the paper's constants, but `c3` at least `ω_b T_s` (a pull of one sample's
    /// worth per sample at base speed): the paper's 0.1 is below the stable least `ω_b T_s/2`
    /// for a fast motor at a slow PWM (a 320 V, 5459 r/min, 3-pole-pair motor at 13 kHz
    /// needs 0.103), and doubling the bound keeps the pull's series accurate.
    pub fn default_for(
        motor: &MotorParams,
        base: &PerUnit,
        ao_gain_rad_s: f64,
    ) -> Result<Self, ConfigError> {
        let [c1, c2, c3] = PAPER_CONSTANTS;
        let c3 = c3.max(base.omega_e_rad_s * base.sample_s);
        Self::new(motor, base, ao_gain_rad_s, [c1, c2, c3])
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
        check("c1", c1, 1e-9, 1e9)?;
        check("c2", c2, 0.0, 1e9)?;
        // The pull must stay below 2 per sample at base speed (its series and stability).
        check("c3", c3, 0.5 * wb * ts, 1e9)?;
        let psi2 = base.flux_wb * base.flux_wb;
        Ok(Self {
            ao: AoConfig::new(motor, base, ao_gain_rad_s)?,
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
            min_speed: pu_from_f64(MIN_SPEED_PU),
            constants: [c1, c2, c3],
        })
    }
}

/// The MRAS estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct MrasEmf {
    config: MrasEmfConfig,
    ao: Ao,
    model: AlphaBeta,
    integral: Pu,
    last: Estimate,
    /// `| |ẽ| − ψ |ω̂| |`: the adjustable model's EMF against the adapted speed.
    consistency: Pu,
}

impl MrasEmf {
    /// A new estimator at rest.
    pub fn new(config: MrasEmfConfig) -> Self {
        Self {
            ao: Ao::new(config.ao),
            config,
            model: AlphaBeta::default(),
            integral: Pu::ZERO,
            last: Estimate::default(),
            consistency: Pu::ZERO,
        }
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
        let c = &self.config;
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
        self.integral = self.integral.saturating_add(c.k_int.apply(eps));
        // ω̂_Ad = (k1 ε + k2 ∫) / ω̂_AO (Solsona, Valla, Muravchik (2000) eq. 29).
        let num = c.k1.apply(eps).saturating_add(c.k2.apply(self.integral));
        let omega = Pu::from_bits(sat_i32(
            // speed_ao ≥ MIN_SPEED_PU > 0; checked so that no panic path is linked.
            ((num.to_bits() as i64) << 24)
                .checked_div(speed_ao.to_bits() as i64)
                .unwrap_or(0),
        ));
        let p = polar(self.model.alpha, self.model.beta);
        self.consistency = p
            .magnitude
            .saturating_sub(mul(c.ao.psi(), omega.saturating_abs()))
            .saturating_abs();
        self.last = Estimate {
            theta: rotor_angle_from_emf(p.angle, omega >= Pu::ZERO),
            omega,
            emf: self.model,
        };
        self.last
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
        let speed_ao = omega.saturating_abs().max(self.config.min_speed);
        let k2 = self.config.k2.to_f64();
        let integral = if k2 > 0.0 {
            crate::units::to_f64(omega) * crate::units::to_f64(speed_ao) / k2
        } else {
            0.0
        };
        self.integral = pu_from_f64(integral);
        self.consistency = Pu::ZERO;
        self.last = Estimate {
            theta,
            omega,
            emf: self.model,
        };
    }
}
