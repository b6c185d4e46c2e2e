//! The sensorless drive: one [`Drive::step`] per control sample, from sampled phase currents
//! and bus voltage to three duties (Khlaief, Boussak, Gossa (2012) Fig. 1, docs/khlaief2012.md).
//!
//! ```text
//!  i_abc, v_dc ─► protection ─► Clarke ─► estimator (i, v over the last period) ─► θ̂, ω̂
//!                                   │                                              │
//!         ω* ─► IP speed loop ─► i_q* ─► PI current loops in the θ̂ frame ◄── Park ◄┘
//!                                          │ v_dq
//!                          inverse Park at θ̂ + ω̂T_s/2 ─► + dead-time compensation ─► SVPWM ─► duties
//!                                                              (the voltage the estimator will see ◄┘)
//! ```
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
mod distortion;
mod interface;
mod monitor;
mod startup;
mod tracking;
mod zero_crossing;

pub use config::{
    AUTO_SALIENCY_MARGIN, DEFAULT_HEALTH_LIMIT_PU, DriveConfig, DriveDesign, DriveOptions,
    MAX_PWM_DELAY_SAMPLES, OVERSPEED_FACTOR, OpenLoopDesign, Protection, StartupMode,
};
pub use distortion::{DistortionDesign, DistortionFrozen, DistortionLearner, DistortionStatus};
pub use interface::{DriveInput, DriveOutput, DriveState, Fault, SpeedRefLimit, Telemetry};
pub use tracking::{
    Frozen, ModelCoefficients, SPEED_FILTER_S, Tracker, TrackerDesign, TrackerInput, TrackerStatus,
    WRITE_THRESHOLD,
};

use crate::angle::{Angle, SinCos};
use crate::control::current::{CurrentController, CurrentInput};
use crate::control::flux::FluxController;
use crate::control::light_load::LightLoad;
use crate::control::speed::SpeedController;
use crate::deadtime::{CurrentSource, DeadTimeBus};
use crate::frames::{AlphaBeta, Dq, clarke, inverse_park, park};
use crate::ipd::{Ipd, IpdResult};
use crate::num::{PU_FRAC, Pu, Unit, follow, mul_unit};
use crate::observer::{AnyEstimator, Estimate, Estimator, Frame, ObserverInput};
use crate::svpwm::{BusReciprocal, Duties, SvpwmOutput};
use startup::OpenLoop;

/// The drive: configuration and state.
#[derive(Clone, Copy, Debug)]
pub struct Drive {
    config: DriveConfig,
    state: DriveState,
    estimator: AnyEstimator,
    current: CurrentController,
    speed: SpeedController,
    ipd: Ipd,
    open_loop: OpenLoop,
    speed_ref: Pu,
    /// [`Drive::run_speed_ref`] of `speed_ref`, computed when it is set (a function of it
    /// and the configuration only).
    speed_ref_run: Pu,
    /// Filtered estimated speed for the speed loop (its time constant longer than the loop's
    /// period: a decimated loop sees the period's mean, not one sample at a fixed phase of what
    /// its own step excites, which biased the speed by 2 % at no load).
    speed_filtered: Pu,
    /// The q-axis current the closed current loop is expected to carry: its reference through
    /// a first-order lag of the loop's time constant; the dead-time signs follow it.
    i_q_expected: Pu,
    /// Voltage applied over the current period, as the estimator should see it.
    v_est: AlphaBeta,
    /// Voltages modulated but not yet applied (the PWM update delay), newest first.
    v_line: [AlphaBeta; MAX_PWM_DELAY_SAMPLES as usize],
    telemetry: Telemetry,
    ipd_result: Option<IpdResult>,
    monitor: monitor::Monitor,
    /// The speed loop's current reference at the last sample.
    iq_ref: Pu,
    /// `1/v_dc` and the voltage circle of the last bus reading, for the modulator.
    inv_vdc: BusReciprocal,
    /// `V_dead/3`, `V_dead/√3` of the last bus reading, for the dead-time vector.
    deadtime_bus: DeadTimeBus,
    /// The d-axis reference (MTPA, field weakening).
    flux: FluxController,
    /// The light-load d-axis current.
    light_load: LightLoad,
    /// The low-speed d-axis current's reference (`control/low_speed.rs`), and its faded level
    /// before the current limit (taken on another slot).
    low_speed_id: Pu,
    low_speed_faded: Pu,
    /// The dead-time calibration's progress.
    calibration: calibrate::Calibration,
    /// The compensation's `V_dead` against the configured one, Q4.28 (the calibration's).
    deadtime_scale: i32,
    /// The slot of this sample (0–7): the speed loop and the d-axis reference's updates take
    /// turns, and so do the monitor's slower checks (one odd slot each) and the light-load
    /// update (slot 7), so that no sample pays for all of them.
    slot: u8,
    /// Samples since the drive tripped into outputs off ([`Drive::faulted`]).
    since_trip: u32,
    /// The current-model MRAS's hold through zero crossings: how long the load has been light.
    zero_crossing: zero_crossing::ZeroCrossing,
}

impl Drive {
    /// A drive in `Idle`. Out of line: built in place in the caller's slot, without the
    /// temporaries an inlined copy leaves in the caller's frame (the 16 KiB target holds a
    /// drive on its stack several times).
    #[inline(never)]
    pub fn new(config: DriveConfig) -> Self {
        Self {
            estimator: AnyEstimator::new(&config.estimator),
            current: CurrentController::new(config.current),
            speed: SpeedController::new(config.speed),
            ipd: Ipd::new(config.ipd),
            open_loop: OpenLoop::default(),
            config,
            state: DriveState::Idle,
            speed_ref: Pu::ZERO,
            speed_ref_run: Pu::ZERO,
            speed_filtered: Pu::ZERO,
            i_q_expected: Pu::ZERO,
            v_est: AlphaBeta::default(),
            v_line: Default::default(),
            telemetry: Telemetry::default(),
            ipd_result: None,
            monitor: monitor::Monitor::default(),
            iq_ref: Pu::ZERO,
            inv_vdc: BusReciprocal::default(),
            deadtime_bus: DeadTimeBus::default(),
            flux: {
                let mut f = FluxController::default();
                f.reset(&config.flux);
                f
            },
            light_load: LightLoad::default(),
            low_speed_id: Pu::ZERO,
            low_speed_faded: Pu::ZERO,
            calibration: calibrate::Calibration::default(),
            deadtime_scale: calibrate::SCALE_ONE,
            slot: 0,
            since_trip: 0,
            zero_crossing: zero_crossing::ZeroCrossing::default(),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &DriveConfig {
        &self.config
    }

    /// The state.
    pub fn state(&self) -> DriveState {
        self.state
    }

    /// What the last step computed.
    pub fn telemetry(&self) -> &Telemetry {
        &self.telemetry
    }

    /// The voltage the estimator will be given at the next sample, αβ per unit: the vector
    /// that acts over the coming period (with a PWM update delay, the one modulated that many
    /// samples before) less the dead-time error. What [`Tracker`] reads besides the telemetry,
    /// and what tests hold against the plant's applied voltage.
    pub fn estimator_voltage(&self) -> AlphaBeta {
        self.v_est
    }

    /// Rewrites the coefficients of the drive's model that depend on `R` and `ψ` (the
    /// current-model MRAS's, and the `ψ` of the current loops' feed-forward) with those a
    /// [`Tracker`] computed. Between two steps (on an MCU with the control interrupt masked);
    /// the other estimators keep their model (docs/tracking.md).
    pub fn set_model(&mut self, c: &ModelCoefficients) {
        #[allow(irrefutable_let_patterns)]
        #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
        if let AnyEstimator::MrasCurrent(m) = &mut self.estimator {
            m.set_model(&c.mras);
        }
        self.current.set_psi(c.psi);
    }

    /// Scales the dead-time compensation's `V_dead` to `scale` times the one the drive was
    /// told (within [0, 4], saturated; absolute), with the light-load current raised with it
    /// (never lowered): what a [`DistortionLearner`] measured while running. Between two steps (on an MCU
    /// with the control interrupt masked).
    pub fn set_deadtime_scale(&mut self, scale: Pu) {
        let bits = scale.to_bits().clamp(0, 4 << PU_FRAC);
        // Q8.24 to Q4.28: at most 4 << 28 < 2³¹.
        self.apply_deadtime_scale(bits << (28 - PU_FRAC));
    }

    /// The estimator's health figure ([`Estimator::health`]) filtered over 10 ms, as the
    /// loss-of-lock check sees it (zero outside the closed loop).
    pub fn health(&self) -> Pu {
        self.monitor.health()
    }

    /// The result of the last initial position detection.
    pub fn ipd_result(&self) -> Option<IpdResult> {
        self.ipd_result
    }

    /// Sets the speed reference, electrical, per unit of `ω_b`, clamped to the maximum speed
    /// ([`crate::FluxConfig::max_speed`]; [`Drive::speed_ref_limit`] tells when it was).
    /// The closed loop's reference is computed here, once, not at every step. (Out of line:
    /// inlined, a setter that reads the configuration made callers keep one more copy of the
    /// drive on their stack.)
    /// In the closed loop the PI form of the speed loop takes the reference's proportional
    /// part here ([`crate::SpeedController::move_reference`]).
    #[inline(never)]
    pub fn set_speed_ref(&mut self, omega: Pu) {
        let from = self.speed_ref_run;
        self.speed_ref = omega;
        self.speed_ref_run = self.run_speed_ref();
        if self.state == DriveState::Run {
            self.speed.move_reference(from, self.speed_ref_run);
        }
    }

    /// The speed reference clamped to the maximum speed (max/min: no panic path).
    #[inline(always)]
    fn speed_ref_used(&self) -> Pu {
        let max = self.config.flux.max_speed();
        self.speed_ref.min(max).max(max.saturating_neg())
    }

    /// The dead-time compensation's `V_dead` against the configured one, per unit (one until
    /// the calibration at a start measured it; docs/drive.md, "dead-time calibration").
    pub fn deadtime_scale(&self) -> Pu {
        Pu::from_bits(self.deadtime_scale >> 4)
    }

    /// The field-weakening offset of the d-axis reference (≤ 0; zero below base speed).
    pub fn field_weakening(&self) -> Pu {
        self.flux.delta()
    }

    /// Starts from `Idle` with the configured start-up; does nothing in other states.
    pub fn start(&mut self) {
        if self.state != DriveState::Idle {
            return;
        }
        // A drive never given a reference runs at the one it holds for zero.
        self.speed_ref_run = self.run_speed_ref();
        self.current.reset();
        self.monitor.reset();
        self.calibration = calibrate::Calibration::default();
        self.v_est = AlphaBeta::default();
        self.v_line = Default::default();
        self.state = match self.config.design.startup {
            StartupMode::Ipd => {
                self.ipd.restart();
                DriveState::Ipd
            }
            // `Auto` is resolved by `DriveConfig::new`; alignment is its safe reading.
            StartupMode::Align | StartupMode::Auto => {
                self.open_loop = OpenLoop::align();
                DriveState::Align
            }
            StartupMode::Known(theta) => self.rotor_found(theta),
        };
    }

    /// Turns the outputs off and returns to `Idle` (also from a fault).
    pub fn stop(&mut self) {
        self.state = DriveState::Idle;
    }

    /// The binding reports that a control step overran its period: trips with
    /// [`Fault::Overrun`] (outputs off) unless already idle or faulted.
    pub fn report_overrun(&mut self) {
        if !matches!(self.state, DriveState::Idle | DriveState::Fault(_)) {
            self.state = DriveState::Fault(Fault::Overrun);
        }
    }

    /// Leaves a fault for `Idle`; does nothing in other states.
    pub fn clear_fault(&mut self) {
        if let DriveState::Fault(_) = self.state {
            self.state = DriveState::Idle;
        }
    }

    /// The rotor is at `theta`: start the estimator there and run, or start open loop.
    fn rotor_found(&mut self, theta: Angle) -> DriveState {
        self.estimator.reset(theta, Pu::ZERO);
        self.current.reset();
        self.flux.reset(&self.config.flux);
        self.light_load
            .reset(&self.config.light_load, Pu::ZERO, Pu::ZERO);
        self.zero_crossing = zero_crossing::ZeroCrossing::default();
        self.low_speed_faded = self.config.low_speed.faded(Pu::ZERO);
        self.low_speed_id =
            self.config
                .low_speed
                .within_limit(self.low_speed_faded, Pu::ZERO, Pu::ZERO);
        self.speed.reset(Pu::ZERO, Pu::ZERO);
        self.iq_ref = Pu::ZERO;
        // The first sample of the closed loop is slot 0: it runs the speed loop. The speed
        // filter starts from the estimator's reset speed, zero.
        self.slot = LAST_SLOT;
        self.speed_filtered = Pu::ZERO;
        self.i_q_expected = Pu::ZERO;
        if self.estimator.kind().needs_open_loop_start() {
            // From rest, in the reference's direction, which the estimator holds through the
            // open loop.
            let reverse = self.speed_ref < Pu::ZERO;
            self.open_loop = OpenLoop::start(theta, reverse);
            self.estimator.hold_direction(Some(!reverse));
            DriveState::OpenLoop
        } else {
            DriveState::Run
        }
    }

    /// Trips on [`Fault::Overspeed`] into the active short circuit.
    #[cold]
    #[inline(never)]
    fn overspeed(&mut self, omega: Pu) -> DriveOutput {
        self.state = DriveState::Fault(Fault::Overspeed(omega));
        self.v_est = AlphaBeta::default();
        ACTIVE_SHORT
    }

    fn trip(&mut self, fault: Fault) -> DriveOutput {
        self.state = DriveState::Fault(fault);
        self.v_est = AlphaBeta::default();
        self.since_trip = 0;
        OFF
    }

    /// Outputs off after a lost lock or an overcurrent, which is what a load driving the
    /// rotor beyond what the drive can brake trips first (docs/field-weakening.md, §4). With
    /// the switches off no current flows once the current the trip left has freewheeled into
    /// the bus, unless the EMF's line peak exceeds the bus and the diodes rectify it: a phase
    /// current beyond 1/8 of the overcurrent limit after [`RECTIFY_GRACE_S`], with the three
    /// summing to less than that (an offset sensor does not), is that, the overspeed the
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
            return self.overspeed(self.telemetry.estimate.omega);
        }
        OFF
    }

    /// One control sample. Integer arithmetic only; never panics, never allocates.
    ///
    /// The stages of the module's diagram in order: protection, Clarke, the estimator (and
    /// the checks on its output), the state's setpoint (the speed loop in `Run`), then the
    /// current loops, the dead-time compensation and the modulator (`Drive::control`).
    pub fn step(&mut self, input: &DriveInput) -> DriveOutput {
        match self.state {
            DriveState::Idle => return OFF,
            DriveState::Fault(Fault::Overspeed(_)) => return ACTIVE_SHORT,
            DriveState::Fault(fault) => return self.faulted(input, fault),
            _ => {}
        }
        if let Some(fault) = self.protection(input) {
            return self.trip(fault);
        }
        // The slot of this sample (outer loops, monitor halves).
        self.slot = (self.slot + 1) & LAST_SLOT;
        let i = clarke(input.i_abc);
        let estimate = self.estimate(i);
        let omega_ref = self.run_speed_ref_step(&estimate);
        if let Some(fault) = self.supervise(input, &estimate, omega_ref) {
            return self.trip(fault);
        }
        let setpoint = match self.state {
            DriveState::Ipd => return self.ipd_step(i, input.vdc),
            DriveState::Align => self.align(i, input.vdc),
            DriveState::OpenLoop => match self.open_loop(&estimate) {
                Ok(setpoint) => setpoint,
                Err(fault) => return self.trip(fault),
            },
            DriveState::Run => {
                let limit = self.config.flux.overspeed.to_bits();
                if !(-limit..=limit).contains(&estimate.omega.to_bits()) {
                    return self.overspeed(estimate.omega);
                }
                self.speed_loop(omega_ref, &estimate)
            }
            DriveState::Idle | DriveState::Fault(_) => return OFF,
        };
        self.control(input, i, setpoint)
    }

    /// The estimator on the period that just ended, and the speed the speed loop sees.
    #[inline(always)]
    fn estimate(&mut self, i: AlphaBeta) -> Estimate {
        if self.slot == SCHEDULE_SLOT {
            self.estimator_upkeep();
        }
        // The estimator always sees the period that just ended.
        let estimate = self.estimator.update(&ObserverInput { i, v: self.v_est });
        self.telemetry.estimate = estimate;
        self.speed_filtered = follow(
            self.speed_filtered,
            estimate.omega,
            self.config.speed_filter_shift,
        );
        estimate
    }

    /// Every eighth sample, on the slot with the least other work (where the monitor checks
    /// for stuck channels), before the update: the current-model MRAS's low-speed gain
    /// schedule, and its hold through a phase current's zero crossing at low speed and light
    /// load over the next eight updates ([`zero_crossing`]), from the phase currents the
    /// monitor read on this slot eight samples before. Measured with `scripts/pil.sh`: taking
    /// this sample's input currents instead, or calling this out of line on the Cortex-M0,
    /// each cost every sample of the Cortex-M0 some 45 instructions; out of line elsewhere,
    /// the board's image is 300 bytes smaller.
    #[cfg_attr(
        all(target_arch = "arm", not(target_has_atomic = "32")),
        inline(always)
    )]
    #[cfg_attr(
        not(all(target_arch = "arm", not(target_has_atomic = "32"))),
        inline(never)
    )]
    fn estimator_upkeep(&mut self) {
        self.estimator.schedule();
        let c = &self.config;
        if c.design.zero_crossing_hold
            && self.state == DriveState::Run
            && self.zero_crossing.holds(
                self.telemetry.estimate.omega,
                self.light_load.level(),
                self.low_speed_id,
                &self.monitor.phases(),
                c.deadtime.band_bits(),
                self.deadtime_bus.v_dead_bits(),
                c.light_load.settled_updates(),
            )
        {
            self.estimator.hold(LAST_SLOT + 1);
        }
    }

    /// The checks on the sensors and the estimate of every sample ([`monitor`]).
    #[inline(always)]
    fn supervise(
        &mut self,
        input: &DriveInput,
        estimate: &Estimate,
        omega_ref: Pu,
    ) -> Option<Fault> {
        let signals = monitor::Signals {
            i_abc: input.i_abc,
            omega: estimate.omega,
            omega_ref,
            iq_ref: self.iq_ref,
            running: self.state == DriveState::Run,
            last: &self.telemetry,
        };
        self.monitor
            .check(&self.config.monitor, &signals, &self.estimator, self.slot)
    }

    /// One sample of the initial position detection, which drives the PWM itself; on success
    /// the drive starts from the angle found.
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
            Some(Err(f)) => self.trip(Fault::InitialPosition(f)),
            Some(Ok(r)) => {
                self.ipd_result = Some(r);
                self.state = self.detected(r.theta);
                self.v_est = AlphaBeta::default();
                self.telemetry.estimate = self.estimator.estimate();
                DriveOutput {
                    duties: Duties::HALF,
                    pwm_on: true,
                }
            }
        }
    }

    /// The detection found the rotor at `theta`: the dead-time calibration there first, when
    /// on, else the start from it.
    #[cold]
    #[inline(never)]
    fn detected(&mut self, theta: Angle) -> DriveState {
        if self.config.calibration.enabled() {
            self.open_loop = OpenLoop::aligned_at(theta, &self.config);
            self.current.reset();
            DriveState::Align
        } else {
            self.rotor_found(theta)
        }
    }

    /// Alignment: a d-axis current a quarter turn ahead of α, then along α, the winding across
    /// it shorted (`startup`); at its end the rotor is where the current points. Then, or after a detection, the dead-time
    /// calibration.
    #[inline(always)]
    fn align(&mut self, i: AlphaBeta, vdc: Pu) -> Setpoint {
        let calibrating = self.config.calibration.enabled();
        if calibrating && self.open_loop.align_done(&self.config) {
            return self.calibrate(vdc);
        }
        let (theta, i_ref) = self.open_loop.align_frame(&self.config, i);
        if !calibrating && self.open_loop.align_done(&self.config) {
            self.state = self.rotor_found(self.open_loop.align_angle());
            self.telemetry.estimate = self.estimator.estimate();
        }
        Setpoint::standstill(theta, i_ref)
    }

    /// One sample of the dead-time calibration (`calibrate`): a d current along the rotor's
    /// angle through the current loops; at its end the compensation is scaled to what the
    /// inverter does and the drive starts from that angle.
    #[cold]
    #[inline(never)]
    fn calibrate(&mut self, vdc: Pu) -> Setpoint {
        let c = &self.config.calibration;
        let theta = self.open_loop.align_angle();
        let sc = theta.sin_cos();
        let i_ref = Dq {
            d: self.calibration.reference(c),
            q: Pu::ZERO,
        };
        // The last sample's command and current in this frame (the rotor stands still), and
        // the compensation's vector for this reference.
        let y = park(self.telemetry.v, sc).d;
        let i = self.telemetry.i_dq.d;
        let v_dt = self.config.deadtime.error_vector_cached(
            inverse_park(i_ref, sc),
            vdc,
            &mut self.deadtime_bus,
        );
        let d = park(v_dt, sc).d;
        if let Some(s) = self.calibration.record(c, y, i, d) {
            // Relative to the compensation in use: a second start refines the first.
            self.apply_deadtime_scale(crate::num::scale_q28(self.deadtime_scale, s));
            self.state = self.rotor_found(theta);
            self.telemetry.estimate = self.estimator.estimate();
        }
        Setpoint::standstill(theta, i_ref)
    }

    /// Runs with a compensation whose `V_dead` is `scale` (Q4.28, saturated to [0, 4]) times
    /// the one the drive was told, and the light-load current raised with it.
    #[cold]
    #[inline(never)]
    fn apply_deadtime_scale(&mut self, scale: i32) {
        let scale = scale.clamp(0, 4 * calibrate::SCALE_ONE);
        // Relative to the scale in use (the configuration holds the scaled values): Q4.28 of
        // new/old, at most 4 (from a scale of zero the compensation stays off).
        let rel = (i64::from(scale) << 28)
            .checked_div(i64::from(self.deadtime_scale))
            .map_or(i64::from(scale), |r| r.min(4 << 28)) as i32;
        self.deadtime_scale = scale;
        self.config.deadtime = self.config.deadtime.scaled(rel);
        // Raised with the scale, never lowered (a larger light-load current only costs copper).
        self.config.light_load = self.config.light_load.scaled(rel);
        self.deadtime_bus = DeadTimeBus::default();
    }

    /// The open-loop start: an imposed frame accelerating to the handover speed, where the
    /// estimator takes over (or the handover check trips).
    #[inline(always)]
    fn open_loop(&mut self, estimate: &Estimate) -> Result<Setpoint, Fault> {
        let (theta, omega, i_ref) = self.open_loop.advance(&self.config);
        if let Some((theta, omega)) = self.open_loop.restart_angle(&self.config) {
            self.estimator.reset(theta, omega);
            // As at the start: the new direction is held until the handover.
            self.estimator.hold_direction(Some(omega > Pu::ZERO));
        }
        if self.open_loop.at_handover(&self.config) {
            let iq = match self.open_loop.handover(estimate, &self.config) {
                Ok(iq) => iq,
                // A rotor the load holds the old way is named at once.
                Err(Fault::DrivenBackwards) => return Err(Fault::DrivenBackwards),
                Err(_) if self.open_loop.wait_for_estimate(&self.config) => {
                    return Ok(Setpoint {
                        theta,
                        omega,
                        i_ref,
                        frame: None,
                    });
                }
                Err(fault) => return Err(fault),
            };
            self.estimator.hold_direction(None);
            self.speed_filtered = estimate.omega;
            self.speed.reset(estimate.omega, iq);
            self.iq_ref = iq;
            self.flux.reset(&self.config.flux);
            self.light_load
                .reset(&self.config.light_load, iq, estimate.omega);
            // After the start, the open loop's current fades out instead of stepping to zero
            // (`low_speed`, "handover").
            self.low_speed_faded = self.config.low_speed.faded(estimate.omega);
            if !self.open_loop.is_reversal() {
                self.low_speed_faded = self.low_speed_faded.max(self.config.open_loop.current);
            }
            self.low_speed_id =
                self.config
                    .low_speed
                    .within_limit(self.low_speed_faded, iq, Pu::ZERO);
            self.slot = LAST_SLOT;
            self.state = DriveState::Run;
        }
        Ok(Setpoint {
            theta,
            omega,
            i_ref,
            frame: None,
        })
    }

    /// [`Drive::run_speed_ref`] for this step; with a back-EMF estimator in the closed loop,
    /// the reference one way and the estimated speed the other, down to 1.25 times the
    /// handover speed, the drive goes back to the open loop to pass through zero (`startup`,
    /// reversal; the state's match then runs its first sample). The current-model MRAS's path
    /// is [`Drive::run_speed_ref`]'s.
    #[inline(always)]
    fn run_speed_ref_step(&mut self, estimate: &Estimate) -> Pu {
        let omega_ref = self.speed_ref_run;
        if self.estimator.kind().needs_open_loop_start()
            && self.state == DriveState::Run
            && (omega_ref.to_bits() ^ estimate.omega.to_bits()) < 0
        {
            self.reverse_open_loop(omega_ref, estimate);
        }
        omega_ref
    }

    /// The reversal of [`Drive::run_speed_ref_step`], out of line, from the speed loop's
    /// filtered speed (`startup`, reversal). (A rotor that a load drives the other way fails
    /// that reversal's handover check.)
    #[cold]
    #[inline(never)]
    fn reverse_open_loop(&mut self, omega_ref: Pu, estimate: &Estimate) {
        let h = self.config.open_loop.handover_speed;
        let omega = self.speed_filtered;
        if omega.saturating_abs() > h.saturating_add(h >> 2) {
            return;
        }
        self.open_loop = OpenLoop::reverse(
            estimate.theta,
            omega,
            self.iq_ref,
            omega_ref < Pu::ZERO,
            &self.config,
        );
        self.state = DriveState::OpenLoop;
    }

    /// The closed loop: the speed loop sets `i_q*` in the estimated frame (every sample by
    /// default, or on even slots: its decimation), the d-axis reference's updates take the odd
    /// slots of eight (docs/drive.md, "outer loops"); the references hold in between.
    #[inline(always)]
    fn speed_loop(&mut self, omega_ref: Pu, estimate: &Estimate) -> Setpoint {
        let c = &self.config;
        if self.slot & c.speed_mask == 0 {
            self.iq_ref = self.speed.step(omega_ref, self.speed_filtered).iq_ref;
        }
        // Every eighth sample: the light-load d current follows |i_q*| slowly and the
        // low-speed current fades with the speed, or the start's handover current decays
        // (slot 7, beside the monitor's tracking check); the low-speed current is held within
        // the current limit that the light-load filter's |i_q*| leaves on slot 3 (beside the
        // health figure, and with MTPA and field weakening the field-weakening integrator).
        if self.slot & 3 == 3 {
            if self.slot == 7 {
                self.light_load
                    .update(&c.light_load, self.iq_ref, self.speed_filtered);
                self.low_speed_faded = c
                    .low_speed
                    .decayed(self.speed_filtered, self.low_speed_faded);
            } else {
                self.low_speed_id = c.low_speed.within_limit(
                    self.low_speed_faded,
                    self.iq_ref,
                    self.light_load.level(),
                );
            }
        }
        let light = self.light_load.id_ref();
        let low = self.low_speed_id;
        // The speed loop's limit is the current circle's `|i_q|` room: `i_q*` needs no clamp.
        let i_ref = if c.flux.enabled() {
            if self.slot & 1 != 0
                // The modulator's vector and circle of the last sample
                // (docs/field-weakening.md).
                && let Some(iq_max) = self.flux.update(
                    &c.flux,
                    self.slot,
                    self.iq_ref,
                    &self.telemetry.v,
                    self.inv_vdc.v_max(),
                )
            {
                self.speed.set_limit(iq_max);
                self.iq_ref = self.iq_ref.min(iq_max).max(iq_max.saturating_neg());
            }
            // The more negative of the two d references, and the low-speed current (each
            // within ±64 pu: the sum cannot wrap).
            Dq {
                d: Pu::from_bits(self.flux.id_ref().min(light).to_bits() + low.to_bits()),
                q: self.iq_ref,
            }
        } else {
            // The light-load current (≤ 0, faded in from standstill, within 10 pu) and the
            // low-speed one (≥ 0, faded out from standstill, within 64 pu): at low speed the
            // second dominates; the sum cannot wrap.
            Dq {
                d: Pu::from_bits(light.to_bits() + low.to_bits()),
                q: self.iq_ref,
            }
        };
        Setpoint {
            theta: estimate.theta,
            omega: estimate.omega,
            i_ref,
            // The current-model MRAS already rotated this sample's current into the frame
            // at θ̂ (same angle, same current, same bits): reuse its sin/cos and Park.
            frame: self.estimator.frame(),
        }
    }

    /// Whether the closed loop holds another speed than the reference set, and why; `None`
    /// when it runs at the reference. Computed on demand (nothing on the control path): a
    /// binding or a log asks it after [`Drive::step`]. A reference the drive does not take
    /// (beyond the maximum speed, below the estimator's least) comes first; then, in the
    /// closed loop, the speed loop's output at its limit.
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
        (self.state == DriveState::Run && self.speed.at_limit(self.iq_ref)).then_some(
            SpeedRefLimit::AtCurrentLimit {
                requested,
                estimated: self.speed_filtered,
            },
        )
    }

    /// The speed reference of the closed loop: a back-EMF estimator cannot run below the
    /// handover speed, so the reference is held at that magnitude (in its direction) there.
    fn run_speed_ref(&self) -> Pu {
        let speed_ref = self.speed_ref_used();
        if !self.estimator.kind().needs_open_loop_start() {
            return speed_ref;
        }
        let min = self.config.open_loop.handover_speed;
        if speed_ref.saturating_abs() >= min {
            speed_ref
        } else if speed_ref < Pu::ZERO {
            min.saturating_neg()
        } else {
            min
        }
    }

    /// Current loops in the setpoint's frame, dead-time compensation and modulation
    /// (Khlaief, Boussak, Gossa (2012), Fig. 1). `i` is the Clarke transform of `input.i_abc`.
    fn control(&mut self, input: &DriveInput, i: AlphaBeta, setpoint: Setpoint) -> DriveOutput {
        let Setpoint {
            theta,
            omega,
            i_ref,
            frame,
        } = setpoint;
        let vdc = input.vdc;
        // Current loops, in the setpoint's frame.
        let i_dq = match frame {
            Some(f) => f.i_dq,
            None => park(i, theta.sin_cos()),
        };
        // The bus terms first: the current loops share their reciprocal with the modulator.
        let inv_vdc = self.inv_vdc.get(vdc, &self.config.svpwm).recip();
        let out = self.current.step_on(
            &CurrentInput {
                i_ref,
                i: i_dq,
                omega,
                vdc,
                hold: self.telemetry.saturated,
            },
            inv_vdc,
        );
        // The voltage acts over the coming period: rotate it to the frame's mid-period angle.
        // With the estimator's two frames, their mean points there exactly, at a length
        // cos(ω T_s/2) (0.9993 at 1 pu on motor B): a gain the current loops take up, while the
        // estimator sees the voltage actually modulated.
        // With a PWM update delay of d samples it acts d periods later, around
        // θ + (d + ½) ω T_s: `mid_turns` = 2d + 1 half steps (`mid_frame_k` = 2d − 1 on from
        // the next frame).
        let sc_mid = match frame {
            Some(f) => mid_frame(f.sc, f.sc_next, self.config.mid_frame_k),
            None => {
                let turn = self.config.open_loop.turn_per_speed;
                let step = turn.apply_bits(omega.to_bits());
                (theta + Angle(step.wrapping_mul(self.config.mid_turns) >> 1)).sin_cos()
            }
        };
        let v_ref = inverse_park(out.v, sc_mid);
        // Dead-time compensation, then the modulator.
        let v_dt = self.deadtime_vector(input.vdc, i_dq, i_ref, sc_mid);
        #[cfg(feature = "overmodulation")]
        let m = if self.config.svpwm.overmodulation() {
            self.overmodulate(input, v_ref, v_dt)
        } else {
            self.modulate(v_ref, vdc, v_dt)
        };
        #[cfg(not(feature = "overmodulation"))]
        let m = self.modulate(v_ref, vdc, v_dt);
        self.telemetry.theta = theta;
        self.telemetry.i_dq = i_dq;
        self.telemetry.i_ref = i_ref;
        self.telemetry.v = m.v;
        self.telemetry.saturated = m.saturated || out.saturated_d || out.saturated_q;
        DriveOutput {
            duties: m.duties,
            pwm_on: true,
        }
    }

    /// The voltage the estimator sees at the next sample, given the one modulated now: that
    /// of `pwm_delay` samples ago, the one that will have acted over the coming period (a
    /// delay line of `pwm_delay` vectors).
    #[inline(always)]
    fn delayed(&mut self, v: AlphaBeta) -> AlphaBeta {
        match self.config.pwm_delay {
            0 => v,
            1 => core::mem::replace(&mut self.v_line[0], v),
            _ => {
                let out = self.v_line[1];
                self.v_line[1] = self.v_line[0];
                self.v_line[0] = v;
                out
            }
        }
    }

    /// [`Drive::control`]'s linear modulation of `v_ref` with the dead-time compensation
    /// `v_dt`; the estimator is given the modulated vector less the dead-time error.
    #[inline(always)]
    fn modulate(&mut self, v_ref: AlphaBeta, vdc: Pu, v_dt: AlphaBeta) -> SvpwmOutput {
        let c = &self.config;
        let m = c
            .svpwm
            .modulate_cached(c.deadtime.command(v_ref, v_dt), vdc, &mut self.inv_vdc);
        let v_applied = c.deadtime.estimator_voltage(m.v, v_dt);
        self.v_est = self.delayed(v_applied);
        m
    }

    /// [`Drive::control`]'s modulation when overmodulating (docs/overmodulation.md): a leg
    /// held at duty 0 or 1 does not switch and loses no dead time, and beyond the hexagon the
    /// currents carry the harmonics of the overmodulation, which the reference does not; so
    /// when a leg is held the estimator is given the duties' vector less the dead-time error
    /// of the legs that switch, with the signs of the measured currents (motor B at its rated
    /// point with the reference's signs: ±20 r/min of ripple on the estimated speed, 2968
    /// r/min reached instead of 3000). Inside the hexagon, as the linear drive.
    #[cfg(feature = "overmodulation")]
    #[cold]
    #[inline(never)]
    fn overmodulate(
        &mut self,
        input: &DriveInput,
        v_ref: AlphaBeta,
        v_dt: AlphaBeta,
    ) -> SvpwmOutput {
        let c = &self.config;
        let m = c.svpwm.overmodulate_cached(
            c.deadtime.command(v_ref, v_dt),
            input.vdc,
            &mut self.inv_vdc,
        );
        let d = m.duties;
        let held = |x: Unit| x == Unit::ZERO || x == Unit::ONE;
        let v_dt = if held(d.a) || held(d.b) || held(d.c) {
            let mut i = input.i_abc;
            // A zero current is a zero sign: no dead-time error on a held leg.
            for (x, duty) in [(&mut i.a, d.a), (&mut i.b, d.b), (&mut i.c, d.c)] {
                if held(duty) {
                    *x = Pu::ZERO;
                }
            }
            c.deadtime
                .error_vector_abc_cached(i, input.vdc, &mut self.deadtime_bus)
        } else {
            v_dt
        };
        let v_applied = c.deadtime.estimator_voltage(m.v, v_dt);
        self.v_est = self.delayed(v_applied);
        m
    }

    /// The dead-time voltage error vector over the coming period (Khlaief, Boussak, Gossa
    /// (2012), eq. 6–9), from the measured current `i_dq` or from the reference `i_ref` (both
    /// in the setpoint's frame), turned to the mid-period angle `sc_mid`.
    #[inline(always)]
    fn deadtime_vector(&mut self, vdc: Pu, i_dq: Dq, i_ref: Dq, sc_mid: SinCos) -> AlphaBeta {
        // The current the loop will carry, not the reference itself: the q reference
        // through the closed current loop's lag (docs/drive.md, "dead-time signs"). A speed
        // loop's reference crossing zero faster than the current flipped the signs early, and
        // the estimator saw twice the dead-time voltage wrong. The d reference (outer loops,
        // alignment, open loop) moves slowly: taken as it is.
        self.i_q_expected = follow(self.i_q_expected, i_ref.q, self.config.deadtime_lag_shift);
        let deadtime = &self.config.deadtime;
        // The measured current as sampled is a period and a half old by the middle of the
        // period the command acts over (more with the PWM update delay): turned ahead with the
        // frame, as the reference is (taken as sampled, the NLO on motor A at 1200 r/min and a
        // quarter of rated torque erred 0.0031 rad rms against 0.0012). Within a band of zero
        // its signs chatter with the ripple and the noise, and the compensation passes that
        // on: there the reference's (a 48 V motor of the random family at no load, its current
        // within the band, lost the NLO's lock in the ramp with the measured signs alone).
        // Under load the reference's signs are wrong where a cycle of the estimate offsets the
        // current from its reference (a strongly salient motor); below the speed whose EMF
        // equals `V_dead` (`|ω̂| ψ`, ψ the base flux), the measured ones are (motor B reversing
        // through zero under its rated load lost its lock): there the reference's
        // (docs/drive.md, "dead-time compensation: which current's sign").
        let measured = if deadtime.design.source == CurrentSource::Measured {
            deadtime.beyond_band(i_dq)
        } else {
            deadtime.loaded(self.i_q_expected)
                && self.speed_filtered.to_bits().unsigned_abs() > self.deadtime_bus.v_dead_bits()
        };
        let i = if measured {
            i_dq
        } else {
            Dq {
                d: i_ref.d,
                q: self.i_q_expected,
            }
        };
        // In Run the reference is on q alone: two products instead of four.
        let i_ab = if i.d == Pu::ZERO {
            AlphaBeta {
                alpha: mul_unit(i.q, sc_mid.sin.saturating_neg()),
                beta: mul_unit(i.q, sc_mid.cos),
            }
        } else {
            inverse_park(i, sc_mid)
        };
        self.config
            .deadtime
            .error_vector_cached(i_ab, vdc, &mut self.deadtime_bus)
    }

    /// The trip checks of every sample.
    fn protection(&self, input: &DriveInput) -> Option<Fault> {
        let p = &self.config.protection;
        // The common case in comparisons only (the limit is positive, so its negation fits).
        let oc = p.overcurrent.to_bits();
        let within = |x: Pu| (-oc..=oc).contains(&x.to_bits());
        let i = &input.i_abc;
        if within(i.a)
            && within(i.b)
            && within(i.c)
            && input.vdc >= p.vdc_min
            && input.vdc <= p.vdc_max
        {
            return None;
        }
        let worst = input
            .i_abc
            .a
            .saturating_abs()
            .max(input.i_abc.b.saturating_abs())
            .max(input.i_abc.c.saturating_abs());
        if worst > p.overcurrent {
            Some(Fault::OverCurrent(worst))
        } else if input.vdc < p.vdc_min {
            Some(Fault::BusUnderVoltage(input.vdc))
        } else if input.vdc > p.vdc_max {
            Some(Fault::BusOverVoltage(input.vdc))
        } else {
            None
        }
    }
}

/// The slot of the current-model MRAS's gain schedule.
const SCHEDULE_SLOT: u8 = 1;

/// The last of the eight outer-loop slots (they count modulo 8): the d-axis reference's
/// updates on odd ones, the speed loop on every sample or (decimated) on even ones.
const LAST_SLOT: u8 = 7;

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
fn mid_frame(now: SinCos, next: SinCos, k: i32) -> SinCos {
    let at = |a: Unit, b: Unit| {
        let (a, b) = (a.to_bits(), b.to_bits());
        Unit::from_bits(b.wrapping_add(b.wrapping_sub(a).wrapping_mul(k) >> 1))
    };
    SinCos {
        sin: at(now.sin, next.sin),
        cos: at(now.cos, next.cos),
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The extrapolated frame against the `f64` unit vector at `θ + (h/2)φ`, for the frames
    /// at `θ` and `θ + φ`: within `3/8 φ²` for
    /// `h` = 3 (one sample of PWM delay) and `φ²/8` for `h` = 1 (the mean of the two frames),
    /// plus the Q2.30 and sine-table rounding.
    #[test]
    fn mid_frame_against_the_f64_rotation() {
        let mut worst: [f64; 2] = [0.0; 2];
        for k in 0..720 {
            let theta = k as f64 * core::f64::consts::PI / 360.0 - core::f64::consts::PI;
            for phi in [-0.08, -0.02, 0.0, 0.0374, 0.08] {
                let now = Angle::from_rad(theta).sin_cos();
                let next = Angle::from_rad(theta + phi).sin_cos();
                for (j, h) in [1, 3].into_iter().enumerate() {
                    let m = mid_frame(now, next, h - 2);
                    let at = theta + 0.5 * h as f64 * phi;
                    let (c, s) = (m.cos.to_bits() as f64, m.sin.to_bits() as f64);
                    let q = (1u64 << 30) as f64;
                    let err = libm::hypot(c / q - at.cos(), s / q - at.sin());
                    let bound = if h == 1 { 0.125 } else { 0.375 } * phi * phi + 1e-4;
                    assert!(err <= bound, "θ {theta} φ {phi} h {h}: {err} > {bound}");
                    worst[j] = worst[j].max(err / bound);
                }
            }
        }
        // The bounds are not loose: the second-order term is reached.
        assert!(worst[1] > 0.5, "{worst:?}");
    }
}
