//! From the C configuration to the core's types, and from the core's states and faults to the
//! C codes. Safe Rust only.

use crate::api::{
    pmsm_config_t, pmsm_deadtime_t, pmsm_estimator_t, pmsm_fault_t, pmsm_startup_t, pmsm_state_t,
    pmsm_status_t,
};
use core::f64::consts::TAU;
use pmsm_core::DeadTimeMode;
use pmsm_core::EstimatorKind;
use pmsm_core::{Angle, ConfigError, InverterParams, MotorParams, PerUnit};
use pmsm_core::{DriveConfig, DriveDesign, DriveState, Fault, StartupMode};

/// Why a configuration was rejected.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Rejected {
    /// An enumerated code out of range (the field is named).
    Code(&'static str),
    /// The core rejected it.
    Config(ConfigError),
}

impl Rejected {
    pub(crate) fn status(&self) -> pmsm_status_t {
        match self {
            Rejected::Code(_) => pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT,
            Rejected::Config(ConfigError::Param(_)) => pmsm_status_t::PMSM_ERR_CONFIG_PARAM,
            Rejected::Config(ConfigError::OutOfEnvelope { .. }) => {
                pmsm_status_t::PMSM_ERR_CONFIG_ENVELOPE
            }
            Rejected::Config(ConfigError::Gain { .. }) => pmsm_status_t::PMSM_ERR_CONFIG_GAIN,
        }
    }
}

impl core::fmt::Display for Rejected {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match self {
            Rejected::Code(field) => write!(f, "`{field}` is not one of its enumerated values"),
            Rejected::Config(e) => e.fmt(f),
        }
    }
}

impl From<ConfigError> for Rejected {
    fn from(e: ConfigError) -> Self {
        Rejected::Config(e)
    }
}

/// `0` is "not given" for the optional doubles of the configuration.
fn given(x: f64) -> Option<f64> {
    if x.to_bits() << 1 == 0 { None } else { Some(x) }
}

/// What a drive is built from, checked.
pub(crate) struct Built {
    pub config: DriveConfig,
    pub period: u16,
    pub pole_pairs: u32,
}

/// Builds and checks the drive configuration of `c` (the same sequence as `pmsm simulate`).
pub(crate) fn build(c: &pmsm_config_t) -> Result<Built, Rejected> {
    let mut motor = MotorParams::new(
        c.pole_pairs,
        c.rs_ohm,
        c.ld_h,
        c.lq_h,
        c.flux_wb,
        c.j_kg_m2,
        c.b_nm_s,
    );
    if let Some(kt) = given(c.kt_nm_per_a) {
        motor.kt_nm_per_a = kt;
    }
    motor.rated_current_a = given(c.rated_current_a);
    motor.rated_speed_rpm = given(c.rated_speed_rpm);
    let sample_hz = given(c.sample_hz).unwrap_or(c.pwm_hz);
    let mut inverter = InverterParams {
        vdc_v: c.vdc_v,
        pwm_hz: c.pwm_hz,
        dead_time_s: c.dead_time_s,
        current_full_scale_a: 1.0,
    };
    let base = PerUnit::new(&motor, &inverter, sample_hz)?;
    inverter.current_full_scale_a = given(c.current_full_scale_a).unwrap_or(4.0 * base.current_a);
    motor.validate().map_err(ConfigError::Param)?;
    inverter.validate().map_err(ConfigError::Param)?;

    let estimator = match c.estimator {
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_MRAS_CURRENT as u32 => {
            EstimatorKind::MrasCurrent
        }
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_NLO as u32 => EstimatorKind::Nlo,
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_AO as u32 => EstimatorKind::Ao,
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_MRAS_EMF as u32 => EstimatorKind::MrasEmf,
        _ => return Err(Rejected::Code("estimator")),
    };
    let mut design = DriveDesign::default_for(&motor, &inverter, &base, estimator);
    design.startup = match c.startup {
        x if x == pmsm_startup_t::PMSM_STARTUP_DEFAULT as u32 => design.startup,
        x if x == pmsm_startup_t::PMSM_STARTUP_IPD as u32 => StartupMode::Ipd,
        x if x == pmsm_startup_t::PMSM_STARTUP_ALIGN as u32 => StartupMode::Align,
        x if x == pmsm_startup_t::PMSM_STARTUP_KNOWN as u32 => {
            StartupMode::Known(Angle(c.startup_angle))
        }
        _ => return Err(Rejected::Code("startup")),
    };
    design.deadtime.mode = match c.deadtime_compensation {
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_DEFAULT as u32 => design.deadtime.mode,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_OFF as u32 => DeadTimeMode::Off,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_COMMAND as u32 => DeadTimeMode::Command,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_ESTIMATOR as u32 => DeadTimeMode::Estimator,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_BOTH as u32 => DeadTimeMode::Both,
        _ => return Err(Rejected::Code("deadtime_compensation")),
    };
    if let Some(g) = given(c.observer_gain_rad_s) {
        design.observer_gain_rad_s = g;
    }
    if let Some(hz) = given(c.current_bandwidth_hz) {
        design.current.bandwidth_rad_s = TAU * hz;
    }
    if let Some(hz) = given(c.speed_bandwidth_hz) {
        design.speed.bandwidth_rad_s = TAU * hz;
    }
    if let Some(a) = given(c.current_limit_a) {
        design.speed.current_limit_a = a;
        design.open_loop.current_a = design.open_loop.current_a.min(a);
    }
    let period =
        u16::try_from(c.pwm_period_ticks).map_err(|_| Rejected::Code("pwm_period_ticks"))?;
    let config = DriveConfig::new(&motor, &inverter, sample_hz, design)?;
    Ok(Built {
        config,
        period,
        pole_pairs: c.pole_pairs,
    })
}

/// The C code of a state.
pub fn state_code(s: &DriveState) -> pmsm_state_t {
    #[allow(unreachable_patterns)] // states added to the core later map to OTHER
    match s {
        DriveState::Idle => pmsm_state_t::PMSM_STATE_IDLE,
        DriveState::Ipd => pmsm_state_t::PMSM_STATE_IPD,
        DriveState::Align => pmsm_state_t::PMSM_STATE_ALIGN,
        DriveState::OpenLoop => pmsm_state_t::PMSM_STATE_OPEN_LOOP,
        DriveState::Run => pmsm_state_t::PMSM_STATE_RUN,
        DriveState::Fault(_) => pmsm_state_t::PMSM_STATE_FAULT,
        _ => pmsm_state_t::PMSM_STATE_OTHER,
    }
}

/// The C code of the fault of a state ([`pmsm_fault_t::PMSM_FAULT_NONE`] outside `Fault`),
/// and its value: Q8.24 per unit for the current and bus faults, the angle difference (turn,
/// 2^32) for the handover, 0 otherwise.
pub fn fault_code(s: &DriveState) -> (pmsm_fault_t, i32) {
    let DriveState::Fault(f) = s else {
        return (pmsm_fault_t::PMSM_FAULT_NONE, 0);
    };
    #[allow(unreachable_patterns)] // faults added to the core later map to OTHER
    match f {
        Fault::OverCurrent(x) => (pmsm_fault_t::PMSM_FAULT_OVERCURRENT, x.to_bits()),
        Fault::BusUnderVoltage(x) => (pmsm_fault_t::PMSM_FAULT_BUS_UNDERVOLTAGE, x.to_bits()),
        Fault::BusOverVoltage(x) => (pmsm_fault_t::PMSM_FAULT_BUS_OVERVOLTAGE, x.to_bits()),
        Fault::InitialPosition(_) => (pmsm_fault_t::PMSM_FAULT_INITIAL_POSITION, 0),
        Fault::Handover(a, _) => (pmsm_fault_t::PMSM_FAULT_HANDOVER, a.0),
        _ => (pmsm_fault_t::PMSM_FAULT_OTHER, 0),
    }
}

/// `core::fmt::Write` into a C buffer: truncates, keeps room for the terminating NUL, and
/// counts the length of the whole message.
pub(crate) struct CBuf<'a> {
    pub buf: &'a mut [u8],
    pub used: usize,
    pub needed: usize,
}

impl core::fmt::Write for CBuf<'_> {
    fn write_str(&mut self, s: &str) -> core::fmt::Result {
        let room = self.buf.len().saturating_sub(1).saturating_sub(self.used);
        let n = room.min(s.len());
        if let (Some(dst), Some(src)) = (
            self.buf.get_mut(self.used..self.used + n),
            s.as_bytes().get(..n),
        ) {
            dst.copy_from_slice(src);
            self.used += n;
        }
        self.needed += s.len();
        Ok(())
    }
}
