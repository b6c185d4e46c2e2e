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
//! | [`identify`] | self-commissioning: R, L_d, L_q, ψ, J and B measured at start-up |
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

pub mod angle;
pub mod control;
pub mod cordic;
pub mod deadtime;
pub mod drive;
pub mod error;
pub mod frames;
pub mod hal;
pub mod identify;
pub mod ipd;
pub mod num;
pub mod observer;
pub mod params;
pub mod svpwm;
pub mod units;

pub use angle::{Angle, SinCos};
pub use error::ConfigError;
pub use frames::{Abc, AlphaBeta, Dq};
pub use identify::{Identified, Identify, IdentifyConfig, IdentifyDesign, IdentifyError};
pub use num::{Pu, Unit};
pub use params::{InverterParams, MotorParams, ParamError};
pub use units::PerUnit;
