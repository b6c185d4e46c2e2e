//! `[control]`: the estimator, the start-up, dead-time compensation, and the overrides of
//! the drive's default design (gains, bandwidths, limits, the model's errors).

use pmsm_core::validate::{in_range, positive};
use pmsm_core::{ParamError, ParamReason};
use serde::Deserialize;

/// Estimators a drive can use.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ObserverKind {
    /// The one the defaults choose for the motor (`pmsm_core::EstimatorKind::for_motor`: the
    /// current-model MRAS on an interior motor, the NLO on a surface motor); the default.
    /// Reading the scenario replaces it with the one chosen ([`Control::observer_auto`] says
    /// so).
    #[default]
    Auto,
    /// Nonlinear reduced-order observer of Solsona, Valla, Muravchik (2000).
    Nlo,
    /// Linear reduced-order observer (AO) of Solsona, Valla, Muravchik (2000).
    Ao,
    /// Tomita's MRAS on the AO, as Solsona, Valla, Muravchik (2000) use it.
    MrasEmf,
    /// Current-model MRAS of Khlaief, Boussak, Gossa (2012).
    MrasCurrent,
}

/// Forms of the speed loop (`pmsm_core::SpeedDesign::reference_weight` 0 and 1).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum SpeedLoopForm {
    /// Proportional action on the estimated speed only (Khlaief, Boussak, Gossa (2012)): no
    /// overshoot, a ramp followed late.
    Ip,
    /// Proportional action on the error: a ramp followed without lag, an overshoot after a
    /// step.
    Pi,
}

/// The current whose signs the dead-time compensation takes (`pmsm_core::CurrentSource`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DeadTimeCurrent {
    /// The current reference turned to αβ.
    Reference,
    /// The measured current (the default with the back-EMF estimators).
    Measured,
    /// The reference at light load, the measured current under load (the default with the
    /// current-model MRAS).
    MeasuredUnderLoad,
}

/// Start-up modes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum Startup {
    /// Initial position detection on a salient motor, alignment otherwise
    /// (`pmsm_core::StartupMode::Auto`); the default.
    #[default]
    Auto,
    /// Initial position detection by voltage pulses (Khlaief, Boussak, Gossa (2012), §4).
    Ipd,
    /// Align the rotor with a d-axis current first.
    Align,
    /// The initial angle is known (from `[initial]`).
    Known,
}

/// Default `[control] pwm_update_delay_periods`: the delay of pmsm-stm32's TIM1
/// ([`pmsm_stm32::PWM_UPDATE_DELAY_SAMPLES`], one period: the compare preload is transferred
/// at the update event of the counter's peak, where the ADC samples; docs/drive.md, PWM
/// update delay), so that a simulated drive meets the timing of the board's.
pub const DEFAULT_PWM_UPDATE_DELAY_PERIODS: u32 = pmsm_stm32::PWM_UPDATE_DELAY_SAMPLES as u32;

/// `[control]` of a scenario; the table and every key in it are optional.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Control {
    /// Control sample rate, Hz (default: the PWM frequency).
    pub sample_hz: Option<f64>,
    /// Estimator (default `auto`).
    #[serde(default)]
    pub observer: ObserverKind,
    /// The estimator was chosen for the motor (`observer = "auto"`, or no `observer`).
    #[serde(skip)]
    pub observer_auto: bool,
    /// Start-up mode (default `auto`).
    #[serde(default)]
    pub startup: Startup,
    /// Dead-time compensation: `true` (both), `false` (off), or `"command"`, `"estimator"`,
    /// `"both"`, `"off"` (default: both).
    #[serde(default)]
    pub deadtime_compensation: Compensation,
    /// Observer gain, rad/s (the estimators of Solsona, Valla, Muravchik (2000)).
    pub observer_gain: Option<f64>,
    /// Current-loop bandwidth, Hz.
    pub current_bandwidth_hz: Option<f64>,
    /// Speed-loop bandwidth, Hz.
    pub speed_bandwidth_hz: Option<f64>,
    /// `"ip"` or `"pi"`: the reference's weight in the speed loop's proportional action 0 or
    /// 1 (default: the drive's, 0.5 with the current-model MRAS and 0 with the back-EMF
    /// estimators; docs/drive.md, "speed loop: the reference's weight").
    pub speed_loop: Option<SpeedLoopForm>,
    /// The reference's weight in the speed loop's proportional action, in [0, 1] (0: the IP
    /// form, 1: the PI form; `pmsm_core::SpeedDesign::reference_weight`); not with
    /// `speed_loop`.
    pub speed_reference_weight: Option<f64>,
    /// MRAS-current adaptation bandwidth `ω_n/(2π)`, Hz: the plain design at `k_∞`
    /// (`pmsm_core::MrasCurrentGains::design`). Default: `MrasCurrentGains::default_for`'s,
    /// `0.02/T_s` raised on a light rotor (docs/khlaief2012.md §2).
    pub mras_bandwidth_hz: Option<f64>,
    /// Raise the MRAS-current adaptation gains at low speed, up to four times, where ξ's
    /// sensitivity to the position error falls (`MrasCurrentGains::low_speed_schedule`,
    /// docs/khlaief2012.md; default: the core's).
    pub mras_low_speed_schedule: Option<bool>,
    /// The weight of the d-axis error in the current-model MRAS's tuning signal, relative to
    /// Khlaief, Boussak, Gossa (2012) eq. 21's, in [0, 1] (`MrasCurrentGains::d_weight`,
    /// docs/khlaief2012.md §2; default `pmsm_core::MrasCurrentGains`'s, 1/2; 1: the paper's).
    pub mras_d_weight: Option<f64>,
    /// Speed at which a back-EMF estimator takes over from the open-loop start, and the least
    /// speed it runs at, mechanical r/min (default: a tenth of the rated speed, and with the
    /// MRAS on the EMF at least where its adaptation is damped ½,
    /// `pmsm_core::MrasEmfConfig::damped_speed_rad_s`; docs/solsona2000.md §5).
    pub handover_speed_rpm: Option<f64>,
    /// Current limit of the speed loop, A peak (default: the rated peak current, `√2 ·
    /// rated_current_a`, the per-unit base `I_b`).
    pub current_limit_a: Option<f64>,
    /// The drive's model of the motor is off the plant's: its resistance times this.
    pub model_rs_factor: Option<f64>,
    /// Its inductances times this.
    pub model_l_factor: Option<f64>,
    /// Its magnet flux times this.
    pub model_flux_factor: Option<f64>,
    /// Trip on loss of lock when the estimator's filtered health figure exceeds this in steady
    /// state, per unit (`Protection::health_limit_pu`; default
    /// `pmsm_core::DEFAULT_HEALTH_LIMIT_PU`, 1.0; 0 turns the check off).
    pub health_limit_pu: Option<f64>,
    /// The dead time the drive's compensation is designed for, s (default: the inverter's
    /// `dead_time_s`; the plant keeps the inverter's).
    pub dead_time_s: Option<f64>,
    /// PWM periods between a control step and the period its duties act over in the plant
    /// (the compare preload; 1 on pmsm-stm32's TIM1): default
    /// [`DEFAULT_PWM_UPDATE_DELAY_PERIODS`]; 0 applies them over the coming period. Outputs
    /// on and off act at once.
    pub pwm_update_delay_periods: Option<u32>,
    /// The delay the drive compensates, PWM periods, a whole number of control samples
    /// (`pmsm_core::DriveDesign::pwm_delay_samples`; default: `pwm_update_delay_periods`;
    /// the plant keeps its own).
    pub pwm_delay_compensation_periods: Option<u32>,
    /// Motor file the drive is designed from (`scenario_extras`); the plant keeps `motor`.
    pub model_motor: Option<String>,
    /// Maximum torque per ampere for interior motors (`pmsm_core::FluxDesign::mtpa`; default:
    /// the drive's, computed from the motor).
    pub mtpa: Option<bool>,
    /// Field weakening by voltage feedback, and the speed reference clamped to the maximum
    /// speed (`pmsm_core::FluxDesign::field_weakening`; default: the drive's, computed from
    /// the motor and the bus).
    pub field_weakening: Option<bool>,
    /// Overmodulation up to six-step beyond the modulator's circle (default false).
    #[serde(default)]
    pub overmodulation: bool,
    /// The d-axis current the drive holds at light load, A peak (docs/drive.md, "light load";
    /// default `pmsm_core::LightLoadConfig::default_current_a`: three times the dead-time
    /// compensation's band, at most a sixth of the current limit, with the current-model
    /// MRAS; 0 with the other estimators; 0 turns it off).
    pub light_load_id_a: Option<f64>,
    /// The positive d-axis current the drive holds at low speed, A peak, faded out at a fifth
    /// of the rated speed (docs/drive.md, "low-speed current"; default
    /// `pmsm_core::LowSpeedConfig::default_current_a`: the current limit, less on a strongly
    /// salient motor; 0 turns it off; at most the current limit).
    pub low_speed_id_a: Option<f64>,
    /// Measure the inverter's distortion voltage at standstill before the run and scale the
    /// dead-time compensation to it (`pmsm_core::DriveDesign::deadtime_calibration`; default
    /// on when the compensation acts on the command and the drive is told a dead time).
    pub deadtime_calibration: Option<bool>,
    /// Hold the current-model MRAS's adaptation through a phase current's zero crossing at
    /// low speed and light load (`pmsm_core::DriveDesign::zero_crossing_hold`, docs/drive.md
    /// "Zero crossings at low speed"; default on; it acts only while the dead-time
    /// compensation does).
    pub zero_crossing_hold: Option<bool>,
    /// The current whose signs the dead-time compensation takes: `"reference"`,
    /// `"measured"` (the default with the back-EMF estimators) or `"measured-under-load"`
    /// (the default with the current-model MRAS; docs/drive.md, "dead-time compensation:
    /// which current's sign").
    pub deadtime_current: Option<DeadTimeCurrent>,
    /// Track the motor's R and ψ while running (`pmsm_core::Tracker`, docs/tracking.md;
    /// default: the drive's, `pmsm_core::DriveDesign::tracking`, on with the current-model MRAS).
    pub tracking: Option<bool>,
    /// Learn the inverter's distortion voltage while running and rescale the dead-time
    /// compensation to it (`pmsm_core::DistortionLearner`, docs/distortion.md; default: the
    /// drive's, `pmsm_core::DriveDesign::deadtime_learning`).
    pub deadtime_learning: Option<bool>,
    /// High-frequency injection at standstill and low speed on a salient motor
    /// (`pmsm_core::InjectionDesign`, docs/injection.md). Default: on where the motor allows it
    /// (`L_q/L_d` ≥ 1.1), else off with the reason printed; `true` asks for it (a motor it
    /// cannot serve is then refused), `false` turns it off.
    pub injection: Option<bool>,
    /// The load observer that feeds the load's current forward into the speed loop
    /// (`pmsm_core::DriveDesign::load_observer_rad_s`, docs/khlaief2012.md §7). Default: the
    /// drive's, on with the back-EMF estimators where the motor's resistive drop is below a
    /// quarter of its EMF; `false` turns it off.
    pub load_observer: Option<bool>,
}

impl Control {
    /// The sample rate within [100 Hz, 200 kHz]; every gain, bandwidth, limit and factor
    /// positive.
    pub(super) fn check(&self) -> Result<(), ParamError> {
        if let Some(hz) = self.sample_hz {
            in_range("control.sample_hz", hz, 100.0, 200e3)?;
        }
        if let Some(h) = self.health_limit_pu {
            in_range("control.health_limit_pu", h, 0.0, 100.0)?;
        }
        if let Some(t) = self.dead_time_s {
            in_range("control.dead_time_s", t, 0.0, 1e-3)?;
        }
        if let Some(i) = self.light_load_id_a {
            in_range("control.light_load_id_a", i, 0.0, 1e4)?;
        }
        if let Some(i) = self.low_speed_id_a {
            in_range("control.low_speed_id_a", i, 0.0, 1e4)?;
        }
        if let Some(b) = self.speed_reference_weight {
            in_range("control.speed_reference_weight", b, 0.0, 1.0)?;
            if self.speed_loop.is_some() {
                return Err(ParamError {
                    key: "control.speed_reference_weight",
                    reason: ParamReason::Inconsistent("control.speed_loop (give one of them)"),
                });
            }
        }
        if let Some(w) = self.mras_d_weight {
            in_range("control.mras_d_weight", w, 0.0, 1.0)?;
        }
        if let Some(n) = self.pwm_update_delay_periods {
            in_range("control.pwm_update_delay_periods", n as f64, 0.0, 16.0)?;
        }
        for (key, v) in [
            ("control.observer_gain", self.observer_gain),
            ("control.current_bandwidth_hz", self.current_bandwidth_hz),
            ("control.speed_bandwidth_hz", self.speed_bandwidth_hz),
            ("control.mras_bandwidth_hz", self.mras_bandwidth_hz),
            ("control.current_limit_a", self.current_limit_a),
            ("control.handover_speed_rpm", self.handover_speed_rpm),
            ("control.model_rs_factor", self.model_rs_factor),
            ("control.model_l_factor", self.model_l_factor),
            ("control.model_flux_factor", self.model_flux_factor),
        ] {
            if let Some(v) = v {
                positive(key, v)?;
            }
        }
        Ok(())
    }
}

/// Where dead-time compensation applies (`deadtime_compensation`).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Deserialize)]
#[serde(untagged)]
pub enum Compensation {
    /// `true`: both; `false`: off.
    Switch(bool),
    /// By name.
    Mode(CompensationMode),
    /// Not given: both, as the drive's design has it (`pmsm_core::DeadTimeDesign`).
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
    /// On the estimator's voltage only (Khlaief, Boussak, Gossa (2012), eq. 9).
    Estimator,
    /// Both.
    Both,
}

impl Compensation {
    /// The mode.
    pub fn mode(self) -> CompensationMode {
        match self {
            Compensation::Switch(true) | Compensation::Unset => CompensationMode::Both,
            Compensation::Switch(false) => CompensationMode::Off,
            Compensation::Mode(m) => m,
        }
    }
}
