//! The hardware of a scenario: its `motor` (a file or an inline table), `[inverter]` and
//! `[sensing]` (the current ADC).

use crate::motor_file::{Motor, RawMotor};
use anyhow::{Result, anyhow};
use pmsm_core::ParamError;
use pmsm_core::validate::{in_range, non_negative, positive};
use serde::Deserialize;
use std::path::Path;

/// `motor`: a path relative to the scenario file, or an inline table.
#[derive(Deserialize)]
#[serde(untagged)]
pub(super) enum MotorRef {
    Path(String),
    Inline(Box<RawMotor>),
}

impl MotorRef {
    /// Reads the motor file (relative to the scenario at `path`, with `read`) or checks the
    /// inline table.
    pub(super) fn resolve(
        self,
        path: &Path,
        read: &dyn Fn(&Path) -> Result<Motor>,
    ) -> Result<Motor> {
        match self {
            MotorRef::Path(p) => {
                let full = path.parent().unwrap_or(Path::new(".")).join(&p);
                read(&full)
            }
            MotorRef::Inline(m) => m
                .into_motor("motor")
                .map_err(|e| anyhow!("{}: motor: {e}", path.display())),
        }
    }
}

/// Inverter of a scenario.
#[derive(Clone, Copy, Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Inverter {
    /// Bus voltage, V.
    pub vdc_v: f64,
    /// PWM frequency, Hz.
    pub pwm_hz: f64,
    /// Dead time, s.
    #[serde(default)]
    pub dead_time_s: f64,
    /// `"averaged"` or `"switching"`.
    #[serde(default = "averaged")]
    pub model: InverterKind,
    /// ADC full scale, A; default 4 × rated peak current (or the per-unit base).
    pub current_full_scale_a: Option<f64>,
    /// IGBT/MOSFET on-state drop, V.
    #[serde(default)]
    pub v_sat_v: f64,
    /// Diode forward drop, V.
    #[serde(default)]
    pub v_f_v: f64,
    /// Width of the current sign, A: the dead-time error fades linearly within
    /// `±sign_band_a` of zero; 0 is the hard sign (the averaged model holds it over each PWM
    /// period; the switching model takes it from the instantaneous current and lets a phase
    /// float at zero, `pmsm_plant::inverter`). Default `pmsm_plant::DEFAULT_SIGN_BAND` of
    /// the ADC full scale.
    pub sign_band_a: Option<f64>,
}

impl Inverter {
    pub(super) fn check(&self) -> Result<(), ParamError> {
        in_range("inverter.vdc_v", self.vdc_v, 1.0, 2000.0)?;
        in_range("inverter.pwm_hz", self.pwm_hz, 1e3, 200e3)?;
        non_negative("inverter.dead_time_s", self.dead_time_s)?;
        non_negative("inverter.v_sat_v", self.v_sat_v)?;
        non_negative("inverter.v_f_v", self.v_f_v)?;
        if let Some(band) = self.sign_band_a {
            in_range("inverter.sign_band_a", band, 0.0, 1e4)?;
        }
        if let Some(fs) = self.current_full_scale_a {
            positive("inverter.current_full_scale_a", fs)?;
        }
        Ok(())
    }
}

/// Inverter model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum InverterKind {
    /// Period-averaged leg voltages.
    Averaged,
    /// Switching edges of centre-aligned PWM.
    Switching,
}

fn averaged() -> InverterKind {
    InverterKind::Averaged
}

/// `[sensing]` of a scenario.
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sensing {
    /// ADC resolution, bits (default 12).
    pub adc_bits: Option<u32>,
    /// White noise on each phase current, A RMS.
    #[serde(default)]
    pub noise_rms_a: f64,
    /// Offset of each phase current, A.
    #[serde(default)]
    pub offset_a: [f64; 3],
    /// Relative gain error of each phase.
    #[serde(default)]
    pub gain_error: [f64; 3],
}

impl Sensing {
    pub(super) fn check(&self) -> Result<(), ParamError> {
        if let Some(bits) = self.adc_bits {
            in_range("sensing.adc_bits", bits as f64, 2.0, 16.0)?;
        }
        non_negative("sensing.noise_rms_a", self.noise_rms_a)?;
        Ok(())
    }
}
