//! The interrupt side's end of a task period and its side of the handoff: the window it
//! publishes, the command it takes and the mode it enters (docs/drive.md, "two rates").

use super::{DriveIsr, Phase};
use crate::angle::Angle;
use crate::deadtime::DeadTimeBus;
use crate::drive::TASK_PERIOD;
use crate::drive::handoff::Handoff;
use crate::drive::interface::{DriveInput, Fault};
use crate::drive::messages::{Command, Mode, ModelUpdate, Status, Window};
use crate::drive::startup::OpenLoop;
use crate::frames::AlphaBeta;
use crate::num::Pu;
#[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
use crate::observer::AnyEstimator;
use crate::observer::Estimator;

impl DriveIsr {
    /// The end of a task period: the overrun check (the task must have answered the previous
    /// window), the window of the samples that ran published. (Off or tripped, a late
    /// answer is no overrun: no sample of control depends on when.)
    #[inline(never)]
    pub(super) fn end_period(&mut self, handoff: &Handoff, input: &DriveInput) {
        if self.answered != self.window && self.active() {
            self.trip(Fault::Overrun);
        }
        let window = self.window(input);
        self.window = handoff.window.publish(&window);
        self.omega_sum = 0;
        self.power_sum = [0; 3];
    }

    /// What the task sees of the period that ends, `input` its last sample's.
    fn window(&self, input: &DriveInput) -> Window {
        let t = &self.telemetry;
        Window {
            epoch: self.epoch,
            trips: self.trips,
            status: match self.phase {
                Phase::Off => Status::Off,
                Phase::Ipd(None) => Status::Ipd,
                Phase::Ipd(Some(theta)) => Status::IpdDone(theta),
                Phase::IpdNoPolarity(f) => Status::IpdNoPolarity(f),
                Phase::Align if self.open_loop.align_done(&self.config.open_loop) => {
                    Status::Aligned(self.open_loop.align_angle())
                }
                Phase::Align => Status::Align,
                Phase::Calibrate(_) => Status::Calibrate,
                Phase::OpenLoop => Status::OpenLoop {
                    at_handover: self.open_loop.at_handover(&self.config.open_loop),
                },
                Phase::Run => Status::Run,
                Phase::Tripped(f) => Status::Tripped(f),
            },
            theta_est: t.estimate.theta,
            omega: t.estimate.omega,
            omega_mean: Pu::from_bits(self.omega_sum),
            health: self.estimator.health(),
            theta: t.theta,
            omega_frame: self.frame_omega,
            reverse: self.open_loop.is_reverse(),
            reversal: self.open_loop.is_reversal(),
            i_dq: t.i_dq,
            i_ref: t.i_ref,
            v: t.v,
            v_est: self.v_est,
            v_dt: self.v_dt,
            saturated: t.saturated,
            #[cfg(feature = "injection")]
            injecting: self.injecting,
            #[cfg(not(feature = "injection"))]
            injecting: false,
            i_abc: input.i_abc,
            vdc: input.vdc,
            power: self.power_sum,
        }
    }

    /// Takes the task's latest command. One answering an older window than the last while
    /// the drive runs is left: the end of the period trips on it ([`Fault::Overrun`]).
    #[inline(never)]
    pub(super) fn take(&mut self, handoff: &Handoff) {
        let (n, command) = handoff.command.read_now::<Command>();
        self.command = n;
        // Once per task period, away from the end of the period's step: the current-model
        // MRAS's low-speed gain schedule, for its estimated speed.
        self.estimator.schedule();
        if command.window != self.window && self.active() {
            return;
        }
        self.answered = command.window;
        self.apply(handoff, &command);
    }

    /// Applies the task's `command`.
    fn apply(&mut self, handoff: &Handoff, command: &Command) {
        if command.model != self.model {
            let (seq, m) = handoff.model.read_now::<ModelUpdate>();
            if seq == command.model {
                self.set_model(&m);
                self.model = seq;
            }
        }
        self.i_ref = command.i_ref;
        self.measured_signs = command.measured_signs;
        self.telemetry.health = command.health;
        if command.hold {
            self.estimator.hold(TASK_PERIOD as u8);
        }
        // A trip stands until the task has seen it.
        let tripped = matches!(self.phase, Phase::Tripped(_));
        if command.epoch != self.epoch
            && !(tripped && command.window.wrapping_sub(self.trip_window) > u32::MAX / 2)
        {
            self.epoch = command.epoch;
            self.enter(command.mode);
        }
    }

    /// The task's learners' model.
    fn set_model(&mut self, m: &ModelUpdate) {
        #[allow(irrefutable_let_patterns)]
        #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
        if let (AnyEstimator::MrasCurrent(e), Some(model)) = (&mut self.estimator, &m.mras) {
            e.set_model(model);
        }
        self.current.set_psi(m.psi);
        self.config.deadtime = self.config.deadtime.with_bus_terms(m.deadtime);
        self.deadtime_bus = DeadTimeBus::default();
    }

    /// Enters the mode the task asks for.
    fn enter(&mut self, mode: Mode) {
        // Every mode starts without the injection; the closed loop hands over to it itself.
        #[cfg(feature = "injection")]
        {
            self.injecting = false;
        }
        match mode {
            Mode::Off => self.phase = Phase::Off,
            Mode::Fault(f) => {
                if !matches!(self.phase, Phase::Tripped(_)) {
                    self.trip(f);
                }
            }
            Mode::Ipd => {
                self.restart();
                self.ipd.restart();
                self.phase = Phase::Ipd(None);
            }
            Mode::Align => {
                self.restart();
                self.open_loop = OpenLoop::align();
                self.phase = Phase::Align;
            }
            Mode::Calibrate { theta, reset } => {
                if reset {
                    self.current.reset();
                }
                self.open_loop = OpenLoop::aligned_at(theta, &self.config.open_loop);
                self.phase = Phase::Calibrate(theta);
            }
            Mode::OpenLoop { theta, reverse } => {
                self.rotor_at(theta);
                // From rest, in the reference's direction, which the estimator holds through
                // the open loop.
                self.open_loop = OpenLoop::start(theta, reverse);
                self.estimator.hold_direction(Some(!reverse));
                self.phase = Phase::OpenLoop;
            }
            Mode::Reverse { omega, iq, reverse } => {
                let theta = self.estimator.estimate().theta;
                self.open_loop =
                    OpenLoop::reverse(theta, omega, iq, reverse, &self.config.open_loop);
                self.phase = Phase::OpenLoop;
            }
            Mode::Run { from: Some(theta) } => {
                self.rotor_at(theta);
                self.phase = Phase::Run;
            }
            Mode::Run { from: None } => {
                self.estimator.hold_direction(None);
                self.phase = Phase::Run;
            }
        }
    }

    /// A start: the loops, the voltages and the sums afresh.
    fn restart(&mut self) {
        self.current.reset();
        self.v_est = AlphaBeta::default();
        self.v_line = Default::default();
        self.sum = 0;
        self.i_q_expected = Pu::ZERO;
    }

    /// The rotor stands at `theta`: the estimator and the current loops start there.
    fn rotor_at(&mut self, theta: Angle) {
        self.estimator.reset(theta, Pu::ZERO);
        self.current.reset();
        self.i_q_expected = Pu::ZERO;
        self.telemetry.estimate = self.estimator.estimate();
    }
}
