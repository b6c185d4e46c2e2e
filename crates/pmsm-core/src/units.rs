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
//! | `ω_b T_s` | [2⁻¹⁴, 1.5] rad | rotation per sample at base speed |
//! | `V_b T_s / (L I_b)` | [2⁻¹⁴, 8] | current change per sample at full voltage, per unit |
//!
//! A 24 V, 0.5 mH, 60 A drone motor and a 540 V, 40 mH, 3 A industrial motor at 10–20 kHz
//! both lie well inside (tests below); so do the papers' motors A and B, a 12 V drone
//! outrunner of 17.6 µH at 24 kHz (`V_b T_s/(L I_b)` 1.5 to 4 as its current rating falls
//! from 16 to 6 A) and a 600 V servo of 4.2 mH at 8 kHz (1.8). The current-change bound is the
//! widest: every coefficient it scales (`T_s/L` in the current model and the estimators'
//! voltage terms) stays below 8 pu, every product with a healthy voltage below 32 pu; the
//! current loops' deadbeat gain `L/T_s` falls to 1/8 pu, still 21 significant bits.
//!
//! The rotation bound leaves 4.2 samples per electrical period at base speed (the no-load
//! speed at the nominal bus): a motor geared for torque, rated at half its no-load speed with
//! 11 samples per period there at 20 kHz, fits. The current-model MRAS turns its estimate at
//! most 1 rad per sample (`MAX_SPEED_PU`); the back-EMF estimators' sinc series holds to 2 rad.
//!
//! Outside, [`ConfigError::OutOfEnvelope`] names the quantity, its value and the range, and
//! what would fit ([`Fit`]): the PWM frequency for the quantities that scale with the sample
//! period, the rated current for those that scale with the base current.

use crate::error::{ConfigError, Fit};
use crate::num::{PU_FRAC, Pu, pu_from_f64};
use crate::params::{InverterParams, MotorParams, positive};

/// Base values of the per-unit system (SI units) and the control sample period.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
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

/// How a derived quantity scales with the settings that move it: with the base current
/// (`R/Z_b`, `L/L_b`) or with the sample period (`ω_b T_s`, and `V_b T_s/(L I_b)`, which the
/// sample rate moves most directly).
#[derive(Clone, Copy)]
enum Moves {
    WithCurrent { rated_rms_a: f64 },
    WithPeriod { sample_hz: f64 },
}

/// Inclusive range check of a derived per-unit quantity; outside, the error says what value
/// of the setting that `moves` it would bring it to the bound it passed (each quantity is
/// proportional or inversely proportional to its setting).
fn envelope(
    quantity: &'static str,
    value: f64,
    (min, max): (f64, f64),
    moves: Moves,
) -> Result<f64, ConfigError> {
    if value.is_finite() && (min..=max).contains(&value) {
        return Ok(value);
    }
    let fit = match moves {
        _ if !value.is_finite() || value <= 0.0 => Fit::Other,
        Moves::WithCurrent { rated_rms_a } if value > max => {
            Fit::RatedCurrentAtMost(rated_rms_a * max / value)
        }
        Moves::WithCurrent { rated_rms_a } => Fit::RatedCurrentAtLeast(rated_rms_a * min / value),
        Moves::WithPeriod { sample_hz } if value > max => {
            Fit::SampleHzAtLeast(sample_hz * value / max)
        }
        Moves::WithPeriod { sample_hz } => Fit::SampleHzAtMost(sample_hz * value / min),
    };
    Err(ConfigError::OutOfEnvelope {
        quantity,
        value,
        min,
        max,
        fit,
    })
}

/// The envelope's ranges (module documentation).
pub const R_RANGE: (f64, f64) = (1.0 / 4096.0, 32.0);
pub const L_RANGE: (f64, f64) = (1.0 / 256.0, 64.0);
pub const SPEED_STEP_RANGE: (f64, f64) = (1.0 / 16384.0, 1.5);
pub const CURRENT_STEP_RANGE: (f64, f64) = (1.0 / 16384.0, 8.0);

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
        let with_current = Moves::WithCurrent {
            rated_rms_a: current_a / core::f64::consts::SQRT_2,
        };
        let with_period = Moves::WithPeriod { sample_hz };
        let r = motor.rs_ohm / impedance_ohm;
        envelope("R / Z_base", r, R_RANGE, with_current)?;
        let ld = motor.ld_h / base.inductance_h;
        envelope("L_d / L_base", ld, L_RANGE, with_current)?;
        let lq = motor.lq_h / base.inductance_h;
        envelope("L_q / L_base", lq, L_RANGE, with_current)?;
        let step = omega_e_rad_s * base.sample_s;
        envelope("omega_base * T_s", step, SPEED_STEP_RANGE, with_period)?;
        let l_min = motor.ld_h.min(motor.lq_h);
        let di = voltage_v * base.sample_s / (l_min * current_a);
        envelope(
            "V_base * T_s / (L * I_base)",
            di,
            CURRENT_STEP_RANGE,
            with_period,
        )?;
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

    /// 12 V drone outrunner: 17.6 µH, 0.115 Ω line to line, 7 pole pairs, Kv 920.
    fn outrunner(rated_rms_a: f64) -> MotorParams {
        let mut m = MotorParams::new(
            7,
            0.0575,
            17.6e-6,
            17.6e-6,
            5.513 / (920.0 * 7.0),
            2e-6,
            1e-7,
        );
        m.rated_current_a = Some(rated_rms_a);
        m
    }

    #[test]
    fn a_drone_outrunner_and_a_600_v_servo_fit() {
        // The outrunner at 24 kHz: a full-voltage sample moves 1.5 to 4 times its rated
        // current as the rating falls from 8 to 3 A.
        for rated in [8.0, 5.0, 3.0] {
            let b = PerUnit::new(&outrunner(rated), &inverter(12.0, 60.0), 24e3).unwrap();
            let di = b.voltage_v * b.sample_s / (17.6e-6 * b.current_a);
            assert!((1.4..4.1).contains(&di), "{rated} A: {di}");
        }
        // A 600 V servo of 4.2 mH, 4 A, at 8 kHz: 1.8.
        let mut servo = MotorParams::new(4, 1.2, 4.2e-3, 4.2e-3, 0.12, 3e-4, 1e-4);
        servo.rated_current_a = Some(4.0);
        let b = PerUnit::new(&servo, &inverter(600.0, 20.0), 8e3).unwrap();
        let di = b.voltage_v * b.sample_s / (4.2e-3 * b.current_a);
        assert!((di - 1.82).abs() < 0.01, "{di}");
    }

    #[test]
    fn outside_the_envelope_says_what_fits() {
        // The outrunner rated 2 A at 12 kHz: a sample at full voltage moves 11.6 times its
        // rated current.
        let motor = outrunner(2.0);
        let inv = inverter(12.0, 60.0);
        let err = PerUnit::new(&motor, &inv, 12e3).unwrap_err();
        let ConfigError::OutOfEnvelope {
            quantity,
            value,
            fit,
            ..
        } = err
        else {
            panic!("{err}");
        };
        assert_eq!(quantity, "V_base * T_s / (L * I_base)");
        let Fit::SampleHzAtLeast(hz) = fit else {
            panic!("{fit:?}");
        };
        assert!((hz - 12e3 * value / 8.0).abs() < 1e-6, "{hz}");
        // That frequency fits, one percent below does not; the message says it.
        assert!(PerUnit::new(&motor, &inv, hz * 1.0001).is_ok());
        assert!(PerUnit::new(&motor, &inv, hz * 0.99).is_err());
        let mut text = heapless::String::<200>::new();
        core::fmt::write(&mut text, format_args!("{err}")).unwrap();
        assert!(text.contains("a PWM frequency of at least 17"), "{text}");
        // A resistance too large for the rated current: the current that fits.
        let mut hot = industrial();
        hot.rs_ohm = 5000.0;
        let err = PerUnit::new(&hot, &inverter(540.0, 10.0), 10e3).unwrap_err();
        let ConfigError::OutOfEnvelope { fit, .. } = err else {
            panic!("{err}");
        };
        let Fit::RatedCurrentAtMost(a) = fit else {
            panic!("{fit:?}");
        };
        hot.rated_current_a = Some(a * 0.999);
        let b = PerUnit::new(&hot, &inverter(540.0, 10.0), 10e3);
        assert!(
            !matches!(
                b,
                Err(ConfigError::OutOfEnvelope {
                    quantity: "R / Z_base",
                    ..
                })
            ),
            "{b:?}"
        );
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
