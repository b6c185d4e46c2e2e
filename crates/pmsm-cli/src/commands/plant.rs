//! `pmsm plant`: integrate the motor model under a voltage sequence.
//!
//! Input CSV: `t_s, v_alpha_v, v_beta_v [, load_nm]`; the voltage (and load) of row k is held
//! over `[t_k, t_k+1)`. Output row k is the state at `t_k`:
//! `t_s, i_alpha_a, i_beta_a, theta_e_rad, omega_m_rad_s`, where `theta_e_rad` is continuous
//! (not wrapped) from `--theta0-deg`.

use crate::{csv_io, motor_file, plot};
use anyhow::{Result, bail};
use pmsm_plant::Motor;
use std::path::PathBuf;

/// Arguments of `pmsm plant`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Motor file (TOML).
    #[arg(long, value_name = "M.toml")]
    pub motor: PathBuf,
    /// Voltage sequence: t_s, v_alpha_v, v_beta_v [, load_nm].
    #[arg(long, value_name = "v.csv")]
    pub input: PathBuf,
    /// State at each input time: t_s, i_alpha_a, i_beta_a, theta_e_rad, omega_m_rad_s.
    #[arg(long, value_name = "out.csv")]
    pub output: PathBuf,
    /// Initial electrical angle of the rotor d axis, degrees.
    #[arg(
        long,
        value_name = "X",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub theta0_deg: f64,
    /// Initial mechanical speed, r/min.
    #[arg(
        long,
        value_name = "N",
        default_value_t = 0.0,
        allow_negative_numbers = true
    )]
    pub speed0_rpm: f64,
    /// Also draw currents, speed and angle to this SVG file.
    #[arg(long, value_name = "out.svg")]
    pub plot: Option<PathBuf>,
}

/// The output columns, in order.
pub const OUTPUT_COLUMNS: [&str; 5] = [
    "t_s",
    "i_alpha_a",
    "i_beta_a",
    "theta_e_rad",
    "omega_m_rad_s",
];

/// Runs `pmsm plant`.
pub fn run(args: &Args) -> Result<()> {
    for (name, value) in [
        ("--theta0-deg", args.theta0_deg),
        ("--speed0-rpm", args.speed0_rpm),
    ] {
        if !value.is_finite() {
            bail!("{name}: must be a finite number");
        }
    }
    let motor = motor_file::read(&args.motor)?;
    let table = csv_io::read(&args.input, &["t_s", "v_alpha_v", "v_beta_v"], &["load_nm"])?;
    let rows = csv_io::check_time(&table, "t_s")?;
    let t = table.required("t_s")?;
    let va = table.required("v_alpha_v")?;
    let vb = table.required("v_beta_v")?;
    let load = table.column("load_nm");

    let omega0_rad_s = args.speed0_rpm * std::f64::consts::TAU / 60.0;
    let mut plant = Motor::new(motor.model, args.theta0_deg.to_radians(), omega0_rad_s)
        .map_err(|e| anyhow::anyhow!("{}: {e}", args.motor.display()))?;
    let mut out = csv_io::Writer::create(&args.output, &OUTPUT_COLUMNS)?;
    let mut trace: [Vec<f64>; 5] = Default::default();
    for k in 0..rows {
        let s = plant.state();
        let row = [
            t[k],
            s.i_alpha_a,
            s.i_beta_a,
            s.theta_e_rad,
            s.omega_m_rad_s,
        ];
        if row.iter().any(|v| !v.is_finite()) {
            bail!(
                "{}: row {}: the model left the range of finite numbers (input too large?)",
                args.input.display(),
                k.max(1)
            );
        }
        out.row(&row)?;
        for (column, value) in trace.iter_mut().zip(row) {
            column.push(value);
        }
        if k + 1 < rows {
            let load_nm = load.map_or(0.0, |l| l[k]);
            plant
                .step(va[k], vb[k], load_nm, t[k + 1] - t[k])
                .map_err(|e| anyhow::anyhow!("{}: row {}: {e}", args.input.display(), k + 1))?;
        }
    }
    let written = out.finish()?;
    print_summary(&motor, &trace, p_of(&motor), written, args);
    if let Some(path) = &args.plot {
        draw(path, &motor.name, &trace)?;
        crate::outln!("  plot       {}", path.display());
    }
    Ok(())
}

fn p_of(motor: &motor_file::Motor) -> f64 {
    motor.model.params.p()
}

fn print_summary(
    motor: &motor_file::Motor,
    trace: &[Vec<f64>; 5],
    p: f64,
    rows: usize,
    args: &Args,
) {
    let [t, ia, ib, _, wm] = trace;
    let mag: Vec<f64> = ia.iter().zip(ib).map(|(a, b)| a.hypot(*b)).collect();
    let peak = mag.iter().fold(0.0f64, |m, x| m.max(*x));
    // Phase RMS of a balanced set: |i_αβ| / √2, averaged in power.
    let rms = (mag.iter().map(|x| x * x).sum::<f64>() / mag.len().max(1) as f64 / 2.0).sqrt();
    let rpm = |w: f64| w * 60.0 / std::f64::consts::TAU;
    let (wmin, wmax) = wm
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| {
            (a.min(*x), b.max(*x))
        });
    let kind = if motor.model.params.is_surface() {
        "surface"
    } else {
        "interior"
    };
    crate::outln!(
        "pmsm plant: {} ({kind}, {p} pole pairs), {rows} rows, {:.4} .. {:.4} s",
        motor.name,
        t.first().copied().unwrap_or(0.0),
        t.last().copied().unwrap_or(0.0)
    );
    crate::outln!("  current    rms {rms:.3} A per phase, peak {peak:.3} A");
    crate::outln!(
        "  speed      final {:.1} r/min, range {:.1} .. {:.1} r/min",
        rpm(wm.last().copied().unwrap_or(0.0)),
        rpm(wmin),
        rpm(wmax)
    );
    crate::outln!("  output     {}", args.output.display());
}

fn draw(path: &std::path::Path, name: &str, trace: &[Vec<f64>; 5]) -> Result<()> {
    let [t, ia, ib, th, wm] = trace;
    let rpm: Vec<f64> = wm
        .iter()
        .map(|w| w * 60.0 / std::f64::consts::TAU)
        .collect();
    // Park at the true angle: what a field-oriented controller would regulate.
    let (id, iq): (Vec<f64>, Vec<f64>) = ia
        .iter()
        .zip(ib)
        .zip(th)
        .map(|((a, b), th)| {
            let (s, c) = th.sin_cos();
            (a * c + b * s, -a * s + b * c)
        })
        .unzip();
    let series = |label, values| plot::Series { label, values };
    plot::write_svg(
        path,
        &format!("pmsm plant: {name}"),
        t,
        &[
            plot::Panel {
                title: "speed (r/min)",
                series: vec![series("mechanical speed", &rpm)],
            },
            plot::Panel {
                title: "rotor-frame current (A)",
                series: vec![series("i_d", &id), series("i_q", &iq)],
            },
            plot::Panel {
                title: "stator current (A)",
                series: vec![series("i_alpha", ia), series("i_beta", ib)],
            },
        ],
    )
}
