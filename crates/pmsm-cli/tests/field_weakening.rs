//! The torque–speed plane (docs/field-weakening.md): MTPA on an interior motor, field weakening
//! by voltage feedback on motor B at its rated point, on a 24 V interior motor beyond rated
//! speed and on a surface motor under a back-EMF estimator, the speed reference clamped to the
//! maximum speed, and the overspeed trip into the active short circuit. Each runs the shipped
//! scenario through `pmsm simulate`'s own code.

use pmsm_cli::commands::simulate::stats::{self, rms_angle, speed_err, window};
use pmsm_cli::commands::simulate::{Row, Run, build_drive, run_scenario};
use pmsm_core::{DriveState, Fault, FluxDesign};

mod common;
use common::example_edited as scenario;

fn first_fault(run: &Run) -> Option<(f64, DriveState)> {
    stats::first_fault(&run.rows).map(|r| (r.t_s, r.state))
}

fn no_fault(run: &Run) {
    if let Some((t, s)) = first_fault(run) {
        panic!("fault at {t} s: {s:?}");
    }
}

fn mean(rows: &[&Row], f: impl Fn(&Row) -> f64) -> f64 {
    rows.iter().map(|r| f(r)).sum::<f64>() / rows.len() as f64
}

/// Motor B at its rated point (3000 r/min, 4 N·m, 540 V): at least 2950 r/min with the
/// drive's defaults (MTPA and field weakening on: the scenario's keys for them taken out),
/// where i_d = 0 settles far below.
#[test]
fn motor_b_reaches_rated_speed_under_rated_load() {
    let sc = scenario(
        "b-3000rpm-fw.toml",
        &[("mtpa = true\n", ""), ("field_weakening = true\n", "")],
    );
    assert_eq!(build_drive(&sc).unwrap().config.design.flux, FluxDesign::ON);
    let run = run_scenario(&sc).unwrap();
    no_fault(&run);
    let tail = window(&run.rows, 2.5, 3.0);
    let speed = mean(&tail, |r| r.speed_rpm);
    let id = mean(&tail, |r| r.i_dq_a[0]);
    println!("motor B, field weakening: {speed:.1} r/min, i_d {id:.2} A");
    assert!(speed >= 2950.0, "{speed} r/min");
    assert!(id < -0.5, "field weakening engaged: i_d {id} A");
    let off = run_scenario(&scenario(
        "b-3000rpm-fw.toml",
        &[
            ("mtpa = true", "mtpa = false"),
            ("field_weakening = true", "field_weakening = false"),
        ],
    ))
    .unwrap();
    let speed_off = mean(&window(&off.rows, 2.5, 3.0), |r| r.speed_rpm);
    println!("motor B, i_d = 0: {speed_off:.1} r/min");
    assert!(speed_off < 2800.0, "{speed_off} r/min");
}

/// Motor C (24 V, EMF at rated speed 1.2 times the bus) at 1.3 times rated speed, no load:
/// within 2 % of the reference, no fault.
#[test]
fn motor_c_beyond_rated_speed() {
    let run = run_scenario(&scenario("c-24v-fw-3900rpm.toml", &[])).unwrap();
    no_fault(&run);
    let tail = window(&run.rows, 1.1, 1.2);
    let speed = mean(&tail, |r| r.speed_rpm);
    let id = mean(&tail, |r| r.i_dq_a[0]);
    println!(
        "motor C at 3900 r/min: {speed:.1} r/min, error {:.3} %, i_d {id:.1} A, angle rms {:.4} rad",
        100.0 * speed_err(&tail),
        rms_angle(&tail)
    );
    assert!((speed - 3900.0).abs() <= 0.02 * 3900.0, "{speed}");
    assert!(speed_err(&tail) <= 0.02);
    assert!(id < -5.0, "field weakening engaged: i_d {id} A");
}

/// Motor C at a third of rated speed with rated torque: MTPA draws at most 95 % of the current
/// of i_d = 0 for the same torque and speed.
#[test]
fn motor_c_mtpa_saves_current() {
    let magnitude = |run: &Run| {
        let tail = window(&run.rows, 1.0, 1.2);
        assert!(speed_err(&tail) <= 0.02, "speed error {}", speed_err(&tail));
        mean(&tail, |r| r.i_dq_a[0].hypot(r.i_dq_a[1]))
    };
    let mtpa = run_scenario(&scenario("c-24v-mtpa-1000rpm.toml", &[])).unwrap();
    no_fault(&mtpa);
    let zero = run_scenario(&scenario(
        "c-24v-mtpa-1000rpm.toml",
        &[("mtpa = true", "mtpa = false")],
    ))
    .unwrap();
    no_fault(&zero);
    let (a, b) = (magnitude(&mtpa), magnitude(&zero));
    println!(
        "motor C, 1000 r/min, 2.81 N·m: |i| {a:.2} A with MTPA, {b:.2} A with i_d = 0 ({:.1} %)",
        100.0 * a / b
    );
    assert!(a <= 0.95 * b, "{a} A vs {b} A");
}

/// A surface motor under the NLO at 1.2 times base speed: field weakening drives i_d negative
/// and the back-EMF estimator stays locked (its model has no i_d term to get wrong).
#[test]
fn nlo_stays_locked_in_field_weakening() {
    let run = run_scenario(&scenario("a-nlo-fw-2300rpm.toml", &[])).unwrap();
    no_fault(&run);
    let tail = window(&run.rows, 3.0, 3.4);
    let id = mean(&tail, |r| r.i_dq_a[0]);
    println!(
        "motor A, NLO, 2300 r/min: speed error {:.3} %, angle rms {:.4} rad, i_d {id:.2} A",
        100.0 * speed_err(&tail),
        rms_angle(&tail)
    );
    assert!(id < -1.0, "field weakening engaged: i_d {id} A");
    assert!(speed_err(&tail) <= 0.02);
    assert!(rms_angle(&tail) <= 0.02, "{} rad", rms_angle(&tail));
}

/// A reference beyond the maximum speed is clamped to it, and the run says so.
#[test]
fn speed_reference_clamped_to_the_maximum_speed() {
    let run = run_scenario(&scenario(
        "c-24v-fw-3900rpm.toml",
        &[("rpm = [0.0, 0.0, 3900.0]", "rpm = [0.0, 0.0, 20000.0]")],
    ))
    .unwrap();
    let (t, asked, used) = run.speed_ref_limited.expect("the reference was clamped");
    println!("asked {asked:.0} r/min at {t:.3} s, used {used:.0} r/min");
    // Motor C: ψ/L_d is above I_max, so the maximum speed is the documented cap, four times
    // the base speed V_b/ψ (2500 r/min).
    assert!((used - 10_000.0).abs() < 10.0, "{used}");
    assert!(asked > used);
}

/// A rotor spun beyond the speed where its EMF passes the bus, under a drive started at rest
/// on it (the known angle, not the speed): the drive never leaves the EMF rectifying into the
/// bus. Its estimator, started at zero speed, does not lock on; the drive ends either in
/// `Overspeed` and the active short (pwm on, every duty 0; the currents near ψ/L_d, the rotor
/// braked), when its estimate passes the overspeed limit first, or in `LossOfLock` with the
/// rotor already braked below that speed by the current limit, outputs off, and no current
/// beyond a tenth of ψ/L_d. Which comes first turns on the rounding of the lost estimate.
#[test]
fn overspeed_trips_into_the_active_short_circuit() {
    let run = run_scenario(&scenario("c-24v-overspeed.toml", &[])).unwrap();
    let (t, state) = first_fault(&run).expect("tripped");
    let after: Vec<&Row> = run.rows.iter().filter(|r| r.t_s > t + 0.02).collect();
    // ψ/L_d = 44.1 A for motor C; its EMF's line peak reaches the 24 V bus at 2500 r/min.
    let i_sc = 0.01323 / 0.0003;
    let peak = after.iter().map(|r| r.i_peak_a).fold(0.0, f64::max);
    let (v0, v1) = (after[0].speed_rpm, after.last().unwrap().speed_rpm);
    println!(
        "{state:?} at {t:.4} s: peak current {peak:.1} A (ψ/L_d {i_sc:.1} A), {v0:.0} → {v1:.0} r/min"
    );
    match state {
        DriveState::Fault(Fault::Overspeed(_)) => {
            assert!(
                after
                    .iter()
                    .all(|r| r.pwm_on && r.duties.iter().all(|d| d.abs() < 1e-12))
            );
            assert!(peak <= 1.2 * i_sc, "{peak} A");
            assert!(v1 < 0.8 * v0, "the short circuit brakes: {v0} → {v1}");
        }
        DriveState::Fault(Fault::LossOfLock) => {
            assert!(after.iter().all(|r| !r.pwm_on));
            assert!(v0 < 2500.0, "{v0} r/min");
            assert!(peak <= 0.1 * i_sc, "{peak} A");
        }
        other => panic!("{other:?}"),
    }
}
