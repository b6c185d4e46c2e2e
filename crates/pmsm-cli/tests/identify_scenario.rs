//! The identified motor file used by a scenario (`[control] model_motor`), and the plant's
//! thermal drift (`[thermal]`), through `pmsm simulate`'s own code.

use pmsm_cli::commands::identify::{identify, motor_toml, rel};
use pmsm_cli::commands::simulate::run_scenario;
use pmsm_cli::commands::simulate::stats::{rms_angle, speed_err, window};
use pmsm_cli::motor_file;
use pmsm_cli::scenario_file;
use pmsm_core::DriveState;
use pmsm_core::InverterParams;
use pmsm_plant::InverterKind;
use std::path::{Path, PathBuf};

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
        .canonicalize()
        .unwrap()
}

/// Motor B (linear) from standstill to 800 r/min with rated load, averaged inverter, the
/// drive designed from `model_motor` if given; `extra` appended.
fn scenario_text(model_motor: Option<&Path>, extra: &str) -> String {
    let mut control = String::from(
        "observer = \"mras-current\"\nstartup = \"align\"\ndeadtime_compensation = true\n",
    );
    if let Some(p) = model_motor {
        control += &format!("model_motor = \"{}\"\n", p.display());
    }
    format!(
        "duration_s = 1.5\nmotor = \"{}\"\n\n[inverter]\nvdc_v = 540.0\npwm_hz = 14000.0\n\
         dead_time_s = 2e-6\nmodel = \"averaged\"\n\n[control]\n{control}\n[initial]\n\
         theta_e_deg = 137.0\n\n[speed_ref]\nt_s = [0.0, 0.1, 0.6]\nrpm = [0.0, 0.0, 800.0]\n\n\
         [load]\nt_s = [0.0, 0.9, 0.91]\nnm = [0.0, 0.0, 4.0]\n{extra}",
        example("motor-b-linear.toml").display()
    )
}

fn tmp(name: &str) -> PathBuf {
    std::env::temp_dir().join(format!("pmsm-identify-{}-{name}", std::process::id()))
}

#[test]
fn the_drive_runs_on_the_identified_motor_file() {
    let truth = motor_file::read(&example("motor-b-linear.toml")).unwrap();
    let limit = std::f64::consts::SQRT_2 * 2.53;
    let inverter = InverterParams {
        vdc_v: 540.0,
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 2.5 * limit,
    };
    let run = identify(&truth.model, &inverter, InverterKind::Averaged, limit, 75.0).unwrap();
    let mut m = run.identified.motor;
    m.rated_current_a = truth.model.params.rated_current_a;
    m.rated_speed_rpm = truth.model.params.rated_speed_rpm;
    let identified = tmp("identified.toml");
    std::fs::write(&identified, motor_toml("motor B identified", &m)).unwrap();
    let back = motor_file::read(&identified).unwrap().model.params;
    assert!(rel(back.rs_ohm, 7.2).abs() < 0.03 && rel(back.flux_wb, 0.305).abs() < 0.03);

    let path = tmp("scenario.toml");
    std::fs::write(&path, scenario_text(Some(&identified), "")).unwrap();
    let sc = scenario_file::read(&path).unwrap();
    let model = sc
        .model_motor
        .as_ref()
        .expect("model_motor read")
        .model
        .params;
    assert!(
        rel(model.ld_h, m.ld_h).abs() < 1e-5
            && rel(sc.motor.model.params.ld_h, 0.025025).abs() < 1e-12
    );
    let sim = run_scenario(&sc).unwrap();
    std::fs::remove_file(&path).ok();
    std::fs::remove_file(&identified).ok();
    assert!(
        !sim.rows
            .iter()
            .any(|r| matches!(r.state, DriveState::Fault(_))),
        "faulted"
    );
    let steady = window(&sim.rows, 1.1, 1.5);
    let (angle, speed) = (rms_angle(&steady), speed_err(&steady));
    println!("identified model: rms angle error {angle:.4} rad, speed error {speed:.4}");
    assert!(angle < 0.08, "{angle}");
    assert!(speed < 0.02, "{speed}");
}

#[test]
fn thermal_table_drifts_the_plant() {
    let base = tmp("cold.toml");
    std::fs::write(&base, scenario_text(None, "")).unwrap();
    let hot = tmp("hot.toml");
    std::fs::write(
        &hot,
        scenario_text(
            None,
            "\n[thermal]\nt_s = [0.0, 1.0]\nrs_factor = [1.0, 1.4]\nflux_factor = [1.0, 0.95]\n",
        ),
    )
    .unwrap();
    let sc_cold = scenario_file::read(&base).unwrap();
    let sc_hot = scenario_file::read(&hot).unwrap();
    std::fs::remove_file(&base).ok();
    std::fs::remove_file(&hot).ok();
    let th = sc_hot.thermal.expect("[thermal] read");
    assert_eq!(th.factors_at(2.0), (1.4, 0.95));
    let cold = run_scenario(&sc_cold).unwrap();
    let warm = run_scenario(&sc_hot).unwrap();
    // Same until the drift starts, then the hot plant needs more voltage for the same
    // load (R · i_q up by 40 % of a 7.2 Ω drop, less EMF): the commanded voltages part. Their
    // means over 0.2 s, as the dead time's compensation ripples each by ±3 V.
    let v = |r: &&pmsm_cli::commands::simulate::Row| r.v_ab_v[0].hypot(r.v_ab_v[1]);
    let mean = |rows: &[pmsm_cli::commands::simulate::Row], t0: f64, t1: f64| {
        let w = window(rows, t0, t1);
        w.iter().map(v).sum::<f64>() / w.len().max(1) as f64
    };
    let first = |rows: &[pmsm_cli::commands::simulate::Row]| v(&&rows[0]);
    assert!((first(&cold.rows) - first(&warm.rows)).abs() < 1e-9);
    let (vc, vw) = (mean(&cold.rows, 1.3, 1.5), mean(&warm.rows, 1.3, 1.5));
    println!("mean |v| over 1.3-1.5 s: cold {vc:.2} V, hot {vw:.2} V");
    assert!((vw - vc).abs() > 2.0, "{vc} {vw}");
    let steady = window(&warm.rows, 1.1, 1.5);
    assert!(speed_err(&steady) < 0.03, "{}", speed_err(&steady));
}

#[test]
fn scenario_keys_are_checked() {
    let bad = tmp("bad.toml");
    std::fs::write(
        &bad,
        scenario_text(
            None,
            "\n[thermal]\nt_s = [0.0]\nrs_factor = [9.0]\nflux_factor = [1.0]\n",
        ),
    )
    .unwrap();
    let e = format!("{:#}", scenario_file::read(&bad).unwrap_err());
    assert!(e.contains("thermal.rs_factor"), "{e}");
    std::fs::write(
        &bad,
        scenario_text(Some(Path::new("/nonexistent/m.toml")), ""),
    )
    .unwrap();
    let e = format!("{:#}", scenario_file::read(&bad).unwrap_err());
    assert!(e.contains("control.model_motor"), "{e}");
    std::fs::remove_file(&bad).ok();
}

#[test]
fn the_command_writes_a_motor_file_and_a_plot() {
    let out = tmp("cli.toml");
    let svg = tmp("cli.svg");
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_pmsm"))
        .args(["identify", "--motor"])
        .arg(example("motor-b-linear.toml"))
        .args([
            "--vdc",
            "540",
            "--pwm-hz",
            "14000",
            "--dead-time-s",
            "2e-6",
            "--averaged",
        ])
        .arg("--output")
        .arg(&out)
        .arg("--plot")
        .arg(&svg)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&o.stdout);
    assert!(
        o.status.success(),
        "{stdout} {}",
        String::from_utf8_lossy(&o.stderr)
    );
    assert!(
        stdout.contains("rs_ohm") && stdout.contains('%'),
        "{stdout}"
    );
    let m = motor_file::read(&out).unwrap().model.params;
    assert!(rel(m.lq_h, 0.04017).abs() < 0.05, "{}", m.lq_h);
    assert_eq!(m.rated_current_a, Some(2.53));
    assert!(std::fs::metadata(&svg).unwrap().len() > 1000);
    // A heavy rotor with too fast a spin: a typed failure naming the step, exit status 1.
    let o = std::process::Command::new(env!("CARGO_BIN_EXE_pmsm"))
        .args(["identify", "--motor"])
        .arg(example("motor-a.toml"))
        .args(["--vdc", "300", "--averaged", "--accel-rad-s2", "2000"])
        .arg("--output")
        .arg(&out)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{stderr}");
    assert!(stderr.contains("flux step"), "{stderr}");
    std::fs::remove_file(&out).ok();
    std::fs::remove_file(&svg).ok();
}
