//! The input of `pmsm observe`: the CSV columns, their sample rate, and the per-unit bases
//! they fit in.

use super::{Args, VoltageTiming};
use crate::csv_io::{self, Table};
use anyhow::{Result, anyhow, bail};
use pmsm_core::{InverterParams, MotorParams, PerUnit};
use std::path::Path;

/// The input columns, uniformly sampled.
pub(super) struct Samples<'a> {
    pub(super) t: &'a [f64],
    pub(super) va: &'a [f64],
    pub(super) vb: &'a [f64],
    pub(super) ia: &'a [f64],
    pub(super) ib: &'a [f64],
    /// Number of rows, at least two.
    pub(super) rows: usize,
    /// Sample period, s.
    pub(super) ts: f64,
}

impl<'a> Samples<'a> {
    /// Checks that `t_s` increases uniformly over at least two rows.
    pub(super) fn from_table(table: &'a Table, path: &Path) -> Result<Self> {
        let rows = csv_io::check_time(table, "t_s")?;
        let t = table.required("t_s")?;
        let shown = path.display();
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
        Ok(Self {
            t,
            va: va?,
            vb: vb?,
            ia: ia?,
            ib: ib?,
            rows,
            ts,
        })
    }

    /// The mean voltage over `[t_{k−1}, t_k]` as `timing` reads it (row 0: its own).
    pub(super) fn interval_voltage(&self, timing: VoltageTiming, k: usize) -> [f64; 2] {
        let (va, vb) = (self.va, self.vb);
        match (timing, k.checked_sub(1)) {
            (_, None) => [va[0], vb[0]],
            (VoltageTiming::Sampled, Some(j)) => [0.5 * (va[j] + va[k]), 0.5 * (vb[j] + vb[k])],
            (VoltageTiming::Held, Some(j)) => [va[j], vb[j]],
        }
    }
}

/// Largest magnitude of the vectors `(a_k, b_k)`.
fn largest_vector(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(a, b)| a.hypot(*b))
        .fold(0.0, f64::max)
}

/// The per-unit bases for the motor at the data's rate, checking that the data fit the
/// fixed-point range.
pub(super) fn per_unit_base(args: &Args, m: &MotorParams, data: &Samples) -> Result<PerUnit> {
    let shown = args.input.display();
    let max_v = largest_vector(data.va, data.vb);
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
    let base = PerUnit::new(m, &inverter, 1.0 / data.ts).map_err(|e| {
        anyhow!(
            "{}: {e} (sample rate {:.1} Hz from `t_s` of {shown}, bus {vdc_v:.1} V)",
            args.motor.display(),
            1.0 / data.ts
        )
    })?;
    let max_i = largest_vector(data.ia, data.ib);
    if max_i > 64.0 * base.current_a || max_v > 64.0 * base.voltage_v {
        bail!(
            "{shown}: currents up to {max_i:.3e} A and voltages up to {max_v:.3e} V exceed the fixed-point range \
             for this motor (64 × {:.3} A, 64 × {:.3} V); check the units or `rated_current_a`",
            base.current_a,
            base.voltage_v
        );
    }
    Ok(base)
}
