//! The fixed-point routine against an `f64` reference motor: a locked rotor (exact
//! zero-order-hold R–L response along d and q, per-phase dead-time error), so that the
//! resistance and inductance steps are bounded against known values and the spin, which
//! needs a turning rotor, fails with a typed error naming its step.

use super::*;
use crate::frames::AlphaBeta;
use crate::num::pu_from_f64;

struct LockedRotor {
    r: f64,
    l: [f64; 2],
    v_dead: f64,
    i: [f64; 2],
}

impl LockedRotor {
    /// One sample period with the αβ voltage `v` (V); rotor at θ = 0, so d = α, q = β.
    fn step(&mut self, v: [f64; 2], ts: f64) {
        let ph = [
            self.i[0],
            -0.5 * self.i[0] + 0.866_025_403_784_438_6 * self.i[1],
            -0.5 * self.i[0] - 0.866_025_403_784_438_6 * self.i[1],
        ];
        let e = ph.map(|x| -self.v_dead * x.signum());
        let err = [
            (2.0 * e[0] - e[1] - e[2]) / 3.0,
            (e[1] - e[2]) / 3.0_f64.sqrt(),
        ];
        for k in 0..2 {
            let a = libm::exp(-self.r * ts / self.l[k]);
            let v_ss = (v[k] + err[k]) / self.r;
            self.i[k] = a * self.i[k] + (1.0 - a) * v_ss;
        }
    }
}

fn run(
    motor: &mut LockedRotor,
    limit_a: f64,
    vdc_v: f64,
) -> (Option<Result<Identified, IdentifyError>>, Identify) {
    let inv = InverterParams {
        vdc_v,
        pwm_hz: 16e3,
        dead_time_s: 1e-6,
        current_full_scale_a: 2.5 * limit_a,
    };
    let c = IdentifyConfig::new(4, &inv, limit_a, IdentifyDesign::default()).unwrap();
    let mut id = Identify::new(c);
    let vdc = pu_from_f64(vdc_v / c.voltage_base_v);
    for _ in 0..2_000_000 {
        let i = AlphaBeta {
            alpha: pu_from_f64(motor.i[0] / c.current_base_a),
            beta: pu_from_f64(motor.i[1] / c.current_base_a),
        };
        let o = id.step(i, vdc);
        if let Some(r) = id.poll() {
            return (Some(r), id);
        }
        let v = if o.pwm_on {
            [
                o.v.alpha.to_num::<f64>() * c.voltage_base_v,
                o.v.beta.to_num::<f64>() * c.voltage_base_v,
            ]
        } else {
            [0.0; 2]
        };
        motor.step(v, c.sample_s);
    }
    (None, id)
}

#[test]
fn resistance_and_inductances_against_the_reference() {
    for (r, ld, lq, limit, vdc) in [
        (0.35, 0.5e-3, 0.8e-3, 7.0, 24.0),
        (4.0, 20e-3, 35e-3, 5.0, 540.0),
        (0.08, 0.15e-3, 0.15e-3, 28.0, 48.0),
    ] {
        let mut m = LockedRotor {
            r,
            l: [ld, lq],
            v_dead: 0.016 * vdc,
            i: [0.0; 2],
        };
        let (res, id) = run(&mut m, limit, vdc);
        // The rotor never turns: the spin finds no flux.
        let err = res
            .expect("finished")
            .expect_err("a locked rotor has no EMF");
        assert!(matches!(err.stage(), Stage::Flux | Stage::Inertia), "{err}");
        let (r_id, v0, [ld_id, lq_id]) = id.measured();
        let e = |a: f64, b: f64| (a / b - 1.0).abs();
        assert!(e(r_id, r) < 0.005, "R {r_id} for {r}");
        assert!(e(ld_id, ld) < 0.01, "L_d {ld_id} for {ld}");
        assert!(e(lq_id, lq) < 0.01, "L_q {lq_id} for {lq}");
        // The intercept is the dead-time error along α for signs (+, −, −): (4/3) V_dead.
        assert!(e(v0, 4.0 / 3.0 * m.v_dead) < 0.05, "v0 {v0}");
    }
}

#[test]
fn an_open_motor_is_no_current_at_the_resistance_step() {
    let mut m = LockedRotor {
        r: 1e6,
        l: [1e-3; 2],
        v_dead: 0.0,
        i: [0.0; 2],
    };
    let (res, _) = run(&mut m, 5.0, 48.0);
    assert_eq!(res, Some(Err(IdentifyError::NoCurrent(Stage::Resistance))));
}

#[test]
fn overcurrent_stops_at_once() {
    let inv = InverterParams {
        vdc_v: 48.0,
        pwm_hz: 16e3,
        dead_time_s: 1e-6,
        current_full_scale_a: 10.0,
    };
    let c = IdentifyConfig::new(4, &inv, 4.0, IdentifyDesign::default()).unwrap();
    let mut id = Identify::new(c);
    let big = AlphaBeta {
        alpha: pu_from_f64(2.0),
        beta: pu_from_f64(0.0),
    };
    let o = id.step(big, pu_from_f64(1.7));
    assert!(!o.pwm_on && o.finished);
    assert_eq!(
        id.poll(),
        Some(Err(IdentifyError::OverCurrent(Stage::Resistance)))
    );
    assert_eq!(id.poll(), None);
}

#[test]
fn bad_designs_are_named() {
    let inv = InverterParams {
        vdc_v: 48.0,
        pwm_hz: 16e3,
        dead_time_s: 1e-6,
        current_full_scale_a: 10.0,
    };
    let key = |r: Result<IdentifyConfig, crate::ConfigError>| match r {
        Err(crate::ConfigError::Param(p)) => p.key,
        other => panic!("{other:?}"),
    };
    assert_eq!(
        key(IdentifyConfig::new(0, &inv, 4.0, IdentifyDesign::default())),
        "pole_pairs"
    );
    assert_eq!(
        key(IdentifyConfig::new(
            4,
            &inv,
            40.0,
            IdentifyDesign::default()
        )),
        "current_limit_a"
    );
    let d = IdentifyDesign {
        levels: [0.3, 0.3, 0.5, 0.6],
        ..Default::default()
    };
    assert_eq!(key(IdentifyConfig::new(4, &inv, 4.0, d)), "identify.levels");
}

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig::with_cases(24))]
    /// Whatever the currents and the bus read, the step neither panics nor wraps (the test
    /// profile checks overflow), and the inverter is off once the routine has ended.
    #[test]
    fn any_input_is_safe(seed in 0u64..u64::MAX, vdc in -3.0f64..3.0, scale in 0.0f64..4.0) {
        let inv = InverterParams {
            vdc_v: 48.0,
            pwm_hz: 16e3,
            dead_time_s: 1e-6,
            current_full_scale_a: 10.0,
        };
        let c = IdentifyConfig::new(4, &inv, 4.0, IdentifyDesign::default()).unwrap();
        let mut id = Identify::new(c);
        let mut x = seed | 1;
        for _ in 0..20_000 {
            // xorshift: cheap, deterministic noise.
            x ^= x << 13;
            x ^= x >> 7;
            x ^= x << 17;
            let a = ((x & 0xffff) as f64 / 65536.0 - 0.5) * scale;
            let b = (((x >> 16) & 0xffff) as f64 / 65536.0 - 0.5) * scale;
            let o = id.step(
                AlphaBeta { alpha: pu_from_f64(a), beta: pu_from_f64(b) },
                pu_from_f64(vdc),
            );
            let done = id.poll().is_some();
            if done || o.finished {
                proptest::prop_assert!(!id.step(AlphaBeta::default(), pu_from_f64(vdc)).pwm_on);
                break;
            }
        }
    }
}
