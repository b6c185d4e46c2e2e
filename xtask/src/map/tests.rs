//! The map's points on the three motors.

use super::*;

fn case(key: &str) -> &'static Case {
    CASES.iter().find(|c| c.key == key).unwrap()
}

#[test]
fn motor_b_holds_its_rated_point_in_field_weakening() {
    let b = case("b");
    let p = run_point(b, b.rated_rpm, b.rated_nm).unwrap();
    assert_eq!(p.outcome, Outcome::Held, "{p:?}");
    assert!(p.angle_rms_rad < 0.05, "{p:?}");
    assert!(p.speed_err_pct < 2.0, "{p:?}");
    // Beyond the voltage of i_d = 0: weakened, at the circle's 97 % margin.
    assert!(
        p.i_d_a < -1.0 && p.modulation > 0.95 && p.modulation < 1.0,
        "{p:?}"
    );
    // The copper loss is 1.5·R·|i|² of the currents the row reports.
    let expected = 1.5 * 7.2 * p.i_mag_a * p.i_mag_a;
    assert!((p.copper_w / expected - 1.0).abs() < 0.05, "{p:?}");
}

#[test]
fn motor_c_runs_unloaded_at_130_percent() {
    let c = case("c");
    let p = run_point(c, 1.3 * c.rated_rpm, 0.0).unwrap();
    assert_eq!(p.outcome, Outcome::Held, "{p:?}");
    assert!(p.speed_err_pct < 2.0, "{p:?}");
    assert!(p.i_d_a < -10.0, "{p:?}");
}

#[test]
fn references_beyond_the_speed_range_are_refused_with_their_reason() {
    let b = case("b");
    let (max_rpm, min_rpm) = speed_limits_rpm(b).unwrap();
    assert!(min_rpm == 0.0 && max_rpm > 1.3 * b.rated_rpm, "{max_rpm}");
    let p = run_point(b, 1.1 * max_rpm, 0.0).unwrap();
    let Outcome::AboveMax(used) = p.outcome else {
        panic!("{p:?}")
    };
    assert!((used / max_rpm - 1.0).abs() < 0.01, "{used} {max_rpm}");
    assert!(p.speed_err_pct < 5.0, "{p:?}");
    // The NLO cannot hold standstill: held at its least speed, 10 % of rated.
    let a = case("a");
    let p = run_point(a, 0.0, 0.0).unwrap();
    let Outcome::BelowMinimum(held) = p.outcome else {
        panic!("{p:?}")
    };
    assert!((held - 0.1 * a.rated_rpm).abs() < 1.0, "{held}");
    assert!((p.speed_rpm - held).abs() < 0.05 * held, "{p:?}");
}
