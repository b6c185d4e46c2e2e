//! Scenario tables added with self-commissioning, kept out of `scenario_file` so that it
//! only gains a field and a call for each:
//!
//! ```toml
//! [control]
//! model_motor = "identified.toml"   # the drive is designed from this file (relative to the
//!                                   # scenario); the plant keeps `motor`
//!
//! [thermal]                         # the plant's true R and ψ drift over time
//! t_s = [0.0, 2.0]
//! rs_factor = [1.0, 1.4]            # piecewise linear, held outside
//! flux_factor = [1.0, 0.95]
//! ```

use crate::motor_file::Motor;
use anyhow::{Result, anyhow};
use pmsm_plant::Thermal;
use serde::Deserialize;
use std::path::Path;

/// `[thermal]` as written.
#[derive(Clone, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RawThermal {
    t_s: Vec<f64>,
    rs_factor: Vec<f64>,
    flux_factor: Vec<f64>,
}

/// Validates `[thermal]`; `shown` names the scenario in messages.
pub fn thermal(raw: Option<&RawThermal>, shown: &str) -> Result<Option<Thermal>> {
    raw.map(|r| {
        Thermal::new(&r.t_s, &r.rs_factor, &r.flux_factor).map_err(|e| anyhow!("{shown}: {e}"))
    })
    .transpose()
}

/// Reads `[control] model_motor`, relative to the scenario file at `scenario`, with `read`.
pub fn model_motor(
    path: Option<&str>,
    scenario: &Path,
    read: &dyn Fn(&Path) -> Result<Motor>,
) -> Result<Option<Motor>> {
    path.map(|p| {
        let full = scenario.parent().unwrap_or(Path::new(".")).join(p);
        read(&full).map_err(|e| anyhow!("control.model_motor: {e:#}"))
    })
    .transpose()
}
