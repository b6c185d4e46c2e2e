//! Generated example inputs.
//!
//! `examples/vf-start-a.csv`: the αβ voltages that a float field-oriented controller (with the
//! true rotor angle, 2 kHz) applied to motor A while starting it from standstill to
//! 1000 r/min, with a 5 N·m load from 1.0 s; `load_nm` carries the load. `pmsm plant` replays
//! it open loop and shows the same start.

use anyhow::Result;
use pmsm_cli::motor_file;
use pmsm_plant::Motor;
use std::fmt::Write as _;
use std::path::Path;

/// Control period of the recording, s.
const TS_S: f64 = 0.5e-3;
/// Duration, s.
const DURATION_S: f64 = 1.5;

/// Writes every generated example file.
pub fn write_all(dir: &Path) -> Result<()> {
    let motor = motor_file::read(&dir.join("motor-a.toml"))?;
    let csv = vf_start(&motor.model)?;
    std::fs::write(dir.join("vf-start-a.csv"), csv)?;
    eprintln!("wrote {}", dir.join("vf-start-a.csv").display());
    Ok(())
}

/// Speed reference of the recording, r/min: a ramp to 1000 r/min in 0.6 s.
fn speed_ref_rpm(t: f64) -> f64 {
    1000.0 * (t / 0.6).clamp(0.0, 1.0)
}

fn load_nm(t: f64) -> f64 {
    if t >= 1.0 { 5.0 } else { 0.0 }
}

fn vf_start(model: &pmsm_plant::MotorModel) -> Result<String> {
    let p = &model.params;
    let mut motor = Motor::new(*model, 0.0, 0.0).map_err(|e| anyhow::anyhow!("{e}"))?;
    // Current loops at 200 Hz bandwidth (pole-zero cancellation), speed PI at 10 Hz.
    let wc = 2.0 * std::f64::consts::PI * 200.0;
    let (kp_i, ki_i) = (wc * p.ld_h, wc * p.rs_ohm);
    let ws = 2.0 * std::f64::consts::PI * 10.0;
    let (kp_w, ki_w) = (
        ws * p.j_kg_m2 / p.kt_nm_per_a,
        ws * ws * p.j_kg_m2 / p.kt_nm_per_a / 4.0,
    );
    let (mut int_d, mut int_q, mut int_w) = (0.0, 0.0, 0.0);
    let i_max = 15.0;
    let mut out = String::from("t_s,v_alpha_v,v_beta_v,load_nm\n");
    let rows = (DURATION_S / TS_S).round() as usize;
    for k in 0..=rows {
        let t = k as f64 * TS_S;
        let s = motor.state();
        let th = s.theta_e_rad;
        let [id, iq] = motor.i_dq();
        let w_e = p.p() * s.omega_m_rad_s;
        let err_w = speed_ref_rpm(t) * std::f64::consts::TAU / 60.0 - s.omega_m_rad_s;
        int_w = (int_w + ki_w * err_w * TS_S).clamp(-i_max, i_max);
        let iq_ref = (kp_w * err_w + int_w).clamp(-i_max, i_max);
        let (ed, eq) = (0.0 - id, iq_ref - iq);
        int_d += ki_i * ed * TS_S;
        int_q += ki_i * eq * TS_S;
        let vd = kp_i * ed + int_d - w_e * p.lq_h * iq;
        let vq = kp_i * eq + int_q + w_e * (p.ld_h * id + p.flux_wb);
        // Apply at the mid-period angle, as a PWM modulator would.
        let th_mid = th + 0.5 * w_e * TS_S;
        let (sn, cs) = th_mid.sin_cos();
        let (va, vb) = (vd * cs - vq * sn, vd * sn + vq * cs);
        writeln!(out, "{},{:.6},{:.6},{}", fmt_t(t), va, vb, load_nm(t))?;
        // Replay reads the rounded voltages: integrate exactly those.
        let (va, vb) = (round6(va), round6(vb));
        motor
            .step(va, vb, load_nm(t), TS_S)
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    Ok(out)
}

fn round6(x: f64) -> f64 {
    format!("{x:.6}").parse().unwrap_or(x)
}

fn fmt_t(t: f64) -> String {
    format!("{t:.4}")
}
