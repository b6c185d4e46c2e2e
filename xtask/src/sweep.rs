//! A sweep of random healthy scenarios: motors within the envelope, speeds, loads, initial
//! angles; none may fault (`cargo xtask sweep N`; the reliability check of no false trips).

use crate::progress;
use anyhow::{Result, bail};
use pmsm_cli::commands::simulate::run_scenario;
use pmsm_cli::commands::simulate::stats::{first_fault, rms_angle};
use pmsm_cli::scenario_file;
use pmsm_tests::signals::SplitMix;
use rayon::prelude::*;

/// Three interior motors the sweep scales: motor B (540 V), a 24 V drone-class motor and a
/// 48 V servo; (toml body, bus V, PWM Hz, dead time s, rated r/min, rated N·m).
const MOTORS: [(&str, f64, f64, f64, f64, f64); 3] = [
    (
        "pole_pairs = 3\nrs_ohm = 7.2\nld_h = 0.025025\nlq_h = 0.04017\nflux_wb = 0.305\nj_kg_m2 = 0.0036\nb_nm_s = 0.0011\nrated_current_a = 2.53\nrated_speed_rpm = 3000\n",
        540.0,
        14e3,
        2e-6,
        3000.0,
        4.0,
    ),
    (
        "pole_pairs = 4\nrs_ohm = 0.3\nld_h = 0.6e-3\nlq_h = 1.0e-3\nflux_wb = 0.01\nj_kg_m2 = 2e-5\nb_nm_s = 1e-6\nrated_current_a = 5.0\nrated_speed_rpm = 3000\n",
        24.0,
        20e3,
        0.5e-6,
        3000.0,
        0.3,
    ),
    (
        "pole_pairs = 5\nrs_ohm = 0.8\nld_h = 2.0e-3\nlq_h = 3.2e-3\nflux_wb = 0.02\nj_kg_m2 = 1e-4\nb_nm_s = 1e-5\nrated_current_a = 4.0\nrated_speed_rpm = 3000\n",
        48.0,
        20e3,
        0.5e-6,
        3000.0,
        0.8,
    ),
];

/// One scenario of the sweep: its text and what the problem report names.
struct Draw {
    text: String,
    rpm: f64,
    load: f64,
    theta: f64,
}

/// Runs `n` random healthy scenarios over all cores; fails if any faults. The scenarios are
/// drawn in order first, so each is the same however the runs are spread.
pub fn run(n: usize) -> Result<()> {
    let mut rng = SplitMix(2026);
    let dir = std::env::temp_dir().join(format!("pmsm-sweep-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    // XTASK_TRACKING=1: the same scenarios with the tracking of R and ψ (docs/tracking.md).
    let tracking = std::env::var_os("XTASK_TRACKING").is_some();
    let draws: Vec<Draw> = (0..n)
        .map(|k| {
            let (body, vdc, pwm, dt, rated_rpm, rated_nm) = MOTORS[k % MOTORS.len()];
            let rpm = rated_rpm
                * rng.uniform(0.1, 0.6)
                * if rng.uniform(0.0, 1.0) < 0.3 {
                    -1.0
                } else {
                    1.0
                };
            let load = rated_nm * rng.uniform(0.0, 0.8) * rpm.signum();
            let theta = rng.uniform(0.0, 360.0);
            let t_load = rng.uniform(0.8, 1.2);
            let text = format!(
                "duration_s = 1.6\nmotor = {{ {} }}\n[inverter]\nvdc_v = {vdc}\npwm_hz = {pwm}\ndead_time_s = {dt}\n\
                 [control]\nobserver = \"mras-current\"\nstartup = \"ipd\"\ndeadtime_compensation = true\n\
                 tracking = {tracking}\n\
                 [initial]\ntheta_e_deg = {theta}\n[speed_ref]\nt_s = [0.0, 0.2, 0.7]\nrpm = [0.0, 0.0, {rpm}]\n\
                 [load]\nt_s = [0.0, {t_load}, {}]\nnm = [0.0, 0.0, {load}]\n",
                body.trim_end().replace('\n', ", "),
                t_load + 0.01
            );
            Draw {
                text,
                rpm,
                load,
                theta,
            }
        })
        .collect();
    let bar = progress::bar(n, format!("sweep {n}"));
    // Each run: its steady position error (rad rms), speed error (fraction) and problem.
    let runs = draws
        .par_iter()
        .enumerate()
        .map(|(k, d)| {
            let path = dir.join(format!("s{k}.toml"));
            std::fs::write(&path, &d.text)?;
            let sc = scenario_file::read(&path)?;
            let run = run_scenario(&sc)?;
            let tail: Vec<_> = run.rows.iter().filter(|r| r.t_s >= 1.3).collect();
            let rms = rms_angle(&tail);
            let speed = tail
                .iter()
                .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs())
                .sum::<f64>()
                / tail.len() as f64
                / d.rpm.abs();
            let problem = match first_fault(&run.rows) {
                Some(r) => Some(format!("{} at {:.3} s", r.fault(), r.t_s)),
                None if rms > 0.2 || speed > 0.05 => Some(format!(
                    "lost the lock: {rms:.3} rad rms, speed error {:.1} %",
                    100.0 * speed
                )),
                None => None,
            };
            if problem.is_some() {
                std::fs::copy(&path, dir.join(format!("failed-{k}.toml")))?;
            }
            bar.inc(1);
            Ok((rms, speed, problem))
        })
        .collect::<Result<Vec<_>>>()?;
    drop(bar);
    let mut faults = Vec::new();
    let (mut worst_rms, mut worst_speed) = (0.0f64, 0.0f64);
    for (k, (d, (rms, speed, problem))) in draws.iter().zip(runs).enumerate() {
        worst_rms = worst_rms.max(rms);
        worst_speed = worst_speed.max(speed);
        if let Some(p) = problem {
            faults.push(format!(
                "scenario {k} ({:.0} r/min, {:.2} N·m, θ0 {:.0}°): {p}",
                d.rpm, d.load, d.theta
            ));
        }
    }
    println!(
        "sweep: {n} random healthy scenarios, {} faulted or lost the lock; worst steady position error {worst_rms:.4} rad rms, speed error {:.2} %",
        faults.len(),
        100.0 * worst_speed
    );
    for f in &faults {
        println!("  {f}");
    }
    if !faults.is_empty() {
        bail!(
            "{} of {n} healthy scenarios faulted (kept in {})",
            faults.len(),
            dir.display()
        );
    }
    std::fs::remove_dir_all(&dir).ok();
    Ok(())
}
