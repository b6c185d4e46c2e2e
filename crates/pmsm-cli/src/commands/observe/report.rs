//! What `pmsm observe` prints and draws: the final estimate and, when the input has the truth,
//! the errors.

use super::estimate::Estimates;
use super::{Args, Observation};
use crate::csv_io::Table;
use crate::plot;
use anyhow::Result;
use pmsm_core::MotorParams;
use std::f64::consts::{PI, TAU};
use std::path::Path;

/// The truth columns, when the input has them.
pub(super) struct Truth<'a> {
    /// Electrical angle, rad.
    pub(super) theta: Option<&'a [f64]>,
    /// Electrical speed, rad/s (from `omega_m_rad_s` times the pole pairs if need be).
    pub(super) omega: Option<Vec<f64>>,
}

impl<'a> Truth<'a> {
    pub(super) fn from_table(table: &'a Table, m: &MotorParams) -> Self {
        let omega = table
            .column("omega_e_rad_s")
            .map(<[f64]>::to_vec)
            .or_else(|| {
                table
                    .column("omega_m_rad_s")
                    .map(|w| w.iter().map(|x| x * m.p()).collect())
            });
        Self {
            theta: table.column("theta_e_rad"),
            omega,
        }
    }

    /// Estimated minus true angle, wrapped to [−π, π), rad.
    pub(super) fn angle_error(&self, est: &Estimates) -> Option<Vec<f64>> {
        self.theta.map(|th| {
            est.theta
                .iter()
                .zip(th)
                .map(|(e, x)| (e - x + PI).rem_euclid(TAU) - PI)
                .collect()
        })
    }
}

/// Prints the run, the final estimate and, when the truth is given, the errors over the last
/// half of the run (after convergence).
pub(super) fn print_summary(args: &Args, name: &str, m: &MotorParams, obs: &Observation) {
    let (data, est, truth) = (&obs.data, &obs.est, &obs.truth);
    let rows = data.rows;
    crate::outln!(
        "pmsm observe: {:?} (g = {} rad/s) on {name}, {rows} rows at {:.1} Hz, voltage {:?}",
        args.observer,
        obs.gain,
        1.0 / data.ts,
        args.voltage
    );
    let last = rows - 1;
    crate::outln!(
        "  final      θ̂ = {:.4} rad, ω̂ = {:.3} rad/s electrical ({:.1} r/min)",
        est.theta[last],
        est.omega[last],
        est.omega[last] / m.p() * 60.0 / TAU
    );
    let half = rows / 2;
    if let Some(err) = &truth.angle_error(est) {
        let tail = &err[half..];
        let rms = (tail.iter().map(|x| x * x).sum::<f64>() / tail.len() as f64).sqrt();
        let max = tail.iter().fold(0.0f64, |a, x| a.max(x.abs()));
        crate::outln!(
            "  angle err  second half: rms {:.4}°, max {:.4}°",
            rms.to_degrees(),
            max.to_degrees()
        );
    }
    if let Some(w) = &truth.omega {
        let scale = w.iter().fold(0.0f64, |a, x| a.max(x.abs())).max(1e-9);
        let max = est.omega[half..]
            .iter()
            .zip(&w[half..])
            .map(|(e, x)| e - x)
            .fold(0.0f64, |a, x| a.max(x.abs()));
        crate::outln!(
            "  speed err  second half: max {:.4} rad/s = {:.4} % of the largest speed",
            max,
            100.0 * max / scale
        );
    }
}

/// Draws the estimated (and true) speed, and the angle error (or the angle without the truth).
pub(super) fn draw(path: &Path, args: &Args, m: &MotorParams, obs: &Observation) -> Result<()> {
    let (est, truth) = (&obs.est, &obs.truth);
    let rpm = |w: &[f64]| {
        w.iter()
            .map(|x| x / m.p() * 60.0 / TAU)
            .collect::<Vec<f64>>()
    };
    let est_rpm = rpm(&est.omega);
    let true_rpm = truth.omega.as_deref().map(rpm);
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
    let deg: Option<Vec<f64>> = truth
        .angle_error(est)
        .map(|e| e.iter().map(|x| x.to_degrees()).collect());
    panels.push(match &deg {
        Some(d) => plot::Panel {
            title: "angle error (°)",
            series: vec![plot::Series {
                label: "θ̂ − θ",
                values: d,
            }],
        },
        None => plot::Panel {
            title: "angle (rad)",
            series: vec![plot::Series {
                label: "θ̂",
                values: &est.theta,
            }],
        },
    });
    plot::write_svg(
        path,
        &format!("pmsm observe: {:?}, g = {}", args.observer, obs.gain),
        obs.data.t,
        &panels,
    )
}
