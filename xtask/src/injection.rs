//! `cargo xtask injection [N] [--seeds A-B] [--off]`: the high-frequency injection
//! (docs/injection.md) on the interior motors of the random family (`family/draw.rs`, N
//! motors per seed, default 40, seeds 1–3), defaults but `[control] injection = true`
//! (`--off`: without it, for comparison). Two runs per motor, 2.5 s each, half rated torque
//! applied at 1 s: **standstill** (0 r/min) and **creep** (2 % of rated speed from 0.6 s). A
//! run holds when, over its last second, the angle error is within 0.05 rad rms, the speed
//! within 1 % of rated speed of the reference, and no fault came; it is silent when the
//! estimate slipped a quarter turn without a named fault (`family::judge::slipping`) or the
//! rotor ran 20 % of rated speed off the reference for 0.2 s without one.

use crate::family::{self, judge};
use crate::progress;
use anyhow::{Context, Result, bail};
use pmsm_cli::commands::simulate::{Row, run_scenario};
use pmsm_cli::scenario_file;
use pmsm_core::DriveState;
use rayon::prelude::*;

/// The usage line.
pub const USAGE: &str = "injection [N] [--seeds A-B] [--off]";

/// The two runs of a motor.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Case {
    Standstill,
    Creep,
}

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
enum Outcome {
    Holds(f64),
    Fault(&'static str, f64),
    OutOfBars(f64, f64),
    Silent(f64),
}

/// Runs `cargo xtask injection` with its arguments.
pub fn main(args: &[String]) -> Result<()> {
    let mut n = 40usize;
    let (mut first, mut last) = (1u64, 3u64);
    let mut on = true;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--seeds" => {
                let v = it.next().context("--seeds needs A-B")?;
                let (a, b) = v.split_once('-').context("--seeds A-B")?;
                (first, last) = (a.parse()?, b.parse()?);
            }
            "--off" => on = false,
            x => {
                n = x
                    .parse()
                    .with_context(|| format!("usage: cargo xtask {USAGE}"))?
            }
        }
    }
    if first > last {
        bail!("--seeds {first}-{last}: the first seed comes first");
    }
    let mut motors = Vec::new();
    for seed in first..=last {
        let (family, _) = family::family(n, seed);
        motors.extend(
            family
                .into_iter()
                .filter(|m| m.lq_h >= m.ld_h * pmsm_core::INJECTION_MIN_SALIENCY)
                .map(|m| (seed, m)),
        );
    }
    let jobs: Vec<(usize, Case)> = (0..motors.len())
        .flat_map(|k| [(k, Case::Standstill), (k, Case::Creep)])
        .collect();
    let bar = progress::bar(jobs.len(), "runs");
    let dir = std::env::temp_dir().join(format!("pmsm-injection-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let outcomes: Vec<Result<Outcome>> = jobs
        .par_iter()
        .map(|&(k, case)| {
            let (seed, m) = &motors[k];
            let path = dir.join(format!("s{seed}-m{}-{case:?}.toml", m.index).to_lowercase());
            let r = run_one(m, case, on, &path);
            bar.inc(1);
            r
        })
        .collect();
    let mut tally = [[0usize; 4]; 2];
    let mut lines = Vec::new();
    for (&(k, case), outcome) in jobs.iter().zip(outcomes) {
        let (seed, m) = &motors[k];
        let outcome = outcome?;
        let column = match outcome {
            Outcome::Holds(_) => 0,
            Outcome::Fault(..) => 1,
            Outcome::OutOfBars(..) => 2,
            Outcome::Silent(_) => 3,
        };
        tally[case as usize][column] += 1;
        if column != 0 {
            lines.push(format!(
                "- seed {seed}, {}: {case:?}: {outcome:?}",
                m.describe()
            ));
        }
    }
    println!(
        "injection {}, {} interior motors (L_q/L_d ≥ {}) of seeds {first}–{last} ({n} motors each)\n",
        if on { "on" } else { "off" },
        motors.len(),
        pmsm_core::INJECTION_MIN_SALIENCY
    );
    println!("| run | holds | named fault | out of the bars | silent |");
    println!("|---|--:|--:|--:|--:|");
    for (case, t) in [(Case::Standstill, tally[0]), (Case::Creep, tally[1])] {
        let all = t.iter().sum::<usize>().max(1);
        println!(
            "| {case:?} | {} ({:.0} %) | {} | {} | {} |",
            t[0],
            100.0 * t[0] as f64 / all as f64,
            t[1],
            t[2],
            t[3]
        );
    }
    println!();
    for l in &lines {
        println!("{l}");
    }
    if lines.is_empty() {
        std::fs::remove_dir_all(&dir).ok();
    } else {
        println!(
            "\nthe scenarios of the runs that did not hold: {}",
            dir.display()
        );
    }
    Ok(())
}

/// The scenario of `case` on `m`.
fn scenario_text(m: &family::Motor, case: Case, on: bool) -> String {
    let creep = 0.02 * m.rated_rpm;
    let (t, rpm) = match case {
        Case::Standstill => ("[0.0]", "[0.0]".to_owned()),
        Case::Creep => ("[0.0, 0.3, 0.6]", format!("[0.0, 0.0, {creep}]")),
    };
    let load = 0.5 * m.rated_nm;
    format!(
        "duration_s = 2.5\n{}\
         [control]\ninjection = {on}\n\
         [initial]\ntheta_e_deg = {}\n\
         [speed_ref]\nt_s = {t}\nrpm = {rpm}\n\
         [load]\nt_s = [0.0, 1.0, 1.01]\nnm = [0.0, 0.0, {load}]\n",
        m.hardware_toml(),
        m.theta0_deg,
    )
}

fn run_one(m: &family::Motor, case: Case, on: bool, path: &std::path::Path) -> Result<Outcome> {
    std::fs::write(path, scenario_text(m, case, on))?;
    let sc = scenario_file::read(path)?;
    let run = run_scenario(&sc)?;
    let outcome = judge_run(&run.rows, m);
    if matches!(outcome, Outcome::Holds(_)) {
        std::fs::remove_file(path).ok();
    }
    Ok(outcome)
}

/// The run's outcome (module documentation).
fn judge_run(rows: &[Row], m: &family::Motor) -> Outcome {
    let fault = rows
        .iter()
        .find(|r| matches!(r.state, DriveState::Fault(_)));
    let t_fault = fault.map_or(f64::INFINITY, |r| r.t_s);
    if let Some(t) = judge::slipping(rows, t_fault) {
        return Outcome::Silent(t);
    }
    // Off the reference by a fifth of rated speed for 0.2 s with no fault.
    let mut since = None;
    for r in rows.iter().take_while(|r| r.t_s < t_fault) {
        if (r.speed_rpm - r.speed_ref_rpm).abs() > 0.2 * m.rated_rpm {
            let t0 = *since.get_or_insert(r.t_s);
            if r.t_s - t0 > 0.2 {
                return Outcome::Silent(t0);
            }
        } else {
            since = None;
        }
    }
    if let Some(r) = fault {
        return Outcome::Fault(r.fault(), r.t_s);
    }
    let tail: Vec<&Row> = rows.iter().filter(|r| r.t_s >= 1.5).collect();
    let n = tail.len().max(1) as f64;
    let rms = (tail
        .iter()
        .map(|r| r.angle_error_rad().powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let speed = tail
        .iter()
        .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs())
        .sum::<f64>()
        / n
        / m.rated_rpm;
    if rms <= 0.05 && speed <= 0.01 {
        Outcome::Holds(rms)
    } else {
        Outcome::OutOfBars(speed, rms)
    }
}
