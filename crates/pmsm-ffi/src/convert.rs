//! From the C configuration to the core's types, and from the core's states and faults to the
//! C codes. Safe Rust only.

use crate::types::{
    pmsm_config_t, pmsm_deadtime_t, pmsm_estimator_t, pmsm_injection_t, pmsm_option_t,
    pmsm_startup_t, pmsm_status_t,
};
use core::f64::consts::TAU;
use pmsm_core::DeadTimeMode;
use pmsm_core::EstimatorKind;
use pmsm_core::IpdFault;
use pmsm_core::{Angle, ConfigError, InverterParams, MotorParams, PerUnit};
use pmsm_core::{DriveConfig, DriveDesign, DriveState, Fault, StartupMode};

/// Why a configuration was rejected.
#[derive(Clone, Copy, Debug)]
pub(crate) enum Rejected {
    /// An integer field outside its range: the field, its value and the accepted range.
    Range {
        field: &'static str,
        value: u32,
        allowed: &'static str,
    },
    /// A part this library was built without: the field, its value and the cargo feature of
    /// pmsm-ffi that builds it in.
    NotBuilt {
        field: &'static str,
        value: u32,
        feature: &'static str,
    },
    /// The core rejected it.
    Config(ConfigError),
}

impl Rejected {
    pub(crate) fn status(&self) -> pmsm_status_t {
        match self {
            Rejected::Range { .. } | Rejected::NotBuilt { .. } => {
                pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT
            }
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
            Rejected::Range {
                field,
                value,
                allowed,
            } => write!(f, "`{field}` is {value}; it must be in {allowed}"),
            Rejected::NotBuilt {
                field,
                value,
                feature,
            } => write!(
                f,
                "`{field}` {value} is not built into this library: build pmsm-ffi with the \
                 cargo feature `{feature}`"
            ),
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

    let estimator = estimator(c.estimator, &motor)?;
    let mut design = DriveDesign::default_for(&motor, &inverter, &base, estimator);
    design.startup = match c.startup {
        x if x == pmsm_startup_t::PMSM_STARTUP_DEFAULT as u32 => design.startup,
        x if x == pmsm_startup_t::PMSM_STARTUP_IPD as u32 => StartupMode::Ipd,
        x if x == pmsm_startup_t::PMSM_STARTUP_ALIGN as u32 => StartupMode::Align,
        x if x == pmsm_startup_t::PMSM_STARTUP_KNOWN as u32 => {
            StartupMode::Known(Angle(c.startup_angle))
        }
        x => {
            return Err(Rejected::Range {
                field: "startup",
                value: x,
                allowed: "0 to 3 (DEFAULT, IPD, ALIGN, KNOWN)",
            });
        }
    };
    design.deadtime.mode = match c.deadtime_compensation {
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_DEFAULT as u32 => design.deadtime.mode,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_OFF as u32 => DeadTimeMode::Off,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_COMMAND as u32 => DeadTimeMode::Command,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_ESTIMATOR as u32 => DeadTimeMode::Estimator,
        x if x == pmsm_deadtime_t::PMSM_DEADTIME_BOTH as u32 => DeadTimeMode::Both,
        x => {
            return Err(Rejected::Range {
                field: "deadtime_compensation",
                value: x,
                allowed: "0 to 4 (DEFAULT, OFF, COMMAND, ESTIMATOR, BOTH)",
            });
        }
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
    design.pwm_delay_samples = u8::try_from(c.pwm_delay_samples)
        .ok()
        .filter(|&d| d <= pmsm_core::MAX_PWM_DELAY_SAMPLES)
        .ok_or(Rejected::Range {
            field: "pwm_delay_samples",
            value: c.pwm_delay_samples,
            allowed: "0 to 2",
        })?;
    injection(c.injection, &mut design)?;
    let tracker = (cfg!(feature = "tracking"), "tracking");
    if let Some(on) = option(c.tracking, "tracking", tracker)? {
        design.tracking = on;
    }
    let learner = (cfg!(feature = "distortion-learner"), "distortion-learner");
    if let Some(on) = option(c.deadtime_learning, "deadtime_learning", learner)? {
        design.deadtime_learning = on;
    }
    let period = u16::try_from(c.pwm_period_ticks).map_err(|_| Rejected::Range {
        field: "pwm_period_ticks",
        value: c.pwm_period_ticks,
        allowed: "0 to 65535",
    })?;
    let config = DriveConfig::new(&motor, &inverter, sample_hz, design)?;
    Ok(Built {
        config,
        period,
        pole_pairs: c.pole_pairs,
    })
}

/// The estimator of a `pmsm_estimator_t` code, if this library was built with it.
fn estimator(code: u32, motor: &MotorParams) -> Result<EstimatorKind, Rejected> {
    let code = if code == pmsm_estimator_t::PMSM_ESTIMATOR_AUTO as u32 {
        let chosen = match EstimatorKind::for_motor(motor) {
            EstimatorKind::Nlo => pmsm_estimator_t::PMSM_ESTIMATOR_NLO,
            EstimatorKind::Ao => pmsm_estimator_t::PMSM_ESTIMATOR_AO,
            EstimatorKind::MrasEmf => pmsm_estimator_t::PMSM_ESTIMATOR_MRAS_EMF,
            EstimatorKind::MrasCurrent => pmsm_estimator_t::PMSM_ESTIMATOR_MRAS_CURRENT,
        };
        chosen as u32
    } else {
        code
    };
    let (kind, built, feature) = match code {
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_MRAS_CURRENT as u32 => (
            EstimatorKind::MrasCurrent,
            cfg!(feature = "mras-current"),
            "mras-current",
        ),
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_NLO as u32 => {
            (EstimatorKind::Nlo, cfg!(feature = "nlo"), "nlo")
        }
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_AO as u32 => {
            (EstimatorKind::Ao, cfg!(feature = "ao"), "ao")
        }
        x if x == pmsm_estimator_t::PMSM_ESTIMATOR_MRAS_EMF as u32 => (
            EstimatorKind::MrasEmf,
            cfg!(feature = "mras-emf"),
            "mras-emf",
        ),
        x => {
            return Err(Rejected::Range {
                field: "estimator",
                value: x,
                allowed: "0 to 4 (MRAS_CURRENT, NLO, AO, MRAS_EMF, AUTO)",
            });
        }
    };
    if built {
        Ok(kind)
    } else {
        Err(Rejected::NotBuilt {
            field: "estimator",
            value: code,
            feature,
        })
    }
}

// `injection` reads a `pmsm_injection_t` as a `pmsm_option_t`: the same codes.
const _: () = assert!(
    pmsm_injection_t::PMSM_INJECTION_DEFAULT as u32 == pmsm_option_t::PMSM_OPTION_DEFAULT as u32
        && pmsm_injection_t::PMSM_INJECTION_OFF as u32 == pmsm_option_t::PMSM_OPTION_OFF as u32
        && pmsm_injection_t::PMSM_INJECTION_ON as u32 == pmsm_option_t::PMSM_OPTION_ON as u32
);

/// Sets the design's injection from a `pmsm_injection_t` code (the codes of a
/// `pmsm_option_t`).
fn injection(code: u32, design: &mut DriveDesign) -> Result<(), Rejected> {
    let built = (cfg!(feature = "injection"), "injection");
    let Some(on) = option(code, "injection", built)? else {
        return Ok(());
    };
    #[cfg(feature = "injection")]
    {
        design.injection = on.then(pmsm_core::InjectionDesign::required);
    }
    #[cfg(not(feature = "injection"))]
    let _ = (on, design);
    Ok(())
}

/// A `pmsm_option_t` code of `field`: `None` for the default, else off or on (on refused by
/// a library built without its cargo feature: `(built, feature)`).
fn option(
    code: u32,
    field: &'static str,
    (built, feature): (bool, &'static str),
) -> Result<Option<bool>, Rejected> {
    match code {
        x if x == pmsm_option_t::PMSM_OPTION_DEFAULT as u32 => Ok(None),
        x if x == pmsm_option_t::PMSM_OPTION_OFF as u32 => Ok(Some(false)),
        x if x == pmsm_option_t::PMSM_OPTION_ON as u32 && built => Ok(Some(true)),
        x if x == pmsm_option_t::PMSM_OPTION_ON as u32 => Err(Rejected::NotBuilt {
            field,
            value: x,
            feature,
        }),
        x => Err(Rejected::Range {
            field,
            value: x,
            allowed: "0 to 2 (DEFAULT, OFF, ON)",
        }),
    }
}

/// What `pmsm_injection_message` says of a built drive.
pub(crate) fn write_injection(
    w: &mut impl core::fmt::Write,
    config: &DriveConfig,
) -> core::fmt::Result {
    #[cfg(feature = "injection")]
    {
        if let Some(f) = config.injection() {
            // Whole milli-units: integer formatting (a float's would add some 20 KiB).
            let milli = |x: f64| (x * 1e3 + 0.5) as i64;
            return write!(
                w,
                "on: {} mV at {} Hz along the estimated d axis, {} mA across it at 45 degrees \
                 of error, {} mA peak to peak of ripple along d",
                milli(f.amplitude_v),
                (f.frequency_hz + 0.5) as i64,
                milli(f.response_a),
                milli(f.ripple_a)
            );
        }
        match config.injection_declined() {
            Some(why) => write!(w, "off: {why}"),
            None => w.write_str("off: `injection` is 1 (OFF)"),
        }
    }
    #[cfg(not(feature = "injection"))]
    {
        let _ = config;
        w.write_str("off: not built into this library (cargo feature `injection`)")
    }
}

/// The C code of a state (a `pmsm_state_t`): the core's [`DriveState::code`].
pub fn state_code(s: &DriveState) -> u32 {
    u32::from(s.code())
}

/// The C code of the fault of a state (a `pmsm_fault_t`: the core's
/// [`DriveState::fault_code`], 0 outside `Fault`) and its value (see `pmsm_fault_t`).
pub fn fault_code(s: &DriveState) -> (u32, i32) {
    let value = match s {
        DriveState::Fault(f) => match f {
            Fault::OverCurrent(x)
            | Fault::BusUnderVoltage(x)
            | Fault::BusOverVoltage(x)
            | Fault::Overspeed(x) => x.to_bits(),
            Fault::InitialPosition(e) => i32::from(e.code()),
            Fault::Handover(a, _) => a.0,
            Fault::CurrentSensor(ch) => ch.map_or(-1, i32::from),
            Fault::PhaseLoss(ph) => i32::from(*ph),
            Fault::Stall | Fault::LossOfLock | Fault::Overrun | Fault::DrivenBackwards => 0,
        },
        _ => 0,
    };
    (u32::from(s.fault_code()), value)
}

/// The C code and measurements of the IPD check that failed, if the drive is in that fault.
pub(crate) fn ipd_fault(s: &DriveState) -> (u32, [i32; 2]) {
    let DriveState::Fault(Fault::InitialPosition(e)) = s else {
        return (0, [0, 0]);
    };
    let v = match e {
        IpdFault::OverCurrent(x) | IpdFault::NoCurrent(x) => [x.to_bits(), 0],
        IpdFault::LowSaliency { modulation, sum } => [modulation.to_bits(), sum.to_bits()],
        IpdFault::NoPolarity { along, opposite } => [along.to_bits(), opposite.to_bits()],
        IpdFault::BusLow => [0, 0],
    };
    (u32::from(e.code()), v)
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
