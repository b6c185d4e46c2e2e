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
//!
//! [control]
//! sample_hz = 14000.0              # default pwm_hz
//! observer = "mras-current"        # nlo | ao | mras-emf | mras-current
//! startup = "ipd"                  # ipd | align | known
//! deadtime_compensation = true
//! observer_gain = 1000.0           # optional gains; defaults come from the motor
//! current_bandwidth_hz = 500.0
//! speed_bandwidth_hz = 10.0
//! health_limit_pu = 0.5            # optional: trip on the estimator's health figure
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

use crate::motor_file::{self, Motor, RawMotor, toml_error};
use anyhow::{Result, anyhow, bail};
use pmsm_core::params::{ParamError, ParamReason, in_range, non_negative, positive};
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
    /// `[thermal]` and `control.model_motor` (`scenario_extras`).
    pub thermal: Option<pmsm_plant::Thermal>,
    /// The drive's motor from `control.model_motor`.
    pub model_motor: Option<Motor>,
}

/// `[faults]` of a scenario: faults injected into the plant at given times.
///
/// ```toml
/// [faults]
/// phase_open = "a"          # a broken phase (a, b or c) ...
/// phase_open_at_s = 1.2     # ... from this time
/// locked_rotor_at_s = 1.5   # the rotor jams
/// adc_stuck_phase = "b"     # a current channel freezes at its value ...
/// adc_stuck_at_s = 1.0      # ... from this time
/// vdc_sag_at_s = 1.3        # the bus drops ...
/// vdc_sag_to_v = 200.0      # ... to this voltage
/// short_phases = "ab"       # a short between two terminals ...
/// short_at_s = 1.1          # ... from this time ...
/// short_ohm = 0.5           # ... of this resistance (default 0.1 Ω)
/// ```
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Faults {
    /// Phase to open.
    pub phase_open: Option<Phase>,
    /// When, s.
    pub phase_open_at_s: Option<f64>,
    /// When the rotor locks, s.
    pub locked_rotor_at_s: Option<f64>,
    /// Current channel to freeze.
    pub adc_stuck_phase: Option<Phase>,
    /// When, s.
    pub adc_stuck_at_s: Option<f64>,
    /// When the bus sags, s.
    pub vdc_sag_at_s: Option<f64>,
    /// To what, V.
    pub vdc_sag_to_v: Option<f64>,
    /// Terminals shorted together.
    pub short_phases: Option<PhasePair>,
    /// When, s.
    pub short_at_s: Option<f64>,
    /// Resistance of the short, Ω.
    pub short_ohm: Option<f64>,
}

/// A phase of the motor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Phase a.
    A,
    /// Phase b.
    B,
    /// Phase c.
    C,
}

impl Phase {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Phase::A => 0,
            Phase::B => 1,
            Phase::C => 2,
        }
    }
}

/// Two terminals: `"ab"`, `"bc"` or `"ca"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhasePair {
    /// a and b.
    Ab,
    /// b and c.
    Bc,
    /// c and a.
    Ca,
}

impl PhasePair {
    /// The first terminal's index (the second is the next one).
    pub fn first(self) -> usize {
        match self {
            PhasePair::Ab => 0,
            PhasePair::Bc => 1,
            PhasePair::Ca => 2,
        }
    }
}

/// Inverter of a scenario.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inverter {
    /// Bus voltage, V.
    pub vdc_v: f64,
    /// PWM frequency, Hz.
    pub pwm_hz: f64,
    /// Dead time, s.
    #[serde(default)]
    pub dead_time_s: f64,
    /// `"averaged"` or `"switching"`.
    #[serde(default = "averaged")]
    pub model: InverterKind,
    /// ADC full scale, A; default 4 × rated peak current (or the per-unit base).
    pub current_full_scale_a: Option<f64>,
    /// IGBT/MOSFET on-state drop, V.
    #[serde(default)]
    pub v_sat_v: f64,
    /// Diode forward drop, V.
    #[serde(default)]
    pub v_f_v: f64,
}

/// Inverter model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InverterKind {
    /// Period-averaged leg voltages.
    Averaged,
    /// Switching edges of centre-aligned PWM.
    Switching,
}

fn averaged() -> InverterKind {
    InverterKind::Averaged
}

/// Estimators a drive can use.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ObserverKind {
    /// Seed 000 NLO.
    Nlo,
    /// Seed 000 AO.
    Ao,
    /// Seed 000 MRAS on the AO.
    MrasEmf,
    /// Seed 001 current-model MRAS.
    MrasCurrent,
}

/// Start-up modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Startup {
    /// Initial position detection by voltage pulses (seed 001 §4).
    Ipd,
    /// Align the rotor with a d-axis current first.
    Align,
    /// The initial angle is known (from `[initial]`).
    Known,
}

/// `[control]` of a scenario.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Control {
    /// Control sample rate, Hz (default: the PWM frequency).
    pub sample_hz: Option<f64>,
    /// Estimator.
    pub observer: ObserverKind,
    /// Start-up mode.
    pub startup: Startup,
    /// Dead-time compensation: `true` (both), `false` (off), or `"command"`, `"estimator"`,
    /// `"both"`, `"off"`.
    #[serde(default)]
    pub deadtime_compensation: Compensation,
    /// Observer gain, rad/s (seed-000 estimators).
    pub observer_gain: Option<f64>,
    /// Current-loop bandwidth, Hz.
    pub current_bandwidth_hz: Option<f64>,
    /// Speed-loop bandwidth, Hz.
    pub speed_bandwidth_hz: Option<f64>,
    /// MRAS-current adaptation bandwidth, Hz.
    pub mras_bandwidth_hz: Option<f64>,
    /// Current limit, A peak (default: twice rated peak).
    pub current_limit_a: Option<f64>,
    /// The drive's model of the motor is off the plant's: its resistance times this.
    pub model_rs_factor: Option<f64>,
    /// Its inductances times this.
    pub model_l_factor: Option<f64>,
    /// Its magnet flux times this.
    pub model_flux_factor: Option<f64>,
    /// Trip on loss of lock when the estimator's filtered health figure exceeds this, per unit
    /// (`Protection::health_limit_pu`; default: report only).
    pub health_limit_pu: Option<f64>,
    /// Motor file the drive is designed from (`scenario_extras`); the plant keeps `motor`.
    pub model_motor: Option<String>,
}

/// Where dead-time compensation applies (`deadtime_compensation`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum Compensation {
    /// `true`: both; `false`: off.
    Switch(bool),
    /// By name.
    Mode(CompensationMode),
    /// Not given: off.
    #[default]
    #[serde(skip)]
    Unset,
}

/// The named compensation modes.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum CompensationMode {
    /// No compensation.
    Off,
    /// On the voltage command only.
    Command,
    /// On the estimator's voltage only (seed 001 eq. 9).
    Estimator,
    /// Both.
    Both,
}

impl Compensation {
    /// The mode.
    pub fn mode(self) -> CompensationMode {
        match self {
            Compensation::Switch(true) => CompensationMode::Both,
            Compensation::Switch(false) | Compensation::Unset => CompensationMode::Off,
            Compensation::Mode(m) => m,
        }
    }
}

/// `[sensing]` of a scenario.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensing {
    /// ADC resolution, bits (default 12).
    pub adc_bits: Option<u32>,
    /// White noise on each phase current, A RMS.
    #[serde(default)]
    pub noise_rms_a: f64,
    /// Offset of each phase current, A.
    #[serde(default)]
    pub offset_a: [f64; 3],
    /// Relative gain error of each phase.
    #[serde(default)]
    pub gain_error: [f64; 3],
}

/// A piecewise-linear signal through breakpoints, constant outside them.
#[derive(Clone, Debug, PartialEq)]
pub struct Breakpoints {
    t_s: Vec<f64>,
    values: Vec<f64>,
}

impl Breakpoints {
    /// A constant.
    pub fn constant(value: f64) -> Self {
        Self {
            t_s: vec![0.0],
            values: vec![value],
        }
    }

    /// Value at `t`.
    pub fn at(&self, t: f64) -> f64 {
        let k = self.t_s.partition_point(|&x| x <= t);
        match (k.checked_sub(1), self.t_s.get(k)) {
            (None, _) => self.values[0],
            (Some(j), None) => self.values[j],
            (Some(j), Some(&t1)) => {
                let (t0, v0, v1) = (self.t_s[j], self.values[j], self.values[k]);
                v0 + (v1 - v0) * (t - t0) / (t1 - t0)
            }
        }
    }

    /// Times of the breakpoints, s.
    pub fn times(&self) -> &[f64] {
        &self.t_s
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawBreakpoints {
    t_s: Vec<f64>,
    #[serde(default)]
    rpm: Option<Vec<f64>>,
    #[serde(default)]
    nm: Option<Vec<f64>>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum MotorRef {
    Path(String),
    Inline(Box<RawMotor>),
}

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct RawInitial {
    #[serde(default)]
    theta_e_deg: f64,
    #[serde(default)]
    speed_rpm: f64,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct RawScenario {
    duration_s: f64,
    motor: MotorRef,
    inverter: Inverter,
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

fn breakpoints(
    raw: Option<RawBreakpoints>,
    table: &'static str,
    unit: &'static str,
) -> Result<Breakpoints, ParamError> {
    let Some(raw) = raw else {
        return Ok(Breakpoints::constant(0.0));
    };
    let bad = |reason| ParamError { key: table, reason };
    let values = match unit {
        "rpm" => raw.rpm,
        _ => raw.nm,
    }
    .ok_or(bad(ParamReason::Inconsistent(if unit == "rpm" {
        "a missing `rpm` list"
    } else {
        "a missing `nm` list"
    })))?;
    if raw.t_s.is_empty() || raw.t_s.len() != values.len() {
        return Err(bad(ParamReason::Inconsistent(
            "`t_s` and the values must be lists of the same, non-zero length",
        )));
    }
    for (k, t) in raw.t_s.iter().enumerate() {
        non_negative(table, *t)?;
        if k > 0 && *t <= raw.t_s[k - 1] {
            return Err(bad(ParamReason::Inconsistent("`t_s` must increase")));
        }
    }
    for v in &values {
        in_range(table, *v, -1e6, 1e6)?;
    }
    Ok(Breakpoints {
        t_s: raw.t_s,
        values,
    })
}

/// Reads and validates a scenario file.
pub fn read(path: &Path) -> Result<Scenario> {
    let text = std::fs::read_to_string(path)
        .map_err(|e| anyhow!("{}: cannot read: {e}", path.display()))?;
    let raw: RawScenario = toml::from_str(&text).map_err(|e| toml_error(&e, &text, path))?;
    let shown = path.display();
    let motor = match raw.motor {
        MotorRef::Path(p) => {
            let full = path.parent().unwrap_or(Path::new(".")).join(&p);
            motor_file::read(&full)?
        }
        MotorRef::Inline(m) => m
            .into_motor("motor")
            .map_err(|e| anyhow!("{shown}: motor: {e}"))?,
    };
    let check = || -> Result<(), ParamError> {
        in_range("duration_s", raw.duration_s, 1e-6, 1e4)?;
        in_range("inverter.vdc_v", raw.inverter.vdc_v, 1.0, 2000.0)?;
        in_range("inverter.pwm_hz", raw.inverter.pwm_hz, 1e3, 200e3)?;
        non_negative("inverter.dead_time_s", raw.inverter.dead_time_s)?;
        non_negative("inverter.v_sat_v", raw.inverter.v_sat_v)?;
        non_negative("inverter.v_f_v", raw.inverter.v_f_v)?;
        if let Some(fs) = raw.inverter.current_full_scale_a {
            positive("inverter.current_full_scale_a", fs)?;
        }
        if let Some(hz) = raw.control.sample_hz {
            in_range("control.sample_hz", hz, 100.0, 200e3)?;
        }
        for (key, v) in [
            ("control.observer_gain", raw.control.observer_gain),
            (
                "control.current_bandwidth_hz",
                raw.control.current_bandwidth_hz,
            ),
            ("control.speed_bandwidth_hz", raw.control.speed_bandwidth_hz),
            ("control.mras_bandwidth_hz", raw.control.mras_bandwidth_hz),
            ("control.current_limit_a", raw.control.current_limit_a),
            ("control.model_rs_factor", raw.control.model_rs_factor),
            ("control.model_l_factor", raw.control.model_l_factor),
            ("control.model_flux_factor", raw.control.model_flux_factor),
            ("control.health_limit_pu", raw.control.health_limit_pu),
        ] {
            if let Some(v) = v {
                positive(key, v)?;
            }
        }
        if let Some(bits) = raw.sensing.adc_bits {
            in_range("sensing.adc_bits", bits as f64, 2.0, 16.0)?;
        }
        non_negative("sensing.noise_rms_a", raw.sensing.noise_rms_a)?;
        in_range("initial.theta_e_deg", raw.initial.theta_e_deg, -1e6, 1e6)?;
        in_range("initial.speed_rpm", raw.initial.speed_rpm, -1e6, 1e6)?;
        let f = &raw.faults;
        for (key, t) in [
            ("faults.phase_open_at_s", f.phase_open_at_s),
            ("faults.locked_rotor_at_s", f.locked_rotor_at_s),
            ("faults.adc_stuck_at_s", f.adc_stuck_at_s),
            ("faults.vdc_sag_at_s", f.vdc_sag_at_s),
            ("faults.short_at_s", f.short_at_s),
        ] {
            if let Some(t) = t {
                non_negative(key, t)?;
            }
        }
        let pair = |key: &'static str, what: bool, when: bool| {
            if what != when {
                Err(ParamError {
                    key,
                    reason: ParamReason::Inconsistent("its companion key (both or neither)"),
                })
            } else {
                Ok(())
            }
        };
        pair(
            "faults.phase_open",
            f.phase_open.is_some(),
            f.phase_open_at_s.is_some(),
        )?;
        pair(
            "faults.adc_stuck_phase",
            f.adc_stuck_phase.is_some(),
            f.adc_stuck_at_s.is_some(),
        )?;
        pair(
            "faults.vdc_sag_to_v",
            f.vdc_sag_to_v.is_some(),
            f.vdc_sag_at_s.is_some(),
        )?;
        pair(
            "faults.short_phases",
            f.short_phases.is_some(),
            f.short_at_s.is_some(),
        )?;
        if let Some(v) = f.vdc_sag_to_v {
            in_range("faults.vdc_sag_to_v", v, 0.0, 2000.0)?;
        }
        if let Some(r) = f.short_ohm {
            positive("faults.short_ohm", r)?;
        }
        Ok(())
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
    Ok(Scenario {
        path: path.to_owned(),
        duration_s: raw.duration_s,
        motor,
        inverter: raw.inverter,
        theta0_rad: raw.initial.theta_e_deg.to_radians(),
        omega_m0_rad_s: raw.initial.speed_rpm * std::f64::consts::TAU / 60.0,
        speed_ref,
        load,
        sensing: raw.sensing,
        faults: raw.faults,
        thermal: crate::scenario_extras::thermal(raw.thermal.as_ref(), &shown.to_string())?,
        model_motor: crate::scenario_extras::model_motor(raw.control.model_motor.as_deref(), path)?,
        control: raw.control,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn breakpoints_interpolate_and_hold() {
        let b = Breakpoints {
            t_s: vec![1.0, 2.0, 4.0],
            values: vec![0.0, 10.0, -10.0],
        };
        for (t, v) in [(0.0, 0.0), (1.5, 5.0), (3.0, 0.0), (9.0, -10.0)] {
            assert!((b.at(t) - v).abs() < 1e-12, "{t}");
        }
    }

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
    }
}
