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
//!
//! Layout: `input` reads and checks the columns and sets the per-unit bases; `estimate`
//! builds the estimator and runs it over the rows; `report` prints and draws the result.

mod estimate;
mod input;
mod report;

use crate::{csv_io, motor_file};
use anyhow::Result;
use estimate::{Estimates, build_estimator, estimate, observer_gain};
use input::{Samples, per_unit_base};
use report::{Truth, draw, print_summary};
use std::path::PathBuf;

/// The estimators `pmsm observe` runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Observer {
    /// Nonlinear reduced-order observer (Solsona, Valla, Muravchik (2000) eq. 15–20).
    Nlo,
    /// Linear reduced-order observer (Solsona, Valla, Muravchik (2000) eq. 21–26).
    Ao,
    /// Tomita's MRAS speed estimator on the AO (Solsona, Valla, Muravchik (2000) eq. 27–29).
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
    let data = Samples::from_table(&table, &args.input)?;
    let base = per_unit_base(args, &m, &data)?;
    let gain = observer_gain(args.gain, &m, &base, data.ts);
    let mut estimator = build_estimator(args, &m, &base, gain)?;
    let est = estimate(args, &data, &base, estimator.as_mut())?;
    let obs = Observation {
        truth: Truth::from_table(&table, &m),
        data,
        gain,
        est,
    };
    print_summary(args, &motor.name, &m, &obs);
    crate::outln!("  output     {}", args.output.display());
    if let Some(path) = &args.plot {
        draw(path, args, &m, &obs)?;
        crate::outln!("  plot       {}", path.display());
    }
    Ok(())
}

/// A run of the estimator on the data, with the truth when given.
struct Observation<'a> {
    data: Samples<'a>,
    /// Observer gain, rad/s.
    gain: f64,
    est: Estimates,
    truth: Truth<'a>,
}
