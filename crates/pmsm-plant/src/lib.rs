//! Floating-point model of a permanent-magnet synchronous motor, its voltage-source inverter
//! and its phase-current sensing: the "real world" that the fixed-point drive of `pmsm-core`
//! is tested against, on the host and inside an emulator.
//!
//! # Conventions (docs/algorithms.md (conventions))
//!
//! - SI units throughout; every name carries its unit (`_v`, `_a`, `_s`, `_rad_s`, `_h`,
//!   `_wb`, `_nm`, `_j`). Angles and speeds are electrical unless named `_m` (mechanical):
//!   `ω = p ω_m`.
//! - Amplitude-invariant Clarke transform, [`clarke`]: `x_α = (2x_a − x_b − x_c)/3`,
//!   `x_β = (x_b − x_c)/√3`, so the length of an αβ vector is the peak phase value. It drops
//!   the zero sequence, which is what a star-connected motor with an isolated neutral sees.
//! - `θ` is the electrical angle of the rotor d axis (the magnet's north pole) from the α axis;
//!   Park: `x_d = x_α cos θ + x_β sin θ`, `x_q = −x_α sin θ + x_β cos θ`.
//! - Motor convention for powers: `1.5 v·i` is the electrical power into the motor.
//! - The magnet flux `ψ` is the peak flux linkage, V·s/rad electrical; the back-EMF is
//!   `e = ψ ω (−sin θ, cos θ)`.
//!
//! # Models
//!
//! - [`motor`]: the surface motor in αβ (Solsona, Valla, Muravchik (2000) eq. 1–6, docs/solsona2000.md §1, with the 5th
//!   and 7th EMF harmonics) and the interior or saturated motor in dq (Khlaief, Boussak, Gossa (2012) eq. 1–5,
//!   docs/khlaief2012.md §1), with the mechanics of docs/algorithms.md (conventions), integrated by classical RK4.
//! - [`saturation`]: d-axis saturation (docs/khlaief2012.md §1) for the polarity detection.
//! - [`inverter`]: averaged and switching-level inverter with dead time and device drops
//!   (Khlaief, Boussak, Gossa (2012) eq. 7–8, docs/khlaief2012.md §4).
//! - [`sensor`]: the phase-current ADC (quantisation, offset, gain error, noise), sampled at the
//!   PWM centre; [`noise`]: its deterministic random numbers.
//! - [`plant`]: all of it stepped one PWM period at a time.
//! - [`thermal`]: piecewise-linear drift of the true resistance and magnet flux over time.
//!
//! # Example
//!
//! Motor B of Khlaief, Boussak, Gossa (2012) on its 540 V, 14 kHz inverter, one PWM period:
//!
//! ```
//! use pmsm_core::{InverterParams, MotorParams};
//! use pmsm_plant::{AdcParams, InverterKind, InverterModel, Motor, MotorModel, Plant};
//!
//! let mut params = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
//! params.rated_current_a = Some(2.53);
//! // Default d-axis saturation for an interior motor, no EMF harmonics; θ_e = 0, at rest.
//! let motor = Motor::new(MotorModel::new(params), 0.0, 0.0)?;
//! let inverter = InverterParams {
//!     vdc_v: 540.0,
//!     pwm_hz: 14e3,
//!     dead_time_s: 2e-6,
//!     current_full_scale_a: 10.0,
//! };
//! let model = InverterModel::new(inverter, InverterKind::Switching);
//! let mut plant = Plant::new(motor, model, AdcParams::from_inverter(&inverter))?;
//! let sample = plant.step_pwm([0.55, 0.475, 0.475], 0.0)?;
//! assert!(sample.i_abc_a_true[0] > 0.0);
//! # Ok::<(), pmsm_plant::PlantError>(())
//! ```
//!
//! Everything is `no_std` (the `std` feature only matters for host builds), does not allocate,
//! computes its maths with `libm`, and reports bad input as a typed error instead of
//! panicking or propagating NaN.
#![cfg_attr(not(feature = "std"), no_std)]
#![forbid(unsafe_code)]

use core::fmt;

use pmsm_core::ParamError;

pub mod inverter;
pub mod motor;
pub mod noise;
pub mod plant;
pub mod saturation;
pub mod sensor;
pub mod thermal;

pub use inverter::{Inverter, InverterKind, InverterModel};
pub use motor::{Mechanics, Motor, MotorModel, MotorState};
pub use plant::{Injected, Plant, Sample};
pub use saturation::Saturation;
pub use sensor::{AdcParams, CurrentSensor};
pub use thermal::Thermal;

/// Why a plant operation was refused. The model's state is left as it was before the call.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PlantError {
    /// A parameter is missing, not finite or out of range.
    Param(ParamError),
    /// An input (named) is NaN or infinite, or the integration produced a non-finite state
    /// (named `"state"`).
    NonFinite(&'static str),
    /// The step would need more RK4 sub-steps than [`motor::MAX_SUBSTEPS`] (a huge `dt`, or an
    /// inductance driven to zero by deep saturation).
    TooManySubsteps,
}

impl fmt::Display for PlantError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            PlantError::Param(e) => e.fmt(f),
            PlantError::NonFinite(what) => write!(f, "`{what}` is not a finite number"),
            PlantError::TooManySubsteps => {
                write!(
                    f,
                    "step needs more than {} integration sub-steps",
                    motor::MAX_SUBSTEPS
                )
            }
        }
    }
}

impl core::error::Error for PlantError {}

impl From<ParamError> for PlantError {
    fn from(e: ParamError) -> Self {
        PlantError::Param(e)
    }
}

/// `√3/2`.
pub(crate) const SQRT3_2: f64 = 0.866_025_403_784_438_6;
/// `1/√3`.
pub(crate) const FRAC_1_SQRT3: f64 = 0.577_350_269_189_625_8;

/// Amplitude-invariant Clarke transform of phase quantities `[a, b, c]` to `[α, β]`
/// (docs/algorithms.md (conventions)). The zero sequence is discarded.
pub fn clarke(abc: [f64; 3]) -> [f64; 2] {
    [
        (2.0 * abc[0] - abc[1] - abc[2]) / 3.0,
        (abc[1] - abc[2]) * FRAC_1_SQRT3,
    ]
}

/// Inverse amplitude-invariant Clarke transform `[α, β]` to phase quantities `[a, b, c]` with
/// zero sum.
pub fn inverse_clarke(ab: [f64; 2]) -> [f64; 3] {
    [
        ab[0],
        -0.5 * ab[0] + SQRT3_2 * ab[1],
        -0.5 * ab[0] - SQRT3_2 * ab[1],
    ]
}

/// Park transform of `[α, β]` to `[d, q]` at electrical angle `theta_e_rad` (docs/algorithms.md (conventions)).
pub fn park(ab: [f64; 2], theta_e_rad: f64) -> [f64; 2] {
    let (s, c) = libm::sincos(theta_e_rad);
    [ab[0] * c + ab[1] * s, -ab[0] * s + ab[1] * c]
}

/// Inverse Park transform of `[d, q]` to `[α, β]` at electrical angle `theta_e_rad`.
pub fn inverse_park(dq: [f64; 2], theta_e_rad: f64) -> [f64; 2] {
    let (s, c) = libm::sincos(theta_e_rad);
    [dq[0] * c - dq[1] * s, dq[0] * s + dq[1] * c]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn clarke_round_trip_and_amplitude() {
        let th = 0.7_f64;
        let abc = [
            2.0 * libm::cos(th),
            2.0 * libm::cos(th - 2.0 * core::f64::consts::PI / 3.0),
            2.0 * libm::cos(th + 2.0 * core::f64::consts::PI / 3.0),
        ];
        let ab = clarke(abc);
        // Amplitude invariant: a balanced 2 A peak set is a 2 A vector at angle θ.
        assert!((ab[0] - 2.0 * libm::cos(th)).abs() < 1e-12);
        assert!((ab[1] - 2.0 * libm::sin(th)).abs() < 1e-12);
        let back = inverse_clarke(ab);
        for k in 0..3 {
            assert!((back[k] - abc[k]).abs() < 1e-12);
        }
        let dq = park(ab, th);
        assert!((dq[0] - 2.0).abs() < 1e-12 && dq[1].abs() < 1e-12);
        let ab2 = inverse_park(dq, th);
        assert!((ab2[0] - ab[0]).abs() < 1e-12 && (ab2[1] - ab[1]).abs() < 1e-12);
    }
}
