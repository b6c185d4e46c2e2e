//! Fixed-point sensorless field-oriented control of permanent-magnet synchronous motors.
//!
//! `no_std`, no allocation, no floating point on the control path. A drive is configured once
//! in `f64` from SI parameters ([`MotorParams`], [`InverterParams`]) into per-unit fixed-point
//! coefficients ([`PerUnit`], [`DriveConfig`]); each [`Drive::step`] is then integer arithmetic
//! on [`Pu`] (Q8.24) and [`Unit`] (Q2.30) signals, which saturates instead of wrapping. Angles
//! are wrapping integer turns ([`Angle`]).
//!
//! ```
//! use pmsm_core::{
//!     Abc, Angle, Drive, DriveConfig, DriveInput, DriveOptions, DriveState, InverterParams,
//!     MotorParams, StartupMode, TASK_PERIOD,
//! };
//!
//! // A 1.1 kW interior motor on a 540 V inverter switching at 14 kHz.
//! let mut motor = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
//! motor.rated_current_a = Some(2.53);
//! let inverter = InverterParams {
//!     vdc_v: 540.0,
//!     pwm_hz: 14e3,
//!     dead_time_s: 2e-6,
//!     current_full_scale_a: 10.0,
//! };
//! // The current-model MRAS (the default estimator), started at a known rotor angle.
//! let options = DriveOptions {
//!     startup: Some(StartupMode::Known(Angle::ZERO)),
//!     ..DriveOptions::default()
//! };
//! let config = DriveConfig::from_params(&motor, &inverter, 14e3, options)?;
//! let base = config.base;
//! let mut drive = Drive::new(config);
//! drive.set_speed_ref(base.speed_pu(100.0));
//! drive.start();
//! assert_eq!(drive.task().state(), DriveState::Run);
//!
//! // One step per PWM period: the sampled phase currents and bus in, three duties out. The
//! // task runs after the step that ends each task period; the interrupt side takes its
//! // command at the next step: the outputs switch from the second task period on.
//! let input = DriveInput {
//!     i_abc: Abc::default(),
//!     vdc: base.voltage_pu(540.0),
//! };
//! for k in 0..6 * TASK_PERIOD {
//!     let out = drive.step(&input);
//!     assert_eq!(out.pwm_on, k >= TASK_PERIOD);
//!     let [a, b, c] = out.duties.to_f64();
//!     assert!([a, b, c].iter().all(|d| (0.0..=1.0).contains(d)));
//!     if k == 2 * TASK_PERIOD {
//!         // At rest with a positive speed reference, the speed loop asks for positive torque
//!         // (from its first run in `Run`, the task's second).
//!         assert!(drive.telemetry().i_ref.q > pmsm_core::Pu::ZERO);
//!     }
//! }
//! assert_eq!(drive.state(), DriveState::Run);
//! # Ok::<(), pmsm_core::ConfigError>(())
//! ```
//!
//! What is where:
//!
//! - the drive: [`Drive`], [`DriveConfig`] (from [`DriveOptions`] or a full [`DriveDesign`],
//!   or from the image of one designed on the host, [`DriveConfig::from_image`],
//!   docs/image.md), its states and faults, and the hardware traits a board implements
//!   ([`ThreePhasePwm`], [`PhaseCurrentSampler`], [`control_step`]);
//! - the estimators behind [`Estimator`]: [`Nlo`], [`Ao`], [`MrasEmf`] (Solsona, Valla,
//!   Muravchik (2000)) and [`MrasCurrent`] (Khlaief, Boussak, Gossa (2012)), each built from its
//!   configuration of coefficients;
//! - the parts of a step, usable alone: [`clarke`], [`park`] and their inverses, the current
//!   and speed loops ([`CurrentController`], [`SpeedController`], [`Pi`]), dead-time
//!   compensation ([`DeadTimeConfig`]), space-vector modulation ([`SvpwmConfig`]) and the
//!   initial position detection ([`Ipd`]);
//! - self-commissioning ([`Identify`]): R, L_d, L_q, ψ, J and B measured at start-up;
//! - the fault recorder ([`FaultRecorder`]): the last samples before a fault, per unit, for a
//!   replay on the host;
//! - numbers: [`Pu`], [`Unit`], [`Angle`], [`polar`] (atan2 and magnitude), and the per-unit bases
//!   [`PerUnit`];
//! - for tools and tests rather than firmware: the design's constants ([`tuning`]), the
//!   double-precision references of closed-form laws ([`reference`](mod@reference)) and the parameter checks
//!   ([`validate`]).
#![no_std]
#![cfg_attr(
    not(test),
    deny(
        clippy::unwrap_used,
        clippy::expect_used,
        clippy::panic,
        clippy::indexing_slicing,
        clippy::unreachable,
        clippy::todo
    )
)]

mod angle;
mod control;
mod cordic;
mod deadtime;
#[cfg(feature = "defmt")]
mod defmt_impls;
mod drive;
mod error;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
mod frames;
mod hal;
mod identify;
mod image;
mod ipd;
mod num;
mod observer;
mod params;
mod recorder;
mod svpwm;
mod units;

pub use angle::{Angle, SinCos, sin_cos};
pub use control::{
    CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput, FluxConfig,
    FluxController, FluxDesign, LightLoad, LightLoadConfig, LowSpeedConfig, Pi, PiConfig, PiOutput,
    SpeedConfig, SpeedController, SpeedDesign, SpeedOutput,
};
pub use cordic::{Polar, polar};
pub use deadtime::{CurrentSource, DeadTimeConfig, DeadTimeDesign, DeadTimeMode, DeviceParams};
#[cfg(feature = "injection")]
pub use drive::InjectionFigures;
pub use drive::{
    ACTIVE_SHORT, DEFAULT_HEALTH_LIMIT_PU, Drive, DriveConfig, DriveDesign, DriveInput, DriveIsr,
    DriveOptions, DriveOutput, DriveState, DriveTask, Fault, Handoff, MAX_PWM_DELAY_SAMPLES,
    OpenLoopDesign, Protection, SpeedRefLimit, StartupMode, TASK_PERIOD, Telemetry,
};
pub use drive::{
    DistortionDesign, DistortionFrozen, DistortionLearner, DistortionStatus, Frozen,
    ModelCoefficients, TRACKER_STAGES, Tracker, TrackerDesign, TrackerInput, TrackerStatus,
};
pub use error::{ConfigError, Fit};
pub use frames::{Abc, AlphaBeta, Dq, clarke, inverse_clarke, inverse_park, park, rotate};
pub use hal::{DutyCyclePwm, PhaseCurrentSampler, PwmErrors, ThreePhasePwm, apply, control_step};
pub use identify::{
    Identified, Identify, IdentifyConfig, IdentifyDesign, IdentifyError, IdentifyOutput, Stage,
};
pub use image::{IMAGE_MAGIC, ImageError};
pub use ipd::{Ipd, IpdConfig, IpdDesign, IpdFault, IpdOutput, IpdResult};
pub use num::{PU_FRAC, Pu, UNIT_FRAC, Unit, mul, mul_unit, pu_from_f64};
#[cfg(feature = "injection")]
pub use observer::PolarityReport;
pub use observer::injection::MIN_SALIENCY as INJECTION_MIN_SALIENCY;
pub use observer::{
    AnyEstimator, Ao, AoConfig, Estimate, Estimator, EstimatorConfig, EstimatorKind,
    InjectionDesign, MrasCurrent, MrasCurrentConfig, MrasCurrentGains, MrasEmf, MrasEmfConfig,
    MrasModel, Nlo, NloConfig, ObserverInput, default_observer_gain,
};
pub use params::{InverterParams, MotorParams, ParamError, ParamReason};
pub use recorder::{FaultRecorder, FaultSample};
pub use svpwm::{Duties, SvpwmConfig, SvpwmOutput};
pub use units::{PerUnit, to_f64};

/// The constants the defaults are designed with (thresholds, time constants, margins, the
/// speed loop's forms), each documented where it is defined: for tools, tests and whoever
/// tunes the design. A firmware needs none of them.
pub mod tuning {
    pub use crate::control::{
        IP_FORM, LIGHT_LOAD_BANDS, LIGHT_LOAD_FILTER_S, LIGHT_LOAD_MAX_PER_LIMIT,
        LIGHT_LOAD_RAISED_PER_LIMIT, LOW_SPEED_FADE_PER_RATED, PI_FORM, SPEED_CAP_PER_BASE,
        SPEED_LOOP_DECIMATION,
    };
    pub use crate::deadtime::MEASURED_SIGN_BANDS;
    pub use crate::drive::{
        AUTO_SALIENCY_MARGIN, MIN_OPEN_LOOP_RAMP_S, OVERSPEED_FACTOR, RECTIFY_GRACE_S,
        SPEED_FILTER_S, SPEED_LOOP_R_ERROR, WRITE_THRESHOLD,
    };
    pub use crate::observer::direction::{
        FLIP_SPEED_PU, THRESHOLD_PU as DIRECTION_THRESHOLD_PU,
        TIME_CONSTANT_S as DIRECTION_TIME_CONSTANT_S,
    };
    pub use crate::observer::emf::MIN_EMF_PU;
    pub use crate::observer::mras_emf::{
        ADAPTATION_BANDWIDTH_TS as MRAS_EMF_ADAPTATION_BANDWIDTH_TS,
        MIN_DAMPING as MRAS_EMF_MIN_DAMPING, MIN_SPEED_PU as MRAS_EMF_MIN_SPEED_PU,
        PAPER_CONSTANTS as MRAS_EMF_PAPER_CONSTANTS,
    };
    pub use crate::observer::{ESTIMATOR_SALIENCY, MAX_GAIN_TS};
    pub use crate::svpwm::OVERMOD_SIX_STEP_REQUEST;
}

/// Double-precision references of fixed-point laws that have a closed form, which the tests
/// bound the drive's integer arithmetic against.
pub mod reference {
    pub use crate::control::{max_speed_f64, mtpa_id_f64, weakening_current_f64};
    pub use crate::svpwm::overmodulate_f64;
}

/// The parameter checks the drive's constructors use, with their typed errors ([`ParamError`]
/// naming the key and the range), for front ends that check their own inputs alike.
pub mod validate {
    pub use crate::params::{in_range, non_negative, positive};
}
