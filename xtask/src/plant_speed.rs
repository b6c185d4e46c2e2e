//! Speed of the floating-point plant: simulated seconds per wall-clock second.

use anyhow::{Result, anyhow};
use pmsm_cli::motor_file;
use pmsm_core::InverterParams;
use pmsm_plant::{AdcParams, InverterKind, InverterModel, Motor, Plant};
use std::path::Path;
use std::time::Instant;

struct Case {
    name: String,
    simulated_s: f64,
    wall_s: f64,
    substep_us: f64,
}

/// A rotating voltage at 40 Hz electrical on the motor alone, through `Motor::step` at 10 kHz.
fn motor_only(path: &Path) -> Result<Case> {
    let m = motor_file::read(path)?;
    let mut motor = Motor::new(m.model, 0.0, 0.0).map_err(|e| anyhow!("{e}"))?;
    let (dt, n) = (1e-4, 20_000);
    let start = Instant::now();
    for k in 0..n {
        let ph = 2.0 * std::f64::consts::PI * 40.0 * k as f64 * dt;
        motor
            .step(30.0 * ph.cos(), 30.0 * ph.sin(), 0.0, dt)
            .map_err(|e| anyhow!("{e}"))?;
    }
    Ok(Case {
        name: format!("{}: motor only, `Motor::step` at 10 kHz", m.name),
        simulated_s: n as f64 * dt,
        wall_s: start.elapsed().as_secs_f64(),
        substep_us: motor.max_substep_s() * 1e6,
    })
}

/// Motor B on its inverter (540 V, 14 kHz, 2 µs), SVPWM-like sinusoidal duties; `hard`: the
/// hard current sign (`sign_band_a = 0`, the switching model's floating phases).
fn with_inverter(path: &Path, kind: InverterKind, hard: bool) -> Result<Case> {
    let m = motor_file::read(path)?;
    let motor = Motor::new(m.model, 0.0, 0.0).map_err(|e| anyhow!("{e}"))?;
    let inv = InverterParams {
        vdc_v: 540.0,
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        current_full_scale_a: 10.0,
    };
    let mut model = InverterModel::new(inv, kind);
    if hard {
        model.sign_band_a = 0.0;
    }
    let mut plant =
        Plant::new(motor, model, AdcParams::from_inverter(&inv)).map_err(|e| anyhow!("{e}"))?;
    let n = 7_000;
    let start = Instant::now();
    for k in 0..n {
        let ph = 2.0 * std::f64::consts::PI * 20.0 * k as f64 / 14e3;
        let d =
            [0.0, 2.0, 4.0].map(|s: f64| 0.5 + 0.1 * (ph - s * std::f64::consts::PI / 3.0).cos());
        plant.step_pwm(d, 0.0).map_err(|e| anyhow!("{e}"))?;
    }
    Ok(Case {
        name: format!(
            "{}: plant with {kind:?} inverter at 14 kHz{}",
            m.name,
            if hard { ", hard sign" } else { "" }
        ),
        simulated_s: plant.time_s(),
        wall_s: start.elapsed().as_secs_f64(),
        substep_us: plant.motor().max_substep_s() * 1e6,
    })
}

/// The markdown section.
pub fn section() -> Result<String> {
    let ex = super::root().join("examples");
    let cases = [
        motor_only(&ex.join("motor-a.toml"))?,
        motor_only(&ex.join("motor-b.toml"))?,
        with_inverter(&ex.join("motor-b.toml"), InverterKind::Averaged, false)?,
        with_inverter(&ex.join("motor-b.toml"), InverterKind::Switching, false)?,
        with_inverter(&ex.join("motor-b.toml"), InverterKind::Switching, true)?,
    ];
    let mut s = String::from(
        "## Speed of the plant model\n\n\
         Release build, one core of the development machine (2-core VM). RK4 sub-steps of at \
         most the length shown.\n\n\
         | case | simulated (s) | wall (s) | simulated s per wall s | RK4 sub-step (µs) |\n\
         |---|---:|---:|---:|---:|\n",
    );
    for c in cases {
        s.push_str(&format!(
            "| {} | {:.2} | {:.3} | {:.1} | {:.2} |\n",
            c.name,
            c.simulated_s,
            c.wall_s,
            c.simulated_s / c.wall_s,
            c.substep_us
        ));
    }
    s.push('\n');
    Ok(s)
}
