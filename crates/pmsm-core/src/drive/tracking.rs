//! On-line tracking of the stator resistance `R` and the magnet flux `ψ` (docs/tracking.md):
//! off the control path, in the drive's task (design key `tracking`), it reads what the
//! interrupt side's window already carries at each task period (the estimated frame, the measured current in it, the voltage the estimator saw,
//! the speed) and rewrites the coefficients of the drive's model that depend on `R` and `ψ`
//! (the current-model MRAS of Khlaief, Boussak, Gossa (2012), and the `ψ` of the current
//! loops' feed-forward) through [`Drive::set_model`].
//!
//! # Measurement
//!
//! In steady state, in the rotor frame, `v = R i + ω (−L_q i_q, L_d i_d) + ω ψ (0, 1)`. In the
//! estimated frame, off by an angle `δ`, the EMF `ω ψ (−sin δ, cos δ)` turns with it while
//! `R i` and (nearly) the inductive drop keep their form. So with the model's inductances,
//! `w = v̂ − ω̂ (−L̂_q î_q, L̂_d î_d)` and the unit vector `n` along `ê = w − R̂ î`,
//!
//! ```text
//! y = n · w = R (n · î) + |ω̂| ψ        (linear in R and ψ, whatever δ is)
//! ```
//!
//! An inductance error adds `ω ΔL i` across the EMF, which tilts `n` but hardly changes `y`
//! (a second-order `ψ` error, 1 % for `L_q` off by 30 % at rated current).
//!
//! # Estimation
//!
//! A two-state Kalman filter on `x = (R/R₀, ψ/ψ₀)` (`R₀`, `ψ₀` the drive's model): the prior
//! is the model's uncertainty (independent, [`TrackerDesign::rs_sigma`],
//! [`TrackerDesign::flux_sigma`]); the drift is a random walk of the temperature, moving `R`
//! and `ψ` together by the copper's and the magnet's coefficients. At one operating point only
//! the sum `R (n·î) + |ω| ψ` is observed; the filter splits a change of it as the drift does
//! (a rise of temperature: `R` up, `ψ` down) and as the prior does (at speed mostly `ψ`, at
//! low speed under load mostly `R`), and operating points with another `i/ω` ratio separate
//! the two. Bounds: `R̂` within [`TrackerDesign::rs_range`], `ψ̂` within
//! [`TrackerDesign::flux_range`] of the model; [`TrackerStatus`] says when one is at a bound.
//!
//! Gates (nothing learnt, the last values kept): outside `Run`, for
//! [`TrackerDesign::settle_s`] after entering it, below [`TrackerDesign::min_speed_rad_s`]
//! (and on the way up until an eighth above it),
//! where the inverter's residual voltage (the dead time near zero current,
//! [`TrackerDesign::inverter_error_v`]) is more than [`TrackerDesign::max_inverter_ratio`] of
//! the EMF, with the modulator saturated, the
//! current away from its reference (a transient, where `L di/dt` is not in the model) or the
//! speed changing faster than [`TrackerDesign::max_accel_rad_s2`] (a ramp: the estimated frame
//! lags and the current carries the acceleration). Where the current moves (a limit cycle of
//! the loops, the settling of a load step) the measurement's noise grows by the voltage
//! `L di/dt` of that motion ([`TrackerDesign::transient_weight`]): it is not in the model, and
//! it correlates with the regressor, so learning through it biases the split.
//!
//! # Cost
//!
//! `f32` arithmetic: about a hundred operations, one sin/cos and three square roots per
//! [`Tracker::update`]; the new coefficients ([`Tracker::coefficients`], two exponentials and
//! about forty operations) only when the estimates, low-passed over
//! [`TrackerDesign::apply_time_s`], moved by more than [`WRITE_THRESHOLD`].
//! [`Drive::set_model`] copies 14 words. On a Cortex-M0, whose `f32` is software at about 140
//! instructions an operation, an update costs about 13 000 instructions and a write 9 000,
//! more than a task period's budget; the drive's task runs them as [`Tracker::task_step`]'s
//! [`TRACKER_STAGES`] stages of at most 5 000, one per task period, the same bits as
//! `update` then `coefficients`, at the start of a cycle of
//! [`TrackerDesign::interval_samples`] (by default ten task periods, the last five idle).

use super::{Drive, DriveState};
use crate::angle::Angle;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, Dq};
use crate::num::{PU_FRAC, Pu};
use crate::observer::{MrasDecay, MrasModel, MrasModelScaling};
use crate::params::{MotorParams, in_range};
use crate::units::PerUnit;

mod design;
mod filter;
pub use design::TrackerDesign;
use filter::{Measurement, Sample};

/// Relative change of `R̂` or `ψ̂` since the last write that makes [`Tracker::update`] ask for
/// a new write.
pub const WRITE_THRESHOLD: f32 = 2e-4;

/// The working stages of [`Tracker::task_step`]'s cycle, one per task period: an update's
/// three parts, then the new coefficients' decay and weights (module docs, "Cost"). The cycle
/// lasts [`TrackerDesign::interval_samples`] (at least these stages' task periods); the task
/// periods after its stages are idle.
pub const TRACKER_STAGES: u32 = 5;

/// What one stage of [`Tracker::task_step`] leaves the next.
#[derive(Clone, Copy, Debug, Default)]
enum Work {
    /// Nothing (frozen, or no write due).
    #[default]
    Idle,
    /// The update's sample, for its measurement.
    Sampled(Sample),
    /// The update's measurement, for its correction.
    Measured(Measurement),
    /// The estimates moved: a write is due.
    Due,
    /// The write's decay, for its weights.
    Decayed(MrasDecay),
}

/// Time constant of the tracker's filters on the estimated speed and its derivative, s.
pub const SPEED_FILTER_S: f64 = 0.02;

/// What the tracker reads of a drive after a step: a few words of the interrupt side's
/// window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackerInput {
    /// Whether the drive runs in the closed loop.
    pub running: bool,
    /// The estimated frame's angle and speed.
    pub theta: Angle,
    /// Estimated speed, per unit of `ω_b`.
    pub omega: Pu,
    /// Measured current in the estimated frame, and its reference, per unit.
    pub i_dq: Dq,
    /// The current reference, per unit.
    pub i_ref: Dq,
    /// The voltage applied over the coming period as the estimator will see it (after the
    /// dead-time correction), αβ, per unit.
    pub v: AlphaBeta,
    /// The modulator or a current loop was at its limit.
    pub saturated: bool,
}

impl TrackerInput {
    /// The input of the drive's last step.
    pub fn sample(drive: &Drive) -> Self {
        let t = drive.telemetry();
        Self {
            running: drive.state() == DriveState::Run,
            theta: t.theta,
            omega: t.estimate.omega,
            i_dq: t.i_dq,
            i_ref: t.i_ref,
            v: drive.estimator_voltage(),
            saturated: t.saturated,
        }
    }
}

/// The coefficients of the drive that depend on `R` and `ψ` ([`Drive::set_model`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ModelCoefficients {
    /// The current-model MRAS's.
    pub mras: MrasModel,
    /// `ψ` of the current loops' feed-forward, per unit.
    pub psi: Pu,
}

/// Why an update did not learn.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Frozen {
    /// Not in `Run` (idle, detection, alignment, open loop, fault).
    #[default]
    NotRunning,
    /// Within [`TrackerDesign::settle_s`] of entering `Run`.
    Settling,
    /// Below [`TrackerDesign::min_speed_rad_s`].
    LowSpeed,
    /// The inverter's residual voltage above [`TrackerDesign::max_inverter_ratio`] of the
    /// EMF (light load at low speed).
    Inverter,
    /// The modulator or a current loop at its limit.
    Saturated,
    /// The current away from its reference, or the speed changing (a ramp).
    Transient,
}

/// What the tracker did at its last update, and where its estimates are.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct TrackerStatus {
    /// The last update learnt (all gates open).
    pub learning: bool,
    /// Why the last update did not learn (meaningless when `learning`).
    pub frozen: Frozen,
    /// `R̂` is at a bound of [`TrackerDesign::rs_range`].
    pub rs_at_bound: bool,
    /// `ψ̂` is at a bound of [`TrackerDesign::flux_range`].
    pub flux_at_bound: bool,
    /// Updates that learnt since the start.
    pub learnt: u32,
}

/// The tracker: design in per unit, and the filter's state (`f32`).
#[derive(Clone, Copy, Debug)]
pub struct Tracker {
    /// The model's coefficients as functions of `R̂/R₀` and `ψ̂/ψ₀`.
    model: MrasModelScaling,
    /// `R₀` in Ω and `ψ₀` in Wb, as the drive was given them.
    rs0_ohm: f64,
    flux0_wb: f64,
    design: TrackerDesign,
    /// `R₀`, `ψ₀`, `L_d`, `L_q` of the model, per unit.
    r0: f32,
    psi0: f32,
    ld: f32,
    lq: f32,
    /// Half a sample's rotation per unit of speed, rad.
    half_turn: f32,
    min_speed: f32,
    max_di: f32,
    /// `max_accel_rad_s2` per unit of `ω_b` per update; the filters' gain per update.
    max_dw: f32,
    filter: f32,
    /// The filtered speed and its filtered change per update, per unit.
    w_f: f32,
    dw_f: f32,
    /// The inverter's residual per unit, its current band (infinite without compensation),
    /// and the largest ratio to the EMF.
    inv_v: f32,
    band: f32,
    inv_ratio: f32,
    /// The current low-passed over [`TrackerDesign::motion_filter_s`] (its gain per update),
    /// its mean motion `L_d |Δi_d| + L_q |Δi_q|`, per unit; the weight turning that into volts
    /// of noise.
    motion_pre: f32,
    i_last: [f32; 2],
    motion: f32,
    motion_gain: f32,
    settle_updates: u32,
    noise2: f32,
    /// Process noise per update `(q_RR, q_Rψ, q_ψψ)` and the largest variances.
    q: [f32; 3],
    p_max: [f32; 2],
    lo: [f32; 2],
    hi: [f32; 2],
    max_step: f32,
    /// [`TrackerDesign::rs_min_drop_ratio`].
    drop_ratio: f32,
    /// `(R/R₀, ψ/ψ₀)`, its covariance `(p_RR, p_Rψ, p_ψψ)`, their low-pass (what the drive
    /// is given) and its values last written.
    x: [f32; 2],
    p: [f32; 3],
    applied: [f32; 2],
    apply_gain: f32,
    written: [f32; 2],
    /// Updates in `Run` since entering it.
    run_updates: u32,
    /// Below the least speed since last under it and not yet above it by [`SPEED_HYSTERESIS`].
    slow: bool,
    status: TrackerStatus,
    /// [`Tracker::task_step`]'s place in its cycle, the cycle's task periods
    /// ([`TrackerDesign::interval_samples`] in whole task periods, at least [`TRACKER_STAGES`]),
    /// and what its last stage left the next.
    stage: u32,
    cycle_periods: u32,
    work: Work,
}

/// The speed gate's hysteresis: frozen below [`TrackerDesign::min_speed_rad_s`], learning
/// again only above it by this share. A speed held at the gate dithers across it, and every
/// return to learning after a freeze comes with the covariance the freeze let grow, so each
/// swing would teach a large step (docs/tracking.md, "Where it does not learn").
const SPEED_HYSTERESIS: f32 = 0.125;

/// One step of a first-order low-pass: `y + g (x − y)`.
fn toward(y: f32, x: f32, g: f32) -> f32 {
    y + g * (x - y)
}

/// A [`Pu`] as `f32` (also the distortion learner's).
pub(super) fn pu(x: Pu) -> f32 {
    x.to_bits() as f32 * (1.0 / (1u32 << PU_FRAC) as f32)
}

/// `(sin θ, cos θ)` as `f32`, from the core's table ([`Angle::sin_cos`], within 3·10⁻⁹): the
/// learners' trigonometry without `f32` tables of its own in a firmware image.
pub(super) fn sin_cos_f32(theta: Angle) -> (f32, f32) {
    let sc = theta.sin_cos();
    let q30 = 1.0 / (1u32 << 30) as f32;
    (sc.sin.to_bits() as f32 * q30, sc.cos.to_bits() as f32 * q30)
}

impl Tracker {
    /// The tracker of a drive built from `motor` (its model of the motor) with the bases
    /// `base`.
    ///
    /// Errors: [`ConfigError::Param`] naming the `tracking.*` field out of its range.
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        design: TrackerDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let d = design;
        in_range(
            "tracking.interval_samples",
            d.interval_samples as f64,
            1.0,
            1e4,
        )?;
        in_range(
            "tracking.min_speed_rad_s",
            d.min_speed_rad_s,
            0.0,
            4.0 * base.omega_e_rad_s,
        )?;
        in_range(
            "tracking.max_current_error_a",
            d.max_current_error_a,
            0.0,
            1e6,
        )?;
        in_range("tracking.settle_s", d.settle_s, 0.0, 100.0)?;
        in_range("tracking.max_accel_rad_s2", d.max_accel_rad_s2, 0.0, 1e9)?;
        in_range("tracking.rs_sigma", d.rs_sigma, 1e-6, 10.0)?;
        in_range("tracking.flux_sigma", d.flux_sigma, 1e-6, 10.0)?;
        in_range("tracking.rs_range.0", d.rs_range.0, 0.01, 1.0)?;
        in_range("tracking.rs_range.1", d.rs_range.1, 1.0, 100.0)?;
        in_range("tracking.flux_range.0", d.flux_range.0, 0.1, 1.0)?;
        in_range("tracking.flux_range.1", d.flux_range.1, 1.0, 10.0)?;
        in_range("tracking.rs_per_k", d.rs_per_k, -0.1, 0.1)?;
        in_range("tracking.flux_per_k", d.flux_per_k, -0.1, 0.1)?;
        in_range(
            "tracking.drift_k_per_sqrt_s",
            d.drift_k_per_sqrt_s,
            0.0,
            1e3,
        )?;
        in_range(
            "tracking.independent_per_sqrt_s",
            d.independent_per_sqrt_s,
            0.0,
            10.0,
        )?;
        in_range("tracking.noise_v", d.noise_v, 1e-9, 1e6)?;
        in_range("tracking.max_step", d.max_step, 1e-6, 1.0)?;
        in_range("tracking.apply_time_s", d.apply_time_s, 0.0, 100.0)?;
        in_range("tracking.inverter_error_v", d.inverter_error_v, 0.0, 1e4)?;
        if let Some(band) = d.current_band_a {
            in_range("tracking.current_band_a", band, 1e-9, 1e6)?;
        }
        in_range(
            "tracking.max_inverter_ratio",
            d.max_inverter_ratio,
            1e-6,
            1e3,
        )?;
        in_range("tracking.transient_weight", d.transient_weight, 0.0, 1e4)?;
        in_range("tracking.motion_filter_s", d.motion_filter_s, 0.0, 1.0)?;
        in_range("tracking.rs_min_drop_ratio", d.rs_min_drop_ratio, 0.0, 10.0)?;
        Ok(Self::build(motor, base, design))
    }

    /// [`Tracker::new`] without the checks: for a design the drive made itself
    /// ([`TrackerDesign::for_drive`] of a configuration that was checked), so that a firmware
    /// links no check of keys it never sets.
    pub(crate) fn build(motor: &MotorParams, base: &PerUnit, design: TrackerDesign) -> Self {
        let d = design;
        let dt = d.interval_samples as f64 * base.sample_s;
        let drift2 = d.drift_k_per_sqrt_s * d.drift_k_per_sqrt_s * dt;
        let ind2 = d.independent_per_sqrt_s * d.independent_per_sqrt_s * dt;
        let (gr, gp) = (d.rs_per_k, d.flux_per_k);
        let (vr, vp) = (d.rs_sigma * d.rs_sigma, d.flux_sigma * d.flux_sigma);
        Self {
            model: MrasModelScaling::new(motor, base),
            rs0_ohm: motor.rs_ohm,
            flux0_wb: motor.flux_wb,
            design,
            r0: (motor.rs_ohm / base.impedance_ohm) as f32,
            psi0: (motor.flux_wb / base.flux_wb) as f32,
            ld: (motor.ld_h / base.inductance_h) as f32,
            lq: (motor.lq_h / base.inductance_h) as f32,
            half_turn: (0.5 * base.omega_e_rad_s * base.sample_s) as f32,
            min_speed: (d.min_speed_rad_s / base.omega_e_rad_s) as f32,
            max_di: (d.max_current_error_a / base.current_a) as f32,
            max_dw: (d.max_accel_rad_s2 * dt / base.omega_e_rad_s) as f32,
            filter: (dt / SPEED_FILTER_S).min(1.0) as f32,
            w_f: 0.0,
            dw_f: 0.0,
            inv_v: (d.inverter_error_v / base.voltage_v) as f32,
            band: d
                .current_band_a
                .map_or(f32::INFINITY, |b| (b / base.current_a) as f32),
            inv_ratio: d.max_inverter_ratio as f32,
            motion_pre: (dt / d.motion_filter_s).min(1.0) as f32,
            i_last: [0.0; 2],
            motion: 0.0,
            // Volts per unit of `L Δi` over one update (`Δt ω_b` in per-unit time).
            motion_gain: (d.transient_weight / (dt * base.omega_e_rad_s)) as f32,
            settle_updates: libm::ceil(d.settle_s / dt) as u32,
            noise2: ((d.noise_v / base.voltage_v) * (d.noise_v / base.voltage_v)) as f32,
            q: [
                (drift2 * gr * gr + ind2) as f32,
                (drift2 * gr * gp) as f32,
                (drift2 * gp * gp + ind2) as f32,
            ],
            p_max: [vr as f32, vp as f32],
            lo: [d.rs_range.0 as f32, d.flux_range.0 as f32],
            hi: [d.rs_range.1 as f32, d.flux_range.1 as f32],
            max_step: d.max_step as f32,
            drop_ratio: d.rs_min_drop_ratio as f32,
            x: [1.0, 1.0],
            p: [vr as f32, 0.0, vp as f32],
            applied: [1.0, 1.0],
            apply_gain: (dt / d.apply_time_s).min(1.0) as f32,
            written: [1.0, 1.0],
            run_updates: 0,
            slow: true,
            status: TrackerStatus::default(),
            stage: 0,
            cycle_periods: (d.interval_samples / crate::drive::TASK_PERIOD).max(TRACKER_STAGES),
            work: Work::Idle,
        }
    }

    /// The design.
    pub fn design(&self) -> &TrackerDesign {
        &self.design
    }

    /// The tracked resistance as the drive is given it, Ω.
    pub fn rs_ohm(&self) -> f64 {
        self.rs0_ohm * self.applied[0] as f64
    }

    /// The tracked magnet flux as the drive is given it, Wb.
    pub fn flux_wb(&self) -> f64 {
        self.flux0_wb * self.applied[1] as f64
    }

    /// `(R̂/R₀, ψ̂/ψ₀)` as the drive is given them (after the low-pass).
    pub fn applied(&self) -> (f32, f32) {
        (self.applied[0], self.applied[1])
    }

    /// The filter's `(R̂/R₀, ψ̂/ψ₀)` (before the low-pass to the drive).
    pub fn ratios(&self) -> (f32, f32) {
        (self.x[0], self.x[1])
    }

    /// The status of the last update.
    pub fn status(&self) -> TrackerStatus {
        self.status
    }

    /// One update on what a step left (every [`TrackerDesign::interval_samples`] samples).
    /// Returns whether the estimates moved enough since the last write for
    /// [`Tracker::coefficients`] to be written to the drive.
    pub fn update(&mut self, input: &TrackerInput) -> bool {
        if let Some(m) = self.begin(input).and_then(|s| self.measure(&s)) {
            self.learn_from(&m);
        }
        self.apply()
    }

    /// One task period's share of the tracker's work, in a cycle of
    /// [`TrackerDesign::interval_samples`] (in whole task periods, at least
    /// [`TRACKER_STAGES`]) whose first [`TRACKER_STAGES`] task periods work: the gates
    /// and the drift on `input` (the only stage that reads it), the measurement, the correction
    /// and the low-pass to the drive, then, when that moved by more than [`WRITE_THRESHOLD`],
    /// the new coefficients' decay and their weights, returned at the last working stage; the
    /// cycle's other task periods do nothing. The stages compute the bits of
    /// [`Tracker::update`] then [`Tracker::coefficients`], each about a fifth of their cost (a
    /// Cortex-M0 has no FPU: docs/tracking.md, "Cost on the MCU").
    pub fn task_step(&mut self, input: &TrackerInput) -> Option<ModelCoefficients> {
        let stage = self.stage;
        self.stage = if stage + 1 < self.cycle_periods {
            stage + 1
        } else {
            0
        };
        let work = core::mem::take(&mut self.work);
        match (stage, work) {
            (0, _) => {
                if let Some(s) = self.begin(input) {
                    self.work = Work::Sampled(s);
                }
            }
            (1, Work::Sampled(s)) => {
                if let Some(m) = self.measure(&s) {
                    self.work = Work::Measured(m);
                }
            }
            (2, work) => {
                if let Work::Measured(m) = work {
                    self.learn_from(&m);
                }
                if self.apply() {
                    self.work = Work::Due;
                }
            }
            (3, Work::Due) => self.work = Work::Decayed(self.model.decay(self.applied[0])),
            (4, Work::Decayed(d)) => return self.written_from(&d).ok(),
            _ => {}
        }
        None
    }

    /// The low-pass from the filter's estimates to the values the drive is given; whether they
    /// moved by more than [`WRITE_THRESHOLD`] since the last write.
    fn apply(&mut self) -> bool {
        let g = self.apply_gain;
        self.applied = [
            toward(self.applied[0], self.x[0], g),
            toward(self.applied[1], self.x[1], g),
        ];
        libm::fabsf(self.applied[0] - self.written[0]) > WRITE_THRESHOLD
            || libm::fabsf(self.applied[1] - self.written[1]) > WRITE_THRESHOLD
    }

    /// The drive's coefficients for the current estimates (`f32`, [`MrasModel`]'s `f64`
    /// reference within a few LSB), and marks them written.
    ///
    /// Errors: [`ConfigError::Gain`] if a coefficient leaves its format (not with the
    /// default bounds on a motor whose drive could be built).
    pub fn coefficients(&mut self) -> Result<ModelCoefficients, ConfigError> {
        self.written_from(&self.model.decay(self.applied[0]))
    }

    /// The coefficients at the applied estimates from their decay, marked written.
    fn written_from(&mut self, decay: &MrasDecay) -> Result<ModelCoefficients, ConfigError> {
        let s_psi = self.applied[1];
        let c = ModelCoefficients {
            mras: self.model.weights(decay, s_psi)?,
            psi: Pu::from_bits(libm::roundf(self.psi0 * s_psi * (1u32 << PU_FRAC) as f32) as i32),
        };
        self.written = self.applied;
        Ok(c)
    }

    /// Samples `drive`, updates, and writes the new coefficients when they moved: the whole
    /// background task for a caller that owns the drive (the simulator). On an MCU: take
    /// [`TrackerInput::sample`] and call [`Drive::set_model`] with the control interrupt
    /// masked, and [`Tracker::update`] and [`Tracker::coefficients`] in between.
    pub fn run(&mut self, drive: &mut Drive) {
        if self.update(&TrackerInput::sample(drive))
            && let Ok(c) = self.coefficients()
        {
            drive.set_model(&c);
        }
    }
}

#[cfg(test)]
mod tests;
