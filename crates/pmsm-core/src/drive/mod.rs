//! The sensorless drive of Khlaief, Boussak, Gossa (2012) Fig. 1 (docs/khlaief2012.md), in two
//! rates (docs/drive.md, "two rates"), as motor-control firmware is built:
//!
//! - [`DriveIsr`], the interrupt side, every PWM period: the trips that cannot wait, Clarke,
//!   the estimator, Park, the PI current loops, the dead-time vector, the modulator and the
//!   PWM-delay line, and while starting the detection's pulses, the alignment's frame and the
//!   open-loop frame;
//! - [`DriveTask`], the task side, every [`TASK_PERIOD`] samples at a lower priority: the state
//!   machine, the speed loop, the d-axis reference (MTPA, field weakening, light-load and
//!   low-speed currents), the slower checks, the calibration, the tracker of `R` and `ψ` and
//!   the learner of the inverter's distortion;
//! - [`Handoff`] between them: lock-free mailboxes of small `Copy` values (the interrupt's
//!   window of the period, the task's command), which need only 32-bit loads and stores.
//!
//! ```text
//!            every sample                                   every TASK_PERIOD samples
//!  i_abc, v_dc ─► DriveIsr ─► duties      window ──────────────► DriveTask ◄── ω*, start, stop
//!                    ▲        (end of period) ──► Handoff ──►        │
//!                    └─────────── command (mode, i_dq*) ◄────────────┘
//! ```
//!
//! The task's command answers one window and takes effect at the interrupt's first step after
//! the task published it, as ST's MCSDK takes its speed loop's current reference: the speed
//! loop's delay is the task's run, not a period. The task must answer before the next period
//! ends, else [`Fault::Overrun`]. [`Drive`] composes the two on one thread (the host, the
//! tests, the processor-in-the-loop replays), the task right after the step that ended a
//! period, so the host and the targets compute the same bits.
//!
//! States: `Idle` → (`Ipd` | `Align`) → (`OpenLoop` for the back-EMF estimators) → `Run`;
//! any fault latches `Fault` with the outputs off until [`Drive::clear_fault`]; [`Drive::stop`]
//! returns to `Idle`.
//!
//! Timing: the currents are sampled at `t_k`, the duties returned apply over `[t_k, t_{k+1})`
//! (the computation is assumed to finish before the first switching edge of the period), or
//! `DriveDesign::pwm_delay_samples` periods later with a preloaded timer (pmsm-stm32's TIM1:
//! one), for which the voltage is turned further and the estimator given the delayed voltage
//! (docs/drive.md, PWM update delay).

mod calibrate;
mod codes;
mod config;
mod design;
mod distortion;
mod handoff;
mod interface;
mod isr;
mod messages;
mod monitor;
mod startup;
mod task;
mod tracking;
mod zero_crossing;

#[cfg(feature = "injection")]
pub use crate::observer::InjectionFigures;
pub use config::DriveConfig;
pub(crate) use design::rated_e_rad_s;
pub use design::{
    AUTO_SALIENCY_MARGIN, DEFAULT_HEALTH_LIMIT_PU, DriveDesign, DriveOptions,
    MAX_PWM_DELAY_SAMPLES, MIN_OPEN_LOOP_RAMP_S, OVERSPEED_FACTOR, OpenLoopDesign, Protection,
    SPEED_LOOP_R_ERROR, StartupMode,
};
pub use distortion::{DistortionDesign, DistortionFrozen, DistortionLearner, DistortionStatus};
pub use handoff::Handoff;
pub(crate) use handoff::{Packer, Unpacker};
pub use interface::{DriveInput, DriveOutput, DriveState, Fault, SpeedRefLimit, Telemetry};
pub use isr::DriveIsr;
pub use task::DriveTask;
pub use tracking::{
    Frozen, ModelCoefficients, SPEED_FILTER_S, TRACKER_STAGES, Tracker, TrackerDesign,
    TrackerInput, TrackerStatus, WRITE_THRESHOLD,
};

use crate::frames::AlphaBeta;
use crate::ipd::IpdResult;
use crate::num::{Pu, Unit};
use crate::svpwm::Duties;

/// Samples per task period: the task runs once per this many PWM periods, and has that long to
/// finish. A power of two (the interrupt side's sums are means by a shift).
pub const TASK_PERIOD: u32 = 8;

/// A whole drive on one thread: the interrupt side every sample and the task side at the end
/// of each task period, with the firmware's timing (module docs). What the host, the tests
/// and the processor-in-the-loop replays run; a firmware runs the two parts
/// ([`Drive::into_parts`]) in its control interrupt and its task.
#[derive(Clone, Debug)]
pub struct Drive {
    isr: DriveIsr,
    task: DriveTask,
    handoff: Handoff,
}

impl Drive {
    /// A drive in `Idle`. Out of line: built in place in the caller's slot.
    #[inline(never)]
    pub fn new(config: DriveConfig) -> Self {
        Self {
            isr: DriveIsr::new(&config),
            task: DriveTask::new(&config),
            handoff: Handoff::new(),
        }
    }

    /// The two parts, for a firmware that runs them in two contexts and keeps their
    /// [`Handoff`] in a `static`.
    pub fn into_parts(self) -> (DriveIsr, DriveTask) {
        (self.isr, self.task)
    }

    /// The two sides and their handoff, to step them apart (benchmarks of each side).
    pub fn parts(&mut self) -> (&mut DriveIsr, &mut DriveTask, &Handoff) {
        (&mut self.isr, &mut self.task, &self.handoff)
    }

    /// The interrupt side.
    pub fn isr(&self) -> &DriveIsr {
        &self.isr
    }

    /// The task side.
    pub fn task(&self) -> &DriveTask {
        &self.task
    }

    /// The state of the outputs: what the interrupt side runs ([`DriveIsr::state`]). The
    /// task's decisions reach it at its first step after the task's run ([`DriveTask::state`]
    /// is the state decided).
    pub fn state(&self) -> DriveState {
        self.isr.state()
    }

    /// What the last step computed.
    pub fn telemetry(&self) -> &Telemetry {
        self.isr.telemetry()
    }

    /// The voltage the estimator will be given at the next sample, αβ per unit
    /// ([`DriveIsr::estimator_voltage`]).
    pub fn estimator_voltage(&self) -> AlphaBeta {
        self.isr.estimator_voltage()
    }

    /// The estimator's health figure, filtered over 10 ms, as the loss-of-lock check sees it
    /// ([`DriveTask::health`]).
    pub fn health(&self) -> Pu {
        self.task.health()
    }

    /// The result of the last initial position detection.
    pub fn ipd_result(&self) -> Option<IpdResult> {
        self.isr.ipd_result()
    }

    /// [`DriveTask::ipd_fallback`].
    pub fn ipd_fallback(&self) -> Option<crate::IpdFault> {
        self.task.ipd_fallback()
    }

    /// Sets the speed reference ([`DriveTask::set_speed_ref`]).
    pub fn set_speed_ref(&mut self, omega: Pu) {
        self.task.set_speed_ref(omega);
    }

    /// [`DriveTask::deadtime_scale`].
    pub fn deadtime_scale(&self) -> Pu {
        self.task.deadtime_scale()
    }

    /// [`DriveTask::field_weakening`].
    pub fn field_weakening(&self) -> Pu {
        self.task.field_weakening()
    }

    /// [`DriveTask::speed_ref_limit`].
    pub fn speed_ref_limit(&self) -> Option<SpeedRefLimit> {
        self.task.speed_ref_limit()
    }

    /// [`DriveTask::set_model`].
    pub fn set_model(&mut self, c: &ModelCoefficients) {
        self.task.set_model(c);
    }

    /// [`DriveTask::set_deadtime_scale`].
    pub fn set_deadtime_scale(&mut self, scale: Pu) {
        self.task.set_deadtime_scale(scale);
    }

    /// Starts from `Idle` with the configured start-up ([`DriveTask::start`]; the interrupt
    /// side follows at the step after the task's next run, within a task period).
    pub fn start(&mut self) {
        self.task.start();
    }

    /// Turns the outputs off and returns to `Idle` (also from a fault).
    pub fn stop(&mut self) {
        self.task.stop();
    }

    /// Leaves a fault for `Idle` ([`DriveTask::clear_fault`]; the interrupt side follows at
    /// the step after the task's next run); does nothing in other states.
    pub fn clear_fault(&mut self) {
        // A trip of the interrupt side the task has not seen yet (it would at the end of
        // this task period): taken now, on this one thread.
        if let Some(f) = self.isr.fault() {
            self.task.take_trip(f, self.isr.trips());
        }
        self.task.clear_fault();
    }

    /// The binding reports that a control step overran its period
    /// ([`DriveIsr::report_overrun`]).
    pub fn report_overrun(&mut self) {
        self.isr.report_overrun();
    }

    /// One control sample: the interrupt side's step, then the task's at the end of a task
    /// period. Integer arithmetic only on the control path; never panics, never allocates.
    pub fn step(&mut self, input: &DriveInput) -> DriveOutput {
        let out = self.isr.step(&self.handoff, input);
        if self.isr.task_due() {
            self.task.step(&self.handoff);
        }
        out
    }
}

/// The active short circuit of [`Fault::Overspeed`]: every leg at duty 0, the low-side
/// switches on over the whole period (the zero vector). The motor's EMF drives the
/// short-circuit current, about `ψ/L_d` at speed, through the windings instead of charging
/// the bus through the diodes (docs/field-weakening.md, overspeed).
pub const ACTIVE_SHORT: DriveOutput = DriveOutput {
    duties: Duties {
        a: Unit::ZERO,
        b: Unit::ZERO,
        c: Unit::ZERO,
    },
    pwm_on: true,
};

/// How long after a trip into outputs off the phase currents are left to freewheel into the
/// bus before a current is taken as the diodes rectifying the EMF (docs/field-weakening.md §4): the
/// decay of the overcurrent limit through the largest inductance against the bus,
/// `I_oc L/V_DC`, is 0.5 ms for motor B at 540 V and 1.3 ms for motor C at 24 V.
pub const RECTIFY_GRACE_S: f64 = 3e-3;

/// Outputs off.
const OFF: DriveOutput = DriveOutput {
    duties: Duties::HALF,
    pwm_on: false,
};
