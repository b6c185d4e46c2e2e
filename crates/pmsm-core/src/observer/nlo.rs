//! NLO: the nonlinear reduced-order observer of Solsona, Valla, Muravchik (2000) (eq. 9–10, 15–20), in the
//! singularity-free form of docs/solsona2000.md §4.
//!
//! The EMF model is its own time derivative under the mechanics of Solsona, Valla, Muravchik (2000) eq. 1–6:
//!
//! ```text
//! dê/dt = f(ê, i, ω̂) + g (e − ê)
//! f = (p K_T ψ / J) (i·û) û − (B/J) ê + ω̂ J ê,   û = ê/|ê|,  J = rotation by +90°
//! ```
//!
//! (the continuous observer `dν/dt = f + g(−R i − ê + v)`, `ê = ν − L g i`, written for its
//! EMF estimate). With exact parameters the steady-state error is zero at any constant speed.
//!
//! # Discretisation (docs/solsona2000.md §4: it matters)
//!
//! Per sample, with `Δ = ω̂ T_s` from the previous estimate:
//!
//! - the rotation `ω̂ J ê` is applied exactly, `ê ← R(Δ) ê` (forward Euler would inflate
//!   `|ê|` by `√(1 + Δ²)` per step: 0.34 % speed bias at 120 rad/s, 20 kHz);
//! - the correction compares the measured mean EMF of the interval ([`EmfMeter`]) with the mean
//!   the model predicts, `sinc(Δ/2) R(Δ/2) ê_{k−1}`, and applies it with the matched pole
//!   `κ = 1 − exp(−g T_s)`: with an exact model the innovation is zero, so a constant speed
//!   leaves no error, whatever `g T_s`;
//! - the slow mechanical terms use forward Euler.
//!
//! # The load (docs/solsona2000.md §4)
//!
//! The paper's mechanical term lets the whole current accelerate the rotor: no load torque.
//! Under a load the model then predicts an EMF that grows where the rotor's does not, and the
//! correction balances it with a standing error: the speed estimate is high by
//! `(p K_T i_L/J)/g`, the acceleration the load current `i_L` would give an unloaded rotor over
//! the observer gain. That is nothing on a heavy rotor (the papers' motors) and half the speed
//! on a light one (a gimbal motor at a tenth of its rated speed under half its rated torque).
//! The observer therefore also estimates the load as a current along `û`, `î_L`, driven by the
//! innovation along `û`:
//!
//! ```text
//! dê/dt = (p K_T ψ / J)(i·û − î_L) û − …,   î_L ← î_L − k_L (ē − ē_pred)·û
//! ```

//!
//! With `a = T_s p K_T ψ I_b/(J V_b)` (the EMF growth per sample per unit current) and the
//! matched pole `κ`, the error along `û` and the load error obey `w² + κ w + a k_L = 0`
//! (`w = z − 1`). `k_L = κ²/(64a)` leaves the EMF's pole near `1 − κ` and gives the load a
//! time constant of about `64/g` (60 ms at `g` = 1000 rad/s): slow enough that the
//! innovation's ripple does not move it (critically damped, `κ²/(4a)`, it did: a 320 V motor
//! ran at 0.051 rad rms instead of 0.013 at no load). `k_L` is capped at 2²⁰ (a rotor so
//! heavy that the load moves nothing measurable).
//!
//! When `|ê|` is below [`MIN_EMF_PU`](super::emf::MIN_EMF_PU) the direction `û` of the previous estimate is kept
//! (docs/solsona2000.md §4). Speed and angle as the AO (eq. 19–20).
//!
//! Signals: `ê` Q8.24 per unit of `V_b`; `Δ` an [`Angle`]; `sinc` Q2.30; gains [`Gain`].

use super::emf::{EmfToRotor, correct};
use super::{
    Direction, EmfMeter, EmfMeterConfig, Estimate, Estimator, ObserverInput, gain, observer_pole,
};
use crate::angle::{Angle, SinCos, sin_cos_frame};
use crate::cordic::polar;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, rotate};
use crate::num::{Gain, Pu, Unit, dot_frame, mul_unit, round_shift_sat, wmul};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Largest `k_L` (module documentation).
pub const LOAD_GAIN_MAX: f64 = 1_048_576.0;

/// Configuration of the [`Nlo`].
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct NloConfig {
    meter: EmfMeterConfig,
    kappa: Gain,
    rotor: EmfToRotor,
    /// Half the rotation per sample, angle LSB per LSB of per-unit speed: `ω_b T_s / 2`.
    half_step: Gain,
    /// `T_s p K_T ψ I_b / (J V_b)`: EMF growth per sample per unit of current along û.
    accel: Gain,
    /// `T_s B / J`.
    friction: Gain,
    /// `k_L = κ²/(64a)`: the load estimate's step per unit of innovation along `û`.
    load_gain: Gain,
}

impl NloConfig {
    /// NLO of gain `g` (rad/s) for `motor` sampled as in `base`. Uses `L_q` for an interior
    /// motor (extended EMF; the paper's model is the surface motor).
    pub fn new(motor: &MotorParams, base: &PerUnit, gain_rad_s: f64) -> Result<Self, ConfigError> {
        motor.validate()?;
        let kappa = observer_pole(base, gain_rad_s)?;
        let ts = base.sample_s;
        let half_step = 0.5 * base.omega_e_rad_s * ts / (Angle::RAD_PER_LSB * (1u64 << 24) as f64);
        let accel = ts * motor.p() * motor.kt_nm_per_a * motor.flux_wb * base.current_a
            / (motor.j_kg_m2 * base.voltage_v);
        // κ as stored (one `exp` in the image, `observer_pole`'s).
        let k = kappa.to_f64();
        let load_gain = (k * k / (64.0 * accel)).min(LOAD_GAIN_MAX);
        Ok(Self {
            meter: EmfMeterConfig::new(motor, base, motor.lq_h)?,
            load_gain: gain("j_kg_m2", load_gain)?,
            kappa,
            rotor: EmfToRotor::new(motor, base)?,
            half_step: gain("sample_hz", half_step)?,
            accel: gain("j_kg_m2", accel)?,
            friction: gain("b_nm_s", ts * motor.b_nm_s / motor.j_kg_m2)?,
        })
    }
}

/// The NLO estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct Nlo {
    config: NloConfig,
    meter: EmfMeter,
    direction: Direction,
    emf: AlphaBeta,
    /// Direction of `ê` used for the mechanical term (kept when `|ê|` is tiny), on the grid of
    /// 2⁻¹⁴: its products with the current are 32 × 16 (`dot_frame`).
    emf_dir: SinCos,
    /// `sin_cos_frame(θ̂)` of the last estimate, which the drive reuses for its frame (it takes
    /// its frames to 2⁻¹⁴): `emf_dir` is it turned a quarter whenever `|ê|` is large enough to
    /// have an angle. The direction's 10⁻⁴ is far below what the mechanical term needs.
    sc: SinCos,
    last: Estimate,
    /// `|Δα| + |Δβ|` of the last innovation (measured minus predicted interval-mean EMF).
    innovation: Pu,
    /// The load as a current along `û`, per unit, within ±[`LOAD_LIMIT`].
    load: Pu,
}

/// Bound of the load estimate, per unit of current: twice the drive's default current limit
/// (a load beyond it stops the rotor whatever the estimate). It also bounds what the
/// estimate's own start from a wrong EMF winds into it.
const LOAD_LIMIT: Pu = Pu::from_bits(2 << 24);

impl Nlo {
    /// A new observer with zero EMF estimate.
    pub fn new(config: NloConfig) -> Self {
        Self {
            meter: EmfMeter::default(),
            direction: Direction::default(),
            config,
            emf: AlphaBeta::default(),
            emf_dir: Angle::ZERO.sin_cos(),
            sc: Angle::ZERO.sin_cos(),
            last: Estimate::default(),
            innovation: Pu::ZERO,
            load: Pu::ZERO,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &NloConfig {
        &self.config
    }

    /// The load it estimates, as a current along the EMF's direction, per unit of `I_b`.
    pub fn load(&self) -> Pu {
        self.load
    }

    /// `sin_cos_frame(θ̂)` of the last estimate (on the drive's grid of 2⁻¹⁴), bit for bit.
    #[cfg_attr(feature = "select-estimators", allow(dead_code))] // the drive's, with the NLO
    pub(crate) fn rotor_sin_cos(&self) -> SinCos {
        self.sc
    }
}

/// The direction of the EMF of a rotor whose frame is `sc`: a quarter turn ahead of `θ̂`
/// turning forwards, behind it backwards (eq. 11: `θ̂ = ∠ê ∓ 90°`). Exact: a swap and a
/// negation.
#[inline(always)]
fn emf_direction(sc: SinCos, forward: bool) -> SinCos {
    if forward {
        SinCos {
            sin: sc.cos,
            cos: sc.sin.saturating_neg(),
        }
    } else {
        SinCos {
            sin: sc.cos.saturating_neg(),
            cos: sc.sin,
        }
    }
}

/// `sinc x = sin x / x ≈ 1 − x²/6 + x⁴/120` for `|x| ≤ 1` (error below 2e−4 at 1 rad,
/// below 1 LSB of Q2.30 under 0.07 rad, where the NLO runs at rated speed).
fn sinc(x: Unit) -> Unit {
    const SIXTH: i32 = 178_956_971; // 1/6, Q2.30
    const ONE_20TH: i32 = 8_947_849; // 1/120, Q2.30
    // Products of two `i32`, exact (`wmul`: no general 64-bit multiply on ARMv6-M).
    let x = x.to_bits();
    let x2 = round_shift_sat(wmul(x, x), 30);
    let x4 = round_shift_sat(wmul(x2, x2), 30);
    let s = (1i64 << 30) - round_shift_sat(wmul(x2, SIXTH), 30) as i64
        + round_shift_sat(wmul(x4, ONE_20TH), 30) as i64;
    Unit::from_bits(s as i32)
}

impl Estimator for Nlo {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        let c = &self.config;
        let previous = self.emf;
        // Half the rotation of the last speed estimate over this interval.
        let half = Angle(c.half_step.apply_bits(self.last.omega.to_bits()));
        let sc = half.sin_cos();
        let half_turned = rotate(previous, sc);
        let mut emf = rotate(half_turned, sc);
        // Mechanical terms: (p K_T ψ / J)(i·û − î_L)û − (B/J) ê, forward Euler.
        let along = dot_frame(
            input.i.alpha,
            self.emf_dir.cos.to_bits(),
            input.i.beta,
            self.emf_dir.sin.to_bits(),
        )
        .saturating_sub(self.load);
        let growth = c.accel.apply(along);
        emf.alpha = emf
            .alpha
            .saturating_add(mul_unit(growth, self.emf_dir.cos))
            .saturating_sub(c.friction.apply(previous.alpha));
        emf.beta = emf
            .beta
            .saturating_add(mul_unit(growth, self.emf_dir.sin))
            .saturating_sub(c.friction.apply(previous.beta));
        // Correction by the innovation of the interval's mean EMF.
        if let Some(measured) = self.meter.update(&self.config.meter, input.i, input.v) {
            let s = sinc(half.to_rad_unit());
            let predicted = AlphaBeta {
                alpha: mul_unit(half_turned.alpha, s),
                beta: mul_unit(half_turned.beta, s),
            };
            let innovation = measured.saturating_sub(predicted);
            self.innovation = innovation.l1_norm();
            // The load is learnt in the closed loop only: in the drive's open loop the current
            // follows the imposed frame, not the rotor, and a load that stalls the open loop
            // would be learnt as one the estimate must fight.
            if !self.direction.is_held() {
                let along = dot_frame(
                    innovation.alpha,
                    self.emf_dir.cos.to_bits(),
                    innovation.beta,
                    self.emf_dir.sin.to_bits(),
                );
                self.load = self
                    .load
                    .saturating_sub(c.load_gain.apply(along))
                    .max(-LOAD_LIMIT)
                    .min(LOAD_LIMIT);
            }
            emf = correct(emf, measured, predicted, c.kappa);
        }
        self.emf = emf;
        let p = polar(emf.alpha, emf.beta);
        self.last = c.rotor.estimate(emf, p, &mut self.direction);
        // One sin/cos for the rotor's frame, which the drive reuses, and the EMF's direction.
        self.sc = sin_cos_frame(self.last.theta);
        if c.rotor.has_angle(&p) {
            let forward = p.angle - self.last.theta == Angle::HALF_PI;
            self.emf_dir = emf_direction(self.sc, forward);
        }
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
        let forward = omega >= Pu::ZERO;
        self.sc = sin_cos_frame(theta);
        self.emf_dir = emf_direction(self.sc, forward);
        self.meter.restart();
        self.innovation = Pu::ZERO;
        // Along the new û a load that opposed the motion may push it: learnt again.
        self.load = Pu::ZERO;
        self.direction.reset(forward);
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
    use crate::fixtures::{base_b, motor_b};
    use crate::num::pu_from_f64;

    /// Over a run on a turning EMF, forwards and backwards: the frame the drive reuses is
    /// `sin_cos_frame(θ̂)` bit for bit, and the EMF's direction, a quarter turn of it, is the
    /// sin/cos of the EMF estimate's own angle within the grid's step, 2⁻¹⁴ (2¹⁶ LSB of
    /// Q2.30), and the 2⁻²² of `sin_cos_frame` before it takes its value down.
    #[test]
    fn one_sin_cos_gives_the_frame_and_the_emf_direction() {
        let (m, base) = (motor_b(), base_b());
        let mut nlo = Nlo::new(NloConfig::new(&m, &base, 1000.0).unwrap());
        for speed in [0.3, -0.3] {
            let omega = pu_from_f64(speed);
            nlo.reset(Angle::from_deg(40.0), omega);
            let (mut worst, mut compared) = (0i32, 0);
            for k in 0..2000 {
                // The EMF of a rotor at the estimated speed, applied as the voltage at zero current.
                let theta = Angle::from_rad(speed * base.omega_e_rad_s * base.sample_s * k as f64)
                    + Angle::from_deg(40.0);
                let v = nlo.config.rotor.emf_of(theta, omega);
                let e = nlo.update(&ObserverInput {
                    i: AlphaBeta::default(),
                    v,
                });
                assert_eq!(nlo.rotor_sin_cos(), sin_cos_frame(e.theta), "step {k}");
                let p = polar(nlo.emf.alpha, nlo.emf.beta);
                if nlo.config.rotor.has_angle(&p) {
                    let exact = p.angle.sin_cos();
                    compared += 1;
                    worst = worst
                        .max((nlo.emf_dir.sin - exact.sin).to_bits().abs())
                        .max((nlo.emf_dir.cos - exact.cos).to_bits().abs());
                }
            }
            assert!(
                compared > 1900 && worst < (1 << 16) + (1 << 8),
                "{speed}: {compared}, {worst} LSB"
            );
        }
    }
}
