//! `pmsm observe`: run a fixed-point estimator of the core on logged or simulated data.
//!
//! Input CSV, uniformly sampled: `t_s, v_alpha_v, v_beta_v, i_alpha_a, i_beta_a`, and
//! optionally the truth to compare with: `theta_e_rad` and `omega_e_rad_s` (or
//! `omega_m_rad_s`, as `pmsm plant` writes it). Output: `t_s, theta_e_est_rad` (in [−π, π)),
//! `omega_e_est_rad_s` (signed, electrical).
//!
//! The estimator sees, at row k, the current of row k and the mean voltage over
//! `[t_{k−1}, t_k]`: with `--voltage sampled` (default: each row holds instantaneous values,
//! as from a simulation) that is `(v_{k−1} + v_k)/2`; with `--voltage held` (row k's voltage is
//! applied over `[t_k, t_{k+1})`, as `pmsm plant` takes it and a PWM drive logs its command)
//! it is `v_{k−1}`.

use crate::{csv_io, motor_file, plot};
use anyhow::{Result, anyhow, bail};
use pmsm_core::{AlphaBeta, InverterParams, PerUnit};
use pmsm_core::{Ao, AoConfig, Estimator, MrasEmf, MrasEmfConfig, Nlo, NloConfig, ObserverInput};
use std::f64::consts::{PI, TAU};
use std::path::PathBuf;

/// The estimators `pmsm observe` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Observer {
    /// Nonlinear reduced-order observer (seed 000 eq. 15–20).
    Nlo,
    /// Linear reduced-order observer (seed 000 eq. 21–26).
    Ao,
    /// Tomita's MRAS speed estimator on the AO (seed 000 eq. 27–29).
    MrasEmf,
}

/// How a row's voltage relates to its time.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum VoltageTiming {
    /// Instantaneous value at `t_k` (simulation); the interval mean is the trapezoid.
    Sampled,
    /// Held over `[t_k, t_{k+1})` (PWM command, `pmsm plant` input).
    Held,
}

/// Arguments of `pmsm observe`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Motor file (TOML).
    #[arg(long, value_name = "M.toml")]
    pub motor: PathBuf,
    /// Which estimator.
    #[arg(long, value_enum)]
    pub observer: Observer,
    /// Observer gain g, rad/s (for mras-emf: of its AO). Default: 3 × rated electrical speed,
    /// within [100, 0.25/T_s].
    #[arg(long, value_name = "G")]
    pub gain: Option<f64>,
    /// Input: t_s, v_alpha_v, v_beta_v, i_alpha_a, i_beta_a [, theta_e_rad, omega_e_rad_s].
    #[arg(long, value_name = "in.csv")]
    pub input: PathBuf,
    /// Output: t_s, theta_e_est_rad, omega_e_est_rad_s.
    #[arg(long, value_name = "out.csv")]
    pub output: PathBuf,
    /// Timing of the voltage columns.
    #[arg(long, value_enum, default_value_t = VoltageTiming::Sampled)]
    pub voltage: VoltageTiming,
    /// DC bus voltage that sets the per-unit base, V. Default: from the largest voltage in
    /// the data.
    #[arg(long, value_name = "V")]
    pub vdc_v: Option<f64>,
    /// Also draw the estimates (and their errors, when the truth is given) to this SVG file.
    #[arg(long, value_name = "out.svg")]
    pub plot: Option<PathBuf>,
}

/// The output columns, in order.
pub const OUTPUT_COLUMNS: [&str; 3] = ["t_s", "theta_e_est_rad", "omega_e_est_rad_s"];

/// Runs `pmsm observe`.
pub fn run(args: &Args) -> Result<()> {
    let motor = motor_file::read(&args.motor)?;
    let m = motor.model.params;
    let table = csv_io::read(
        &args.input,
        &["t_s", "v_alpha_v", "v_beta_v", "i_alpha_a", "i_beta_a"],
        &["theta_e_rad", "omega_e_rad_s", "omega_m_rad_s"],
    )?;
    let rows = csv_io::check_time(&table, "t_s")?;
    let t = table.required("t_s")?;
    let shown = args.input.display();
    if rows < 2 {
        bail!("{shown}: at least two rows are needed to know the sample rate");
    }
    let first = t[1] - t[0];
    for (k, pair) in t.windows(2).enumerate() {
        let dt = pair[1] - pair[0];
        if (dt - first).abs() > 1e-3 * first {
            bail!(
                "{shown}: row {}, column `t_s`: step {dt} s differs from the first step {first} s (sampling must be uniform)",
                k + 2
            );
        }
    }
    let ts = (t[rows - 1] - t[0]) / (rows - 1) as f64;
    let [va, vb, ia, ib] =
        ["v_alpha_v", "v_beta_v", "i_alpha_a", "i_beta_a"].map(|c| table.required(c));
    let (va, vb, ia, ib) = (va?, vb?, ia?, ib?);

    let max_v = va
        .iter()
        .zip(vb)
        .map(|(a, b)| a.hypot(*b))
        .fold(0.0, f64::max);
    let vdc_v = match args.vdc_v {
        Some(v) if v.is_finite() && v > 0.0 => v,
        Some(v) => bail!("--vdc-v: must be a positive number, not {v}"),
        // V_b = V_DC/√3 at 1.25 × the largest voltage vector of the data.
        None => (1.25 * 3f64.sqrt() * max_v).max(1e-3),
    };
    // No inverter in this command: only the bus voltage matters, for the voltage base.
    let inverter = InverterParams {
        vdc_v,
        pwm_hz: 20e3,
        dead_time_s: 0.0,
        current_full_scale_a: 1.0,
    };
    let base = PerUnit::new(&m, &inverter, 1.0 / ts).map_err(|e| {
        anyhow!(
            "{}: {e} (sample rate {:.1} Hz from `t_s` of {shown}, bus {vdc_v:.1} V)",
            args.motor.display(),
            1.0 / ts
        )
    })?;
    let max_i = ia
        .iter()
        .zip(ib)
        .map(|(a, b)| a.hypot(*b))
        .fold(0.0, f64::max);
    if max_i > 64.0 * base.current_a || max_v > 64.0 * base.voltage_v {
        bail!(
            "{shown}: currents up to {max_i:.3e} A and voltages up to {max_v:.3e} V exceed the fixed-point range \
             for this motor (64 × {:.3} A, 64 × {:.3} V); check the units or `rated_current_a`",
            base.current_a,
            base.voltage_v
        );
    }
    let rated_e = m
        .rated_speed_rpm
        .map_or(base.omega_e_rad_s, |n| n * TAU / 60.0 * m.p());
    let gain = match args.gain {
        Some(g) => g,
        None => (3.0 * rated_e).clamp(100.0, 0.25 / ts),
    };
    let cfg_err = |e: pmsm_core::ConfigError| anyhow!("{}: {e}", args.motor.display());
    let mut estimator: Box<dyn Estimator> = match args.observer {
        Observer::Nlo => Box::new(Nlo::new(NloConfig::new(&m, &base, gain).map_err(cfg_err)?)),
        Observer::Ao => Box::new(Ao::new(AoConfig::new(&m, &base, gain).map_err(cfg_err)?)),
        Observer::MrasEmf => Box::new(MrasEmf::new(
            MrasEmfConfig::paper(&m, &base, gain).map_err(cfg_err)?,
        )),
    };

    let mut out = csv_io::Writer::create(&args.output, &OUTPUT_COLUMNS)?;
    let (mut theta, mut omega) = (Vec::with_capacity(rows), Vec::with_capacity(rows));
    for k in 0..rows {
        let v = match (args.voltage, k.checked_sub(1)) {
            (_, None) => [va[0], vb[0]],
            (VoltageTiming::Sampled, Some(j)) => [0.5 * (va[j] + va[k]), 0.5 * (vb[j] + vb[k])],
            (VoltageTiming::Held, Some(j)) => [va[j], vb[j]],
        };
        let input = ObserverInput {
            i: AlphaBeta {
                alpha: base.current_pu(ia[k]),
                beta: base.current_pu(ib[k]),
            },
            v: AlphaBeta {
                alpha: base.voltage_pu(v[0]),
                beta: base.voltage_pu(v[1]),
            },
        };
        let e = estimator.update(&input);
        let (th, w) = (e.theta.to_rad(), base.speed_rad_s(e.omega));
        out.row(&[t[k], th, w])?;
        theta.push(th);
        omega.push(w);
    }
    out.finish()?;

    let truth_w: Option<Vec<f64>> =
        table
            .column("omega_e_rad_s")
            .map(<[f64]>::to_vec)
            .or_else(|| {
                table
                    .column("omega_m_rad_s")
                    .map(|w| w.iter().map(|x| x * m.p()).collect())
            });
    let truth_th = table.column("theta_e_rad");
    println!(
        "pmsm observe: {:?} (g = {gain} rad/s) on {}, {rows} rows at {:.1} Hz, voltage {:?}",
        args.observer,
        motor.name,
        1.0 / ts,
        args.voltage
    );
    let last = rows - 1;
    println!(
        "  final      θ̂ = {:.4} rad, ω̂ = {:.3} rad/s electrical ({:.1} r/min)",
        theta[last],
        omega[last],
        omega[last] / m.p() * 60.0 / TAU
    );
    // Errors over the last half of the run (after convergence), when the truth is given.
    let half = rows / 2;
    let angle_err: Option<Vec<f64>> = truth_th.map(|th| {
        theta
            .iter()
            .zip(th)
            .map(|(e, x)| (e - x + PI).rem_euclid(TAU) - PI)
            .collect()
    });
    if let Some(err) = &angle_err {
        let tail = &err[half..];
        let rms = (tail.iter().map(|x| x * x).sum::<f64>() / tail.len() as f64).sqrt();
        let max = tail.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        println!(
            "  angle err  second half: rms {:.4}°, max {:.4}°",
            rms.to_degrees(),
            max.to_degrees()
        );
    }
    let speed_err: Option<Vec<f64>> = truth_w
        .as_ref()
        .map(|w| omega.iter().zip(w).map(|(e, x)| e - x).collect());
    if let (Some(err), Some(w)) = (&speed_err, &truth_w) {
        let scale = w.iter().fold(0.0f64, |a, x| a.max(x.abs())).max(1e-9);
        let max = err[half..].iter().fold(0.0f64, |a, x| a.max(x.abs()));
        println!(
            "  speed err  second half: max {:.4} rad/s = {:.4} % of the largest speed",
            max,
            100.0 * max / scale
        );
    }
    println!("  output     {}", args.output.display());
    if let Some(path) = &args.plot {
        let rpm = |w: &[f64]| {
            w.iter()
                .map(|x| x / m.p() * 60.0 / TAU)
                .collect::<Vec<f64>>()
        };
        let est_rpm = rpm(&omega);
        let true_rpm = truth_w.as_deref().map(rpm);
        let mut speed = vec![plot::Series {
            label: "estimated",
            values: &est_rpm,
        }];
        if let Some(w) = &true_rpm {
            speed.push(plot::Series {
                label: "true",
                values: w,
            });
        }
        let mut panels = vec![plot::Panel {
            title: "speed (r/min)",
            series: speed,
        }];
        let deg: Option<Vec<f64>> = angle_err
            .as_ref()
            .map(|e| e.iter().map(|x| x.to_degrees()).collect());
        match &deg {
            Some(d) => panels.push(plot::Panel {
                title: "angle error (°)",
                series: vec![plot::Series {
                    label: "θ̂ − θ",
                    values: d,
                }],
            }),
            None => panels.push(plot::Panel {
                title: "angle (rad)",
                series: vec![plot::Series {
                    label: "θ̂",
                    values: &theta,
                }],
            }),
        }
        plot::write_svg(
            path,
            &format!("pmsm observe: {:?}, g = {gain}", args.observer),
            t,
            &panels,
        )?;
        println!("  plot       {}", path.display());
    }
    Ok(())
}
