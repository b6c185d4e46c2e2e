//! Motors and inverter of the two seeds (scenarios.md), shared by the integration tests.
#![allow(dead_code)]

use pmsm_core::{InverterParams, MotorParams};

/// Motor A (seed 000, surface) with the paper's K_T = 1.108 N·m/A.
pub fn motor_a() -> MotorParams {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    m.rated_speed_rpm = Some(1200.0);
    m
}

/// Motor B (seed 001, interior).
pub fn motor_b() -> MotorParams {
    let mut m = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
    m.rated_current_a = Some(2.53);
    m.rated_speed_rpm = Some(3000.0);
    m
}

/// Seed 001's inverter: 540 V, 14 kHz, 2 µs; sensing ±10 A.
pub fn inverter_b() -> InverterParams {
    InverterParams {
        vdc_v: 540.0,
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    }
}

/// Relative difference `|a − b| / |b|`.
pub fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}
