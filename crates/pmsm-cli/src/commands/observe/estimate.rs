//! The estimator of `pmsm observe` and its run over the input rows.

use super::input::Samples;
use super::{Args, OUTPUT_COLUMNS, Observer};
use crate::csv_io;
use anyhow::{Result, anyhow};
use pmsm_core::{AlphaBeta, MotorParams, PerUnit};
use pmsm_core::{Ao, AoConfig, Estimator, MrasEmf, MrasEmfConfig, Nlo, NloConfig, ObserverInput};
use std::f64::consts::TAU;

/// `--gain`, or 3 × the rated electrical speed within [100, 0.25/T_s], rad/s.
pub(super) fn observer_gain(gain: Option<f64>, m: &MotorParams, base: &PerUnit, ts: f64) -> f64 {
    let rated_e = m
        .rated_speed_rpm
        .map_or(base.omega_e_rad_s, |n| n * TAU / 60.0 * m.p());
    match gain {
        Some(g) => g,
        None => (3.0 * rated_e).clamp(100.0, 0.25 / ts),
    }
}

/// The estimator `--observer` names, with gain `gain`.
pub(super) fn build_estimator(
    args: &Args,
    m: &MotorParams,
    base: &PerUnit,
    gain: f64,
) -> Result<Box<dyn Estimator>> {
    let cfg_err = |e: pmsm_core::ConfigError| anyhow!("{}: {e}", args.motor.display());
    Ok(match args.observer {
        Observer::Nlo => Box::new(Nlo::new(NloConfig::new(m, base, gain).map_err(cfg_err)?)),
        Observer::Ao => Box::new(Ao::new(AoConfig::new(m, base, gain).map_err(cfg_err)?)),
        Observer::MrasEmf => Box::new(MrasEmf::new(
            MrasEmfConfig::default_for(m, base, gain).map_err(cfg_err)?,
        )),
    })
}

/// The estimates at every row: electrical angle, rad, and speed, rad/s.
pub(super) struct Estimates {
    pub(super) theta: Vec<f64>,
    pub(super) omega: Vec<f64>,
}

/// Runs the estimator over the rows and writes its estimates to `--output`.
pub(super) fn estimate(
    args: &Args,
    data: &Samples,
    base: &PerUnit,
    estimator: &mut dyn Estimator,
) -> Result<Estimates> {
    let mut out = csv_io::Writer::create(&args.output, &OUTPUT_COLUMNS)?;
    let rows = data.rows;
    let (mut theta, mut omega) = (Vec::with_capacity(rows), Vec::with_capacity(rows));
    for k in 0..rows {
        let v = data.interval_voltage(args.voltage, k);
        let input = ObserverInput {
            i: AlphaBeta {
                alpha: base.current_pu(data.ia[k]),
                beta: base.current_pu(data.ib[k]),
            },
            v: AlphaBeta {
                alpha: base.voltage_pu(v[0]),
                beta: base.voltage_pu(v[1]),
            },
        };
        let e = estimator.update(&input);
        let (th, w) = (e.theta.to_rad(), base.speed_rad_s(e.omega));
        out.row(&[data.t[k], th, w])?;
        theta.push(th);
        omega.push(w);
    }
    out.finish()?;
    Ok(Estimates { theta, omega })
}
