//! The files a run writes: one CSV row per control sample, and the SVG plot.

use super::Row;
use crate::plot;
use crate::scenario_file::Scenario;
use anyhow::{Context, Result, anyhow, bail};
use pmsm_core::DriveState;
use std::io::Write as _;
use std::path::Path;

/// The output columns, in order.
pub const OUTPUT_COLUMNS: [&str; 19] = [
    "t_s",
    "speed_ref_rpm",
    "speed_rpm",
    "speed_est_rpm",
    "theta_e_rad",
    "theta_e_est_rad",
    "i_d_a",
    "i_q_a",
    "i_q_ref_a",
    "v_alpha_v",
    "v_beta_v",
    "duty_a",
    "duty_b",
    "duty_c",
    "pwm_on",
    "fault",
    "health",
    "rs_est_ohm",
    "flux_est_wb",
];

/// Writes `rows` as CSV with the [`OUTPUT_COLUMNS`]; refuses non-finite values.
pub(super) fn write_csv(path: &Path, rows: &[Row]) -> Result<()> {
    let file = std::fs::File::create(path)
        .with_context(|| format!("{}: cannot create", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let err = |e: std::io::Error| anyhow!("{}: cannot write: {e}", path.display());
    writeln!(w, "{}", OUTPUT_COLUMNS.join(",")).map_err(err)?;
    for r in rows {
        let nums = [
            r.t_s,
            r.speed_ref_rpm,
            r.speed_rpm,
            r.speed_est_rpm,
            r.theta_e_rad,
            r.theta_e_est_rad,
            r.i_dq_a[0],
            r.i_dq_a[1],
            r.i_q_ref_a,
            r.v_ab_v[0],
            r.v_ab_v[1],
            r.duties[0],
            r.duties[1],
            r.duties[2],
        ];
        if nums.iter().any(|x| !x.is_finite()) {
            bail!(
                "{}: t = {} s: refusing to write a non-finite value",
                path.display(),
                r.t_s
            );
        }
        let line: Vec<String> = nums.iter().map(|x| format!("{x}")).collect();
        writeln!(
            w,
            "{},{},{},{},{},{}",
            line.join(","),
            u8::from(r.pwm_on),
            r.fault(),
            r.health,
            r.model_rs_flux[0],
            r.model_rs_flux[1]
        )
        .map_err(err)?;
    }
    w.flush().map_err(err)
}

/// The angle error as the plot shows it: none (NaN, a gap) before the estimator runs (idle,
/// initial position detection, alignment), where the estimate is not yet an estimate of
/// anything; the CSV keeps both angles of every row.
pub fn plotted_angle_error(r: &Row) -> f64 {
    match r.state {
        DriveState::Idle | DriveState::Ipd | DriveState::Align => f64::NAN,
        _ => r.angle_error_rad(),
    }
}

/// Draws speed, angle error (from when the estimator runs) and dq currents of a run to an SVG
/// file.
pub fn draw(path: &Path, sc: &Scenario, rows: &[Row]) -> Result<()> {
    let t: Vec<f64> = rows.iter().map(|r| r.t_s).collect();
    let col = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    let (sref, s, sest) = (
        col(&|r| r.speed_ref_rpm),
        col(&|r| r.speed_rpm),
        col(&|r| r.speed_est_rpm),
    );
    let err = col(&plotted_angle_error);
    let (id, iq, iqr) = (
        col(&|r| r.i_dq_a[0]),
        col(&|r| r.i_dq_a[1]),
        col(&|r| r.i_q_ref_a),
    );
    let ser = |label, values| plot::Series { label, values };
    plot::write_svg(
        path,
        &format!(
            "pmsm simulate: {} ({:?}, {:?})",
            sc.motor.name, sc.control.observer, sc.control.startup
        ),
        &t,
        &[
            plot::Panel {
                title: "speed (r/min)",
                series: vec![
                    ser("reference", &sref),
                    ser("true", &s),
                    ser("estimated", &sest),
                ],
            },
            plot::Panel {
                title: "angle error (rad)",
                series: vec![ser("θ̂ − θ", &err)],
            },
            plot::Panel {
                title: "current (A)",
                series: vec![ser("i_d", &id), ser("i_q", &iq), ser("i_q*", &iqr)],
            },
        ],
    )
}
