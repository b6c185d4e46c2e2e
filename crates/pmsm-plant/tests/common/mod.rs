//! Motors A and B and their inverters (examples/motor-a.toml, motor-b.toml), shared by the integration tests.
#![allow(dead_code)]

use pmsm_core::MotorParams;

/// Motor A (Solsona, Valla, Muravchik (2000), surface) with the paper's K_T = 1.108 N·m/A.
pub fn motor_a() -> MotorParams {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    m.rated_speed_rpm = Some(1200.0);
    m
}

#[allow(unused_imports)] // not every test binary uses both
pub use pmsm_core::fixtures::{inverter_b, motor_b};

/// Relative difference `|a − b| / |b|`.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}
