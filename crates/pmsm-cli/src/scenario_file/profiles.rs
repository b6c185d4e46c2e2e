//! The time course of a scenario: `[initial]` state, `[speed_ref]` and `[load]` profiles.

use pmsm_core::validate::{in_range, non_negative};
use pmsm_core::{ParamError, ParamReason};
use serde::Deserialize;

#[derive(Deserialize, Default)]
#[serde(deny_unknown_fields)]
pub(super) struct RawInitial {
    #[serde(default)]
    pub(super) theta_e_deg: f64,
    #[serde(default)]
    pub(super) speed_rpm: f64,
}

impl RawInitial {
    pub(super) fn check(&self) -> Result<(), ParamError> {
        in_range("initial.theta_e_deg", self.theta_e_deg, -1e6, 1e6)?;
        in_range("initial.speed_rpm", self.speed_rpm, -1e6, 1e6)?;
        Ok(())
    }
}

/// A piecewise-linear signal through breakpoints, constant outside them.
#[derive(Clone, Debug, PartialEq)]
pub struct Breakpoints {
    t_s: Vec<f64>,
    values: Vec<f64>,
}

impl Breakpoints {
    /// A constant.
    pub fn constant(value: f64) -> Self {
        Self {
            t_s: vec![0.0],
            values: vec![value],
        }
    }

    /// Value at `t`.
    pub fn at(&self, t: f64) -> f64 {
        let k = self.t_s.partition_point(|&x| x <= t);
        match (k.checked_sub(1), self.t_s.get(k)) {
            (None, _) => self.values[0],
            (Some(j), None) => self.values[j],
            (Some(j), Some(&t1)) => {
                let (t0, v0, v1) = (self.t_s[j], self.values[j], self.values[k]);
                v0 + (v1 - v0) * (t - t0) / (t1 - t0)
            }
        }
    }

    /// Times of the breakpoints, s.
    pub fn times(&self) -> &[f64] {
        &self.t_s
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct RawBreakpoints {
    t_s: Vec<f64>,
    #[serde(default)]
    rpm: Option<Vec<f64>>,
    #[serde(default)]
    nm: Option<Vec<f64>>,
}

/// The breakpoints of `[table]`, values from its `unit` list (`rpm` or `nm`); zero when
/// the table is absent.
pub(super) fn breakpoints(
    raw: Option<RawBreakpoints>,
    table: &'static str,
    unit: &'static str,
) -> Result<Breakpoints, ParamError> {
    let Some(raw) = raw else {
        return Ok(Breakpoints::constant(0.0));
    };
    let bad = |reason| ParamError { key: table, reason };
    let values = match unit {
        "rpm" => raw.rpm,
        _ => raw.nm,
    }
    .ok_or(bad(ParamReason::Inconsistent(if unit == "rpm" {
        "a missing `rpm` list"
    } else {
        "a missing `nm` list"
    })))?;
    if raw.t_s.is_empty() || raw.t_s.len() != values.len() {
        return Err(bad(ParamReason::Inconsistent(
            "`t_s` and the values must be lists of the same, non-zero length",
        )));
    }
    for (k, t) in raw.t_s.iter().enumerate() {
        non_negative(table, *t)?;
        if k > 0 && *t <= raw.t_s[k - 1] {
            return Err(bad(ParamReason::Inconsistent("`t_s` must increase")));
        }
    }
    for v in &values {
        in_range(table, *v, -1e6, 1e6)?;
    }
    Ok(Breakpoints {
        t_s: raw.t_s,
        values,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn breakpoints_interpolate_and_hold() {
        let b = Breakpoints {
            t_s: vec![1.0, 2.0, 4.0],
            values: vec![0.0, 10.0, -10.0],
        };
        for (t, v) in [(0.0, 0.0), (1.5, 5.0), (3.0, 0.0), (9.0, -10.0)] {
            assert!((b.at(t) - v).abs() < 1e-12, "{t}");
        }
    }
}
