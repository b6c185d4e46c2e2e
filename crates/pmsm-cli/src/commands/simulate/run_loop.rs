//! The simulation loop: one drive step per control sample, then the plant over the PWM
//! periods of that sample; one [`Row`] per sample.

use super::drive::{DriveSetup, build_drive};
use super::plant::{Injector, build_plant};
use crate::scenario_file::Scenario;
use anyhow::{Result, anyhow};
use pmsm_core::Abc;
use pmsm_core::{Drive, DriveInput, DriveOutput, DriveState};
use pmsm_plant::{Plant, PlantError};
use std::collections::VecDeque;
use std::f64::consts::{PI, TAU};

/// One control sample of a run, in SI units.
#[derive(Clone, Debug)]
pub struct Row {
    /// Time, s.
    pub t_s: f64,
    /// Speed reference, r/min.
    pub speed_ref_rpm: f64,
    /// True speed, r/min.
    pub speed_rpm: f64,
    /// Estimated speed, r/min.
    pub speed_est_rpm: f64,
    /// True electrical angle, rad, [−π, π).
    pub theta_e_rad: f64,
    /// Estimated electrical angle, rad, [−π, π).
    pub theta_e_est_rad: f64,
    /// True rotor-frame currents, A.
    pub i_dq_a: [f64; 2],
    /// q-current reference, A.
    pub i_q_ref_a: f64,
    /// Commanded voltage, V.
    pub v_ab_v: [f64; 2],
    /// Leg duties.
    pub duties: [f64; 3],
    /// Inverter switching.
    pub pwm_on: bool,
    /// The drive's state.
    pub state: DriveState,
    /// Largest phase current at this sample, A.
    pub i_peak_a: f64,
    /// The estimator's health figure as the drive filters it, per unit (of `V_b` for the EMF
    /// estimators, of `I_b` for the current-model MRAS; 0 outside the closed loop).
    pub health: f64,
    /// In the closed loop with the reference below the estimator's least speed
    /// (`pmsm_core::SpeedRefLimit`): the reference the speed loop holds instead, r/min.
    pub speed_ref_held_rpm: Option<f64>,
    /// In the closed loop with the speed loop's output at its limit
    /// (`pmsm_core::SpeedRefLimit::AtCurrentLimit`): the speed the drive estimates, r/min.
    pub current_limited_est_rpm: Option<f64>,
    /// The tracked R and ψ (Ω, Wb) with `[control] tracking`, else the drive's model's.
    pub model_rs_flux: [f64; 2],
    /// The tracker's status after this sample, with `[control] tracking`.
    pub tracker: Option<pmsm_core::TrackerStatus>,
}

impl Row {
    /// Estimated minus true angle, wrapped, rad.
    pub fn angle_error_rad(&self) -> f64 {
        wrap(self.theta_e_est_rad - self.theta_e_rad)
    }

    /// The fault's name, or "".
    pub fn fault(&self) -> &'static str {
        match self.state {
            DriveState::Fault(f) => f.name(),
            _ => "",
        }
    }
}

/// Wraps to [−π, π).
pub fn wrap(x: f64) -> f64 {
    (x + PI).rem_euclid(TAU) - PI
}

/// The result of a run.
#[derive(Debug)]
pub struct Run {
    /// Every control sample.
    pub rows: Vec<Row>,
    /// Detected initial angle and true one, degrees, when the start-up was `ipd`.
    pub ipd: Option<(f64, f64)>,
    /// The fault recorder, fed after each step.
    pub recorder: super::super::fault_dump::Recorder,
    /// The first speed reference the drive clamped to its maximum speed: time (s), the
    /// reference and the speed used (r/min).
    pub speed_ref_limited: Option<(f64, f64, f64)>,
    /// The start-up the drive used (`auto` resolved).
    pub startup: pmsm_core::StartupMode,
    /// The detection without polarity that an automatic start fell back from to the
    /// alignment (`pmsm_core::Drive::ipd_fallback`).
    pub ipd_fallback: Option<pmsm_core::IpdFault>,
    /// The dead-time compensation's `V_dead` against the one the drive was told, at the
    /// end (the calibration's; 1 without one).
    pub deadtime_scale: f64,
    /// The distortion learner's status at the end (`[control] deadtime_learning`).
    pub learner: Option<pmsm_core::DistortionStatus>,
    /// The high-frequency injection as designed (`[control] injection`).
    pub injection: Option<pmsm_core::InjectionFigures>,
    /// Why the default injection was left out; the low-speed d current (A) that holds the
    /// rotor instead, the speed where it has faded out (r/min) and its copper loss at
    /// standstill (W).
    pub injection_declined: Option<(pmsm_core::ConfigError, f64, f64, f64)>,
    /// What the injection's polarity checks found when the drive came back to zero speed.
    pub polarity: pmsm_core::PolarityReport,
}

/// Builds the drive and the plant of `sc` and runs them.
pub fn run_scenario(sc: &Scenario) -> Result<Run> {
    let setup = build_drive(sc)?;
    let plant = build_plant(sc, &setup.inverter)?;
    step_loop(sc, setup, plant)
}

/// What the drive's sensors read at the end of the last PWM period.
struct Sensed {
    /// Phase currents from the ADC codes, A.
    i_abc_a: [f64; 3],
    /// The codes, at which a stuck channel freezes.
    codes: [u16; 3],
    /// Bus voltage, V.
    vdc_v: f64,
}

/// Starts the drive and steps it and the plant over the scenario's duration, injecting its
/// faults; one row per control sample.
pub fn step_loop(sc: &Scenario, setup: DriveSetup, plant: Plant) -> Result<Run> {
    let mut sim = Simulation::new(sc, setup, plant);
    sim.advance(sc, usize::MAX)?;
    Ok(sim.finish())
}

/// A run in progress, stepped a number of samples at a time (a browser shows its progress
/// between them); [`step_loop`] is one call of [`Simulation::advance`] over all of them.
pub struct Simulation {
    setup: DriveSetup,
    plant: Plant,
    /// Samples in all, and the next one.
    n: usize,
    k: usize,
    rows: Vec<Row>,
    sensed: Sensed,
    ipd: Option<(f64, f64)>,
    speed_ref_limited: Option<(f64, f64, f64)>,
    injector: Injector,
    recorder: super::super::fault_dump::Recorder,
    startup: pmsm_core::StartupMode,
    compare: CompareRegisters,
    injection: Option<pmsm_core::InjectionFigures>,
    injection_declined: Option<(pmsm_core::ConfigError, f64, f64, f64)>,
}

impl Simulation {
    /// The drive of `setup` started against `plant`, at the scenario's first sample.
    pub fn new(sc: &Scenario, mut setup: DriveSetup, plant: Plant) -> Self {
        let n = (sc.duration_s * setup.sample_hz).round() as usize;
        let recorder = super::super::fault_dump::Recorder::new(setup.base, setup.sample_hz);
        let startup = setup.config.design.startup;
        let injection = setup.config.injection();
        let d = &setup.config.design;
        let rpm = 60.0 / (TAU * setup.config.motor.p());
        let injection_declined = setup.config.injection_declined().map(|e| {
            let (id, r) = (d.low_speed_id_a, setup.config.motor.rs_ohm);
            (e, id, d.low_speed_fade_rad_s * rpm, 1.5 * r * id * id)
        });
        let compare = CompareRegisters::new(setup.pwm_delay_periods);
        setup.drive.start();
        Self {
            setup,
            plant,
            n,
            k: 0,
            rows: Vec::with_capacity(n),
            sensed: Sensed {
                i_abc_a: [0.0; 3],
                codes: [0; 3],
                vdc_v: sc.inverter.vdc_v,
            },
            ipd: None,
            speed_ref_limited: None,
            injector: Injector::new(&sc.faults),
            recorder,
            startup,
            compare,
            injection,
            injection_declined,
        }
    }

    /// Samples done and in all.
    pub fn progress(&self) -> (usize, usize) {
        (self.k, self.n)
    }

    /// Steps at most `samples` more samples of `sc` (the scenario it was built from); true
    /// once the run is complete.
    pub fn advance(&mut self, sc: &Scenario, samples: usize) -> Result<bool> {
        let shown = sc.path.display();
        let end = self.n.min(self.k.saturating_add(samples));
        while self.k < end {
            let (k, setup, plant) = (self.k, &mut self.setup, &mut self.plant);
            let t = k as f64 / setup.sample_hz;
            let speed_ref_rpm = sc.speed_ref.at(t);
            let (input, out) = control_step(setup, speed_ref_rpm, &self.sensed);
            self.recorder.record(k, &setup.drive, &input);
            if let (None, Some(pmsm_core::SpeedRefLimit::AboveMaxSpeed { used, .. })) =
                (self.speed_ref_limited, setup.drive.speed_ref_limit())
            {
                let rpm = setup.base.speed_rad_s(used) / setup.model.p() * 60.0 / TAU;
                self.speed_ref_limited = Some((t, speed_ref_rpm, rpm));
            }
            if self.ipd.is_none() {
                self.ipd = ipd_detected(&setup.drive, plant);
            }
            self.rows.push(record(t, speed_ref_rpm, setup, &out, plant));
            self.injector
                .apply(t, plant, self.sensed.codes)
                .map_err(|e| anyhow!("{shown}: t = {t:.6} s: {e}"))?;
            if let Some(th) = &sc.thermal {
                th.apply(plant)
                    .map_err(|e| anyhow!("{shown}: thermal: {e}"))?;
            }
            let load_nm = sc.load.at(t);
            let periods = setup.pwm_per_sample;
            advance_plant(
                plant,
                &out,
                &mut self.compare,
                load_nm,
                periods,
                &mut self.sensed,
            )
            .map_err(|e| anyhow!("{shown}: the plant failed at t = {t:.6} s: {e}"))?;
            self.k += 1;
        }
        Ok(self.k >= self.n)
    }

    /// The run so far (all of it once [`Simulation::advance`] said so).
    pub fn finish(self) -> Run {
        let drive = &self.setup.drive;
        Run {
            rows: self.rows,
            ipd: self.ipd,
            recorder: self.recorder,
            speed_ref_limited: self.speed_ref_limited,
            startup: self.startup,
            ipd_fallback: drive.ipd_fallback(),
            deadtime_scale: drive.deadtime_scale().to_num::<f64>(),
            learner: drive
                .task()
                .learner()
                .map(pmsm_core::DistortionLearner::status),
            injection: self.injection,
            injection_declined: self.injection_declined,
            polarity: drive.task().polarity(),
        }
    }
}

/// One drive step on what the sensors read, towards `speed_ref_rpm`: its input and output.
fn control_step(
    setup: &mut DriveSetup,
    speed_ref_rpm: f64,
    sensed: &Sensed,
) -> (DriveInput, DriveOutput) {
    let base = &setup.base;
    let p = setup.model.p();
    setup
        .drive
        .set_speed_ref(base.speed_pu(speed_ref_rpm * TAU / 60.0 * p));
    let i = sensed.i_abc_a;
    let input = DriveInput {
        i_abc: Abc {
            a: base.current_pu(i[0]),
            b: base.current_pu(i[1]),
            c: base.current_pu(i[2]),
        },
        vdc: base.voltage_pu(sensed.vdc_v),
    };
    (input, setup.drive.step(&input))
}

/// The detected initial angle and the plant's true one, degrees in [0, 360), once the initial
/// position detection has a result.
fn ipd_detected(drive: &Drive, plant: &Plant) -> Option<(f64, f64)> {
    let r = drive.ipd_result()?;
    let true_deg = plant
        .motor()
        .state()
        .theta_e_rad
        .to_degrees()
        .rem_euclid(360.0);
    Some((r.theta_deg_0_360(), true_deg))
}

/// The row of the sample at `t`: the plant's truth and the drive's telemetry, in SI units.
fn record(t: f64, speed_ref_rpm: f64, setup: &DriveSetup, out: &DriveOutput, plant: &Plant) -> Row {
    let (drive, base, p) = (&setup.drive, &setup.base, setup.model.p());
    let tel = drive.telemetry();
    let s = plant.motor().state();
    let i_true = plant.motor().i_abc();
    let rpm = |omega_e: pmsm_core::Pu| base.speed_rad_s(omega_e) / p * 60.0 / TAU;
    let limit = drive.speed_ref_limit();
    Row {
        t_s: t,
        speed_ref_rpm,
        speed_rpm: s.omega_m_rad_s * 60.0 / TAU,
        speed_est_rpm: rpm(tel.estimate.omega),
        theta_e_rad: wrap(s.theta_e_rad),
        theta_e_est_rad: tel.estimate.theta.to_rad(),
        i_dq_a: plant.motor().i_dq(),
        i_q_ref_a: base.current_a(tel.i_ref.q),
        v_ab_v: [base.voltage_v(tel.v.alpha), base.voltage_v(tel.v.beta)],
        duties: if out.pwm_on {
            out.duties.to_f64()
        } else {
            [0.0; 3]
        },
        pwm_on: out.pwm_on,
        state: drive.state(),
        i_peak_a: i_true.iter().fold(0.0f64, |a, x| a.max(x.abs())),
        health: pmsm_core::to_f64(drive.health()),
        speed_ref_held_rpm: match limit {
            Some(pmsm_core::SpeedRefLimit::BelowEstimatorMinimum { held, .. })
                if drive.state() == DriveState::Run =>
            {
                Some(rpm(held))
            }
            _ => None,
        },
        current_limited_est_rpm: match limit {
            Some(pmsm_core::SpeedRefLimit::AtCurrentLimit { estimated, .. }) => {
                Some(rpm(estimated))
            }
            _ => None,
        },
        model_rs_flux: match setup.drive.task().tracker() {
            Some(tr) => [tr.rs_ohm(), tr.flux_wb()],
            None => [setup.model.rs_ohm, setup.model.flux_wb],
        },
        tracker: setup.drive.task().tracker().map(pmsm_core::Tracker::status),
    }
}

/// The timer's compare registers: duties written at a period's start are preloaded and act
/// `delay` periods later (pmsm-stm32's TIM1, docs/drive.md, PWM update delay); until then the
/// active ones hold, from the start half duties (the timer's initial compare value).
struct CompareRegisters {
    /// Writes not yet transferred, oldest first (`None`: nothing written that period).
    preload: VecDeque<Option<[f64; 3]>>,
    active: [f64; 3],
    delay: usize,
}

impl CompareRegisters {
    fn new(delay: usize) -> Self {
        Self {
            preload: VecDeque::with_capacity(delay + 1),
            active: [0.5; 3],
            delay,
        }
    }

    /// One period's start: `write` goes in, the write of `delay` periods ago becomes active.
    fn period(&mut self, write: Option<[f64; 3]>) -> [f64; 3] {
        self.preload.push_back(write);
        if self.preload.len() > self.delay
            && let Some(Some(d)) = self.preload.pop_front()
        {
            self.active = d;
        }
        self.active
    }
}

/// Integrates the plant over the `periods` PWM periods of one control sample under `out` and
/// `load_nm`, and updates what the sensors read. The duties go through the compare
/// registers; the outputs go on and off at once (the break and `MOE` are not preloaded).
fn advance_plant(
    plant: &mut Plant,
    out: &DriveOutput,
    compare: &mut CompareRegisters,
    load_nm: f64,
    periods: usize,
    sensed: &mut Sensed,
) -> Result<(), PlantError> {
    for k in 0..periods {
        // The drive writes its duties once per sample, at the first period's start.
        let write = (k == 0 && out.pwm_on).then(|| out.duties.to_f64());
        let duties = compare.period(write);
        let sample = if out.pwm_on {
            plant.step_pwm(duties, load_nm)
        } else {
            plant.step_off(load_nm)
        }?;
        sensed.i_abc_a = sample.i_abc_a_measured;
        sensed.codes = sample.adc_codes;
        sensed.vdc_v = sample.vdc_v;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::CompareRegisters;

    // The registers copy duties, never compute them: exact comparison is the point.
    #[allow(clippy::float_cmp)]
    #[test]
    fn compare_registers_load_the_duties_delay_periods_later() {
        let (a, b, c) = ([0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]);
        // Without delay a write acts in its own period.
        let mut r = CompareRegisters::new(0);
        assert_eq!(r.period(Some(a)), a);
        assert_eq!(r.period(None), a);
        assert_eq!(r.period(Some(b)), b);
        // One period: the timer's initial half duties first, then each write a period late;
        // a period without a write keeps the active values.
        let mut r = CompareRegisters::new(1);
        assert_eq!(r.period(Some(a)), [0.5; 3]);
        assert_eq!(r.period(Some(b)), a);
        assert_eq!(r.period(None), b);
        assert_eq!(r.period(Some(c)), b);
        assert_eq!(r.period(None), c);
        // Two periods.
        let mut r = CompareRegisters::new(2);
        assert_eq!(r.period(Some(a)), [0.5; 3]);
        assert_eq!(r.period(Some(b)), [0.5; 3]);
        assert_eq!(r.period(Some(c)), a);
        assert_eq!(r.period(None), b);
        assert_eq!(r.period(None), c);
    }
}
