//! Statistics of a stretch of a run, for tests and reports.

use super::Row;

/// The rows with `t0 ≤ t < t1`.
pub fn window(rows: &[Row], t0: f64, t1: f64) -> Vec<&Row> {
    rows.iter().filter(|r| r.t_s >= t0 && r.t_s < t1).collect()
}

/// The first row in a fault state, if any.
pub fn first_fault(rows: &[Row]) -> Option<&Row> {
    rows.iter().find(|r| !r.fault().is_empty())
}

/// Largest |angle error|, rad.
pub fn max_angle(rows: &[&Row]) -> f64 {
    rows.iter()
        .map(|r| r.angle_error_rad().abs())
        .fold(0.0, f64::max)
}

/// Largest |speed − `rpm`|, r/min (0 for no rows).
pub fn max_speed_off(rows: &[&Row], rpm: f64) -> f64 {
    rows.iter()
        .map(|r| (r.speed_rpm - rpm).abs())
        .fold(0.0, f64::max)
}

/// RMS angle error, rad (0 for no rows).
pub fn rms_angle(rows: &[&Row]) -> f64 {
    (rows
        .iter()
        .map(|r| r.angle_error_rad().powi(2))
        .sum::<f64>()
        / rows.len().max(1) as f64)
        .sqrt()
}

/// Population standard deviation of `f` over `rows` (0 for no rows).
pub fn std_dev(rows: &[&Row], f: impl Fn(&Row) -> f64) -> f64 {
    let n = rows.len().max(1) as f64;
    let mean = rows.iter().map(|r| f(r)).sum::<f64>() / n;
    (rows.iter().map(|r| (f(r) - mean).powi(2)).sum::<f64>() / n).sqrt()
}

/// Mean |speed − reference| / |reference| (0 for no rows).
pub fn speed_err(rows: &[&Row]) -> f64 {
    rows.iter()
        .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs() / r.speed_ref_rpm.abs())
        .sum::<f64>()
        / rows.len().max(1) as f64
}
