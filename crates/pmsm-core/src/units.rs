//! Per-unit scaling: base values computed from the motor and the inverter, and the envelope of
//! motors and sample rates the fixed-point formats support.
//!
//! # Bases
//!
//! | base | value | why |
//! |---|---|---|
//! | voltage `V_b` | `V_DC / √3` | the largest phase-peak voltage SVPWM makes linearly |
//! | current `I_b` | `√2 · rated_current_a`, else `min(ψ/L_d, V_b/R)` | 1 pu = rated peak current |
//! | speed `ω_b` | `V_b / ψ`, electrical rad/s | no-load speed at nominal bus: EMF ≤ 1 pu there |
//! | flux `ψ_b` | `V_b / ω_b = ψ` | so the magnet flux is exactly 1 pu |
//! | impedance `Z_b` | `V_b / I_b` | |
//! | inductance `L_b` | `Z_b / ω_b` | |
//! | torque `T_b` | `1.5 p ψ_b I_b` | |
//!
//! # Envelope
//!
//! A motor, inverter and sample rate are supported when these per-unit quantities fall in the
//! ranges below, which keep every coefficient of the core representable in Q8.24 with at
//! least 10 significant bits, and every healthy signal below 1/30 of the Q8.24 range:
//!
//! | quantity | range | meaning |
//! |---|---|---|
//! | `R / Z_b` | [2⁻¹², 32] | resistive drop at rated current, per unit |
//! | `L_d / L_b`, `L_q / L_b` | [2⁻⁸, 64] | reactance at base speed, per unit |
//! | `ω_b T_s` | [2⁻¹⁴, 1] rad | rotation per sample at base speed |
//! | `V_b T_s / (L I_b)` | [2⁻¹⁴, 1] | current change per sample at full voltage, per unit |
//!
//! A 24 V, 0.5 mH, 60 A drone motor and a 540 V, 40 mH, 3 A industrial motor at 10–20 kHz
//! both lie well inside (tests below); so do the papers' motors A and B.

use crate::error::ConfigError;
use crate::num::{PU_FRAC, Pu, pu_from_f64};
use crate::params::{InverterParams, MotorParams, positive};

/// Base values of the per-unit system (SI units) and the control sample period.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PerUnit {
    /// Base voltage `V_b`, V (phase peak).
    pub voltage_v: f64,
    /// Base current `I_b`, A (phase peak).
    pub current_a: f64,
    /// Base electrical speed `ω_b`, rad/s.
    pub omega_e_rad_s: f64,
    /// Base flux linkage `ψ_b`, Wb.
    pub flux_wb: f64,
    /// Base impedance `Z_b`, Ω.
    pub impedance_ohm: f64,
    /// Base inductance `L_b`, H.
    pub inductance_h: f64,
    /// Base torque `T_b`, N·m.
    pub torque_nm: f64,
    /// Control sample period `T_s`, s.
    pub sample_s: f64,
}

/// Inclusive range check of a derived per-unit quantity.
fn envelope(quantity: &'static str, value: f64, min: f64, max: f64) -> Result<f64, ConfigError> {
    if value.is_finite() && (min..=max).contains(&value) {
        Ok(value)
    } else {
        Err(ConfigError::OutOfEnvelope {
            quantity,
            value,
            min,
            max,
        })
    }
}

impl PerUnit {
    /// Bases for `motor` on `inverter`, controlled at `sample_hz`; checks the envelope.
    pub fn new(
        motor: &MotorParams,
        inverter: &InverterParams,
        sample_hz: f64,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        inverter.validate()?;
        let sample_hz = positive("sample_hz", sample_hz)?;
        let voltage_v = inverter.vdc_v / libm::sqrt(3.0);
        let current_a = match motor.rated_current_a {
            Some(rms) => core::f64::consts::SQRT_2 * rms,
            None => (motor.flux_wb / motor.ld_h).min(voltage_v / motor.rs_ohm),
        };
        let omega_e_rad_s = voltage_v / motor.flux_wb;
        let impedance_ohm = voltage_v / current_a;
        let base = Self {
            voltage_v,
            current_a,
            omega_e_rad_s,
            flux_wb: motor.flux_wb,
            impedance_ohm,
            inductance_h: impedance_ohm / omega_e_rad_s,
            torque_nm: 1.5 * motor.p() * motor.flux_wb * current_a,
            sample_s: 1.0 / sample_hz,
        };
        envelope(
            "R / Z_base",
            motor.rs_ohm / impedance_ohm,
            1.0 / 4096.0,
            32.0,
        )?;
        envelope(
            "L_d / L_base",
            motor.ld_h / base.inductance_h,
            1.0 / 256.0,
            64.0,
        )?;
        envelope(
            "L_q / L_base",
            motor.lq_h / base.inductance_h,
            1.0 / 256.0,
            64.0,
        )?;
        envelope(
            "omega_base * T_s",
            omega_e_rad_s * base.sample_s,
            1.0 / 16384.0,
            1.0,
        )?;
        let l_min = motor.ld_h.min(motor.lq_h);
        let di = voltage_v * base.sample_s / (l_min * current_a);
        envelope("V_base * T_s / (L * I_base)", di, 1.0 / 16384.0, 1.0)?;
        Ok(base)
    }

    /// Amperes to per unit (saturating).
    pub fn current_pu(&self, amps: f64) -> Pu {
        pu_from_f64(amps / self.current_a)
    }

    /// Volts to per unit (saturating).
    pub fn voltage_pu(&self, volts: f64) -> Pu {
        pu_from_f64(volts / self.voltage_v)
    }

    /// Electrical rad/s to per unit (saturating).
    pub fn speed_pu(&self, omega_e_rad_s: f64) -> Pu {
        pu_from_f64(omega_e_rad_s / self.omega_e_rad_s)
    }

    /// Per-unit current to amperes.
    pub fn current_a(&self, x: Pu) -> f64 {
        to_f64(x) * self.current_a
    }

    /// Per-unit voltage to volts.
    pub fn voltage_v(&self, x: Pu) -> f64 {
        to_f64(x) * self.voltage_v
    }

    /// Per-unit speed to electrical rad/s.
    pub fn speed_rad_s(&self, x: Pu) -> f64 {
        to_f64(x) * self.omega_e_rad_s
    }
}

/// A [`Pu`] value as `f64` (exact).
pub fn to_f64(x: Pu) -> f64 {
    x.to_bits() as f64 / (1u64 << PU_FRAC) as f64
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn inverter(vdc_v: f64, full_scale_a: f64) -> InverterParams {
        InverterParams {
            vdc_v,
            pwm_hz: 20e3,
            dead_time_s: 0.5e-6,
            current_full_scale_a: full_scale_a,
        }
    }

    /// 24 V, 0.5 mH, 60 A, 7 pole pairs: a drone motor (about 9 000 r/min at 24 V).
    fn drone() -> MotorParams {
        let mut m = MotorParams::new(7, 0.02, 0.5e-3, 0.5e-3, 0.002, 2e-5, 1e-6);
        m.rated_current_a = Some(60.0);
        m
    }

    /// 540 V, 40 mH, 3 A, 2 pole pairs: an industrial servo or pump motor.
    fn industrial() -> MotorParams {
        let mut m = MotorParams::new(2, 4.0, 0.040, 0.048, 1.2, 0.01, 0.001);
        m.rated_current_a = Some(3.0);
        m
    }

    #[test]
    fn envelope_corners_fit() {
        for hz in [10e3, 20e3] {
            let d = PerUnit::new(&drone(), &inverter(24.0, 150.0), hz).unwrap();
            assert!((d.voltage_v - 13.856).abs() < 1e-3);
            assert!((d.current_a - 84.85).abs() < 0.01);
            PerUnit::new(&industrial(), &inverter(540.0, 10.0), hz).unwrap();
        }
    }

    #[test]
    fn papers_motors_fit() {
        let mut a = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
        a.kt_nm_per_a = 1.108;
        let pa = PerUnit::new(&a, &inverter(300.0, 40.0), 20e3).unwrap();
        assert!((pa.flux_wb - 0.288).abs() < 1e-12);
        let b = crate::fixtures::motor_b();
        PerUnit::new(&b, &inverter(540.0, 10.0), 1.0 / 150e-6).unwrap();
        PerUnit::new(&b, &inverter(540.0, 10.0), 14e3).unwrap();
    }

    #[test]
    fn outside_the_envelope_is_a_named_error() {
        // A 0.5 mH motor sampled at 1 kHz: one sample at full voltage moves 2 pu of current.
        let err = PerUnit::new(&drone(), &inverter(24.0, 150.0), 1e3).unwrap_err();
        assert!(matches!(
            err,
            ConfigError::OutOfEnvelope {
                quantity: "omega_base * T_s",
                ..
            } | ConfigError::OutOfEnvelope {
                quantity: "V_base * T_s / (L * I_base)",
                ..
            }
        ));
        let mut bad = drone();
        bad.rs_ohm = f64::NAN;
        let err = PerUnit::new(&bad, &inverter(24.0, 150.0), 20e3).unwrap_err();
        assert!(matches!(err, ConfigError::Param(e) if e.key == "rs_ohm"));
        let err = PerUnit::new(&drone(), &inverter(24.0, 150.0), 0.0).unwrap_err();
        assert!(matches!(err, ConfigError::Param(e) if e.key == "sample_hz"));
    }

    #[test]
    fn conversions_round_trip_within_one_lsb() {
        let b = PerUnit::new(&industrial(), &inverter(540.0, 10.0), 10e3).unwrap();
        for amps in [-12.0, -3.0, 0.0, 0.001, 4.2] {
            let back = b.current_a(b.current_pu(amps));
            assert!((back - amps).abs() <= b.current_a / (1u64 << PU_FRAC) as f64);
        }
        // Saturation, not wrapping, far outside the range.
        assert_eq!(b.current_pu(1e9), Pu::MAX);
        assert_eq!(b.voltage_pu(-1e9), Pu::MIN);
    }

    proptest! {
        /// Motors scaled between the two envelope corners (geometric interpolation of every
        /// parameter, sample rate 8–20 kHz) all fit: the envelope is convex in log space.
        #[test]
        fn motors_between_the_corners_fit(t in 0.0f64..=1.0, hz in 8e3f64..20e3) {
            let (d, i) = (drone(), industrial());
            let g = |a: f64, b: f64| a * (b / a).powf(t);
            let mut m = MotorParams::new(
                if t < 0.5 { 7 } else { 2 },
                g(d.rs_ohm, i.rs_ohm),
                g(d.ld_h, i.ld_h),
                g(d.lq_h, i.lq_h),
                g(d.flux_wb, i.flux_wb),
                g(d.j_kg_m2, i.j_kg_m2),
                g(d.b_nm_s, i.b_nm_s),
            );
            m.rated_current_a = Some(g(60.0, 3.0));
            let inv = inverter(g(24.0, 540.0), g(150.0, 10.0));
            prop_assert!(PerUnit::new(&m, &inv, hz).is_ok());
        }
    }
}
