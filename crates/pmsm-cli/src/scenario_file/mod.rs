//! The scenario file of `pmsm simulate` (TOML, SI units).
//!
//! ```toml
//! duration_s = 3.0
//! motor = "motor-b.toml"            # relative to this file, or an inline table
//!
//! [inverter]
//! vdc_v = 540.0
//! pwm_hz = 14000.0
//! dead_time_s = 2e-6
//! model = "switching"              # or "averaged" (default "averaged")
//! current_full_scale_a = 10.0      # optional ADC range, default 4 × rated peak current
//! sign_band_a = 0.0                # 0 = hard current sign (default 1 % of the full scale);
//!                                  # switching model: instantaneous, a phase floats at zero
//!
//! [control]
//! sample_hz = 14000.0              # default pwm_hz
//! observer = "mras-current"        # auto | nlo | ao | mras-emf | mras-current (default
//!                                  # auto: mras-current on an interior motor, nlo on a
//!                                  # surface motor; the whole [control] table is optional)
//! startup = "ipd"                  # auto | ipd | align | known (default auto: ipd when
//!                                  # |L_q − L_d|/(L_q + L_d) ≥ 10 %, else align)
//! deadtime_compensation = true     # default true (both: command and estimator)
//! dead_time_s = 1.5e-6             # what the drive's compensation assumes (default: the
//!                                  # inverter's dead_time_s, which the plant keeps)
//! pwm_update_delay_periods = 1     # the plant applies the duties 1 PWM period later
//!                                  # (pmsm-stm32's TIM1; the default)
//! pwm_delay_compensation_periods = 1 # what the drive compensates (default: the plant's)
//! observer_gain = 1000.0           # optional gains; defaults come from the motor
//! current_bandwidth_hz = 500.0
//! speed_bandwidth_hz = 10.0
//! speed_loop = "pi"                # "ip" or "pi": a ramp followed without lag (default: the
//!                                  # drive's, the reference weighed by a half with the
//!                                  # current-model MRAS; or speed_reference_weight = 0..1)
//! handover_speed_rpm = 150.0       # where a back-EMF estimator takes over from the open
//!                                  # loop, and its least speed (default: a tenth of rated
//!                                  # speed, the MRAS on the EMF where its adaptation is damped)
//! low_speed_id_a = 0.0             # the positive d current held at low speed (default: the
//!                                  # current limit, faded out at a fifth of rated speed)
//! health_limit_pu = 0.5            # trip on the estimator's health figure in steady state
//!                                  # (default 1.0; 0 = off)
//! mtpa = false                     # maximum torque per ampere on interior motors (default on)
//! field_weakening = false          # field weakening, speed clamped to the maximum (default on)
//! overmodulation = true            # optional: beyond the circle up to six-step
//! injection = true                 # optional: high-frequency injection at standstill and
//!                                  # low speed on a salient motor (docs/injection.md)
//! load_observer = false            # optional: no load observer (docs/khlaief2012.md §7)
//!
//! [initial]
//! theta_e_deg = 40.0
//! speed_rpm = 0.0
//!
//! [speed_ref]                      # piecewise linear
//! t_s = [0.0, 0.5, 3.0]
//! rpm = [0.0, 800.0, 800.0]
//!
//! [load]
//! t_s = [0.0, 1.5, 1.5001]
//! nm = [0.0, 0.0, 4.0]
//!
//! [sensing]
//! adc_bits = 12
//! noise_rms_a = 0.01
//! ```
//!
//! Unknown keys and bad values end with one line naming the file and the key.
//!
//! One module per kind of table: [`hardware`] (`motor`, `[inverter]`, `[sensing]`),
//! [`control`] (`[control]`), [`profiles`] (`[initial]`, `[speed_ref]`, `[load]`) and
//! [`faults`] (`[faults]`). A new key goes into its table's struct and that struct's `check`.

pub mod control;
pub mod faults;
pub mod hardware;
pub mod profiles;

pub use control::{
    Compensation, CompensationMode, Control, DeadTimeCurrent, ObserverKind, SpeedLoopForm, Startup,
};
pub use faults::{Faults, Phase, PhasePair};
pub use hardware::{Inverter, InverterKind, Sensing};
pub use profiles::Breakpoints;

use crate::motor_file::{Motor, toml_error};
use anyhow::{Result, anyhow, bail};
use hardware::MotorRef;
use pmsm_core::ParamError;
use pmsm_core::validate::in_range;
use profiles::{RawBreakpoints, RawInitial, breakpoints};
use serde::Deserialize;
use std::path::{Path, PathBuf};

/// A validated scenario.
#[derive(Clone, Debug)]
pub struct Scenario {
    /// The file it came from.
    pub path: PathBuf,
    /// Simulated time, s.
    pub duration_s: f64,
    /// The motor.
    pub motor: Motor,
    /// `[inverter]`.
    pub inverter: Inverter,
    /// `[control]`.
    pub control: Control,
    /// `[initial]` electrical angle, rad.
    pub theta0_rad: f64,
    /// `[initial]` mechanical speed, rad/s.
    pub omega_m0_rad_s: f64,
    /// `[speed_ref]`, r/min against time.
    pub speed_ref: Breakpoints,
    /// `[load]`, N·m against time.
    pub load: Breakpoints,
    /// `[sensing]`.
    pub sensing: Sensing,
    /// `[faults]`: faults injected into the plant.
    pub faults: Faults,
    /// `[thermal]`: drift of the plant's true R and ψ (`scenario_extras`).
    pub thermal: Option<pmsm_plant::Thermal>,
    /// The drive's motor from `control.model_motor` (`scenario_extras`).
    pub model_motor: Option<Motor>,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    duration_s: f64,
    motor: MotorRef,
    inverter: Inverter,
    #[serde(default)]
    control: Control,
    #[serde(default)]
    initial: RawInitial,
    speed_ref: Option<RawBreakpoints>,
    load: Option<RawBreakpoints>,
    #[serde(default)]
    sensing: Sensing,
    #[serde(default)]
    faults: Faults,
    thermal: Option<crate::scenario_extras::RawThermal>,
}

/// Reads and validates a scenario file.
pub fn read(path: &Path) -> Result<Scenario> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    parse(&text, path, &crate::motor_file::read)
}

/// Parses and validates the text of a scenario file named `path` (in messages, and the
/// directory that a motor file's name is relative to); `motor_file` reads a motor file named
/// by the scenario (from the file system for [`read`], from memory in a browser).
pub fn parse(
    text: &str,
    path: &Path,
    motor_file: &dyn Fn(&Path) -> Result<Motor>,
) -> Result<Scenario> {
    let raw: RawScenario = toml::from_str(text).map_err(|e| toml_error(&e, text, path))?;
    let shown = path.display();
    let motor = raw.motor.resolve(path, motor_file)?;
    // Table by table; the first bad key is the one reported.
    let check = || -> Result<(), ParamError> {
        in_range("duration_s", raw.duration_s, 1e-6, 1e4)?;
        raw.inverter.check()?;
        raw.control.check()?;
        raw.sensing.check()?;
        raw.initial.check()?;
        raw.faults.check()
    };
    check().map_err(|e| anyhow!("{shown}: {e}"))?;
    let speed_ref =
        breakpoints(raw.speed_ref, "speed_ref", "rpm").map_err(|e| anyhow!("{shown}: {e}"))?;
    let load = breakpoints(raw.load, "load", "nm").map_err(|e| anyhow!("{shown}: {e}"))?;
    if raw
        .control
        .sample_hz
        .is_some_and(|hz| hz > raw.inverter.pwm_hz)
    {
        bail!("{shown}: `control.sample_hz` must not exceed `inverter.pwm_hz`");
    }
    let model_motor =
        crate::scenario_extras::model_motor(raw.control.model_motor.as_deref(), path, motor_file)?;
    let mut control = raw.control;
    if control.observer == ObserverKind::Auto {
        // Chosen for the motor the drive is told of (its inductances' ratio).
        let told = &model_motor.as_ref().unwrap_or(&motor).model.params;
        control.observer = match pmsm_core::EstimatorKind::for_motor(told) {
            pmsm_core::EstimatorKind::Nlo => ObserverKind::Nlo,
            pmsm_core::EstimatorKind::Ao => ObserverKind::Ao,
            pmsm_core::EstimatorKind::MrasEmf => ObserverKind::MrasEmf,
            pmsm_core::EstimatorKind::MrasCurrent => ObserverKind::MrasCurrent,
        };
        control.observer_auto = true;
    }
    Ok(Scenario {
        path: path.to_owned(),
        duration_s: raw.duration_s,
        motor,
        inverter: raw.inverter,
        thermal: crate::scenario_extras::thermal(raw.thermal.as_ref(), &shown.to_string())?,
        model_motor,
        control,
        theta0_rad: raw.initial.theta_e_deg.to_radians(),
        omega_m0_rad_s: raw.initial.speed_rpm * std::f64::consts::TAU / 60.0,
        speed_ref,
        load,
        sensing: raw.sensing,
        faults: raw.faults,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn err(text: &str) -> String {
        let dir = std::env::temp_dir().join(format!("pmsm-scn-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("s.toml");
        std::fs::write(&p, text).unwrap();
        let e = format!("{:#}", read(&p).unwrap_err());
        std::fs::remove_dir_all(&dir).ok();
        e
    }

    const BASE: &str = "duration_s = 1.0\n\
        motor = { pole_pairs = 3, rs_ohm = 7.2, ld_h = 0.025, lq_h = 0.04, flux_wb = 0.305, j_kg_m2 = 0.0036 }\n\
        [inverter]\nvdc_v = 540.0\npwm_hz = 14000.0\n\
        [control]\nobserver = \"mras-current\"\nstartup = \"ipd\"\n";

    /// The scenario `text` read from a file.
    fn read_text(text: &str) -> Scenario {
        let dir = std::env::temp_dir().join(format!("pmsm-scn-ok-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let p = dir.join("s.toml");
        std::fs::write(&p, text).unwrap();
        let sc = read(&p).unwrap();
        std::fs::remove_dir_all(&dir).ok();
        sc
    }

    #[test]
    fn the_estimator_is_chosen_for_the_motor_by_default() {
        // No [control] at all: motor B (L_q/L_d 1.6) gets the current-model MRAS.
        let plain = BASE.split("[control]").next().unwrap();
        let sc = read_text(plain);
        assert_eq!(sc.control.observer, ObserverKind::MrasCurrent);
        assert!(sc.control.observer_auto);
        // The same motor made surface, `observer = "auto"` said: the NLO.
        let surface = BASE
            .replace("lq_h = 0.04", "lq_h = 0.025")
            .replace("observer = \"mras-current\"", "observer = \"auto\"");
        let sc = read_text(&surface);
        assert_eq!(sc.control.observer, ObserverKind::Nlo);
        assert!(sc.control.observer_auto);
        // A named estimator is kept.
        let sc = read_text(BASE);
        assert_eq!(sc.control.observer, ObserverKind::MrasCurrent);
        assert!(!sc.control.observer_auto);
    }

    #[test]
    fn errors_name_the_key() {
        assert!(err(&BASE.replace("vdc_v = 540.0", "vdc_v = -1.0")).contains("`inverter.vdc_v`"));
        assert!(err(&BASE.replace("startup = \"ipd\"", "startup = \"push\"")).contains("startup"));
        assert!(
            err(&format!(
                "{BASE}[speed_ref]\nt_s = [0.0, 1.0]\nrpm = [5.0]\n"
            ))
            .contains("speed_ref")
        );
        assert!(
            err(&format!(
                "{BASE}[speed_ref]\nt_s = [1.0, 0.5]\nrpm = [5.0, 6.0]\n"
            ))
            .contains("must increase")
        );
        assert!(err(&format!("{BASE}[control2]\nx = 1\n")).contains("control2"));
        assert!(err(&BASE.replace("rs_ohm = 7.2", "rs_ohm = 0.0")).contains("`rs_ohm`"));
        assert!(
            err(&format!("{BASE}handover_speed_rpm = 0.0\n"))
                .contains("`control.handover_speed_rpm` must be greater than zero")
        );
    }
}
