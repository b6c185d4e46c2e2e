//! Motor A of `docs/scenarios.md` (seed 000) on a 300 V bus, sampled at 20 kHz.

use pmsm_core::observer::{AoConfig, MrasEmfConfig, NloConfig};
use pmsm_core::{ConfigError, InverterParams, MotorParams, PerUnit};

/// Control sample rate, Hz.
pub const SAMPLE_HZ: f64 = 20e3;
/// DC bus, V.
pub const VDC_V: f64 = 300.0;
/// Observer gain `g` of the NLO and the AO (scenarios.md, motor A), rad/s.
pub const OBSERVER_GAIN_RAD_S: f64 = 1000.0;

/// Motor A (surface PMSM, 1.2 kW, 1200 r/min) with the paper's `K_T`.
pub fn motor_a() -> MotorParams {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    m.rated_current_a = Some(6.1);
    m.rated_speed_rpm = Some(1200.0);
    m
}

/// The inverter: 300 V bus, 20 kHz PWM, 1 µs dead time, 20 A current full scale.
pub fn inverter() -> InverterParams {
    InverterParams {
        vdc_v: VDC_V,
        pwm_hz: SAMPLE_HZ,
        dead_time_s: 1e-6,
        current_full_scale_a: 20.0,
    }
}

/// Motor, inverter and per-unit bases of every PIL run.
#[derive(Clone, Copy, Debug)]
pub struct Setup {
    /// Motor A.
    pub motor: MotorParams,
    /// See [`inverter`].
    pub inverter: InverterParams,
    /// Per-unit bases (`V_b = V_DC/√3`, `I_b = √2 · 6.1 A`, `ω_b = V_b/ψ`).
    pub base: PerUnit,
}

impl Setup {
    /// Motor A at 20 kHz on 300 V.
    pub fn motor_a() -> Result<Self, ConfigError> {
        let motor = motor_a();
        let inverter = inverter();
        let base = PerUnit::new(&motor, &inverter, SAMPLE_HZ)?;
        Ok(Self {
            motor,
            inverter,
            base,
        })
    }

    /// NLO of gain [`OBSERVER_GAIN_RAD_S`].
    pub fn nlo(&self) -> Result<NloConfig, ConfigError> {
        NloConfig::new(&self.motor, &self.base, OBSERVER_GAIN_RAD_S)
    }

    /// AO of gain [`OBSERVER_GAIN_RAD_S`].
    pub fn ao(&self) -> Result<AoConfig, ConfigError> {
        AoConfig::new(&self.motor, &self.base, OBSERVER_GAIN_RAD_S)
    }

    /// Tomita's MRAS with the paper's constants on an AO of gain [`OBSERVER_GAIN_RAD_S`].
    pub fn mras_emf(&self) -> Result<MrasEmfConfig, ConfigError> {
        MrasEmfConfig::paper(&self.motor, &self.base, OBSERVER_GAIN_RAD_S)
    }
}
