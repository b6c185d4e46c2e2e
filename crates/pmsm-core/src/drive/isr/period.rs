//! The interrupt side's end of a task period and its side of the handoff: the window it
//! publishes, the command it takes and the mode it enters (docs/drive.md, "two rates").

use super::{DriveIsr, Phase};
use crate::angle::Angle;
use crate::deadtime::DeadTimeBus;
use crate::drive::TASK_PERIOD;
use crate::drive::handoff::{Handoff, Packer, WINDOW_WORDS};
use crate::drive::interface::{DriveInput, Fault};
use crate::drive::messages::{Command, Mode, ModelUpdate, Status, Window};
use crate::drive::startup::OpenLoop;
use crate::frames::AlphaBeta;
use crate::num::Pu;
#[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
use crate::observer::AnyEstimator;
use crate::observer::Estimator;
use core::sync::atomic::AtomicU32;

impl DriveIsr {
    /// The end of a task period: the overrun check (the task must have answered the previous
    /// window), the window of the samples that ran published. (Off or tripped, a late
    /// answer is no overrun: no sample of control depends on when.) Inlined on ARMv6-M only,
    /// where that shortens the end of a period's step, the worst case; on a Cortex-M4 the
    /// inlined copy lengthens every step (`scripts/pil.sh`).
    #[cfg_attr(
        all(target_arch = "arm", not(target_has_atomic = "32")),
        inline(always)
    )]
    #[cfg_attr(
        not(all(target_arch = "arm", not(target_has_atomic = "32"))),
        inline(never)
    )]
    pub(super) fn end_period(&mut self, handoff: &Handoff, input: &DriveInput) {
        if self.answered != self.window && self.active() {
            self.trip(Fault::Overrun);
        }
        self.window = handoff
            .window
            .publish_packed(|slot| self.pack_window(input, slot));
        self.omega_sum = 0;
        self.power_sum = [0; 3];
    }

    /// [`DriveIsr::window`]'s words (as [`Window`]'s `Message::pack` writes them) straight
    /// from the interrupt side's state into the mailbox's `slot`: a load and a store per word,
    /// where building the window first held its 33 words across the status's branches and
    /// spilled them. The tests hold the two to the same words.
    #[inline(always)]
    pub(super) fn pack_window(&self, input: &DriveInput, slot: &[AtomicU32; WINDOW_WORDS]) {
        let t = &self.telemetry;
        let w = &mut Packer::new(slot);
        // The status first: a fault's words are its one call, with nothing else loaded yet.
        self.status().write(w);
        w.u32(self.epoch);
        w.u32(self.trips);
        w.i32(t.estimate.theta.0);
        w.i32(t.estimate.omega.to_bits());
        w.i32(self.omega_sum);
        w.i32(self.estimator.health().to_bits());
        w.i32(t.theta.0);
        w.i32(self.frame_omega.to_bits());
        w.bool(self.open_loop.is_reverse());
        w.bool(self.open_loop.is_reversal());
        for x in [
            t.i_dq.d,
            t.i_dq.q,
            t.i_ref.d,
            t.i_ref.q,
            t.v.alpha,
            t.v.beta,
            self.v_est.alpha,
            self.v_est.beta,
            self.v_dt.alpha,
            self.v_dt.beta,
            input.i_abc.a,
            input.i_abc.b,
            input.i_abc.c,
            self.inv_vdc.reading(),
        ] {
            w.i32(x.to_bits());
        }
        w.u32(Window::flags(t.saturated, self.injecting()));
        for p in self.power_sum {
            w.u32(p);
        }
    }

    /// Whether the injection gave the angle at the last sample.
    fn injecting(&self) -> bool {
        #[cfg(feature = "injection")]
        return self.injecting;
        #[cfg(not(feature = "injection"))]
        false
    }

    /// What the task sees of the period that ends, `input` its last sample's: the message
    /// [`DriveIsr::pack_window`] writes.
    #[cfg(test)]
    pub(super) fn window(&self, input: &DriveInput) -> Window {
        let t = &self.telemetry;
        Window {
            epoch: self.epoch,
            trips: self.trips,
            status: self.status(),
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
            injecting: self.injecting(),
            i_abc: input.i_abc,
            vdc: self.inv_vdc.reading(),
            power: self.power_sum,
        }
    }

    /// The window's status of the phase the interrupt side is in.
    #[inline(always)]
    fn status(&self) -> Status {
        match self.phase {
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
        self.open_loop.shift = command.frame_shift;
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

#[cfg(test)]
mod tests {
    extern crate std;
    use crate::drive::handoff::{Message, WINDOW_WORDS};
    use crate::drive::messages::Window;
    use crate::drive::{Drive, DriveConfig, DriveInput, DriveOptions};
    use crate::fixtures::{inverter_b, motor_b};
    use crate::frames::{AlphaBeta, inverse_clarke};
    use crate::num::Pu;
    use core::sync::atomic::{AtomicU32, Ordering};

    fn words(pack: impl FnOnce(&[AtomicU32; WINDOW_WORDS])) -> [u32; WINDOW_WORDS] {
        let slot = [const { AtomicU32::new(0) }; WINDOW_WORDS];
        pack(&slot);
        slot.map(|w| w.load(Ordering::Relaxed))
    }

    /// Through the start (detection, closed loop) and a trip: at every sample the words written
    /// straight from the interrupt side are those of its window, and they read back as it.
    #[test]
    fn the_window_is_written_as_the_message_packs_it() {
        let (m, inv) = (motor_b(), inverter_b());
        let config = DriveConfig::from_params(&m, &inv, inv.pwm_hz, DriveOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
        let mut drive = Drive::new(config);
        drive.start();
        drive.set_speed_ref(Pu::from_num(0.3));
        let mut statuses = std::collections::BTreeSet::new();
        let mut theta = 0.0f64;
        for k in 0..6000 {
            theta += 0.02;
            // A phase current beyond the overcurrent trip near the end: the tripped status.
            let amp = if k == 5000 { 40.0 } else { 0.3 };
            let input = DriveInput {
                i_abc: inverse_clarke(AlphaBeta {
                    alpha: Pu::from_num(amp * libm::cos(theta)),
                    beta: Pu::from_num(amp * libm::sin(theta)),
                }),
                vdc: Pu::from_num(1.732),
            };
            drive.step(&input);
            let isr = drive.isr();
            let window = isr.window(&input);
            statuses.insert(std::format!("{:?}", window.status));
            let direct = words(|slot| isr.pack_window(&input, slot));
            assert_eq!(direct, words(|slot| window.pack(slot)), "step {k}");
            let slot = direct.map(AtomicU32::new);
            assert_eq!(Window::unpack(&slot), window, "step {k}");
        }
        assert!(statuses.len() >= 3, "{statuses:?}");
        assert!(
            statuses.iter().any(|s| s.starts_with("Tripped")),
            "{statuses:?}"
        );
    }
}
