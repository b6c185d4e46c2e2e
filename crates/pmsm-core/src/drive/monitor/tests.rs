use super::*;
use crate::drive::{DriveConfig, DriveOptions, TASK_PERIOD};
use crate::fixtures::{inverter_b, motor_b};
use crate::observer::EstimatorKind;

fn config() -> DriveConfig {
    let options = DriveOptions {
        estimator: Some(EstimatorKind::Nlo),
        ..DriveOptions::default()
    };
    DriveConfig::from_params(&motor_b(), &inverter_b(), 14e3, options).unwrap()
}

/// The estimated angle's turn per sample at the speed `omega` (per unit).
fn turn_of(omega: f64) -> Angle {
    let c = config();
    let rad = omega * c.base.omega_e_rad_s * c.base.sample_s;
    Angle((rad / core::f64::consts::TAU * 4_294_967_296.0).round() as i64 as i32)
}

/// A steady closed loop's signals at the estimated speed `omega` (per unit), its angle still
/// (which the angle's check takes as no evidence).
fn steady(omega: f64) -> Signals {
    Signals {
        i_abc: Abc::default(),
        power: [0; 3],
        omega: pu_from_f64(omega),
        omega_mean: pu_from_f64(omega),
        theta_est: Angle::ZERO,
        omega_ref: Pu::ZERO,
        iq_ref: Pu::ZERO,
        running: true,
        health: Pu::ZERO,
        i_ref: Dq::default(),
        i_dq: Dq::default(),
        saturated: false,
    }
}

/// Steps the monitor once per task period with the signals `signals(k)` of its last sample
/// `k` (14 kHz samples); that sample of the first fault.
fn periods(n: u32, signals: impl Fn(u32) -> Signals) -> Option<(u32, Fault)> {
    let c = config();
    let mut m = Monitor::default();
    for w in 0..n / TASK_PERIOD {
        let k = (w + 1) * TASK_PERIOD - 1;
        if let Some(f) = m.check(&c.task.monitor, &signals(k)) {
            return Some((k, f));
        }
    }
    None
}

/// Steps the monitor with `omega(k)` against the reference `omega_ref` at the current
/// reference `iq_ref`; the sample of the first fault.
fn run(omega_ref: f64, iq_ref: f64, omega: impl Fn(u32) -> f64, n: u32) -> Option<(u32, Fault)> {
    periods(n, |k| Signals {
        omega_ref: pu_from_f64(omega_ref),
        iq_ref: pu_from_f64(iq_ref),
        ..steady(omega(k))
    })
}

/// Steps the monitor at a steady 0.5 pu with the current loops `error` (a fraction of the
/// current limit) off their q reference, the modulator limiting or not; the sample of the
/// first fault.
fn tracking(error: f64, saturated: bool, n: u32) -> Option<(u32, Fault)> {
    let c = config();
    let limit = c.design.speed.current_limit_a / c.base.current_a;
    periods(n, |_| Signals {
        omega_ref: pu_from_f64(0.5),
        iq_ref: pu_from_f64(0.2 * limit),
        i_ref: Dq {
            d: Pu::ZERO,
            q: pu_from_f64(0.2 * limit),
        },
        i_dq: Dq {
            d: Pu::ZERO,
            q: pu_from_f64((0.2 - error) * limit),
        },
        saturated,
        ..steady(0.5)
    })
}

/// Phase a holds its bits while b and c change every sample, the estimate at 0.2 pu: the
/// sample of the first fault in the closed loop (`running`) or outside it (an alignment,
/// whose rotor is held still whatever the estimator drifts to).
fn stuck_a(running: bool, n: u32) -> Option<(u32, Fault)> {
    periods(n, |k| {
        let wobble = pu_from_f64(0.001 * f64::from(k % 3));
        Signals {
            i_abc: Abc {
                a: pu_from_f64(0.1),
                b: pu_from_f64(-0.05) + wobble,
                c: pu_from_f64(-0.05) - wobble,
            },
            running,
            ..steady(0.2)
        }
    })
}

#[test]
fn a_stuck_phase_trips_in_the_closed_loop_only() {
    // 50 ms at 14 kHz is 700 samples, counted in steps of eight.
    let (k, f) = stuck_a(true, 2000).expect("a fault");
    assert_eq!(f, Fault::CurrentSensor(Some(0)));
    assert!((700..=720).contains(&k), "{k}");
    assert_eq!(stuck_a(false, 2000), None);
}

#[test]
fn current_loops_that_lose_their_references_trip_loss_of_lock() {
    // Judged from 100 ms (1400 samples at 14 kHz) after entering the closed loop; the
    // 10 ms filter has settled by then.
    let (k, f) = tracking(0.5, false, 3000).expect("a fault");
    assert_eq!(f, Fault::LossOfLock);
    assert!((1400..=1420).contains(&k), "{k}");
    // A third of the limit is the threshold: a quarter never trips, nor any error while the
    // modulator limits the voltage (the loop cannot follow then).
    assert_eq!(tracking(0.25, false, 3000), None);
    assert_eq!(tracking(0.9, true, 3000), None);
}

#[test]
fn a_stall_trips_in_50_ms_and_an_acceleration_at_the_limit_does_not() {
    let c = config();
    let limit = c.design.speed.current_limit_a / c.base.current_a;
    // The motor's largest acceleration in pu/s, from the floor's rise per step of eight
    // samples (1/64 of it).
    let a_max = crate::units::to_f64(c.task.monitor.stall_rise) * 64.0 * 14e3 / 8.0;
    assert!((1.0..20.0).contains(&a_max), "{a_max}");
    // A rotor held at 0.1 pu against a reference of 0.5 pu, the loop at its limit: judged
    // from 100 ms in the closed loop (1400 samples), then 50 ms (700 samples, counted in
    // steps of eight).
    let (k, f) = run(0.5, limit, |_| 0.1, 3000).expect("a fault");
    assert_eq!(f, Fault::Stall);
    assert!((2100..=2120).contains(&k), "{k}");
    // The same backwards (a reference of −0.5 pu).
    let (k, f) = run(-0.5, -limit, |_| -0.1, 3000).expect("a fault");
    assert_eq!(f, Fault::Stall);
    assert!((2100..=2120).contains(&k), "{k}");
    // Falling: a rotor that a load brings to rest.
    let falling = |k: u32| (0.2 - k as f64 / 14e3).max(0.0);
    assert_eq!(
        run(0.5, limit, falling, 3000).map(|x| x.1),
        Some(Fault::Stall)
    );
    // Accelerating at the limit from rest to the reference, at a thirty-second of the
    // largest acceleration (a heavy load) or at all of it, with a ripple of ±0.005 pu:
    // never a stall, however long below half the reference (up to 4 s here).
    for share in [1.0 / 32.0, 1.0] {
        let ramp = move |k: u32| {
            let t = k as f64 / 14e3;
            (share * a_max * t).min(0.5) + 0.005 * libm::sin(3000.0 * t)
        };
        let n = (0.5 / (share * a_max) * 14e3) as u32 + 200;
        assert_eq!(run(0.5, limit, ramp, n), None, "{share}");
    }
    // At a 128th of it: too slow, a stall (50 ms after the ripple falls under the
    // floor).
    let crawl = move |k: u32| {
        let t = k as f64 / 14e3;
        a_max / 128.0 * t + 0.005 * libm::sin(3000.0 * t)
    };
    let (k, f) = run(0.5, limit, crawl, 4000).expect("a fault");
    assert_eq!(f, Fault::Stall);
    assert!(k < 2800, "{k}");
}

#[test]
fn a_rotor_driven_backwards_trips_within_its_time() {
    let c = config();
    let limit = c.design.speed.current_limit_a / c.base.current_a;
    // Motor B's largest acceleration p K_T I_max/J is about 4 pu/s. Pushed forwards at the
    // limit, the rotor turning backwards beyond 0.1 pu and accelerating that way at 1 pu/s
    // (14 000 samples a second): 20 ms (280 samples) of it trips.
    let back = |k: u32| -0.11 - (k as f64) / 14e3;
    let (k, f) = run(0.1, limit, back, 3000).expect("a fault");
    assert_eq!(f, Fault::DrivenBackwards);
    assert!((280..=290).contains(&k), "{k}");
    // The same with the reference and push backwards, the rotor driven forwards.
    let (k, f) = run(-0.1, -limit, |k| -back(k), 3000).expect("a fault");
    assert_eq!(f, Fault::DrivenBackwards);
    assert!((280..=290).contains(&k), "{k}");
    // From rest: the wrong-way speed passes 0.1 pu at sample 1400, and 20 ms of it trips
    // (before the stall check, judged from sample 1400, has counted its 50 ms).
    let (k, f) = run(0.1, limit, |k| -(k as f64) / 14e3, 3000).expect("a fault");
    assert_eq!(f, Fault::DrivenBackwards);
    assert!((1400..=1690).contains(&k), "{k}");
    // Already backwards at a steady 0.5 pu when the loop reaches its limit: 20 ms.
    let (k, f) = run(0.1, limit, |_| -0.5, 3000).expect("a fault");
    assert_eq!(f, Fault::DrivenBackwards);
    assert!(k <= 300, "{k}");
    // Not pushing at the limit: nothing (a loop still in control).
    assert_eq!(run(0.1, 0.5 * limit, back, 3000), None);
    // Healthy reversals at the limit: the wrong-way speed falls from 0.8 pu to 0 at the
    // full deceleration (0.2 s) or at a fifth of it (an overhauling load, 1 s), with a
    // ripple of ±0.03 pu: not driven backwards (the stall check, which knows no sign, may
    // see the slow one's half-speed span).
    for span_s in [0.2, 1.0] {
        let reversal = move |k: u32| {
            let t = k as f64 / 14e3;
            (0.8 * (1.0 - t / span_s)).max(0.0) + 0.03 * libm::sin(2000.0 * t)
        };
        let n = (span_s * 14e3) as u32 + 200;
        let f = run(-0.8, -limit, reversal, n).map(|x| x.1);
        assert_ne!(f, Some(Fault::DrivenBackwards), "{span_s} s");
    }
}

/// The estimated angle turning at `by_angle` while the estimated speed says `omega` (both per
/// unit); the sample of the first fault within `n` samples.
fn against(omega: f64, by_angle: f64, n: u32) -> Option<(u32, Fault)> {
    let turn = turn_of(by_angle);
    periods(n, |k| Signals {
        theta_est: Angle(turn.0.wrapping_mul(k as i32)),
        ..steady(omega)
    })
}

#[test]
fn an_angle_turning_against_the_speed_trips_within_a_quarter_turn() {
    let c = config();
    // Samples for the two speeds' difference to turn the angle a quarter turn away.
    let quarter = |apart: f64| {
        core::f64::consts::FRAC_PI_2 / (apart * c.base.omega_e_rad_s * c.base.sample_s)
    };
    for (omega, by_angle) in [(0.2, -0.2), (-0.1, 0.3), (0.05, -0.05)] {
        let (k, f) = against(omega, by_angle, 20_000).expect("trips");
        assert_eq!(f, Fault::LossOfLock);
        let due = quarter(f64::abs(omega - by_angle));
        assert!(
            (k as f64) <= due + 2.0 * TASK_PERIOD as f64,
            "{omega} against {by_angle}: sample {k}, a quarter turn at {due:.0}"
        );
        assert!(
            (k as f64) >= due - 2.0 * TASK_PERIOD as f64,
            "too early: {k} < {due:.0}"
        );
    }
    // A mirror solution at a tenth of base speed ends within 50 ms.
    let (k, _) = against(0.1, -0.1, 20_000).expect("trips");
    assert!(f64::from(k) * c.base.sample_s < 0.05, "sample {k}");
}

#[test]
fn an_angle_turning_with_the_speed_or_below_the_floor_never_trips() {
    // One second each: the angle with the speed (a lagging or leading estimate too), and
    // the two against each other below 0.03 pu (the jitter about standstill).
    for (omega, by_angle) in [
        (0.2, 0.2),
        (0.5, 0.3),
        (-0.4, -0.6),
        (0.02, -0.02),
        (-0.025, 0.5),
    ] {
        assert_eq!(
            against(omega, by_angle, 14_000),
            None,
            "{omega} / {by_angle}"
        );
    }
    // Above a quarter turn a task period it is not judged: at 5.5 pu (3.2 rad a period) the
    // angle's wrapped turn reads backwards.
    assert_eq!(against(5.5, 5.5, 14_000), None);
    // Out of the closed loop (the open loop's frame is imposed) it is not judged.
    let turn = turn_of(-0.3);
    let out = periods(14_000, |k| Signals {
        theta_est: Angle(turn.0.wrapping_mul(k as i32)),
        running: false,
        ..steady(0.3)
    });
    assert_eq!(out, None);
}

/// At the current limit, the estimate at 0.3 pu from the closed loop's start, falling from
/// sample 2000 at `rate` times the motor's largest acceleration to 0.2 pu, with the health
/// figure `health` (per unit) and the loop's torque along (`sign` 1) or against (−1) the
/// reference of 0.5 pu; the sample of the first fault within `n` samples.
fn slowing(rate: f64, health: f64, sign: f64, n: u32) -> Option<(u32, Fault)> {
    let c = config();
    let limit = c.design.speed.current_limit_a / c.base.current_a;
    let a_max = crate::units::to_f64(c.task.monitor.stall_rise) * 64.0 * 14e3 / 8.0;
    periods(n, |k| {
        let t = f64::from(k.saturating_sub(2000)) / 14e3;
        Signals {
            omega_ref: pu_from_f64(0.5),
            iq_ref: pu_from_f64(sign * limit),
            health: pu_from_f64(health),
            ..steady((0.3 - rate * a_max * t).max(0.2))
        }
    })
}

#[test]
fn an_estimate_slowing_against_the_limits_torque_while_unhealthy_trips_loss_of_lock() {
    // Twice the motor's largest acceleration against its torque: a load of three times the
    // drive's torque, or an estimate that has left the rotor. The 5 ms filter (four task
    // periods of 0.57 ms to the power of two, 4.6 ms) passes the limit within 0.7 of its
    // time constant: 3.2 ms, 45 samples.
    let (k, f) = slowing(2.0, 2.0, 1.0, 2400).expect("a fault");
    assert_eq!(f, Fault::LossOfLock);
    assert!((2020..=2080).contains(&k), "{k}");
    // Not while the estimator explains the currents (a model's error makes a healthy
    // estimate swing about the limit), not at half the full torque's deceleration (a load
    // of 1.5 times the drive's torque), nor slowing along the torque.
    assert_eq!(slowing(2.0, 0.5, 1.0, 2400), None);
    assert_eq!(slowing(0.5, 2.0, 1.0, 2400), None);
    assert_eq!(slowing(2.0, 2.0, -1.0, 2400), None);
}
