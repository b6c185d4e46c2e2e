//! Fault detection on injected faults (`[faults]` of a scenario), with the time from the
//! fault to the outputs being off; and healthy runs that must never trip.

use pmsm_cli::commands::simulate::{Run, run_scenario};
use pmsm_cli::scenario_file;
use pmsm_core::DriveState;
use std::path::Path;

fn examples() -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .canonicalize()
        .unwrap()
}

/// `b-800rpm-load.toml` (load 4 N·m from 1.0 to 1.6 s) with `faults` appended and `edits`.
fn run_with(faults: &str, edits: &[(&str, &str)]) -> Run {
    let mut text = std::fs::read_to_string(examples().join("b-800rpm-load.toml")).unwrap();
    text = text.replace(
        "motor = \"motor-b.toml\"",
        &format!("motor = \"{}/motor-b.toml\"", examples().display()),
    );
    for (a, b) in edits {
        assert!(text.contains(a));
        text = text.replace(a, b);
    }
    text.push_str("\n[faults]\n");
    text.push_str(faults);
    let path = std::env::temp_dir().join(format!(
        "pmsm-faults-{}-{}.toml",
        std::process::id(),
        text.len()
    ));
    std::fs::write(&path, text).unwrap();
    let sc = scenario_file::read(&path).unwrap();
    std::fs::remove_file(&path).ok();
    run_scenario(&sc).unwrap()
}

/// The first fault after `t0`: its time after `t0` and its name; and that the outputs stay off.
fn detected(run: &Run, t0: f64) -> (f64, &'static str) {
    let first = run
        .rows
        .iter()
        .find(|r| matches!(r.state, DriveState::Fault(_)))
        .expect("no fault detected");
    assert!(
        first.t_s >= t0,
        "tripped before the fault, at {} s: {}",
        first.t_s,
        first.fault()
    );
    assert!(
        run.rows
            .iter()
            .filter(|r| r.t_s > first.t_s)
            .all(|r| !r.pwm_on),
        "outputs back on after the fault"
    );
    (first.t_s - t0, first.fault())
}

#[test]
fn open_phase_is_detected_within_50_ms() {
    // Under load (1.3, 1.45 s: rated load from 1.0 to 1.6 s) and at no load (0.8, 1.8 s: the
    // current is then ripple and friction, a tenth of rated), every phase.
    for (phase, at) in [
        ("a", 1.3),
        ("c", 1.45),
        ("a", 0.8),
        ("b", 0.85),
        ("c", 1.8),
        ("b", 1.9),
        ("a", 0.93),
        ("b", 1.83),
        ("c", 1.71),
        ("a", 1.77),
        ("c", 0.72),
    ] {
        let run = run_with(
            &format!("phase_open = \"{phase}\"\nphase_open_at_s = {at}\n"),
            &[],
        );
        let (dt, name) = detected(&run, at);
        println!(
            "phase {phase} open at {at} s: {name} after {:.1} ms",
            1e3 * dt
        );
        assert!(dt <= 0.05, "{dt}");
    }
}

#[test]
fn locked_rotor_is_detected_within_200_ms() {
    let run = run_with("locked_rotor_at_s = 1.3\n", &[]);
    let (dt, name) = detected(&run, 1.3);
    println!("locked rotor: {name} after {:.1} ms", 1e3 * dt);
    assert!(dt <= 0.2, "{dt}");
}

#[test]
fn stuck_current_sensor_is_detected_within_100_ms() {
    for (phase, at) in [("b", 0.9), ("a", 1.3)] {
        let run = run_with(
            &format!("adc_stuck_phase = \"{phase}\"\nadc_stuck_at_s = {at}\n"),
            &[],
        );
        let (dt, name) = detected(&run, at);
        println!(
            "ADC {phase} stuck at {at} s: {name} after {:.1} ms",
            1e3 * dt
        );
        assert!(dt <= 0.1, "{dt}");
    }
}

#[test]
fn bus_sag_is_detected_within_10_ms() {
    let run = run_with("vdc_sag_at_s = 1.3\nvdc_sag_to_v = 200.0\n", &[]);
    let (dt, name) = detected(&run, 1.3);
    println!("bus sag: {name} after {:.2} ms", 1e3 * dt);
    assert!(dt <= 0.01 && name == "bus_undervoltage");
}

#[test]
fn terminal_short_trips_on_overcurrent() {
    let run = run_with(
        "short_phases = \"ab\"\nshort_at_s = 1.3\nshort_ohm = 1.0\n",
        &[],
    );
    let (dt, name) = detected(&run, 1.3);
    println!("short a–b: {name} after {:.2} ms", 1e3 * dt);
    assert!(dt <= 0.005 && name == "overcurrent");
}

/// The estimator's own health figure (the current-model MRAS's model current error, eq. 16):
/// with the drive's model resistance three times the motor's the estimate drifts away (the
/// angle error passes 1 rad) without any other check tripping; the figure then rises far
/// above its healthy level, and a drive given a limit trips on it.
#[test]
fn health_figure_shows_a_lost_lock() {
    let with = |extra: &str| {
        run_with(
            "",
            &[(
                "deadtime_compensation = true",
                &format!("deadtime_compensation = true\n{extra}"),
            )],
        )
    };
    let max_health = |run: &Run| run.rows.iter().fold(0.0f64, |m, r| m.max(r.health));
    let max_err_after = |run: &Run, t0: f64| {
        run.rows
            .iter()
            .filter(|r| r.t_s > t0 && r.pwm_on)
            .fold(0.0f64, |m, r| m.max(r.angle_error_rad().abs()))
    };
    let healthy = with("health_limit_pu = 0.5");
    assert!(healthy.rows.iter().all(|r| r.fault().is_empty()));
    let h_ok = max_health(&healthy);
    let drifting = with("model_rs_factor = 3.0");
    assert!(drifting.rows.iter().all(|r| r.fault().is_empty()));
    let (h_lost, err_lost) = (max_health(&drifting), max_err_after(&drifting, 0.3));
    let caught = with("model_rs_factor = 3.0\nhealth_limit_pu = 0.5");
    let (dt, name) = detected(&caught, 0.0);
    println!(
        "health: healthy max {h_ok:.3} pu; model R ×3: max {h_lost:.3} pu, angle error up to \
         {err_lost:.2} rad, no trip without a limit; with a 0.5 pu limit {name} at {dt:.3} s"
    );
    assert!(h_ok < 0.1, "{h_ok}");
    assert!(err_lost > 1.0 && h_lost > 0.5, "{err_lost} {h_lost}");
    assert_eq!(name, "loss_of_lock");
    assert!(dt < 0.5, "{dt}");
}
