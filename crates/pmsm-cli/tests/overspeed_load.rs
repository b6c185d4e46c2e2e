//! A load torque that drives the motor beyond the speed where its EMF equals the bus
//! (docs/field-weakening.md §4): the drive ends in `Overspeed` with the active short circuit,
//! whichever check trips first, on motor C (24 V) with and without field weakening and on
//! motor B (540 V). Each runs `pmsm simulate`'s own code on a scenario written here.

use std::f64::consts::{SQRT_2, TAU};

use pmsm_cli::commands::simulate::{Row, Run, run_scenario};
use pmsm_core::{DriveState, Fault};

mod common;
use common::scenario_text;

/// Drive started from standstill at a known angle, accelerated to `rpm` by 0.3 s (motor C) or
/// 0.6 s (motor B), then a load of `load_nm` (negative: driving) from `t_load`.
fn run(motor: &str, vdc: f64, pwm: f64, dt: f64, rpm: f64, load_nm: f64, fw: bool) -> Run {
    let (ramp, t_load, dur) = if motor.contains("motor-b") {
        (0.6, 0.65, 0.9)
    } else {
        (0.3, 0.35, 0.6)
    };
    let text = format!(
        "duration_s = {dur}\nmotor = \"{motor}\"\n[inverter]\nvdc_v = {vdc}\npwm_hz = {pwm}\n\
         dead_time_s = {dt}\nmodel = \"averaged\"\n[control]\nobserver = \"mras-current\"\n\
         startup = \"known\"\ndeadtime_compensation = true\nmtpa = {fw}\nfield_weakening = {fw}\n\
         [initial]\ntheta_e_deg = 0.0\n[speed_ref]\nt_s = [0.0, 0.05, {ramp}]\n\
         rpm = [0.0, 0.0, {rpm}]\n[load]\nt_s = [0.0, {t_load}, {}]\nnm = [0.0, 0.0, {load_nm}]\n",
        t_load + 0.01
    );
    run_scenario(&scenario_text("overspeed", &text)).unwrap()
}

/// Mechanical speed at which the EMF's line peak equals the bus, `ω ψ = V_DC/√3`, r/min.
fn emf_equals_bus_rpm(vdc: f64, psi: f64, p: f64) -> f64 {
    vdc / 3f64.sqrt() / psi / p * 60.0 / TAU
}

struct Outcome {
    /// When the speed first passed the EMF = bus speed, s.
    t_cross: f64,
    /// The first fault and when.
    first: (f64, DriveState),
    /// When the drive entered `Overspeed`, s.
    t_overspeed: f64,
    /// Largest phase current after it, A.
    peak_after_a: f64,
}

fn outcome(run: &Run, emf_rpm: f64) -> Outcome {
    let faulted = |r: &&Row| matches!(r.state, DriveState::Fault(_));
    let first = run.rows.iter().find(faulted).expect("tripped");
    let os = run
        .rows
        .iter()
        .find(|r| matches!(r.state, DriveState::Fault(Fault::Overspeed(_))))
        .expect("ends in overspeed");
    let after: Vec<&Row> = run.rows.iter().filter(|r| r.t_s > os.t_s).collect();
    // Latched: every later sample is the overspeed fault and the active short (pwm on, every
    // duty 0: all low-side switches on).
    for r in &after {
        assert!(
            matches!(r.state, DriveState::Fault(Fault::Overspeed(_))),
            "{:?}",
            r.state
        );
        assert!(
            r.pwm_on && r.duties.iter().all(|d| d.abs() < 1e-12),
            "{r:?}"
        );
    }
    Outcome {
        t_cross: run
            .rows
            .iter()
            .find(|r| r.speed_rpm.abs() > emf_rpm)
            .expect("crossed")
            .t_s,
        first: (first.t_s, first.state),
        t_overspeed: os.t_s,
        peak_after_a: after.iter().map(|r| r.i_peak_a).fold(0.0, f64::max),
    }
}

fn report(name: &str, o: &Outcome, emf_rpm: f64, oc_a: f64) {
    println!(
        "{name}: EMF = bus at {emf_rpm:.0} r/min crossed at {:.4} s; first fault {:?} at {:.4} s; \
         overspeed at {:.4} s ({:+.1} ms from the crossing); peak current after {:.1} A \
         (overcurrent limit {oc_a:.1} A)",
        o.t_cross,
        o.first.1,
        o.first.0,
        o.t_overspeed,
        1e3 * (o.t_overspeed - o.t_cross),
        o.peak_after_a
    );
}

/// Motor C without field weakening at 2000 r/min, then −6 N·m (twice rated torque, more than
/// the drive can brake): the estimate crosses the overspeed threshold first; the trip comes
/// within 30 ms of the EMF reaching the bus (measured 23 ms) and the short-circuit current,
/// about ψ/L_d = 44 A, stays below the 106 A overcurrent limit.
#[test]
fn motor_c_driven_past_the_bus() {
    let emf = emf_equals_bus_rpm(24.0, 0.01323, 4.0);
    let oc = 3.0 * 25.0 * SQRT_2;
    let o = outcome(
        &run("motor-c-24v.toml", 24.0, 20e3, 5e-7, 2000.0, -6.0, false),
        emf,
    );
    report("motor C", &o, emf, oc);
    assert!(matches!(o.first.1, DriveState::Fault(Fault::Overspeed(_))));
    let dt = o.t_overspeed - o.t_cross;
    assert!((0.0..=0.03).contains(&dt), "{dt} s");
    assert!(o.peak_after_a < oc, "{} A", o.peak_after_a);
}

/// The same with field weakening: the drive holds the current well beyond the EMF = bus speed
/// (that is what field weakening is for) until the load out-brakes it and the lock is lost;
/// outputs off, the diodes rectify the EMF into the bus, and within 5 ms of that trip (the
/// freewheeling grace, 3 ms, and the first rectified current) the drive turns to the
/// overspeed fault and the active short; the current stays below the overcurrent limit.
#[test]
fn motor_c_in_field_weakening_driven_past_the_bus() {
    let emf = emf_equals_bus_rpm(24.0, 0.01323, 4.0);
    let oc = 3.0 * 25.0 * SQRT_2;
    let o = outcome(
        &run("motor-c-24v.toml", 24.0, 20e3, 5e-7, 2000.0, -6.0, true),
        emf,
    );
    report("motor C, field weakening", &o, emf, oc);
    assert!(o.first.0 > o.t_cross, "in control past the crossing");
    assert!(
        o.t_overspeed - o.first.0 <= 0.005,
        "{}",
        o.t_overspeed - o.first.0
    );
    assert!(o.peak_after_a < oc, "{} A", o.peak_after_a);
}

/// Motor B (540 V) at 2800 r/min, then −8 N·m (twice rated): braking at the current limit
/// needs `v_d = ω L_q i_q` on top of the EMF, so the current loops lose the current and the
/// overcurrent trip comes just below the EMF = bus speed (3254 r/min); the rotor goes on
/// accelerating, the diodes rectify, and the drive turns to the overspeed fault within 40 ms
/// of the crossing (measured 25 ms). Motor B's short-circuit current ψ/L_d = 12.2 A is above
/// its overcurrent limit (three times rated peak, 10.7 A): the physics, not the drive, sets
/// the current after the short, which stays within 1.5 ψ/L_d (docs/field-weakening.md §4).
#[test]
fn motor_b_driven_past_the_bus() {
    let emf = emf_equals_bus_rpm(540.0, 0.305, 3.0);
    let oc = 3.0 * 2.53 * SQRT_2;
    let i_sc = 0.305 / 0.025025;
    let o = outcome(
        &run("motor-b.toml", 540.0, 14e3, 2e-6, 2800.0, -8.0, false),
        emf,
    );
    report("motor B", &o, emf, oc);
    assert!(
        (o.t_overspeed - o.t_cross).abs() <= 0.04,
        "{}",
        o.t_overspeed - o.t_cross
    );
    assert!(o.peak_after_a < 1.5 * i_sc, "{} A", o.peak_after_a);
}
