//! The motor and inverter this firmware drives. The B-G431B-ESC1 kit ships with the gimbal
//! motor GBM2804H-100T (examples/motor-gbm2804h-100t.toml): these are its values, from ST's
//! and iFlight's published data. For another motor REPLACE them (R and L measured
//! line-to-neutral, ψ from the back-EMF constant: ψ = Ke[V_peak,LL / (rad/s mech)] / (√3 · p)),
//! or identify it on the board (`--features commissioning`, the README).
//!
//! A surface motor: the defaults drive it with the NLO after an alignment
//! (`EstimatorKind::for_motor`, docs/drive.md "which estimator"); an interior one needs
//! pmsm-core's features `mras-current` and `ipd` instead (Cargo.toml, README.md "Size").
//!
//! build.rs reads this file too: it designs the drive on the host from these values and the
//! firmware loads the result (docs/image.md), so a motor the drive cannot run fails the build.

use pmsm_core::{InverterParams, MotorParams};

/// Pole pairs (12 slots, 14 poles).
pub const POLE_PAIRS: u32 = 7;
/// Stator phase resistance, Ω.
pub const RS_OHM: f64 = 5.3;
/// d-axis inductance, H.
pub const LD_H: f64 = 1.06e-3;
/// q-axis inductance, H (a surface motor: `L_q = L_d`).
pub const LQ_H: f64 = 1.06e-3;
/// Magnet flux linkage, Wb (peak, electrical).
pub const FLUX_WB: f64 = 0.0056;
/// Rated current, A RMS (the per-unit base current is its peak, 1.13 A).
pub const RATED_A_RMS: f64 = 0.8;
/// Rotor inertia, kg·m² (the bare motor's bell).
pub const J_KG_M2: f64 = 6e-6;
/// Viscous friction, N·m·s/rad.
pub const B_NM_S: f64 = 1e-6;

/// Nominal bus voltage, V (the motor's 3S supply).
pub const VDC_V: f64 = 12.0;
/// PWM frequency, Hz (one control sample per PWM period).
pub const PWM_HZ: u32 = 20_000;
/// Dead time, ns.
pub const DEAD_TIME_NS: u32 = 500;

/// The motor.
pub fn motor() -> MotorParams {
    let mut m = MotorParams::new(POLE_PAIRS, RS_OHM, LD_H, LQ_H, FLUX_WB, J_KG_M2, B_NM_S);
    m.rated_current_a = Some(RATED_A_RMS);
    m
}

/// The inverter (the board's current full scale: ±1.65 V / (9.14 · 3 mΩ) ≈ 60 A).
pub fn inverter() -> InverterParams {
    InverterParams {
        vdc_v: VDC_V,
        pwm_hz: PWM_HZ as f64,
        dead_time_s: DEAD_TIME_NS as f64 * 1e-9,
        current_full_scale_a: crate::sensing::CURRENT.full_scale_a(),
    }
}

/// The drive's options on this board: defaults, and the compensation of TIM1's compare
/// preload (the duties of a sample act one period later,
/// `pmsm_stm32::PWM_UPDATE_DELAY_SAMPLES`).
pub fn options() -> pmsm_core::DriveOptions {
    pmsm_core::DriveOptions {
        pwm_delay_samples: Some(pmsm_stm32::PWM_UPDATE_DELAY_SAMPLES),
        ..pmsm_core::DriveOptions::default()
    }
}
