//! On-line learning of the inverter's distortion voltage while running (docs/distortion.md):
//! off the control path like [`super::Tracker`], in the drive's task (design key
//! `deadtime_learning`), it reads the interrupt side's window at each task period and
//! rescales the dead-time compensation's `V_dead` ([`Drive::set_deadtime_scale`]) to the one
//! the inverter shows.
//!
//! # Measurement
//!
//! The inverter takes `V_true P` from every command, `P` the Clarke transform of the phase
//! currents' signs (a hexagon of length 4/3); the compensation adds back `V_c P` (`V_c` the
//! told `V_dead` times the scale in use). What the current loops put out, which is what the
//! estimator is given, is therefore
//!
//! ```text
//! u = R i + L di/dt + ω J L i + e_ω + e P,     e = V_true − V_c
//! ```
//!
//! In the rotor frame `P` is a constant plus a ripple at six times the electrical angle (the
//! sector steps), which nothing else in a sinusoidal motor carries. Demodulated at `6θ̂` over
//! a batch, with the means taken out, the voltage's and the current's ripple phasors `U`, `I`
//! and the pattern's `P₆` obey, per axis,
//!
//! ```text
//! U_d − (R + j6ωL_d) I_d + ω L_q I_q = e P₆d
//! U_q − (R + j6ωL_q) I_q − ω L_d I_d = e P₆q
//! ```
//!
//! and `ê` is their least-squares solution. The current loops share the ripple between `U`
//! (below their bandwidth) and `I` (above it); the impedance puts the two together, so the
//! estimate holds at any speed the decimated sampling resolves. A wrong `R` or `L` changes the
//! estimate's gain, not its zero: with `e = 0` there is no ripple at all (apart from the
//! fading of the sign near zero current, hence the current gate).
//!
//! # Update
//!
//! At the end of each batch whose predecessor agrees in sign, the scale read is the one in use
//! plus [`DistortionDesign::gain`] times the smaller `ê` of the two over the told `V_dead`
//! (at most [`DistortionDesign::max_step`] from it), within
//! [`DistortionDesign::scale_range`]. It is written to the drive when it moved by more than
//! [`DistortionDesign::write_threshold`] and lies beyond [`DistortionDesign::dead_band`] of
//! the scale the drive had (told, or calibrated at standstill); within that band the drive
//! keeps its own. The batch is thrown away when the speed or the current reference's length
//! moved, or the length spread, by more than [`DistortionDesign::max_speed_change`] of its
//! mean in it.
//! Gates (the sample is skipped): outside `Run`, [`DistortionDesign::settle_s`] after
//! entering it, below [`DistortionDesign::min_speed_rad_s`] (too few sector steps per batch)
//! or where the sixth harmonic turns by more than a quarter turn between two updates, with
//! the current within [`DistortionDesign::min_current_bands`] of the compensation's band, or
//! the modulator or a current loop at its limit.
//!
//! # Cost
//!
//! Integers while it listens (two sin/cos from the table, three Park rotations, a dozen
//! products: no software `f32` on a Cortex-M0); a batch's end, about 90 `f32` operations, over
//! the five updates after it (`batch`).

mod batch;

use super::tracking::pu;
use super::{Drive, DriveConfig, TrackerInput};
use crate::angle::Angle;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, Dq, inverse_park, park};
use crate::num::{PU_FRAC, Pu, pu_from_f64};
use crate::params::{MotorParams, ParamError, ParamReason, in_range};
use batch::{Batch, End, HARMONIC_FRAC, Model, SIGNAL_FRAC, within};

/// How the learner is designed, SI units; [`DistortionDesign::for_drive`] gives the defaults.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DistortionDesign {
    /// Control samples between two calls of [`DistortionLearner::update`].
    pub interval_samples: u32,
    /// Length of a batch, s.
    pub batch_s: f64,
    /// Least electrical speed at which the learner listens, rad/s.
    pub min_speed_rad_s: f64,
    /// Time in `Run` before the learner listens, s.
    pub settle_s: f64,
    /// The current's length must exceed this many times the compensation's current band.
    pub min_current_bands: f64,
    /// A batch in which the speed, or the current reference's length (the mean of its second
    /// half against its first), moved by more than this fraction of its mean is discarded (a ramp, a load step: a step inside a batch
    /// leaks into the demodulation).
    pub max_speed_change: f64,
    /// Largest change of the scale per batch.
    pub max_step: f64,
    /// Fraction of the measured error taken at each batch (0–1].
    pub gain: f64,
    /// The scale is kept within this range.
    pub scale_range: (f64, f64),
    /// Smallest change of the scale written to the drive.
    pub write_threshold: f64,
    /// A scale within this of the one the drive had (told, or calibrated at standstill) is
    /// not written: on an inverter it was told right the learner reads a few percent off one
    /// (docs/distortion.md, "What it reads on an inverter it was told right").
    pub dead_band: f64,
    /// The compensation's `V_dead` at the nominal bus, V (what the drive was told).
    pub v_dead_v: f64,
    /// The compensation's current band, A.
    pub band_a: f64,
}

impl DistortionDesign {
    /// For `config`'s dead-time compensation: an update every task period, batches of
    /// 0.2 s, from three electrical turns per batch up, 50 ms after entering `Run`, the
    /// current beyond ten bands, the speed and the current reference within 10 %, three
    /// quarters of the error per batch and at most a quarter, the scale within [0.25, 4],
    /// written when it moved by 3 % (the standstill calibration's dead band) and lies 15 %
    /// or more from the drive's own.
    pub fn for_drive(config: &DriveConfig) -> Self {
        let batch_s = 0.2;
        Self {
            interval_samples: super::TASK_PERIOD,
            batch_s,
            min_speed_rad_s: 3.0 * core::f64::consts::TAU / batch_s,
            settle_s: 0.05,
            min_current_bands: 10.0,
            max_speed_change: 0.1,
            max_step: 0.25,
            gain: 0.75,
            scale_range: (0.25, 4.0),
            write_threshold: 0.03,
            dead_band: 0.15,
            v_dead_v: if config.deadtime_compensation() {
                config.v_dead_nominal_v()
            } else {
                0.0
            },
            band_a: config.design.deadtime.band_a,
        }
    }
}

/// Why the last update did not listen.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum DistortionFrozen {
    /// Not in `Run`.
    #[default]
    NotRunning,
    /// Within [`DistortionDesign::settle_s`] of entering `Run`.
    Settling,
    /// Below [`DistortionDesign::min_speed_rad_s`], or too fast for the update rate.
    Speed,
    /// The current within [`DistortionDesign::min_current_bands`] bands of zero.
    LowCurrent,
    /// The modulator or a current loop at its limit.
    Saturated,
}

/// What the learner did at its last update, and where its estimate is.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct DistortionStatus {
    /// The last update was accumulated.
    pub listening: bool,
    /// Why not (meaningless when `listening`).
    pub frozen: DistortionFrozen,
    /// Batches completed and used.
    pub batches: u32,
    /// Batches discarded (the speed moved).
    pub discarded: u32,
    /// The last batch's `ê = V_true − V_c`, V at the nominal bus's scale.
    pub error_v: f32,
    /// The scale the learner holds (of the told `V_dead`): its own, or the drive's when that
    /// changed since the last write.
    pub scale: f32,
}

/// The learner: design in per unit, a batch's sums (integers) and the scale (`f32`).
#[derive(Clone, Copy, Debug)]
pub struct DistortionLearner {
    /// The design's gates and steps that the updates read, as `f32` (the `f64` design is not
    /// kept: the learner's state is part of the task's).
    max_speed_change: f32,
    max_step: f32,
    scale_range: (f32, f32),
    write_threshold: f32,
    dead_band: f32,
    model: Model,
    /// The scale's step per unit of `ê` (the gain over the told `V_dead` per unit), volts per
    /// unit of voltage.
    gain_per_pu: f32,
    volts_per_pu: f32,
    /// `2²⁰` over the band per unit (at most 2⁴⁰).
    inv_band_q20: i64,
    /// The square of the current below which it does not listen, in Q12 per unit squared.
    min_current_sq: i64,
    /// The speed's range where it listens, Q8.24 bits.
    min_speed: i32,
    max_speed: i32,
    batch_updates: u32,
    settle_updates: u32,
    run_updates: u32,
    batch: Batch,
    /// The scale last written (or read from the drive); the one read is the status's.
    written: f32,
    /// The drive's own scale (told, or calibrated), which readings within the dead band leave
    /// in place.
    own: f32,
    /// The last used batch's `ê` per unit, zero when none since the scale came from the drive:
    /// a batch moves the scale only when its predecessor agrees.
    last_error: f32,
    status: DistortionStatus,
}

/// The Clarke transform of the phase currents' signs (amplitude-invariant, length 4/3 between
/// sector steps), in Q12, each sign linear within the band as the compensation's is, from the
/// current `i` (αβ, per unit); `inv_band_q20` is `2²⁰/band` (at most 2⁴⁰: each product below
/// 2⁶¹).
fn sign_pattern(i: AlphaBeta, inv_band_q20: i64) -> (i32, i32) {
    const ONE: i64 = 1 << SIGNAL_FRAC;
    let sg = |x: i64| (((x >> (PU_FRAC - SIGNAL_FRAC)) * inv_band_q20) >> 20).clamp(-ONE, ONE);
    let a = i64::from(i.alpha.to_bits());
    // The phases b and c: −a/2 ± (√3/2) β (56756/2¹⁶ = √3/2 to 10⁻⁵).
    let h = crate::num::wmul(i.beta.to_bits(), 56_756) >> 16;
    let (sa, sb, sc) = (sg(a), sg(-(a >> 1) + h), sg(-(a >> 1) - h));
    // (2 s_a − s_b − s_c)/3 and (s_b − s_c)/√3 (21845 and 37837 over 2¹⁶), in 32-bit products:
    // each sign is within ±2¹², so each product is below 2²⁹.
    let (sa, sb, sc) = (sa as i32, sb as i32, sc as i32);
    (
        ((2 * sa - sb - sc) * 21_845) >> 16,
        ((sb - sc) * 37_837) >> 16,
    )
}

/// `|x|` of a current in Q12 per unit, to 7 %: the largest component and 3/8 of the other
/// (a gate's length, without a square root).
fn length_q12(x: Dq) -> i32 {
    let (a, b) = (
        (x.d.to_bits() >> SIGNAL_FRAC).saturating_abs(),
        (x.q.to_bits() >> SIGNAL_FRAC).saturating_abs(),
    );
    let (hi, lo) = if a > b { (a, b) } else { (b, a) };
    hi + ((3 * lo) >> 3)
}

impl DistortionLearner {
    /// The learner of a drive built from `motor` (its model of the motor) with `config`.
    ///
    /// Errors: [`ConfigError::Param`] naming the `distortion.*` field out of its range
    /// (`distortion.v_dead_v` zero: the drive does not compensate, there is nothing to scale).
    pub fn new(
        motor: &MotorParams,
        config: &DriveConfig,
        design: DistortionDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let base = &config.base;
        let d = design;
        in_range(
            "distortion.interval_samples",
            d.interval_samples as f64,
            1.0,
            1e4,
        )?;
        let dt = d.interval_samples as f64 * base.sample_s;
        in_range("distortion.batch_s", d.batch_s, 10.0 * dt, 100.0)?;
        in_range(
            "distortion.min_speed_rad_s",
            d.min_speed_rad_s,
            0.0,
            4.0 * base.omega_e_rad_s,
        )?;
        in_range("distortion.settle_s", d.settle_s, 0.0, 100.0)?;
        in_range(
            "distortion.min_current_bands",
            d.min_current_bands,
            0.0,
            1e3,
        )?;
        in_range("distortion.max_speed_change", d.max_speed_change, 0.0, 10.0)?;
        in_range("distortion.gain", d.gain, 1e-3, 1.0)?;
        in_range("distortion.max_step", d.max_step, 1e-3, 4.0)?;
        in_range("distortion.scale_range.0", d.scale_range.0, 0.0, 1.0)?;
        in_range("distortion.scale_range.1", d.scale_range.1, 1.0, 4.0)?;
        in_range("distortion.write_threshold", d.write_threshold, 0.0, 1.0)?;
        in_range("distortion.dead_band", d.dead_band, 0.0, 1.0)?;
        in_range("distortion.band_a", d.band_a, 1e-9, 1e6)?;
        Self::build(motor, config, design).ok_or(
            ParamError {
                key: "distortion.v_dead_v",
                reason: ParamReason::NotPositive,
            }
            .into(),
        )
    }

    /// [`DistortionLearner::new`] without the checks of the design's ranges: for the drive's
    /// own design ([`DistortionDesign::for_drive`] of a configuration that was checked), so
    /// that a firmware links no check of keys it never sets. `None` when the compensation is
    /// off (`v_dead_v` not positive: nothing to scale).
    pub(crate) fn build(
        motor: &MotorParams,
        config: &DriveConfig,
        design: DistortionDesign,
    ) -> Option<Self> {
        let d = design;
        if d.v_dead_v.is_nan() || d.v_dead_v <= 0.0 {
            return None;
        }
        let base = &config.base;
        let dt = d.interval_samples as f64 * base.sample_s;
        let turn = base.omega_e_rad_s * dt;
        Some(Self {
            max_speed_change: d.max_speed_change as f32,
            max_step: d.max_step as f32,
            scale_range: (d.scale_range.0 as f32, d.scale_range.1 as f32),
            write_threshold: d.write_threshold as f32,
            dead_band: d.dead_band as f32,
            model: Model {
                r: (motor.rs_ohm / base.impedance_ohm) as f32,
                ld: (motor.ld_h / base.inductance_h) as f32,
                lq: (motor.lq_h / base.inductance_h) as f32,
            },
            gain_per_pu: (d.gain * base.voltage_v / d.v_dead_v) as f32,
            volts_per_pu: base.voltage_v as f32,
            inv_band_q20: ((1u64 << 20) as f64 * base.current_a / d.band_a).min((1u64 << 40) as f64)
                as i64,
            min_current_sq: {
                let i = d.min_current_bands * d.band_a / base.current_a * (1 << SIGNAL_FRAC) as f64;
                (i * i) as i64
            },
            min_speed: pu_from_f64(d.min_speed_rad_s / base.omega_e_rad_s).to_bits(),
            // The sixth harmonic turns at most a quarter turn per update.
            max_speed: pu_from_f64(core::f64::consts::FRAC_PI_2 / (6.0 * turn)).to_bits(),
            batch_updates: libm::ceil(d.batch_s / dt) as u32,
            settle_updates: libm::ceil(d.settle_s / dt) as u32,
            run_updates: 0,
            batch: Batch::default(),
            written: 1.0,
            own: 1.0,
            last_error: 0.0,
            status: DistortionStatus {
                scale: 1.0,
                ..DistortionStatus::default()
            },
        })
    }

    /// The status of the last update.
    pub fn status(&self) -> DistortionStatus {
        self.status
    }

    /// One update on what a step left (every [`DistortionDesign::interval_samples`] samples).
    /// `scale` is the drive's ([`Drive::deadtime_scale`]): a standstill calibration since the
    /// last write is taken as it is. Returns the scale to write to the drive, when it moved.
    pub fn update(&mut self, input: &TrackerInput, scale: Pu) -> Option<Pu> {
        let drive_scale = pu(scale);
        if libm::fabsf(drive_scale - self.written) > 1e-6 {
            (self.status.scale, self.written, self.own) = (drive_scale, drive_scale, drive_scale);
            self.last_error = 0.0;
        }
        if self.batch.n < self.batch_updates {
            self.listen(input);
            return None;
        }
        // A full batch ends over the next updates, one stage each (`batch`), which do not
        // listen.
        self.status.listening = false;
        let end = self.batch.end_stage(self.max_speed_change, &self.model);
        if end != End::Pending {
            self.batch = Batch::default();
        }
        let e = match end {
            End::Error(e) => e,
            End::Moved => {
                self.status.discarded = self.status.discarded.saturating_add(1);
                return None;
            }
            End::Pending | End::NoSolution => return None,
        };
        self.take(e);
        let learnt = self.status.scale;
        let scale = if libm::fabsf(learnt - self.own) < self.dead_band {
            self.own
        } else {
            learnt
        };
        let step = libm::fabsf(scale - self.written);
        if step > self.write_threshold {
            self.written = scale;
            // Within the scale's range [0, 4]: the bits fit, rounded.
            return Some(Pu::from_bits(
                (scale * (1u32 << PU_FRAC) as f32 + 0.5) as i32,
            ));
        }
        None
    }

    /// Samples `drive`, updates, and writes a new scale when it moved: a learner of one's
    /// own beside a host [`Drive`] (the drive's task runs its own when the design asks).
    pub fn run(&mut self, drive: &mut Drive) {
        if let Some(s) = self.update(&TrackerInput::sample(drive), drive.deadtime_scale()) {
            drive.set_deadtime_scale(s);
        }
    }

    /// The gates, and the sample's terms added to the batch.
    fn listen(&mut self, input: &TrackerInput) {
        self.status.listening = false;
        if !input.running {
            self.run_updates = 0;
            self.batch = Batch::default();
            self.status.frozen = DistortionFrozen::NotRunning;
            return;
        }
        self.run_updates = self.run_updates.saturating_add(1);
        let w = input.omega.to_bits();
        let q12 = |x: i32| x >> SIGNAL_FRAC;
        let (id, iq) = (q12(input.i_dq.d.to_bits()), q12(input.i_dq.q.to_bits()));
        let current_sq = crate::num::wmul(id, id) + crate::num::wmul(iq, iq);
        let frozen = if self.run_updates <= self.settle_updates {
            Some(DistortionFrozen::Settling)
        } else if !(self.min_speed..=self.max_speed).contains(&w.saturating_abs()) {
            Some(DistortionFrozen::Speed)
        } else if current_sq < self.min_current_sq {
            Some(DistortionFrozen::LowCurrent)
        } else if input.saturated {
            Some(DistortionFrozen::Saturated)
        } else {
            None
        };
        if let Some(f) = frozen {
            self.status.frozen = f;
            return;
        }
        // Integers only (module docs, "Cost"): the voltage, the current and the sign pattern
        // in the estimated frame, in Q12; cos 6θ, sin 6θ in Q11 from the table at 6θ.
        let sc = input.theta.sin_cos();
        let sc6 = Angle(input.theta.0.wrapping_mul(6)).sin_cos();
        let u = park(input.v, sc);
        let (pa, pb) = sign_pattern(inverse_park(input.i_dq, sc), self.inv_band_q20);
        // Park's rotation is linear: the pattern's Q12 through it as bits.
        let p = park(
            AlphaBeta {
                alpha: Pu::from_bits(pa),
                beta: Pu::from_bits(pb),
            },
            sc,
        );
        let x = [
            q12(u.d.to_bits()),
            q12(u.q.to_bits()),
            id,
            iq,
            p.d.to_bits(),
            p.q.to_bits(),
        ];
        let h = |x: crate::num::Unit| x.to_bits() >> (crate::num::UNIT_FRAC - HARMONIC_FRAC);
        let second = 2 * self.batch.n >= self.batch_updates;
        self.batch.add(
            &x,
            h(sc6.cos),
            h(sc6.sin),
            w,
            length_q12(input.i_ref),
            second,
        );
        self.status.listening = true;
    }

    /// A batch's `ê` (per unit) taken: the scale's step.
    fn take(&mut self, e: f32) {
        self.status.batches = self.status.batches.saturating_add(1);
        self.status.error_v = e * self.volts_per_pu;
        // Two batches in a row must agree, and the smaller of the two is taken: a transient
        // that one batch mistook for a distortion (a load step at the current limit) does not
        // move the scale; a distortion shows in every batch.
        let last = core::mem::replace(&mut self.last_error, e);
        if last * e <= 0.0 {
            return;
        }
        let e = if libm::fabsf(e) < libm::fabsf(last) {
            e
        } else {
            last
        };
        let (lo, hi) = self.scale_range;
        let max = self.max_step;
        let step = within(self.gain_per_pu * e, -max, max);
        // From the scale in use, against which `ê` was measured: a reading left unwritten
        // (within the dead band) is not added up batch after batch.
        self.status.scale = within(self.written + step, lo, hi);
    }
}

#[cfg(test)]
mod tests;
