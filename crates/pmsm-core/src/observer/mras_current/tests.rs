//! Unit tests of the current-model MRAS.

use super::*;
use crate::angle::Angle;
use crate::error::ConfigError;
use crate::frames::AlphaBeta;
use crate::num::Pu;
use crate::observer::{Estimator, ObserverInput};
use crate::params::{InverterParams, MotorParams};
use crate::units::PerUnit;

fn motor_b() -> (MotorParams, PerUnit) {
    (crate::fixtures::motor_b(), crate::fixtures::base_b())
}

#[test]
fn gains_out_of_range_are_named() {
    let (m, b) = motor_b();
    let mut g = MrasCurrentGains::default_for(&m, &b);
    g.kp = -1.0;
    assert!(matches!(
        MrasCurrentConfig::new(&m, &b, g),
        Err(ConfigError::Gain {
            key: "mras_current.kp",
            ..
        })
    ));
    let mut g = MrasCurrentGains::default_for(&m, &b);
    g.ki = 1e12;
    assert!(matches!(
        MrasCurrentConfig::new(&m, &b, g),
        Err(ConfigError::Gain {
            key: "mras_current.ki",
            ..
        })
    ));
}

fn inverter(vdc_v: f64, full_scale_a: f64) -> InverterParams {
    InverterParams {
        vdc_v,
        pwm_hz: 20e3,
        dead_time_s: 0.5e-6,
        current_full_scale_a: full_scale_a,
    }
}

/// The corners of the motor family of `units` (a drone and an industrial motor, 8–20 kHz)
/// fit every format with the default gains; a motor whose `ψ/L_d` exceeds the offsets'
/// range (32 pu) is a named error, not a wrapped coefficient.
#[test]
fn family_corners_fit_and_too_small_an_inductance_is_named() {
    let mut drone = MotorParams::new(7, 0.02, 0.5e-3, 0.5e-3, 0.002, 2e-5, 1e-6);
    drone.rated_current_a = Some(60.0);
    let mut industrial = MotorParams::new(2, 4.0, 0.040, 0.048, 1.2, 0.01, 0.001);
    industrial.rated_current_a = Some(3.0);
    for hz in [8e3, 10e3, 20e3] {
        for (m, inv) in [
            (drone, inverter(24.0, 150.0)),
            (industrial, inverter(540.0, 10.0)),
        ] {
            let b = PerUnit::new(&m, &inv, hz).unwrap();
            let g = MrasCurrentGains::default_for(&m, &b);
            assert!(MrasCurrentConfig::new(&m, &b, g).is_ok(), "{m:?} {hz}");
        }
    }
    let (mut m, _) = motor_b();
    m.ld_h = 2.5e-3;
    m.lq_h = 4e-3;
    let inv = InverterParams {
        vdc_v: 540.0,
        pwm_hz: 40e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    };
    let b = PerUnit::new(&m, &inv, 40e3).unwrap();
    let g = MrasCurrentGains::default_for(&m, &b);
    assert!(matches!(
        MrasCurrentConfig::new(&m, &b, g),
        Err(ConfigError::Gain { key: "ld_h", .. })
    ));
}

/// Without a proportional gain the integrator stops at the limit (conditional
/// integration) instead of back-calculating; wild inputs still saturate, never panic.
#[test]
fn conditional_integration_without_kp() {
    let (m, b) = motor_b();
    let mut g = MrasCurrentGains::default_for(&m, &b);
    g.kp = 0.0;
    let cfg = MrasCurrentConfig::new(&m, &b, g).unwrap();
    let mut e = MrasCurrent::new(cfg);
    e.reset(Angle::ZERO, cfg.omega_max);
    let wild = ObserverInput {
        i: AlphaBeta {
            alpha: Pu::MIN,
            beta: Pu::MAX,
        },
        v: AlphaBeta {
            alpha: Pu::MAX,
            beta: Pu::MAX,
        },
    };
    for _ in 0..100 {
        let out = e.update(&wild);
        assert!(out.omega.abs() <= cfg.omega_max);
    }
}

#[test]
fn model_at_rest_stays_at_rest_and_reset_seeds() {
    let (m, b) = motor_b();
    let cfg = MrasCurrentConfig::new(&m, &b, MrasCurrentGains::default_for(&m, &b)).unwrap();
    let mut e = MrasCurrent::new(cfg);
    e.reset(Angle::from_deg(30.0), Pu::ZERO);
    for _ in 0..1000 {
        let out = e.update(&ObserverInput::default());
        assert_eq!(out.theta, Angle::from_deg(30.0));
        assert_eq!(out.omega, Pu::ZERO);
    }
    // Wild inputs saturate, never panic.
    let wild = ObserverInput {
        i: AlphaBeta {
            alpha: Pu::MAX,
            beta: Pu::MIN,
        },
        v: AlphaBeta {
            alpha: Pu::MIN,
            beta: Pu::MAX,
        },
    };
    for _ in 0..100 {
        let out = e.update(&wild);
        assert!(out.omega.abs() <= cfg.omega_max);
    }
}
