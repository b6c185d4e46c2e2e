//! Motor B of Khlaief, Boussak, Gossa (2012) and its inverter, the parameters most tests and
//! examples run on (with the feature `fixtures`, and in the crate's own unit tests).

use crate::params::{InverterParams, MotorParams};
use crate::units::PerUnit;

/// Motor B: 1.1 kW interior PMSM, `p = 3`, `R = 7.2 Ω`, `L_d = 25.025 mH`, `L_q = 40.17 mH`,
/// `ψ = 0.305 Wb`, `J = 0.0036 kg·m²`, `B = 0.0011 N·m·s`, rated 2.53 A and 3000 r/min
/// (`examples/motor-b.toml`).
pub fn motor_b() -> MotorParams {
    let mut m = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
    m.rated_current_a = Some(2.53);
    m.rated_speed_rpm = Some(3000.0);
    m
}

/// Motor B's inverter: 540 V bus, SVPWM at 14 kHz, 2 µs dead time, ±10 A current sensing.
pub fn inverter_b() -> InverterParams {
    InverterParams {
        vdc_v: 540.0,
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    }
}

/// Motor B's per-unit bases, sampled at the PWM rate of [`inverter_b`].
#[allow(clippy::expect_used)]
pub fn base_b() -> PerUnit {
    let inv = inverter_b();
    PerUnit::new(&motor_b(), &inv, inv.pwm_hz).expect("motor B fits the per-unit envelope")
}
