//! The task side of the drive: what runs once per task period, at a priority below the
//! control interrupt (docs/drive.md, "two rates").
//!
//! ```text
//!  window (the interrupt's period: status, last sample, means)
//!     │
//!     ├─► state machine: detection → alignment → calibration → open loop → run, faults
//!     ├─► slow checks (stall, lost lock, phase loss, stuck sensor, driven backwards)
//!     ├─► ω* ─► IP speed loop ─► i_q*;  d-axis reference: MTPA, field weakening,
//!     │         light-load and low-speed currents  ─► i_dq*
//!     └─► tracker of R and ψ, learner of the inverter's distortion ─► model update
//!                                                    │
//!  command (mode, i_dq*, choices) ◄──────────────────┘
//! ```
//!
//! The task reads the interrupt's latest window, decides, and publishes its command, which the
//! interrupt side takes at its first step after: the task has until the end of the next task
//! period to run, and its answer acts as soon as it is there. Its user-facing calls ([`DriveTask::start`], [`DriveTask::set_speed_ref`], …) act at
//! its next step.

#[cfg(feature = "injection")]
mod injection;
mod learn;
mod speed_schedule;
mod start;

use super::TASK_PERIOD;
use super::calibrate::{Calibration, SCALE_ONE};
use super::config::{DriveConfig, TaskConfig};
use super::design::StartupMode;
#[cfg(feature = "distortion-learner")]
use super::distortion::DistortionLearner;
use super::handoff::Handoff;
use super::interface::{DriveState, Fault, SpeedRefLimit};
use super::messages::{Command, Mode, ModelUpdate, Status, Window};
use super::monitor::{Monitor, Signals};
use super::startup::frame_shift;
use super::tracking::ModelCoefficients;
#[cfg(feature = "tracking")]
use super::tracking::Tracker;
use super::zero_crossing::ZeroCrossing;
use crate::angle::Angle;
use crate::control::flux::FluxController;
use crate::control::light_load::LightLoad;
use crate::control::speed::SpeedController;
use crate::frames::Dq;
use crate::ipd::IpdFault;
use crate::num::{PU_FRAC, Pu, follow};

/// The task side: its configuration and state, the learners, and what it last saw of the
/// interrupt side. One [`DriveTask::step`] per task period.
#[derive(Clone, Copy, Debug)]
pub struct DriveTask {
    pub(crate) config: TaskConfig,
    state: DriveState,
    /// The mode commanded and its number (bumped at each change).
    mode: Mode,
    epoch: u32,
    /// The last window's number.
    window: u32,
    /// The interrupt side's trips already taken.
    trips: u32,
    /// The detection that found no polarity, which the start fell back from to the
    /// alignment (`IsrConfig::ipd_fallback`).
    ipd_fallback: Option<IpdFault>,
    speed: SpeedController,
    /// The speed loop runs the stiff gains (`TaskConfig::speed_stiff`).
    speed_stiff: bool,
    /// The load observer (`TaskConfig::load_observer`), reset at each handover.
    #[cfg(feature = "load-observer")]
    pub(super) load: crate::control::load_observer::LoadObserver,
    /// Held at low speed on the injection's angle: the slower speed loop
    /// (`TaskConfig::speed_injecting`), no low-speed d current.
    #[cfg(feature = "injection")]
    injection_hold: bool,
    /// The polarity check, whether the drive ran since the last one (or a turn waits for its
    /// verification), and the speed reference of the last period (a check runs at a steady
    /// one).
    #[cfg(feature = "injection")]
    polarity: crate::observer::PolarityCheck,
    #[cfg(feature = "injection")]
    polarity_armed: bool,
    #[cfg(feature = "injection")]
    polarity_ref: Pu,
    /// The d-axis reference a running check started from.
    #[cfg(feature = "injection")]
    polarity_from: Pu,
    speed_ref: Pu,
    /// [`DriveTask::run_speed_ref`] of `speed_ref`, computed when it is set.
    speed_ref_run: Pu,
    /// The period's mean estimated speed through the speed filter: what the speed loop sees.
    speed_filtered: Pu,
    /// The open loop's frame lead sent with the command (its damping).
    frame_shift: Angle,
    /// The speed loop's current reference, and the reference sent.
    iq_ref: Pu,
    i_ref: Dq,
    measured_signs: bool,
    hold: bool,
    /// The d-axis reference (MTPA, field weakening).
    flux: FluxController,
    /// The light-load d-axis current.
    light_load: LightLoad,
    /// The low-speed d-axis current's reference (`control/low_speed.rs`), and its faded level
    /// before the current limit.
    low_speed_id: Pu,
    low_speed_faded: Pu,
    monitor: Monitor,
    /// The dead-time calibration's progress and angle.
    calibration: Calibration,
    /// The compensation's `V_dead` against the configured one, Q4.28.
    deadtime_scale: i32,
    zero_crossing: ZeroCrossing,
    /// Task periods the handover has waited for the estimate.
    waited: u32,
    /// Whether the speed reference was negative at the last handover into the closed loop.
    handed_over_negative: bool,
    #[cfg(feature = "tracking")]
    tracker: Option<Tracker>,
    #[cfg(feature = "distortion-learner")]
    learner: Option<DistortionLearner>,
    /// The model the interrupt side runs with, and its number in the model mailbox.
    model: ModelUpdate,
    model_seq: u32,
    /// A model to publish at the next step.
    model_dirty: bool,
}

impl DriveTask {
    /// The task side of a drive built from `config`, idle, with the tracker and the learner
    /// its design asks for. Out of line: built in place in the caller's slot.
    #[inline(never)]
    pub fn new(config: &DriveConfig) -> Self {
        let c = TaskConfig {
            startup: config.design.startup,
            ..config.task
        };
        #[cfg(feature = "tracking")]
        let tracker = if config.design.tracking {
            learn::tracker_of(config)
        } else {
            None
        };
        #[cfg(feature = "distortion-learner")]
        let learner = if config.design.deadtime_learning {
            learn::learner_of(config)
        } else {
            None
        };
        #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
        let mras = match &config.estimator {
            #[allow(unreachable_patterns)]
            crate::observer::EstimatorConfig::MrasCurrent(m) => Some(m.model()),
            #[allow(unreachable_patterns)]
            _ => None,
        };
        #[cfg(not(any(not(feature = "select-estimators"), feature = "mras-current")))]
        let mras = None;
        Self {
            speed: SpeedController::new(config.speed),
            speed_stiff: false,
            #[cfg(feature = "load-observer")]
            load: Default::default(),
            #[cfg(feature = "injection")]
            injection_hold: false,
            #[cfg(feature = "injection")]
            polarity: crate::observer::PolarityCheck::default(),
            #[cfg(feature = "injection")]
            polarity_armed: false,
            #[cfg(feature = "injection")]
            polarity_ref: Pu::ZERO,
            #[cfg(feature = "injection")]
            polarity_from: Pu::ZERO,
            flux: {
                let mut f = FluxController::default();
                f.reset(&c.flux);
                f
            },
            model: ModelUpdate {
                mras,
                psi: config.current.psi(),
                deadtime: c.deadtime.bus_terms(),
            },
            config: c,
            state: DriveState::Idle,
            mode: Mode::Off,
            epoch: 0,
            window: 0,
            trips: 0,
            ipd_fallback: None,
            speed_ref: Pu::ZERO,
            speed_ref_run: Pu::ZERO,
            speed_filtered: Pu::ZERO,
            frame_shift: Angle::ZERO,
            iq_ref: Pu::ZERO,
            i_ref: Dq::default(),
            measured_signs: false,
            hold: false,
            light_load: LightLoad::default(),
            low_speed_id: Pu::ZERO,
            low_speed_faded: Pu::ZERO,
            monitor: Monitor::default(),
            calibration: Calibration::default(),
            deadtime_scale: SCALE_ONE,
            zero_crossing: ZeroCrossing::default(),
            waited: 0,
            handed_over_negative: false,
            #[cfg(feature = "tracking")]
            tracker,
            #[cfg(feature = "distortion-learner")]
            learner,
            model_seq: 0,
            model_dirty: false,
        }
    }

    /// What the drive is doing.
    pub fn state(&self) -> DriveState {
        self.state
    }

    /// One task period: reads the interrupt side's latest window from `handoff`, decides, and
    /// publishes the command (and a model update when the learners changed the model). Does
    /// nothing if no window came since the last step.
    pub fn step(&mut self, handoff: &Handoff) {
        let (seq, window) = handoff.window.read::<Window>();
        if seq == self.window {
            return;
        }
        self.window = seq;
        self.decide(&window);
        if self.model_dirty {
            self.model_dirty = false;
            self.model_seq = handoff.model.publish(&self.model);
        }
        handoff.command.publish(&Command {
            window: seq,
            epoch: self.epoch,
            mode: self.mode,
            i_ref: self.i_ref,
            measured_signs: self.measured_signs,
            hold: self.hold,
            model: self.model_seq,
            health: self.monitor.health(),
            frame_shift: self.frame_shift,
        });
    }

    /// Starts from `Idle` with the configured start-up; does nothing in other states.
    pub fn start(&mut self) {
        if !matches!(self.state, DriveState::Idle) {
            return;
        }
        // A drive never given a reference runs at the one it holds for zero.
        self.speed_ref_run = self.run_speed_ref();
        self.monitor.reset();
        self.calibration = Calibration::default();
        self.ipd_fallback = None;
        match self.config.startup {
            StartupMode::Ipd => self.command(DriveState::Ipd, Mode::Ipd),
            // `Auto` is resolved by `DriveConfig::new`; alignment is its safe reading.
            StartupMode::Align | StartupMode::Auto => self.command(DriveState::Align, Mode::Align),
            StartupMode::Known(theta) => self.rotor_found(theta),
        }
    }

    /// Turns the outputs off and returns to `Idle` (also from a fault).
    pub fn stop(&mut self) {
        self.command(DriveState::Idle, Mode::Off);
    }

    /// Leaves a fault for `Idle`; does nothing in other states.
    pub fn clear_fault(&mut self) {
        if let DriveState::Fault(_) = self.state {
            self.stop();
        }
    }

    /// Sets the speed reference, electrical, per unit of `ω_b`, clamped to the maximum speed
    /// ([`crate::FluxConfig::max_speed`]; [`DriveTask::speed_ref_limit`] tells when it was).
    /// In the closed loop the PI form of the speed loop takes the reference's proportional
    /// part here ([`crate::SpeedController::move_reference`]).
    pub fn set_speed_ref(&mut self, omega: Pu) {
        let from = self.speed_ref_run;
        self.speed_ref = omega;
        self.speed_ref_run = self.run_speed_ref();
        if matches!(self.state, DriveState::Run) {
            self.speed.move_reference(from, self.speed_ref_run);
        }
    }

    /// The estimator's health figure ([`crate::Estimator::health`]) filtered over 10 ms, as
    /// the loss-of-lock check sees it (zero outside the closed loop).
    pub fn health(&self) -> Pu {
        self.monitor.health()
    }

    /// The dead-time compensation's `V_dead` against the configured one, per unit (one until
    /// a calibration or the learner measured it; docs/drive.md, "dead-time calibration").
    pub fn deadtime_scale(&self) -> Pu {
        Pu::from_bits(self.deadtime_scale >> (28 - PU_FRAC))
    }

    /// The detection whose missing polarity made the last start fall back to the alignment
    /// ([`StartupMode::Auto`](crate::StartupMode) on a motor that barely saturates), if it did.
    pub fn ipd_fallback(&self) -> Option<IpdFault> {
        self.ipd_fallback
    }

    /// The field-weakening offset of the d-axis reference (≤ 0; zero below base speed).
    pub fn field_weakening(&self) -> Pu {
        self.flux.delta()
    }

    /// The tracker of `R` and `ψ`, when the design runs one.
    #[cfg(feature = "tracking")]
    pub fn tracker(&self) -> Option<&Tracker> {
        self.tracker.as_ref()
    }

    /// The learner of the inverter's distortion voltage, when the design runs one.
    #[cfg(feature = "distortion-learner")]
    pub fn learner(&self) -> Option<&DistortionLearner> {
        self.learner.as_ref()
    }

    /// Rewrites the coefficients of the drive's model that depend on `R` and `ψ` (the
    /// current-model MRAS's, and the `ψ` of the current loops' feed-forward): sent to the
    /// interrupt side with the next command.
    pub fn set_model(&mut self, c: &ModelCoefficients) {
        if self.model.mras.is_some() {
            self.model.mras = Some(c.mras);
        }
        self.model.psi = c.psi;
        self.model_dirty = true;
    }

    /// Scales the dead-time compensation's `V_dead` to `scale` times the one the drive was
    /// told (within [0, 4], saturated; absolute), with the light-load current raised with it
    /// (never lowered): sent to the interrupt side with the next command.
    pub fn set_deadtime_scale(&mut self, scale: Pu) {
        let bits = scale.to_bits().clamp(0, 4 << PU_FRAC);
        // Q8.24 to Q4.28: at most 4 << 28 < 2³¹.
        self.apply_deadtime_scale(bits << (28 - PU_FRAC));
    }

    /// Whether the closed loop holds another speed than the reference set, and why; `None`
    /// when it runs at the reference. A reference the drive does not take (beyond the maximum
    /// speed, below the estimator's least) comes first; then, in the closed loop, the speed
    /// loop's output at its limit.
    pub fn speed_ref_limit(&self) -> Option<SpeedRefLimit> {
        let requested = self.speed_ref;
        let used = self.speed_ref_used();
        if used != requested {
            return Some(SpeedRefLimit::AboveMaxSpeed { requested, used });
        }
        let held = self.run_speed_ref();
        if held != requested {
            return Some(SpeedRefLimit::BelowEstimatorMinimum { requested, held });
        }
        (matches!(self.state, DriveState::Run) && self.speed.at_limit(self.iq_ref)).then_some(
            SpeedRefLimit::AtCurrentLimit {
                requested,
                estimated: self.speed_filtered,
            },
        )
    }

    /// The speed reference clamped to the maximum speed (max/min: no panic path).
    fn speed_ref_used(&self) -> Pu {
        let max = self.config.flux.max_speed();
        self.speed_ref.min(max).max(max.saturating_neg())
    }

    /// The speed reference of the closed loop: a back-EMF estimator cannot run below the
    /// handover speed, so the reference is held at that magnitude (in its direction) there.
    fn run_speed_ref(&self) -> Pu {
        let speed_ref = self.speed_ref_used();
        if !self.config.estimator.needs_open_loop_start() {
            return speed_ref;
        }
        let min = self.config.handover_speed;
        if speed_ref.saturating_abs() >= min {
            speed_ref
        } else if speed_ref < Pu::ZERO {
            min.saturating_neg()
        } else {
            min
        }
    }

    /// A new state and mode, with a new epoch: the interrupt side enters it afresh.
    fn command(&mut self, state: DriveState, mode: Mode) {
        self.state = state;
        self.mode = mode;
        self.epoch = self.epoch.wrapping_add(1);
    }

    /// Trips into `fault` (the interrupt side turns the outputs off when it takes the
    /// command).
    fn fault(&mut self, fault: Fault) {
        self.command(DriveState::Fault(fault), Mode::Fault(fault));
    }

    /// A trip of the interrupt side (it has turned the outputs off already), its count
    /// `trips`: taken as the drive's fault if new, unless the drive was stopped meanwhile.
    pub(crate) fn take_trip(&mut self, fault: Fault, trips: u32) {
        if trips != self.trips {
            self.trips = trips;
            if self.mode != Mode::Off {
                self.state = DriveState::Fault(fault);
                self.mode = Mode::Fault(fault);
            }
        }
    }

    /// The decisions of one task period.
    fn decide(&mut self, w: &Window) {
        if let Status::Tripped(f) = w.status {
            self.take_trip(f, w.trips);
        }
        // The interrupt side runs the mode last commanded (not one still on its way).
        let current = w.epoch == self.epoch;
        let running = current && matches!(self.state, DriveState::Run);
        self.hold = false;
        let c = &self.config;
        self.frame_shift = if current && matches!(self.state, DriveState::OpenLoop) {
            frame_shift(
                w.omega_frame,
                w.omega_mean,
                c.handover_speed,
                c.open_loop_damping,
            )
        } else {
            Angle::ZERO
        };
        match (self.state, w.status) {
            (DriveState::Ipd, Status::IpdDone(theta)) if current => self.detected(theta),
            // An automatic start whose detection saw the axis but not the polarity (a salient
            // motor whose iron barely saturates): the alignment needs no polarity.
            (DriveState::Ipd, Status::IpdNoPolarity(f)) if current => {
                self.ipd_fallback = Some(f);
                self.command(DriveState::Align, Mode::Align);
            }
            (DriveState::Align, Status::Aligned(theta)) if current => self.aligned(theta),
            (DriveState::Align, Status::Calibrate) if current => self.calibrate(w),
            (DriveState::OpenLoop, Status::OpenLoop { at_handover: true }) if current => {
                self.handover(w)
            }
            (DriveState::Run, _) if running => self.run(w),
            _ => {}
        }
        if !running {
            self.measured_signs = false;
            // The checks keep their counts at zero outside the closed loop.
            let _ = self
                .monitor
                .check(&self.config.monitor, &self.signals(w, false));
        }
        self.learn(w, running);
    }

    /// What the checks see of the window.
    fn signals(&self, w: &Window, running: bool) -> Signals {
        Signals {
            i_abc: w.i_abc,
            power: w.power,
            omega: w.omega,
            omega_mean: w.omega_mean,
            theta_est: w.theta_est,
            omega_ref: self.speed_ref_run,
            iq_ref: self.iq_ref,
            running,
            health: w.health,
            i_ref: w.i_ref,
            i_dq: w.i_dq,
            saturated: w.saturated,
        }
    }

    /// The d-axis reference of the closed loop: the more negative of the flux controller's
    /// and the light-load current's, plus the low-speed current and a polarity check's bias
    /// (each within ±64 pu: the sum cannot wrap); q the speed loop's.
    fn d_reference(&self) -> Dq {
        let light = self.light_load.id_ref();
        let d = if self.config.flux.enabled() {
            self.flux.id_ref().min(light)
        } else {
            light
        };
        #[cfg(feature = "injection")]
        let d = self.polarity_d(d);
        Dq {
            d: Pu::from_bits(d.to_bits() + self.low_speed_id.to_bits()),
            q: self.iq_ref,
        }
    }

    /// One task period of the closed loop: the reversal through the open loop for a back-EMF
    /// estimator, the checks, the speed loop, the d-axis reference, the dead-time signs and
    /// the zero-crossing hold.
    fn run(&mut self, w: &Window) {
        let c = &self.config;
        self.speed_filtered = follow(self.speed_filtered, w.omega_mean, c.speed_filter_shift);
        let omega_ref = self.speed_ref_run;
        // With a back-EMF estimator, the reference one way and the estimated speed the other,
        // down to 1.25 times the handover speed: back to the open loop to pass through zero
        // (`startup`, reversal), from the filtered speed.
        if c.estimator.needs_open_loop_start() && (omega_ref.to_bits() ^ w.omega.to_bits()) < 0 {
            let h = c.handover_speed;
            if self.speed_filtered.saturating_abs() <= h.saturating_add(h >> 2) {
                // Within the checks' settling time of a handover made for a reference of this
                // sign, the estimate has turned against the frame it was handed: the rotor is
                // not where the open loop left it (a load that overpowered the open-loop
                // current turned it the other way, and the estimate wanders about its mirror).
                // Another pass through the open loop would hand over again, resetting the
                // checks each time: a lost lock.
                if self.monitor.settling(&c.monitor)
                    && (omega_ref < Pu::ZERO) == self.handed_over_negative
                {
                    return self.fault(Fault::LossOfLock);
                }
                self.waited = 0;
                let mode = Mode::Reverse {
                    omega: self.speed_filtered,
                    iq: self.iq_ref,
                    reverse: omega_ref < Pu::ZERO,
                };
                return self.command(DriveState::OpenLoop, mode);
            }
        }
        if let Some(f) = self
            .monitor
            .check(&self.config.monitor, &self.signals(w, true))
        {
            return self.fault(f);
        }
        self.speed_schedule(w, omega_ref);
        #[cfg(feature = "injection")]
        {
            if self.check_polarity(w, omega_ref) {
                // The angle turned by a half: the closed loop restarts from it.
                return;
            }
        }
        let c = &self.config;
        // The load's current moved: the speed loop's output with it, before its step.
        #[cfg(feature = "load-observer")]
        if let Some(o) = &c.load_observer {
            let delta = self.load.step(o, w.omega_mean, w.i_dq.q);
            self.speed.shift_output(delta);
        }
        self.iq_ref = self.speed.step(omega_ref, self.speed_filtered).iq_ref;
        // The light-load d current follows |i_q*| slowly, the low-speed current fades with the
        // speed (or the start's handover current decays), held within the current limit that
        // the light-load filter's |i_q*| leaves.
        self.light_load
            .update(&c.light_load, self.iq_ref, self.speed_filtered);
        self.low_speed_faded = c
            .low_speed
            .decayed(self.speed_filtered, self.low_speed_faded);
        self.low_speed_id =
            c.low_speed
                .within_limit(self.low_speed_faded, self.iq_ref, self.light_load.level());
        // Held at low speed on the injection's angle, no d current holds the rotor.
        #[cfg(feature = "injection")]
        if self.injection_hold {
            self.low_speed_id = Pu::ZERO;
        }
        // MTPA and field weakening, on the modulator's vector and circle of the last sample
        // (docs/field-weakening.md); the speed loop's limit the current circle's `|i_q|` room.
        if c.flux.enabled() {
            let v_max = c.svpwm.v_max(w.vdc);
            let iq_max = self.flux.update(&c.flux, self.iq_ref, &w.v, v_max);
            self.speed.set_limit(iq_max);
            self.iq_ref = self.iq_ref.min(iq_max).max(iq_max.saturating_neg());
        }
        self.i_ref = self.d_reference();
        // The dead-time compensation of the current-model MRAS takes the measured currents'
        // signs under load and above the speed whose EMF equals `V_dead` (`|ω̂| ψ`, ψ the base
        // flux): docs/drive.md, "dead-time compensation: which current's sign".
        let v_dead = c.deadtime.v_dead(w.vdc).to_bits().unsigned_abs();
        self.measured_signs =
            c.deadtime.loaded(self.iq_ref) && self.speed_filtered.to_bits().unsigned_abs() > v_dead;
        self.hold = c.zero_crossing_hold
            && self.zero_crossing.holds(
                w.omega,
                self.light_load.level(),
                self.low_speed_id,
                &w.i_abc,
                c.deadtime.band_bits(),
                v_dead,
                c.light_load.settled_updates(),
            );
    }
}

/// The task's period in samples, as a `u8` (the hold's count).
const _: () = assert!(TASK_PERIOD <= 64);
