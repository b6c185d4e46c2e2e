//! The interrupt side of the drive: what must happen every PWM period (docs/drive.md, "two
//! rates").
//!
//! ```text
//!  i_abc, v_dc ─► trips ─► Clarke ─► estimator (i, v over the last period) ─► θ̂, ω̂
//!                                │                                          │
//!            i_dq* (the task's) ─┴─► PI current loops in the θ̂ frame ◄── Park ◄┘
//!                                          │ v_dq
//!                inverse Park at θ̂ + ω̂T_s/2 ─► + dead-time compensation ─► SVPWM ─► duties
//!                                                      (the voltage the estimator will see ◄┘)
//! ```
//!
//! Besides the closed loop it runs what needs every sample while starting: the initial position
//! detection's pulses, the alignment's frame, the dead-time calibration's current and the
//! open-loop frame. It trips at once on what cannot wait: overcurrent, the bus out of its
//! range, three phase currents that do not sum to zero, and an estimated speed beyond the
//! overspeed limit. It takes the task's command at the first step after the task published
//! it, and at the end of each task period publishes its window: the sums and the last
//! sample the task decides from.

mod control;
#[cfg(feature = "injection")]
mod injection;
mod period;

use super::config::IsrConfig;
use super::handoff::Handoff;
use super::interface::{DriveInput, DriveOutput, Fault, Telemetry};
use super::monitor::{follow_nonnegative, phase_power};
use super::startup::OpenLoop;
use super::{ACTIVE_SHORT, DriveConfig, MAX_PWM_DELAY_SAMPLES, OFF, TASK_PERIOD};
use crate::angle::{Angle, SinCos};
use crate::control::current::CurrentController;
use crate::deadtime::DeadTimeBus;
use crate::frames::{AlphaBeta, Dq, clarke};
use crate::ipd::{Ipd, IpdFault, IpdResult};
use crate::num::{Pu, Unit};
use crate::observer::{AnyEstimator, Estimate, Estimator, Frame, ObserverInput};
use crate::svpwm::{BusReciprocal, Duties};

/// What the interrupt side does.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Phase {
    Off,
    /// The detection; `Some` once it found the rotor (the zero vector held).
    Ipd(Option<Angle>),
    /// The detection found the axis, not the polarity, and the start may fall back to the
    /// alignment (`IsrConfig::ipd_fallback`): the zero vector until the task says what next.
    #[cfg_attr(not(feature = "ipd"), allow(dead_code))] // entered by the detection's step
    IpdNoPolarity(IpdFault),
    Align,
    Calibrate(Angle),
    OpenLoop,
    Run,
    Tripped(Fault),
}

/// The interrupt side: its configuration (fixed point only) and state. One
/// [`DriveIsr::step`] per PWM period from the control interrupt.
#[derive(Clone, Copy, Debug)]
pub struct DriveIsr {
    pub(crate) config: IsrConfig,
    phase: Phase,
    /// The task's mode-change count in effect, the last window's number, the command in
    /// effect and the window it answers, the model update in effect, and the trips so far
    /// (each window reports them).
    epoch: u32,
    window: u32,
    command: u32,
    answered: u32,
    model: u32,
    trips: u32,
    /// The first window whose task answer may leave a trip.
    trip_window: u32,
    /// Samples into the task period.
    tick: u32,
    estimator: AnyEstimator,
    current: CurrentController,
    ipd: Ipd,
    ipd_result: Option<IpdResult>,
    open_loop: OpenLoop,
    /// The task's current reference (taken as it comes: a ramp over the period, a hold of
    /// the task's staircase, made the back-EMF estimators' speed loops ring on the random
    /// family) and its choices.
    i_ref: Dq,
    measured_signs: bool,
    /// The q-axis current the closed current loop is expected to carry: its reference through
    /// a first-order lag of the loop's time constant; the dead-time signs follow it.
    i_q_expected: Pu,
    /// Voltage applied over the current period, as the estimator should see it.
    v_est: AlphaBeta,
    /// Voltages modulated but not yet applied (the PWM update delay), newest first.
    v_line: [AlphaBeta; MAX_PWM_DELAY_SAMPLES as usize],
    telemetry: Telemetry,
    /// The speed of the frame the current loops ran in at the last sample, and the dead-time
    /// compensation's vector.
    frame_omega: Pu,
    v_dt: AlphaBeta,
    /// `1/v_dc` and the voltage circle of the last bus reading, for the modulator.
    inv_vdc: BusReciprocal,
    /// `V_dead/3`, `V_dead/√3` of the last bus reading, for the dead-time vector.
    deadtime_bus: DeadTimeBus,
    /// Samples since the drive tripped into outputs off ([`DriveIsr::faulted`]).
    since_trip: u32,
    /// `|i_a + i_b + i_c|` filtered, in quarters of [`Pu`]'s bits.
    sum: i32,
    /// The period's sums: estimated speed and each phase's squared current, each term
    /// divided by the period's length (so they are means).
    omega_sum: i32,
    power_sum: [u32; 3],
    /// The high-frequency injection, and whether it gives the angle now.
    #[cfg(feature = "injection")]
    injection: crate::observer::Injection,
    #[cfg(feature = "injection")]
    injecting: bool,
}

/// The period's length as a shift: its sums add each term shifted by it.
const PERIOD_SHIFT: u32 = TASK_PERIOD.trailing_zeros();
const _: () = assert!(TASK_PERIOD.is_power_of_two());

impl DriveIsr {
    /// The interrupt side of a drive built from `config`, outputs off. Out of line: built in
    /// place in the caller's slot.
    #[inline(never)]
    pub fn new(config: &DriveConfig) -> Self {
        let c = config.isr;
        Self {
            estimator: AnyEstimator::new(&config.estimator),
            current: CurrentController::new(config.current),
            ipd: Ipd::new(config.ipd),
            ipd_result: None,
            open_loop: OpenLoop::default(),
            config: c,
            phase: Phase::Off,
            epoch: 0,
            window: 0,
            command: 0,
            answered: 0,
            model: 0,
            trips: 0,
            trip_window: 0,
            tick: 0,
            i_ref: Dq::default(),
            measured_signs: false,
            i_q_expected: Pu::ZERO,
            v_est: AlphaBeta::default(),
            v_line: Default::default(),
            telemetry: Telemetry::default(),
            frame_omega: Pu::ZERO,
            v_dt: AlphaBeta::default(),
            inv_vdc: BusReciprocal::default(),
            deadtime_bus: DeadTimeBus::default(),
            since_trip: 0,
            sum: 0,
            omega_sum: 0,
            power_sum: [0; 3],
            #[cfg(feature = "injection")]
            injection: crate::observer::Injection::default(),
            #[cfg(feature = "injection")]
            injecting: false,
        }
    }

    /// What the last step computed.
    pub fn telemetry(&self) -> &Telemetry {
        &self.telemetry
    }

    /// The fault the interrupt side has latched (its own trip, or the task's fault it took),
    /// `None` while it runs or is off.
    pub fn fault(&self) -> Option<Fault> {
        match self.phase {
            Phase::Tripped(f) => Some(f),
            _ => None,
        }
    }

    /// The state as the interrupt side knows it: what it runs (the calibration shows as
    /// `Align`), `Idle` when off, the fault it latched.
    pub fn state(&self) -> super::DriveState {
        use super::DriveState as S;
        match self.phase {
            Phase::Off => S::Idle,
            Phase::Ipd(_) | Phase::IpdNoPolarity(_) => S::Ipd,
            Phase::Align | Phase::Calibrate(_) => S::Align,
            Phase::OpenLoop => S::OpenLoop,
            Phase::Run => S::Run,
            Phase::Tripped(f) => S::Fault(f),
        }
    }

    /// Whether the outputs switch under the drive's control (not off, not tripped).
    pub fn active(&self) -> bool {
        !matches!(self.phase, Phase::Off | Phase::Tripped(_))
    }

    /// The trips so far (the task takes each new one as a fault).
    pub fn trips(&self) -> u32 {
        self.trips
    }

    /// The result of the last initial position detection.
    pub fn ipd_result(&self) -> Option<IpdResult> {
        self.ipd_result
    }

    /// The voltage the estimator will be given at the next sample, αβ per unit: the vector
    /// that acts over the coming period (with a PWM update delay, the one modulated that many
    /// samples before) less the dead-time error.
    pub fn estimator_voltage(&self) -> AlphaBeta {
        self.v_est
    }

    /// The estimator (its state, for tests and logs).
    pub fn estimator(&self) -> &AnyEstimator {
        &self.estimator
    }

    /// Whether the step just taken ended a task period: the binding pends the task, which
    /// must finish its [`super::DriveTask::step`] before the next period ends.
    pub fn task_due(&self) -> bool {
        self.tick == 0
    }

    /// The binding reports that a control step overran its period: trips with
    /// [`Fault::Overrun`] (outputs off) unless off or tripped already.
    pub fn report_overrun(&mut self) {
        if self.active() {
            self.trip(Fault::Overrun);
        }
    }

    /// One PWM period: from the sampled phase currents and bus voltage to the duties of the
    /// next period. Integer arithmetic only; never panics, never allocates. It takes the
    /// task's command from `handoff` at the first step after the task published it, and at
    /// the end of a task period publishes its window there ([`DriveIsr::task_due`] then
    /// tells).
    pub fn step(&mut self, handoff: &Handoff, input: &DriveInput) -> DriveOutput {
        // The task's answer as soon as it is there (one load while it is not): the speed
        // loop's delay is the task's run, not a task period.
        if handoff.command.published() != self.command {
            self.take(handoff);
        }
        let out = self.sample(input);
        self.tick = (self.tick + 1) & (TASK_PERIOD - 1);
        if self.tick == 0 {
            self.end_period(handoff, input);
        }
        out
    }

    /// The work of one sample.
    #[inline(always)]
    fn sample(&mut self, input: &DriveInput) -> DriveOutput {
        match self.phase {
            Phase::Off => return OFF,
            Phase::Tripped(Fault::Overspeed(_)) => return ACTIVE_SHORT,
            Phase::Tripped(f) => return self.faulted(input, f),
            _ => {}
        }
        if let Some(fault) = self.protection(input) {
            return self.trip(fault);
        }
        let i = clarke(input.i_abc);
        let setpoint = match self.phase {
            Phase::Run => {
                #[cfg(feature = "injection")]
                if self.config.injection.is_some()
                    && let Some(setpoint) = self.injected(i)
                {
                    return self.control(input, i, setpoint);
                }
                let e = self.estimate(i);
                let limit = self.config.protection.overspeed.to_bits();
                if !(-limit..=limit).contains(&e.omega.to_bits()) {
                    return self.overspeed(e.omega);
                }
                Setpoint {
                    theta: e.theta,
                    omega: e.omega,
                    i_ref: self.i_ref,
                    // The current-model MRAS already rotated this sample's current into the
                    // frame at θ̂ (same angle, same current, same bits): reuse its sin/cos and
                    // Park.
                    frame: self.estimator.frame(),
                }
            }
            Phase::OpenLoop => {
                self.estimate(i);
                self.open_loop_step()
            }
            #[cfg(feature = "ipd")]
            Phase::Ipd(None) => return self.ipd_step(i, input.vdc),
            // Never entered: `DriveConfig::new` refuses the detection in a build without it.
            #[cfg(not(feature = "ipd"))]
            Phase::Ipd(None) => return OFF,
            Phase::Ipd(Some(_)) | Phase::IpdNoPolarity(_) => {
                // The detection is done: the zero vector until the task says what next.
                self.v_est = AlphaBeta::default();
                return DriveOutput {
                    duties: Duties::HALF,
                    pwm_on: true,
                };
            }
            Phase::Align => {
                let (theta, i_ref) = self.open_loop.align_frame(&self.config.open_loop, i);
                Setpoint::standstill(theta, i_ref)
            }
            Phase::Calibrate(theta) => Setpoint::standstill(
                theta,
                Dq {
                    d: self.i_ref.d,
                    q: Pu::ZERO,
                },
            ),
            Phase::Off | Phase::Tripped(_) => return OFF,
        };
        self.control(input, i, setpoint)
    }

    /// The estimator on the period that just ended; the speed summed for the window.
    #[inline(always)]
    fn estimate(&mut self, i: AlphaBeta) -> Estimate {
        // The estimator always sees the period that just ended.
        let estimate = self.estimator.update(&ObserverInput { i, v: self.v_est });
        self.telemetry.estimate = estimate;
        self.omega_sum = self
            .omega_sum
            .wrapping_add(estimate.omega.to_bits() >> PERIOD_SHIFT);
        estimate
    }

    /// One sample of the open-loop frame; the estimator restarts where a reversal passes
    /// through zero.
    #[inline(always)]
    fn open_loop_step(&mut self) -> Setpoint {
        let c = &self.config.open_loop;
        let (theta, omega, i_ref) = self.open_loop.advance(c);
        if let Some((theta, omega)) = self.open_loop.restart_angle(c) {
            self.estimator.reset(theta, omega);
            // As at the start: the new direction is held until the handover.
            self.estimator.hold_direction(Some(omega > Pu::ZERO));
        }
        Setpoint {
            theta,
            omega,
            i_ref,
            frame: None,
        }
    }

    /// The trips of every sample: overcurrent, the bus, and three phase currents that do not
    /// sum to zero (a broken sensor: filtered over 1 ms, above 0.15 `I_b`).
    #[inline(always)]
    fn protection(&mut self, input: &DriveInput) -> Option<Fault> {
        let p = &self.config.protection;
        let i = &input.i_abc;
        // Three currents of a star winding sum to zero. In quarters of Pu's bits: the sum
        // within ±3·2²⁹, no wrap and no saturating step.
        let sum = (i.a.to_bits() >> 2)
            .wrapping_add(i.b.to_bits() >> 2)
            .wrapping_add(i.c.to_bits() >> 2)
            .wrapping_abs();
        self.sum = follow_nonnegative(self.sum, sum, p.sum_shift);
        for (s, x) in self.power_sum.iter_mut().zip([i.a, i.b, i.c]) {
            *s = s.wrapping_add(phase_power(x) >> PERIOD_SHIFT);
        }
        // The common case in comparisons only (the limit is positive, so its negation fits).
        let oc = p.overcurrent.to_bits();
        let within = |x: Pu| (-oc..=oc).contains(&x.to_bits());
        if within(i.a)
            && within(i.b)
            && within(i.c)
            && input.vdc >= p.vdc_min
            && input.vdc <= p.vdc_max
            && self.sum <= p.sum_limit
        {
            return None;
        }
        let worst =
            i.a.saturating_abs()
                .max(i.b.saturating_abs())
                .max(i.c.saturating_abs());
        Some(if worst > p.overcurrent {
            Fault::OverCurrent(worst)
        } else if input.vdc < p.vdc_min {
            Fault::BusUnderVoltage(input.vdc)
        } else if input.vdc > p.vdc_max {
            Fault::BusOverVoltage(input.vdc)
        } else {
            Fault::CurrentSensor(None)
        })
    }

    /// Latches `fault`, outputs off.
    fn trip(&mut self, fault: Fault) -> DriveOutput {
        self.latch(fault);
        self.v_est = AlphaBeta::default();
        self.since_trip = 0;
        OFF
    }

    /// Latches `fault` and counts it (the task takes each new count as a fault).
    fn latch(&mut self, fault: Fault) {
        self.phase = Phase::Tripped(fault);
        self.trips = self.trips.wrapping_add(1);
        self.trip_window = self.window.wrapping_add(1);
    }

    /// Trips on [`Fault::Overspeed`] into the active short circuit.
    #[cold]
    #[inline(never)]
    fn overspeed(&mut self, omega: Pu) -> DriveOutput {
        self.trip(Fault::Overspeed(omega));
        ACTIVE_SHORT
    }

    /// Outputs off after a lost lock or an overcurrent, which is what a load driving the
    /// rotor beyond what the drive can brake trips first (docs/field-weakening.md, §4). With
    /// the switches off no current flows once the current the trip left has freewheeled into
    /// the bus, unless the EMF's line peak exceeds the bus and the diodes rectify it: a phase
    /// current beyond 1/8 of the overcurrent limit after [`super::RECTIFY_GRACE_S`], with the
    /// three summing to less than that (an offset sensor does not), is that, the overspeed the
    /// estimator could no longer see, and the drive turns to the active short.
    #[cold]
    #[inline(never)]
    fn faulted(&mut self, input: &DriveInput, fault: Fault) -> DriveOutput {
        if !matches!(fault, Fault::LossOfLock | Fault::OverCurrent(_)) {
            return OFF;
        }
        if self.since_trip < self.config.rectify_grace_samples {
            self.since_trip += 1;
            return OFF;
        }
        let lim = self.config.protection.overcurrent.to_bits() >> 3;
        let i = &input.i_abc;
        // Rectified phase currents sum to zero (isolated neutral); an offset sensor does not.
        let sum = i.a.saturating_add(i.b).saturating_add(i.c).to_bits();
        if sum.unsigned_abs() < lim as u32
            && [i.a, i.b, i.c]
                .iter()
                .any(|x| x.to_bits().unsigned_abs() > lim as u32)
        {
            self.latch(Fault::Overspeed(self.telemetry.estimate.omega));
            return ACTIVE_SHORT;
        }
        OFF
    }

    /// One sample of the initial position detection, which drives the PWM itself.
    #[cfg(feature = "ipd")]
    #[inline(always)]
    fn ipd_step(&mut self, i: AlphaBeta, vdc: Pu) -> DriveOutput {
        let out = self.ipd.step(i, vdc);
        self.v_est = self.delayed(out.v);
        self.telemetry.v = out.v;
        match out.done {
            None => DriveOutput {
                duties: out.duties,
                pwm_on: out.pwm_on,
            },
            Some(Err(f @ IpdFault::NoPolarity { .. })) if self.config.ipd_fallback => {
                self.phase = Phase::IpdNoPolarity(f);
                self.v_est = AlphaBeta::default();
                DriveOutput {
                    duties: Duties::HALF,
                    pwm_on: true,
                }
            }
            Some(Err(f)) => self.trip(Fault::InitialPosition(f)),
            Some(Ok(r)) => {
                self.ipd_result = Some(r);
                self.phase = Phase::Ipd(Some(r.theta));
                self.v_est = AlphaBeta::default();
                DriveOutput {
                    duties: Duties::HALF,
                    pwm_on: true,
                }
            }
        }
    }
}

/// What the current loops track at one sample: the frame they run in and the reference.
#[derive(Clone, Copy, Debug)]
struct Setpoint {
    /// Angle of the frame (the estimate, or the imposed frame while starting).
    theta: Angle,
    /// Speed of the frame, per unit of `ω_b`.
    omega: Pu,
    /// Current reference in that frame.
    i_ref: Dq,
    /// The estimator's own frame at `theta`, when it computed one ([`Frame`]).
    frame: Option<Frame>,
}

impl Setpoint {
    /// A frame standing still at `theta` with the reference `i_ref` (alignment, calibration).
    fn standstill(theta: Angle, i_ref: Dq) -> Self {
        Self {
            theta,
            omega: Pu::ZERO,
            i_ref,
            frame: None,
        }
    }
}

/// The frame `k/2 + 1` steps on from `now`, extrapolated along its step `next − now`:
/// `next + k (next − now)/2` componentwise (floor). For `k` = −1, the mean of the two frames;
/// for 2d − 1, the mid-period vector `d` periods later (a rotation to first order; its length
/// is off by `3/8 (ω T_s)²` for d = 1). The step is `ω T_s` of the unit vector, far from
/// overflowing Q2.30.
#[inline(always)]
pub(crate) fn mid_frame(now: SinCos, next: SinCos, k: i32) -> SinCos {
    let at = |a: Unit, b: Unit| {
        let (a, b) = (a.to_bits(), b.to_bits());
        Unit::from_bits(b.wrapping_add(b.wrapping_sub(a).wrapping_mul(k) >> 1))
    };
    SinCos {
        sin: at(now.sin, next.sin),
        cos: at(now.cos, next.cos),
    }
}

// What the interrupt side keeps of the configuration (its own, its controllers' and
// detector's, each estimator's) holds no floating-point value: the design figures stay with
// the task and the `DriveConfig`.
const _: () = {
    use crate::control::current::CurrentConfig;
    use crate::image::Words;
    use crate::ipd::IpdConfig;
    use crate::observer::{AoConfig, MrasCurrentConfig, MrasEmf, NloConfig};
    assert!(<IsrConfig as Words>::FLOATS == 0);
    assert!(<CurrentConfig as Words>::FLOATS == 0);
    assert!(<IpdConfig as Words>::FLOATS == 0);
    assert!(<NloConfig as Words>::FLOATS == 0);
    assert!(<AoConfig as Words>::FLOATS == 0);
    assert!(MrasEmf::LAW_FLOATS == 0);
    assert!(<MrasCurrentConfig as Words>::FLOATS == 0);
};
