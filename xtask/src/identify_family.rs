//! `cargo xtask identify-family [N] [--seed S]`: the motor identification (docs/identification.md)
//! on the random family of `cargo xtask family` (12–540 V, surface and interior, defaults only),
//! with linear magnetics, the switching inverter and the 12-bit ADC; each motor's errors and
//! the worst against the bars R 3 %, L 5 %, ψ 3 %, J 15 %. Exit status 1 when a bar is missed.

use crate::family::{Motor, family};
use crate::progress;
use anyhow::{Result, bail};
use pmsm_cli::commands::identify::{BARS, errors, identify};
use pmsm_core::{InverterParams, MotorParams};
use pmsm_plant::{InverterKind, MotorModel, Saturation};
use rayon::prelude::*;

/// The errors of one motor's identification, or why it failed.
fn one(m: &Motor) -> Result<[f64; 6]> {
    let mut params = MotorParams::new(
        m.pole_pairs,
        m.rs_ohm,
        m.ld_h,
        m.lq_h,
        m.flux_wb,
        m.j_kg_m2,
        m.b_nm_s,
    );
    params.rated_current_a = Some(m.rated_peak_a / std::f64::consts::SQRT_2);
    let mut model = MotorModel::new(params);
    model.saturation = Saturation::Linear;
    let limit = m.rated_peak_a;
    let inverter = InverterParams {
        vdc_v: m.vdc_v,
        pwm_hz: m.pwm_hz,
        dead_time_s: m.dead_time_s,
        current_full_scale_a: 2.5 * limit,
    };
    let run = identify(
        &model,
        &inverter,
        InverterKind::Switching,
        limit,
        m.theta0_deg,
    )?;
    Ok(errors(&run.identified.motor, &model.params))
}

pub fn main(args: &[String]) -> Result<()> {
    let mut n = 40;
    let mut seed = 1;
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--seed" => match it.next().and_then(|s| s.parse().ok()) {
                Some(s) => seed = s,
                None => bail!("--seed needs a number"),
            },
            x => match x.parse() {
                Ok(k) => n = k,
                Err(_) => bail!("usage: cargo xtask identify-family [N] [--seed S]"),
            },
        }
    }
    let (motors, _) = family(n, seed);
    let bar = progress::bar(n, format!("identify-family {n} --seed {seed}"));
    let identified: Vec<Result<[f64; 6]>> = motors
        .par_iter()
        .map(|m| {
            let e = one(m);
            bar.inc(1);
            e
        })
        .collect();
    drop(bar);
    println!("| motor | R % | L_d % | L_q % | ψ % | J % | B % |\n|---|---|---|---|---|---|---|");
    let mut worst = [0.0f64; 5];
    let mut missed = Vec::new();
    for (m, e) in motors.iter().zip(identified) {
        match e {
            Ok(e) => {
                println!(
                    "| {} | {:+.2} | {:+.2} | {:+.2} | {:+.2} | {:+.2} | {:+.1} |",
                    m.describe(),
                    100.0 * e[0],
                    100.0 * e[1],
                    100.0 * e[2],
                    100.0 * e[3],
                    100.0 * e[4],
                    100.0 * e[5]
                );
                for k in 0..5 {
                    worst[k] = worst[k].max(e[k].abs());
                    if e[k].abs() > BARS[k] {
                        missed.push(format!(
                            "#{} {}: {:+.2} %",
                            m.index,
                            ["R", "L_d", "L_q", "ψ", "J"][k],
                            100.0 * e[k]
                        ));
                    }
                }
            }
            Err(e) => {
                println!("| {} | failed: {e:#} | | | | | |", m.describe());
                missed.push(format!("#{}: {e:#}", m.index));
            }
        }
    }
    println!(
        "\nidentify-family: {n} motors (seed {seed}); worst R {:.2} %, L_d {:.2} %, L_q {:.2} %, ψ {:.2} %, J {:.2} % (bars 3, 5, 5, 3, 15)",
        100.0 * worst[0],
        100.0 * worst[1],
        100.0 * worst[2],
        100.0 * worst[3],
        100.0 * worst[4]
    );
    if !missed.is_empty() {
        bail!("{} missed: {}", missed.len(), missed.join("; "));
    }
    Ok(())
}
