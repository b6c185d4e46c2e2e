//! The fixed-point drive of a scenario, from its `[inverter]` and `[control]` tables and its
//! motor: the one place where the per-unit bases, the design and the configuration are made.

use crate::scenario_file::{
    CompensationMode, DeadTimeCurrent, ObserverKind, Scenario, SpeedLoopForm, Startup,
};
use anyhow::{Result, anyhow, bail};
use pmsm_core::tuning::{IP_FORM, PI_FORM};
use pmsm_core::{Angle, InverterParams, MotorParams, PerUnit};
use pmsm_core::{CurrentSource, DeadTimeMode};
use pmsm_core::{DistortionDesign, DistortionLearner};
use pmsm_core::{Drive, DriveConfig, DriveDesign, StartupMode, Tracker, TrackerDesign};
use pmsm_core::{EstimatorKind, MrasCurrentGains};
use std::f64::consts::TAU;

/// The drive of a scenario and what the loop needs to talk to it in SI units.
#[derive(Debug)]
pub struct DriveSetup {
    /// The drive, not started.
    pub drive: Drive,
    /// Its configuration.
    pub config: DriveConfig,
    /// Its per-unit bases.
    pub base: PerUnit,
    /// The drive's model of the motor (the plant keeps the true one).
    pub model: MotorParams,
    /// The inverter, with the ADC full scale resolved, as the plant has it (`[inverter]`).
    pub inverter: InverterParams,
    /// The inverter as the drive is told it: the same but for `[control] dead_time_s`.
    pub drive_inverter: InverterParams,
    /// Control sample rate, Hz.
    pub sample_hz: f64,
    /// PWM periods per control sample.
    pub pwm_per_sample: usize,
    /// PWM periods the plant applies the duties later (`[control] pwm_update_delay_periods`).
    pub pwm_delay_periods: usize,
}

/// Builds the drive of `sc`: bases, default design for the motor, the scenario's overrides,
/// configuration.
pub fn build_drive(sc: &Scenario) -> Result<DriveSetup> {
    let shown = sc.path.display();
    let model = drive_model(sc);
    let (sample_hz, pwm_per_sample) = sample_rate(sc)?;
    let mut inverter = InverterParams {
        vdc_v: sc.inverter.vdc_v,
        pwm_hz: sc.inverter.pwm_hz,
        dead_time_s: sc.inverter.dead_time_s,
        current_full_scale_a: 1.0,
    };
    let base = PerUnit::new(&model, &inverter, sample_hz).map_err(|e| anyhow!("{shown}: {e}"))?;
    // The ADC range follows the current base unless the scenario sets it.
    inverter.current_full_scale_a = sc
        .inverter
        .current_full_scale_a
        .unwrap_or(4.0 * base.current_a);
    // The drive's dead-time compensation is designed for the dead time it is told.
    let drive_inverter = InverterParams {
        dead_time_s: sc.control.dead_time_s.unwrap_or(inverter.dead_time_s),
        ..inverter
    };
    let estimator = estimator_kind(sc.control.observer, &model);
    let mut design = DriveDesign::default_for(&model, &drive_inverter, &base, estimator);
    apply_control(&mut design, sc, &model);
    let pwm_delay_periods = sc
        .control
        .pwm_update_delay_periods
        .unwrap_or(crate::scenario_file::control::DEFAULT_PWM_UPDATE_DELAY_PERIODS)
        as usize;
    design.pwm_delay_samples = compensation_samples(sc, pwm_delay_periods, pwm_per_sample)?;
    let config = DriveConfig::new(&model, &drive_inverter, sample_hz, design)
        .map_err(|e| anyhow!("{shown}: {e}"))?;
    // The task builds its learners from the configuration; here their design errors are
    // named.
    if config.design.tracking {
        Tracker::new(&model, &base, TrackerDesign::for_drive(&config))
            .map_err(|e| anyhow!("{shown}: {e}"))?;
    }
    if config.design.deadtime_learning && config.deadtime_compensation() {
        DistortionLearner::new(&model, &config, DistortionDesign::for_drive(&config))
            .map_err(|e| anyhow!("{shown}: {e}"))?;
    }
    Ok(DriveSetup {
        drive: Drive::new(config),
        config,
        base,
        model,
        inverter,
        drive_inverter,
        sample_hz,
        pwm_per_sample,
        pwm_delay_periods,
    })
}

/// The delay the drive compensates, control samples: `[control]
/// pwm_delay_compensation_periods` (a whole number of samples), by default the plant's delay
/// rounded to samples.
fn compensation_samples(sc: &Scenario, plant_periods: usize, pwm_per_sample: usize) -> Result<u8> {
    let samples = match sc.control.pwm_delay_compensation_periods {
        Some(n) => {
            let n = n as usize;
            if !n.is_multiple_of(pwm_per_sample) {
                bail!(
                    "{}: `control.pwm_delay_compensation_periods` ({n}) must be a whole number \
                     of control samples ({pwm_per_sample} PWM periods each)",
                    sc.path.display()
                );
            }
            n / pwm_per_sample
        }
        None => (plant_periods + pwm_per_sample / 2) / pwm_per_sample,
    };
    u8::try_from(samples)
        .ok()
        .filter(|&s| s <= pmsm_core::MAX_PWM_DELAY_SAMPLES)
        .ok_or_else(|| {
            anyhow!(
                "{}: the drive compensates at most {} control samples of PWM update delay \
                 ({samples} asked: `control.pwm_delay_compensation_periods`)",
                sc.path.display(),
                pmsm_core::MAX_PWM_DELAY_SAMPLES
            )
        })
}

/// The motor as the drive believes it to be: `control.model_motor` if given, else the
/// scenario's, scaled by the `model_*_factor`s of `[control]`.
fn drive_model(sc: &Scenario) -> MotorParams {
    let c = &sc.control;
    let mut model = sc.model_motor.as_ref().unwrap_or(&sc.motor).model.params;
    model.rs_ohm *= c.model_rs_factor.unwrap_or(1.0);
    model.ld_h *= c.model_l_factor.unwrap_or(1.0);
    model.lq_h *= c.model_l_factor.unwrap_or(1.0);
    model.flux_wb *= c.model_flux_factor.unwrap_or(1.0);
    model.kt_nm_per_a *= c.model_flux_factor.unwrap_or(1.0);
    model
}

/// The control sample rate, Hz, and the whole number of PWM periods per sample.
fn sample_rate(sc: &Scenario) -> Result<(f64, usize)> {
    let pwm_hz = sc.inverter.pwm_hz;
    let sample_hz = sc.control.sample_hz.unwrap_or(pwm_hz);
    let ratio = pwm_hz / sample_hz;
    if (ratio - ratio.round()).abs() > 1e-9 {
        bail!(
            "{}: `control.sample_hz` ({sample_hz}) must divide `inverter.pwm_hz` ({pwm_hz})",
            sc.path.display()
        );
    }
    Ok((sample_hz, ratio.round() as usize))
}

/// Sets in `design` what `[control]` and `[inverter]` give beyond the defaults.
fn apply_control(design: &mut DriveDesign, sc: &Scenario, model: &MotorParams) {
    let c = &sc.control;
    design.startup = startup_mode(c.startup, sc.theta0_rad);
    design.deadtime.mode = deadtime_mode(c.deadtime_compensation.mode());
    // The default limit holds unless the scenario sets one; 0 turns the check off.
    if let Some(h) = c.health_limit_pu {
        design.protection.health_limit_pu = (h > 0.0).then_some(h);
    }
    let set = |x: &mut bool, on: Option<bool>| *x = on.unwrap_or(*x);
    set(&mut design.tracking, c.tracking);
    set(&mut design.deadtime_learning, c.deadtime_learning);
    // Asked for by name, the injection is designed or refused; by default it falls back.
    if let Some(on) = c.injection {
        design.injection = on.then(pmsm_core::InjectionDesign::required);
    }
    if c.load_observer == Some(false) {
        design.load_observer_rad_s = None;
    }
    set(&mut design.flux.mtpa, c.mtpa);
    set(&mut design.flux.field_weakening, c.field_weakening);
    design.overmodulation = c.overmodulation;
    design.deadtime.device.v_sat_v = sc.inverter.v_sat_v;
    design.deadtime.device.v_f_v = sc.inverter.v_f_v;
    if let Some(on) = c.deadtime_calibration {
        design.deadtime_calibration = on;
    }
    if let Some(on) = c.zero_crossing_hold {
        design.zero_crossing_hold = on;
    }
    if let Some(source) = c.deadtime_current {
        design.deadtime.source = match source {
            DeadTimeCurrent::Reference => CurrentSource::Reference,
            DeadTimeCurrent::Measured => CurrentSource::Measured,
            DeadTimeCurrent::MeasuredUnderLoad => CurrentSource::MeasuredUnderLoad,
        };
    }
    if let Some(i) = c.light_load_id_a {
        design.light_load_id_a = i;
    }
    if let Some(i) = c.low_speed_id_a {
        design.low_speed_id_a = i;
    }
    if let Some(g) = c.observer_gain {
        design.observer_gain_rad_s = g;
    }
    if let Some(hz) = c.current_bandwidth_hz {
        design.current.bandwidth_rad_s = TAU * hz;
    }
    if let Some(hz) = c.speed_bandwidth_hz {
        design.speed.bandwidth_rad_s = TAU * hz;
    }
    if let Some(form) = c.speed_loop {
        design.speed.reference_weight = match form {
            SpeedLoopForm::Ip => IP_FORM,
            SpeedLoopForm::Pi => PI_FORM,
        };
    }
    if let Some(b) = c.speed_reference_weight {
        design.speed.reference_weight = b;
    }
    if let Some(hz) = c.mras_bandwidth_hz {
        design.mras_current = MrasCurrentGains::design(model, TAU * hz);
    }
    if let Some(on) = c.mras_low_speed_schedule {
        design.mras_current.low_speed_schedule = on;
    }
    if let Some(w) = c.mras_d_weight {
        design.mras_current.d_weight = w as f32;
    }
    if let Some(rpm) = c.handover_speed_rpm {
        design.open_loop.handover_speed_rad_s = rpm * TAU / 60.0 * model.p();
    }
    if let Some(a) = c.current_limit_a {
        design.speed.current_limit_a = a;
        design.open_loop.current_a = design.open_loop.current_a.min(a);
    }
}

fn estimator_kind(observer: ObserverKind, model: &MotorParams) -> EstimatorKind {
    match observer {
        // Resolved when the scenario is read; the same choice here.
        ObserverKind::Auto => EstimatorKind::for_motor(model),
        ObserverKind::Nlo => EstimatorKind::Nlo,
        ObserverKind::Ao => EstimatorKind::Ao,
        ObserverKind::MrasEmf => EstimatorKind::MrasEmf,
        ObserverKind::MrasCurrent => EstimatorKind::MrasCurrent,
    }
}

/// `known` takes the true initial angle of `[initial]`.
fn startup_mode(startup: Startup, theta0_rad: f64) -> StartupMode {
    match startup {
        Startup::Auto => StartupMode::Auto,
        Startup::Ipd => StartupMode::Ipd,
        Startup::Align => StartupMode::Align,
        Startup::Known => StartupMode::Known(Angle::from_rad(theta0_rad)),
    }
}

fn deadtime_mode(mode: CompensationMode) -> DeadTimeMode {
    match mode {
        CompensationMode::Off => DeadTimeMode::Off,
        CompensationMode::Command => DeadTimeMode::Command,
        CompensationMode::Estimator => DeadTimeMode::Estimator,
        CompensationMode::Both => DeadTimeMode::Both,
    }
}
