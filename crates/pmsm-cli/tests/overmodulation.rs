//! Overmodulation up to six-step (docs/overmodulation.md) in the closed loop: the speed and the
//! current it gains on motor B at its rated point and on motor C beyond rated speed, and the
//! voltage the estimator is given against the plant's average applied voltage.

use std::f64::consts::TAU;

use pmsm_cli::commands::simulate::stats::{max_speed_off, window};
use pmsm_cli::commands::simulate::{Row, Run, build_drive, build_plant, run_scenario};
use pmsm_core::{Abc, DriveInput, DriveState};

mod common;
use common::example_edited as scenario;

fn no_fault(run: &Run) {
    if let Some(r) = run
        .rows
        .iter()
        .find(|r| matches!(r.state, DriveState::Fault(_)))
    {
        panic!("fault at {} s: {:?}", r.t_s, r.state);
    }
}

fn mean(rows: &[&Row], f: impl Fn(&Row) -> f64) -> f64 {
    rows.iter().map(|r| f(r)).sum::<f64>() / rows.len() as f64
}

/// Speed, current magnitude and rms length of the modulator's vector over the window
/// `[t0, t1]` of `name` edited by `edits`.
fn speed_current_voltage(name: &str, edits: &[(&str, &str)], t0: f64, t1: f64) -> [f64; 3] {
    let run = run_scenario(&scenario(name, edits)).unwrap();
    no_fault(&run);
    let tail = window(&run.rows, t0, t1);
    [
        mean(&tail, |r| r.speed_rpm),
        mean(&tail, |r| r.i_dq_a[0].hypot(r.i_dq_a[1])),
        mean(&tail, |r| r.v_ab_v[0].powi(2) + r.v_ab_v[1].powi(2)).sqrt(),
    ]
}

fn speed_and_current(name: &str, edits: &[(&str, &str)], t0: f64, t1: f64) -> (f64, f64) {
    let [w, i, _] = speed_current_voltage(name, edits, t0, t1);
    (w, i)
}

const OVERMOD: (&str, &str) = (
    "field_weakening = ",
    "overmodulation = true\nfield_weakening = ",
);
const NO_FW: [(&str, &str); 2] = [
    ("mtpa = true", "mtpa = false"),
    ("field_weakening = true", "field_weakening = false"),
];

/// Motor B, 540 V, 4 N·m, 3000 r/min asked: with i_d = 0 the current loops' circle (the
/// dead-time compensation passing on to the hexagon) holds it near 2700 r/min, overmodulation
/// reaches the reference; with field weakening both reach it, overmodulation
/// with at least 10 % less current (less negative i_d).
#[test]
fn motor_b_rated_point() {
    let f = "b-3000rpm-fw.toml";
    let (w0, _) = speed_and_current(f, &NO_FW, 2.5, 3.0);
    let (w1, _) = speed_and_current(f, &[NO_FW[0], NO_FW[1], OVERMOD], 2.5, 3.0);
    let (w2, i2) = speed_and_current(f, &[], 2.5, 3.0);
    let (w3, i3) = speed_and_current(f, &[OVERMOD], 2.5, 3.0);
    println!("motor B, i_d = 0: {w0:.1} r/min, overmodulating {w1:.1} r/min");
    println!(
        "motor B, field weakening: {w2:.1} r/min |i| {i2:.2} A, overmodulating {w3:.1} r/min |i| {i3:.2} A"
    );
    assert!(w0 < 2750.0, "{w0}");
    assert!(w1 > 2980.0, "{w1}");
    assert!(w2 > 2950.0 && w3 > 2990.0, "{w2} {w3}");
    assert!(i3 < 0.9 * i2, "{i3} A vs {i2} A");
}

/// Motor C, 24 V, no load, 3900 r/min asked: with i_d = 0 overmodulation raises the speed the
/// voltage allows by at least 10 %; with field weakening it holds 3900 r/min with at least 15 %
/// less current, the field weakening holding the applied vector's rms length at its margin
/// `15/16` of the hexagon's vertex `2 V_DC/3` (15.0 V) within 1 %.
#[test]
fn motor_c_beyond_rated_speed() {
    let f = "c-24v-fw-3900rpm.toml";
    let (w0, _) = speed_and_current(f, &NO_FW, 1.1, 1.2);
    let (w1, _) = speed_and_current(f, &[NO_FW[0], NO_FW[1], OVERMOD], 1.1, 1.2);
    let (w2, i2) = speed_and_current(f, &[], 1.1, 1.2);
    let [w3, i3, v3] = speed_current_voltage(f, &[OVERMOD], 1.1, 1.2);
    let target = 15.0 / 16.0 * 2.0 / 3.0 * 24.0;
    println!(
        "motor C, field weakening overmodulating: rms |v| {v3:.2} V (15/16 · 2 V_DC/3 = {target:.2} V)"
    );
    assert!((v3 - target).abs() < 0.01 * target, "{v3} V");
    println!("motor C, i_d = 0: {w0:.1} r/min, overmodulating {w1:.1} r/min");
    println!(
        "motor C, field weakening: {w2:.1} r/min |i| {i2:.2} A, overmodulating {w3:.1} r/min |i| {i3:.2} A"
    );
    assert!(w1 > 1.10 * w0, "{w1} vs {w0}");
    assert!(
        (w2 - 3900.0).abs() < 20.0 && (w3 - 3900.0).abs() < 20.0,
        "{w2} {w3}"
    );
    assert!(i3 < 0.85 * i2, "{i3} A vs {i2} A");
}

/// Motor C overmodulating with field weakening, unloaded, at speeds near six-step: the speed
/// holds within 20 r/min of the reference (its swing over the window) and the current stays
/// below the rated peak. At a margin of 31/32 of the vertex the current loops saturated on
/// every vertex and the speed swung by ±90 r/min with current peaks of 60 A at 3800, 3850 and
/// 3950 r/min.
#[test]
fn motor_c_near_six_step_holds() {
    for rpm in [3800.0, 3850.0, 3950.0] {
        let edit = format!("rpm = [0.0, 0.0, {rpm:.1}]");
        let run = run_scenario(&scenario(
            "c-24v-fw-3900rpm.toml",
            &[OVERMOD, ("rpm = [0.0, 0.0, 3900.0]", &edit)],
        ))
        .unwrap();
        no_fault(&run);
        let tail = window(&run.rows, 1.1, 1.2);
        let swing = max_speed_off(&tail, rpm);
        let peak = tail
            .iter()
            .map(|r| r.i_dq_a[0].hypot(r.i_dq_a[1]))
            .fold(0.0, f64::max);
        println!(
            "motor C overmodulating at {rpm} r/min: speed within {swing:.1} r/min, |i| peak {peak:.1} A"
        );
        assert!(swing < 20.0, "{rpm} r/min: swing {swing} r/min");
        assert!(
            peak < 25.0 * std::f64::consts::SQRT_2,
            "{rpm} r/min: peak {peak} A"
        );
    }
}

/// The estimator is given the voltage the inverter applies: motor B at its rated point,
/// overmodulating (legs held at the rails most of the time), averaged inverter with its 2 µs
/// dead time. Over the last second the drive's estimator voltage differs from the plant's
/// period-average applied voltage by at most 0.2 % of the bus on average (measured 0.16 V,
/// 0.03 %) and by less than 5 % of the dead-time error the compensation corrects (10.3 V);
/// more than half of the legs are held at a rail (measured 62 %).
#[test]
fn estimator_sees_the_applied_voltage() {
    // This loop hands the duties to the plant at once: no PWM update delay to compensate.
    let sc = scenario(
        "b-3000rpm-fw.toml",
        &[
            OVERMOD,
            ("model = \"switching\"", "model = \"averaged\""),
            ("[control]", "[control]\npwm_update_delay_periods = 0"),
        ],
    );
    let mut setup = build_drive(&sc).unwrap();
    let mut plant = build_plant(&sc, &setup.inverter).unwrap();
    let base = setup.base;
    let p = setup.model.p();
    let n = (sc.duration_s * setup.sample_hz).round() as usize;
    let (mut i_meas, mut vdc) = ([0.0; 3], sc.inverter.vdc_v);
    let (mut err_sum, mut dt_sum, mut held, mut count) = (0.0, 0.0, 0usize, 0usize);
    setup.drive.start();
    for k in 0..n {
        let t = k as f64 / setup.sample_hz;
        let rpm = sc.speed_ref.at(t);
        setup
            .drive
            .set_speed_ref(base.speed_pu(rpm * TAU / 60.0 * p));
        let input = DriveInput {
            i_abc: Abc {
                a: base.current_pu(i_meas[0]),
                b: base.current_pu(i_meas[1]),
                c: base.current_pu(i_meas[2]),
            },
            vdc: base.voltage_pu(vdc),
        };
        let out = setup.drive.step(&input);
        let duties = out.duties.to_f64();
        if t > 2.0 && out.pwm_on {
            let v = setup.drive.estimator_voltage();
            let v_est = [base.voltage_v(v.alpha), base.voltage_v(v.beta)];
            let i_true = plant.motor().i_abc();
            let model = plant.inverter().model();
            let applied = model.averaged_alpha_beta_v(duties, vdc, i_true);
            let ideal = pmsm_plant::InverterModel::ideal_alpha_beta_v(duties, vdc);
            err_sum += (v_est[0] - applied[0]).hypot(v_est[1] - applied[1]);
            dt_sum += (ideal[0] - applied[0]).hypot(ideal[1] - applied[1]);
            held += duties.iter().filter(|d| d.min(1.0 - **d) < 1e-12).count();
            count += 1;
        }
        for _ in 0..setup.pwm_per_sample {
            let s = if out.pwm_on {
                plant.step_pwm(duties, sc.load.at(t))
            } else {
                plant.step_off(sc.load.at(t))
            }
            .unwrap();
            i_meas = s.i_abc_a_measured;
            vdc = s.vdc_v;
        }
    }
    assert!(count > 0, "{:?} at the end", setup.drive.state());
    let (err, dt) = (err_sum / count as f64, dt_sum / count as f64);
    let held_share = held as f64 / (3 * count) as f64;
    println!(
        "estimator voltage vs applied: {err:.2} V mean ({:.2} % of the bus); dead-time error {dt:.2} V; legs held {:.0} %",
        100.0 * err / vdc,
        100.0 * held_share
    );
    assert!(held_share > 0.5, "overmodulating: {held_share}");
    assert!(err < 0.002 * vdc, "{err} V");
    assert!(err < 0.05 * dt, "{err} V vs {dt} V");
}
