//! Fixed-point sensorless field-oriented control of permanent-magnet synchronous motors.
//!
//! `no_std`, no allocation, no floating point on the control path. Configuration is computed
//! once in `f64` from SI parameters ([`params`]) into per-unit fixed-point coefficients
//! ([`units`]); the hot path is integer arithmetic on the formats of [`num`], which saturates
//! instead of wrapping. Angles are wrapping integer turns ([`angle`]).
//!
//! | module | contents |
//! |---|---|
//! | [`num`] | Q formats (`Pu` = Q8.24, `Unit` = Q2.30), rounding, saturating products |
//! | [`angle`] | `Angle` (one turn = 2³²), sin/cos |
//! | [`cordic`] | atan2 and magnitude by CORDIC |
//! | [`frames`] | `Abc`, `AlphaBeta`, `Dq`; Clarke, Park and their inverses |
//! | [`units`] | per-unit bases from motor and inverter, the supported envelope |
//! | [`params`] | motor and inverter parameters (SI) and their validation |
//! | [`observer`] | the `Estimator` interface and the estimators (NLO, AO, MRAS on the EMF, MRAS on the current model) |
//! | [`svpwm`] | space-vector modulation with the circle limit |
//! | [`deadtime`] | dead-time compensation (seed 001 eq. 6–9) |
//! | [`control`] | PI current loops and the IP speed loop, with anti-windup |
//! | [`ipd`] | initial rotor position from voltage pulses, with N/S polarity |
//! | [`drive`] | the drive: state machine and data flow of one control step |
//! | [`hal`] | the narrow hardware traits a board binding implements (PWM, current sampling) |
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
mod drive;
mod error;
#[cfg(any(test, feature = "fixtures"))]
pub mod fixtures;
mod frames;
mod hal;
mod ipd;
mod num;
mod observer;
mod params;
mod sqrt;
mod svpwm;
mod units;

pub use angle::{Angle, SinCos, sin_cos};
pub use control::{
    CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput, Pi, PiConfig,
    PiOutput, SpeedConfig, SpeedController, SpeedDesign, SpeedOutput,
};
pub use cordic::{Polar, polar};
pub use deadtime::{CurrentSource, DeadTimeConfig, DeadTimeDesign, DeadTimeMode, DeviceParams};
pub use drive::{
    Drive, DriveConfig, DriveDesign, DriveInput, DriveOptions, DriveOutput, DriveState, Fault,
    OpenLoopDesign, Protection, StartupMode, Telemetry,
};
pub use error::ConfigError;
pub use frames::{Abc, AlphaBeta, Dq, clarke, inverse_clarke, inverse_park, park, rotate};
pub use hal::{PhaseCurrentSampler, ThreePhasePwm, apply, control_step};
pub use ipd::{Ipd, IpdConfig, IpdDesign, IpdFault, IpdOutput, IpdResult};
pub use num::{PU_FRAC, Pu, UNIT_FRAC, Unit, mul, mul_unit, pu_from_f64};
pub use observer::direction::{
    FLIP_SPEED_PU, THRESHOLD_PU as DIRECTION_THRESHOLD_PU,
    TIME_CONSTANT_S as DIRECTION_TIME_CONSTANT_S,
};
pub use observer::emf::MIN_EMF_PU;
pub use observer::mras_emf::{
    MIN_SPEED_PU as MRAS_EMF_MIN_SPEED_PU, PAPER_CONSTANTS as MRAS_EMF_PAPER_CONSTANTS,
};
pub use observer::{
    AnyEstimator, Ao, AoConfig, Estimate, Estimator, EstimatorConfig, EstimatorKind, MAX_GAIN_TS,
    MrasCurrent, MrasCurrentConfig, MrasCurrentGains, MrasEmf, MrasEmfConfig, Nlo, NloConfig,
    ObserverInput, default_observer_gain,
};
pub use params::{
    InverterParams, MotorParams, ParamError, ParamReason, in_range, non_negative, positive,
};
pub use svpwm::{Duties, SvpwmConfig, SvpwmOutput};
pub use units::{PerUnit, to_f64};
