//! The PWM update delay of pmsm-stm32's TIM1 (the duties of a sample act one period later,
//! docs/drive.md) in the simulator, and the drive's compensation of it: motor B on the
//! switching inverter with 2 µs dead time, started by the initial position detection, on
//! the current-model MRAS (examples/b-800rpm-load.toml shortened).

use pmsm_cli::commands::simulate::stats::{rms_angle, window};
use pmsm_cli::commands::simulate::{Run, run_scenario};
use pmsm_core::DriveState;

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

/// b-800rpm-load.toml with the plant's delay of one period, compensated by the drive for
/// `compensated` periods, the speed ramp to `rpm` over 0.1–`ramp_end_s`, `load_nm` from
/// `load_s`, for `duration_s`: the rms angle error over `[t0, duration_s)`, rad.
fn loaded_error(
    rpm: f64,
    ramp_end_s: f64,
    load_nm: f64,
    load_s: f64,
    duration_s: f64,
    compensated: u32,
) -> f64 {
    let control = format!(
        "deadtime_compensation = true\npwm_update_delay_periods = 1\npwm_delay_compensation_periods = {compensated}"
    );
    let speed = format!("rpm = [0.0, 0.0, {rpm}]");
    let ramp = format!("t_s = [0.0, 0.1, {ramp_end_s}]");
    let load = format!(
        "t_s = [0.0, {load_s}, {}]\nnm = [0.0, 0.0, {load_nm}]",
        load_s + 0.01
    );
    let duration = format!("duration_s = {duration_s}");
    let sc = scenario(
        "b-800rpm-load.toml",
        &[
            ("duration_s = 2.0", &duration),
            ("deadtime_compensation = true", &control),
            ("t_s = [0.0, 0.1, 0.6]", &ramp),
            ("rpm = [0.0, 0.0, 800.0]", &speed),
            (
                "t_s = [0.0, 1.0, 1.01, 1.6, 1.61]\nnm = [0.0, 0.0, 4.0, 4.0, 0.0]",
                &load,
            ),
        ],
    );
    let run = run_scenario(&sc).unwrap();
    no_fault(&run);
    rms_angle(&window(&run.rows, load_s + 0.2, duration_s))
}

#[test]
fn rated_load_at_800_rpm_with_the_mcu_pwm_delay() {
    // Rated load (4 N·m) from 0.7 s, error over 0.9–1.2 s.
    let with = loaded_error(800.0, 0.6, 4.0, 0.7, 1.2, 1);
    let without = loaded_error(800.0, 0.6, 4.0, 0.7, 1.2, 0);
    println!("800 r/min, rated load, delay 1: {with:.4} rad rms compensated, {without:.4} not");
    assert!(with <= 0.01, "{with} rad");
    // The delay uncompensated turns the voltage a sample late: the error is several times
    // larger.
    assert!(without >= 2.0 * with, "{without} vs {with}");
}

#[test]
fn three_nm_at_2400_rpm_with_the_mcu_pwm_delay() {
    // 3 N·m from 1.0 s at 2400 r/min (reached at 0.8 s), error over 1.2–1.4 s.
    let with = loaded_error(2400.0, 0.8, 3.0, 1.0, 1.4, 1);
    let without = loaded_error(2400.0, 0.8, 3.0, 1.0, 1.4, 0);
    println!("2400 r/min, 3 N·m, delay 1: {with:.4} rad rms compensated, {without:.4} not");
    assert!(with <= 0.02, "{with} rad");
    assert!(without >= 2.0 * with, "{without} vs {with}");
}

#[test]
fn compensation_beyond_what_the_drive_holds_is_refused() {
    let sc = scenario(
        "b-800rpm-load.toml",
        &[(
            "deadtime_compensation = true",
            "deadtime_compensation = true\npwm_delay_compensation_periods = 3",
        )],
    );
    let e = run_scenario(&sc).unwrap_err().to_string();
    assert!(e.contains("pwm_delay_compensation_periods"), "{e}");
}
