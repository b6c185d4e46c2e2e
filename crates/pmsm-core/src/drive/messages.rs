//! What the two rates tell each other (docs/drive.md, "two rates"): the interrupt's
//! [`Window`] at the end of each task period, the task's [`Command`] in return, and a
//! [`ModelUpdate`] when the task's learners change the drive's model. Small `Copy` values,
//! sent as 32-bit words through [`super::handoff::Mailbox`].
//!
//! | signal | unit, format |
//! |---|---|
//! | angles | turn, [`Angle`] (2³² per turn) |
//! | speeds | `ω_b`, [`Pu`] Q8.24 |
//! | currents, voltages | `I_b`, `V_b`, [`Pu`] Q8.24 |
//! | `power` | phase current squared, Q8.12 squares (`(i·2¹²)²`, [`super::monitor`]) |

use super::handoff::{Message, Packer, Unpacker};
use super::interface::Fault;
use crate::angle::Angle;
use crate::frames::{Abc, AlphaBeta, Dq};
use crate::ipd::IpdFault;
use crate::num::Pu;
use crate::observer::MrasModel;
use core::sync::atomic::AtomicU32;

/// What the interrupt side is doing, as the window reports it.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Status {
    /// Outputs off.
    #[default]
    Off,
    /// The initial position detection runs.
    Ipd,
    /// The detection found the rotor at this angle; the zero vector is held.
    IpdDone(Angle),
    /// The detection found the axis, not the polarity (`IpdFault::NoPolarity`), and the start
    /// may fall back to the alignment; the zero vector is held.
    IpdNoPolarity(IpdFault),
    /// The alignment runs.
    Align,
    /// The alignment ended with the rotor at this angle; its current is held.
    Aligned(Angle),
    /// A d current at standstill for the dead-time calibration.
    Calibrate,
    /// The open-loop frame turns; at or past the handover speed in its direction.
    OpenLoop {
        /// At or past the handover speed.
        at_handover: bool,
    },
    /// The closed loop.
    Run,
    /// Tripped: outputs off (or the active short of [`Fault::Overspeed`]).
    Tripped(Fault),
}

/// What the task asks the interrupt side to do (from the interrupt's first step after the task
/// published it).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Mode {
    /// Outputs off.
    #[default]
    Off,
    /// Run the initial position detection.
    Ipd,
    /// Run the alignment.
    Align,
    /// Hold the d current of [`Command::i_ref`] at standstill at `theta`; `reset`: the current
    /// loops start afresh (after a detection; an alignment's loops carry on).
    Calibrate {
        /// The rotor's angle.
        theta: Angle,
        /// Restart the current loops.
        reset: bool,
    },
    /// The open-loop start from rest at `theta`, backwards if `reverse`; the estimator starts
    /// there.
    OpenLoop {
        /// The rotor's angle.
        theta: Angle,
        /// Backwards.
        reverse: bool,
    },
    /// The open-loop reversal from the closed loop ([`super::startup::OpenLoop::reverse`]) at
    /// the estimated speed `omega`, the current `iq` turned into the frame.
    Reverse {
        /// The speed the frame starts at.
        omega: Pu,
        /// The speed loop's q current when it began.
        iq: Pu,
        /// Towards negative speed.
        reverse: bool,
    },
    /// The closed loop on [`Command::i_ref`]; `from`: the rotor stands at this angle (the
    /// estimator and the current loops start there), else the estimator carries on (a
    /// handover).
    Run {
        /// Start from rest at this angle.
        from: Option<Angle>,
    },
    /// Outputs off with this fault (the task's checks).
    Fault(Fault),
}

/// The task's answer to a window.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Command {
    /// The number of the window it answers (the interrupt applies it at its first step after
    /// the task published it; none answering the last window when the next period ends is
    /// the task's overrun).
    pub window: u32,
    /// Counts the task's mode changes: a new value makes the interrupt enter `mode` afresh.
    pub epoch: u32,
    pub mode: Mode,
    /// The current reference, in the estimated frame (`Run`) or the rotor's (`Calibrate`).
    pub i_ref: Dq,
    /// The dead-time compensation takes the measured currents' signs (the task's choice for
    /// [`crate::CurrentSource::MeasuredUnderLoad`]).
    pub measured_signs: bool,
    /// Hold the current-model MRAS's adaptation over the next task period (through a phase
    /// current's zero crossing at low speed, [`super::zero_crossing`]).
    pub hold: bool,
    /// The number of the model update to run with (the model mailbox's); 0: the configured.
    pub model: u32,
    /// The estimator's health figure as the task filters it (for the interrupt side's
    /// telemetry).
    pub health: Pu,
    /// The open loop's frame ahead of its ramp by this (its damping, `startup`).
    pub frame_shift: Angle,
}

/// What the interrupt side did over one task period: its status, the last sample, and means.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Window {
    /// The command epoch these samples ran under.
    pub epoch: u32,
    /// The interrupt side's trips so far (a new count is a new fault).
    pub trips: u32,
    pub status: Status,
    /// The estimate at the last sample.
    pub theta_est: Angle,
    pub omega: Pu,
    /// The estimated speed's mean over the period.
    pub omega_mean: Pu,
    /// The estimator's health figure at the last sample ([`crate::Estimator::health`]).
    pub health: Pu,
    /// The frame the current loops ran in at the last sample (the estimate, or the imposed
    /// frame while starting) and its speed.
    pub theta: Angle,
    pub omega_frame: Pu,
    /// The open-loop frame turns backwards; it is a reversal from the closed loop.
    pub reverse: bool,
    pub reversal: bool,
    /// The last sample's current in that frame, its reference, the modulator's voltage (αβ),
    /// the voltage the estimator will see (αβ), and whether a limit held the voltage.
    pub i_dq: Dq,
    pub i_ref: Dq,
    pub v: AlphaBeta,
    pub v_est: AlphaBeta,
    /// The dead-time compensation's vector of the last sample, αβ.
    pub v_dt: AlphaBeta,
    pub saturated: bool,
    /// The high-frequency injection gave the angle at the last sample.
    pub injecting: bool,
    /// The last sample's phase currents.
    pub i_abc: Abc,
    /// The bus as the control path took it at its last step: the reading its bus terms were
    /// computed from, within 0.2 % of that step's (`BusReciprocal`), so that the task's
    /// voltage limits are the modulator's (zero before the control path first runs; the task
    /// reads it in the closed loop only).
    pub vdc: Pu,
    /// Each phase's mean squared current over the period (Q8.12 squares).
    pub power: [u32; 3],
}

fn write_angle<const N: usize>(w: &mut Packer<N>, a: Angle) {
    w.i32(a.0);
}

fn read_angle<const N: usize>(r: &mut Unpacker<N>) -> Angle {
    Angle(r.i32())
}

fn write_pu<const N: usize>(w: &mut Packer<N>, x: Pu) {
    w.i32(x.to_bits());
}

fn read_pu<const N: usize>(r: &mut Unpacker<N>) -> Pu {
    Pu::from_bits(r.i32())
}

/// A fault in four words: its code, and its payload's.
#[inline(never)]
fn fault_words(f: &Fault) -> [u32; 4] {
    let (a, b, c) = match *f {
        Fault::OverCurrent(x)
        | Fault::BusUnderVoltage(x)
        | Fault::BusOverVoltage(x)
        | Fault::Overspeed(x) => (x.to_bits(), 0, 0),
        Fault::InitialPosition(i) => {
            let (x, y) = match i {
                IpdFault::OverCurrent(x) | IpdFault::NoCurrent(x) => (x, Pu::ZERO),
                IpdFault::LowSaliency { modulation, sum } => (modulation, sum),
                IpdFault::NoPolarity { along, opposite } => (along, opposite),
                IpdFault::BusLow => (Pu::ZERO, Pu::ZERO),
            };
            (i32::from(i.code()), x.to_bits(), y.to_bits())
        }
        Fault::Handover(a, x) => (a.0, x.to_bits(), 0),
        Fault::CurrentSensor(k) => (k.map_or(-1, i32::from), 0, 0),
        Fault::PhaseLoss(k) => (i32::from(k), 0, 0),
        Fault::Stall | Fault::LossOfLock | Fault::Overrun | Fault::DrivenBackwards => (0, 0, 0),
    };
    [u32::from(f.code()), a as u32, b as u32, c as u32]
}

/// [`fault_words`]'s fault; an unknown code reads as [`Fault::Overrun`] (never written).
#[inline(never)]
fn fault_of(w: [u32; 4]) -> Fault {
    let [code, a, b, c] = w.map(|x| x as i32);
    let pu = Pu::from_bits;
    match code {
        1 => Fault::OverCurrent(pu(a)),
        2 => Fault::BusUnderVoltage(pu(a)),
        3 => Fault::BusOverVoltage(pu(a)),
        4 => Fault::InitialPosition(match a {
            1 => IpdFault::OverCurrent(pu(b)),
            2 => IpdFault::NoCurrent(pu(b)),
            3 => IpdFault::LowSaliency {
                modulation: pu(b),
                sum: pu(c),
            },
            4 => IpdFault::NoPolarity {
                along: pu(b),
                opposite: pu(c),
            },
            _ => IpdFault::BusLow,
        }),
        5 => Fault::Handover(Angle(a), pu(b)),
        6 => Fault::CurrentSensor(u8::try_from(a).ok()),
        7 => Fault::PhaseLoss(a as u8),
        8 => Fault::Stall,
        9 => Fault::LossOfLock,
        11 => Fault::Overspeed(pu(a)),
        12 => Fault::DrivenBackwards,
        _ => Fault::Overrun,
    }
}

/// A fault's words into a message.
fn write_fault<const N: usize>(w: &mut Packer<N>, f: &Fault) {
    for x in fault_words(f) {
        w.u32(x);
    }
}

/// A fault from a message's words.
fn read_fault<const N: usize>(r: &mut Unpacker<N>) -> Fault {
    fault_of([r.u32(), r.u32(), r.u32(), r.u32()])
}

impl Status {
    pub(crate) fn write<const N: usize>(&self, w: &mut Packer<N>) {
        let (tag, x) = match *self {
            Status::Off => (0, 0),
            Status::Ipd => (1, 0),
            Status::IpdDone(a) => (2, a.0),
            Status::Align => (3, 0),
            Status::Aligned(a) => (4, a.0),
            Status::Calibrate => (5, 0),
            Status::OpenLoop { at_handover } => (6, i32::from(at_handover)),
            Status::Run => (7, 0),
            Status::Tripped(f) => {
                w.u32(8);
                write_fault(w, &f);
                return;
            }
            Status::IpdNoPolarity(f) => {
                w.u32(9);
                write_fault(w, &Fault::InitialPosition(f));
                return;
            }
        };
        w.u32(tag);
        w.i32(x);
        for _ in 0..3 {
            w.u32(0);
        }
    }

    fn read<const N: usize>(r: &mut Unpacker<N>) -> Self {
        let tag = r.u32();
        if tag == 8 {
            return Status::Tripped(read_fault(r));
        }
        if tag == 9 {
            return match read_fault(r) {
                Fault::InitialPosition(f) => Status::IpdNoPolarity(f),
                _ => Status::Off,
            };
        }
        let x = r.i32();
        for _ in 0..3 {
            r.u32();
        }
        match tag {
            1 => Status::Ipd,
            2 => Status::IpdDone(Angle(x)),
            3 => Status::Align,
            4 => Status::Aligned(Angle(x)),
            5 => Status::Calibrate,
            6 => Status::OpenLoop {
                at_handover: x != 0,
            },
            7 => Status::Run,
            _ => Status::Off,
        }
    }
}

impl Mode {
    fn write<const N: usize>(&self, w: &mut Packer<N>) {
        let (tag, a, b, c) = match *self {
            Mode::Off => (0, 0, 0, 0),
            Mode::Ipd => (1, 0, 0, 0),
            Mode::Align => (2, 0, 0, 0),
            Mode::Calibrate { theta, reset } => (3, theta.0, i32::from(reset), 0),
            Mode::OpenLoop { theta, reverse } => (4, theta.0, i32::from(reverse), 0),
            Mode::Reverse { omega, iq, reverse } => {
                (5, omega.to_bits(), iq.to_bits(), i32::from(reverse))
            }
            Mode::Run { from } => (6, from.map_or(0, |a| a.0), i32::from(from.is_some()), 0),
            Mode::Fault(f) => {
                w.u32(7);
                write_fault(w, &f);
                return;
            }
        };
        w.u32(tag);
        w.i32(a);
        w.i32(b);
        w.i32(c);
        w.u32(0);
    }

    fn read<const N: usize>(r: &mut Unpacker<N>) -> Self {
        let tag = r.u32();
        if tag == 7 {
            return Mode::Fault(read_fault(r));
        }
        let (a, b, c) = (r.i32(), r.i32(), r.i32());
        r.u32();
        match tag {
            1 => Mode::Ipd,
            2 => Mode::Align,
            3 => Mode::Calibrate {
                theta: Angle(a),
                reset: b != 0,
            },
            4 => Mode::OpenLoop {
                theta: Angle(a),
                reverse: b != 0,
            },
            5 => Mode::Reverse {
                omega: Pu::from_bits(a),
                iq: Pu::from_bits(b),
                reverse: c != 0,
            },
            6 => Mode::Run {
                from: (b != 0).then_some(Angle(a)),
            },
            _ => Mode::Off,
        }
    }
}

/// Words of a [`Status`] or a [`Mode`]: a tag and four.
const TAGGED_WORDS: usize = 5;

pub(crate) const COMMAND_WORDS: usize = 2 + TAGGED_WORDS + 2 + 2 + 3;

impl Message<COMMAND_WORDS> for Command {
    fn pack(&self, slot: &[AtomicU32; COMMAND_WORDS]) {
        let w = &mut Packer::new(slot);
        w.u32(self.window);
        w.u32(self.epoch);
        self.mode.write(w);
        write_pu(w, self.i_ref.d);
        write_pu(w, self.i_ref.q);
        w.bool(self.measured_signs);
        w.bool(self.hold);
        w.u32(self.model);
        write_pu(w, self.health);
        w.i32(self.frame_shift.0);
    }

    fn unpack(slot: &[AtomicU32; COMMAND_WORDS]) -> Self {
        let r = &mut Unpacker::new(slot);
        let window = r.u32();
        let epoch = r.u32();
        let mode = Mode::read(r);
        Self {
            window,
            epoch,
            mode,
            i_ref: Dq {
                d: read_pu(r),
                q: read_pu(r),
            },
            measured_signs: r.bool(),
            hold: r.bool(),
            model: r.u32(),
            health: read_pu(r),
            frame_shift: Angle(r.i32()),
        }
    }
}

pub(crate) const WINDOW_WORDS: usize = 2 + TAGGED_WORDS + 4 + 2 + 2 + 14 + 1 + 3;

impl Window {
    /// The word of the two flags (one word for both: the interrupt side writes every word of
    /// the window).
    #[inline(always)]
    pub(crate) fn flags(saturated: bool, injecting: bool) -> u32 {
        u32::from(saturated) | u32::from(injecting) << 1
    }
}

impl Message<WINDOW_WORDS> for Window {
    fn pack(&self, slot: &[AtomicU32; WINDOW_WORDS]) {
        let w = &mut Packer::new(slot);
        // The status first: its fault's words are the only call, with nothing else loaded yet.
        self.status.write(w);
        w.u32(self.epoch);
        w.u32(self.trips);
        write_angle(w, self.theta_est);
        write_pu(w, self.omega);
        write_pu(w, self.omega_mean);
        write_pu(w, self.health);
        write_angle(w, self.theta);
        write_pu(w, self.omega_frame);
        w.bool(self.reverse);
        w.bool(self.reversal);
        for x in [
            self.i_dq.d,
            self.i_dq.q,
            self.i_ref.d,
            self.i_ref.q,
            self.v.alpha,
            self.v.beta,
            self.v_est.alpha,
            self.v_est.beta,
            self.v_dt.alpha,
            self.v_dt.beta,
            self.i_abc.a,
            self.i_abc.b,
            self.i_abc.c,
            self.vdc,
        ] {
            write_pu(w, x);
        }
        w.u32(Window::flags(self.saturated, self.injecting));
        for p in self.power {
            w.u32(p);
        }
    }

    fn unpack(slot: &[AtomicU32; WINDOW_WORDS]) -> Self {
        let r = &mut Unpacker::new(slot);
        let status = Status::read(r);
        let epoch = r.u32();
        let trips = r.u32();
        let theta_est = read_angle(r);
        let omega = read_pu(r);
        let omega_mean = read_pu(r);
        let health = read_pu(r);
        let theta = read_angle(r);
        let omega_frame = read_pu(r);
        let reverse = r.bool();
        let reversal = r.bool();
        let mut p = || read_pu(r);
        let i_dq = Dq { d: p(), q: p() };
        let i_ref = Dq { d: p(), q: p() };
        let v = AlphaBeta {
            alpha: p(),
            beta: p(),
        };
        let v_est = AlphaBeta {
            alpha: p(),
            beta: p(),
        };
        let v_dt = AlphaBeta {
            alpha: p(),
            beta: p(),
        };
        let i_abc = Abc {
            a: p(),
            b: p(),
            c: p(),
        };
        let vdc = p();
        let flags = r.u32();
        let (saturated, injecting) = (flags & 1 != 0, flags & 2 != 0);
        let power = [r.u32(), r.u32(), r.u32()];
        Self {
            epoch,
            trips,
            status,
            theta_est,
            omega,
            omega_mean,
            health,
            theta,
            omega_frame,
            reverse,
            reversal,
            i_dq,
            i_ref,
            v,
            v_est,
            v_dt,
            saturated,
            injecting,
            i_abc,
            vdc,
            power,
        }
    }
}

/// The parts of the interrupt side's model that the task's learners change: the
/// current-model MRAS's coefficients of `R` and `ψ` (the tracker), the current loops' `ψ`
/// (the tracker) and the dead-time compensation's `V_dead` terms (the calibration and the
/// learner).
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct ModelUpdate {
    /// `None` with another estimator.
    pub mras: Option<MrasModel>,
    pub psi: Pu,
    /// The compensation's bus terms ([`crate::DeadTimeConfig`]'s `k_bus`, `v_const` bits).
    pub deadtime: (i32, i32),
}

pub(crate) const MODEL_WORDS: usize = 1 + crate::observer::MRAS_MODEL_WORDS + 3;

impl Message<MODEL_WORDS> for ModelUpdate {
    fn pack(&self, slot: &[AtomicU32; MODEL_WORDS]) {
        let w = &mut Packer::new(slot);
        w.bool(self.mras.is_some());
        match &self.mras {
            Some(m) => m.write_words(w),
            None => {
                for _ in 0..crate::observer::MRAS_MODEL_WORDS {
                    w.u32(0);
                }
            }
        }
        write_pu(w, self.psi);
        w.i32(self.deadtime.0);
        w.i32(self.deadtime.1);
    }

    fn unpack(slot: &[AtomicU32; MODEL_WORDS]) -> Self {
        let r = &mut Unpacker::new(slot);
        let some = r.bool();
        let m = MrasModel::read_words(r);
        Self {
            mras: some.then_some(m),
            psi: read_pu(r),
            deadtime: (r.i32(), r.i32()),
        }
    }
}

#[cfg(test)]
mod tests;
