//! `pmsm simulate`: the fixed-point drive of the core against the floating-point plant.
//!
//! Output, one row per control sample: `t_s, speed_ref_rpm, speed_rpm, speed_est_rpm,
//! theta_e_rad, theta_e_est_rad, i_d_a, i_q_a, i_q_ref_a, v_alpha_v, v_beta_v, duty_a, duty_b,
//! duty_c, pwm_on, fault, health, rs_est_ohm, flux_est_wb`. Angles in [−π, π); `i_d`, `i_q` in
//! the true rotor frame; `i_q_ref` and the voltage are the controller's; `health` is the
//! estimator's health figure as the drive's loss-of-lock check filters it (per unit; see
//! `Estimator::health`); `rs_est_ohm`, `flux_est_wb` the drive's R and ψ (tracked with
//! `[control] tracking`, docs/tracking.md).
//!
//! Layout: [`drive`] builds the fixed-point drive from the scenario's motor, `[inverter]` and
//! `[control]`; [`plant`] builds the floating-point plant and injects `[faults]`;
//! [`run_loop`] steps both and collects the rows; [`report`] summarises them on the terminal
//! and [`output`] writes the CSV and SVG files.

pub mod drive;
pub mod output;
pub mod plant;
pub mod report;
pub mod run_loop;
pub mod stats;

pub use drive::{DriveSetup, build_drive};
pub use output::{OUTPUT_COLUMNS, draw, plotted_angle_error};
pub use plant::build_plant;
pub use report::{Phase, current_limit_notice, phases, speed_ref_notice, summary};
pub use run_loop::{Row, Run, Simulation, run_scenario, step_loop, wrap};

use crate::scenario_file;
use anyhow::Result;
use std::path::PathBuf;

/// Arguments of `pmsm simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (TOML).
    #[arg(value_name = "SCENARIO.toml")]
    pub scenario: PathBuf,
    /// One row per control sample (see the module docs for the columns).
    #[arg(long, value_name = "out.csv")]
    pub output: PathBuf,
    /// Also draw speed, angle error and currents to this SVG file (the angle error from when
    /// the estimator runs: none during the detection or alignment; the CSV has both angles of
    /// every sample).
    #[arg(long, value_name = "out.svg")]
    pub plot: Option<PathBuf>,
    /// If the drive trips, write the fault recorder's samples before the fault to this CSV
    /// (the input of `pmsm observe`; see `fault_dump`).
    #[arg(long, value_name = "FILE")]
    pub fault_dump: Option<PathBuf>,
}

/// Runs `pmsm simulate`.
pub fn run(args: &Args) -> Result<()> {
    let sc = scenario_file::read(&args.scenario)?;
    let result = run_scenario(&sc)?;
    output::write_csv(&args.output, &result.rows)?;
    report::print_summary(&sc, &result);
    crate::outln!("  output     {}", args.output.display());
    super::fault_dump::write_if_faulted(
        args.fault_dump.as_deref(),
        &result.recorder,
        &result.rows,
    )?;
    if let Some(path) = &args.plot {
        draw(path, &sc, &result.rows)?;
        crate::outln!("  plot       {}", path.display());
    }
    Ok(())
}
