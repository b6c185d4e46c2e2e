//! Unit tests of `ipd`.

use super::*;

fn motor_b() -> (MotorParams, PerUnit) {
    (crate::fixtures::motor_b(), crate::fixtures::base_b())
}

#[test]
fn motor_b_pulses_match_the_seed() {
    let (m, b) = motor_b();
    let c = IpdConfig::new(&m, &b, IpdDesign::default()).unwrap();
    // Khlaief, Boussak, Gossa (2012): 200 µs and 700 µs.
    assert_eq!(c.n_short, 3);
    assert_eq!(c.n_long, 10);
    assert!(c.total_samples() < 14_000 / 2);
}

#[test]
fn sectors_follow_table_2() {
    for (deg, s) in [
        (0.0, 1),
        (59.9, 1),
        (60.1, 2),
        (179.0, 3),
        (181.0, 4),
        (299.0, 5),
        (359.9, 6),
    ] {
        assert_eq!(sector(Angle::from_deg(deg)), s, "{deg}");
    }
    assert!((THIRD_TURN.to_deg() - 120.0).abs() < 1e-6);
    assert!(((-THIRD_TURN).to_deg() + 120.0).abs() < 1e-6);
}

#[test]
fn overcurrent_and_unreachable_peaks() {
    let (m, b) = motor_b();
    let d = IpdDesign {
        long_current_pu: 15.0,
        current_limit_pu: 20.0,
        ..Default::default()
    };
    assert!(matches!(
        IpdConfig::new(&m, &b, d),
        Err(ConfigError::Param(ParamError {
            key: "ipd.long_current_pu",
            ..
        }))
    ));
    let mut ipd = Ipd::new(IpdConfig::new(&m, &b, IpdDesign::default()).unwrap());
    let big = AlphaBeta {
        alpha: Pu::from_num(4),
        beta: Pu::ZERO,
    };
    let out = ipd.step(big, Pu::from_num(1.732));
    assert!(!out.pwm_on);
    assert!(matches!(out.done, Some(Err(IpdFault::OverCurrent(_)))));
    // Stays stopped.
    assert!(!ipd.step(AlphaBeta::default(), Pu::from_num(1.732)).pwm_on);
}
