//! A run's rows as the page plots them: one `f32` column per signal.

use pmsm_cli::commands::simulate::Row;
use pmsm_core::DriveState;

/// The columns of [`series`], in order: time (s); speed reference, true and estimated speed
/// (r/min); angle error (estimated − true, rad, wrapped; NaN outside the closed loop); true
/// d and q current and the q reference (A); the three duties (0…1; 0 with the outputs off);
/// the drive's state (0 idle, 1 detection, 2 alignment, 3 open loop, 4 closed loop, 5 fault).
pub const SERIES: [&str; 12] = [
    "t_s",
    "speed_ref_rpm",
    "speed_rpm",
    "speed_est_rpm",
    "angle_err_rad",
    "i_d_a",
    "i_q_a",
    "i_q_ref_a",
    "duty_a",
    "duty_b",
    "duty_c",
    "state",
];

/// The rows as [`SERIES`] columns, column after column (`rows.len()` values each).
pub fn series(rows: &[Row]) -> Vec<f32> {
    let column = |k: usize, r: &Row| -> f64 {
        match k {
            0 => r.t_s,
            1 => r.speed_ref_rpm,
            2 => r.speed_rpm,
            3 => r.speed_est_rpm,
            4 => {
                if r.state == DriveState::Run {
                    r.angle_error_rad()
                } else {
                    f64::NAN
                }
            }
            5 => r.i_dq_a[0],
            6 => r.i_dq_a[1],
            7 => r.i_q_ref_a,
            8..=10 => r.duties[k - 8],
            _ => match r.state {
                DriveState::Idle => 0.0,
                DriveState::Ipd => 1.0,
                DriveState::Align => 2.0,
                DriveState::OpenLoop => 3.0,
                DriveState::Run => 4.0,
                DriveState::Fault(_) => 5.0,
            },
        }
    };
    (0..SERIES.len())
        .flat_map(|k| rows.iter().map(move |r| column(k, r) as f32))
        .collect()
}
