//! Physical parameters of a motor and an inverter, in SI units, as written in a motor file.
//!
//! These are floating point: they are read once, validated, and turned into fixed-point
//! coefficients by the `Config` constructors. Field names are the keys of the motor file, so
//! an error can name the key a user has to fix.

use core::fmt;

/// Parameters of a permanent-magnet synchronous motor (SI units, electrical angle).
///
/// `ld_h == lq_h` is a surface motor (Solsona, Valla, Muravchik (2000)), `ld_h < lq_h` an interior one (Khlaief, Boussak, Gossa (2012)).
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct MotorParams {
    /// Pole pairs `p` (mechanical speed `ω_m = ω / p`).
    pub pole_pairs: u32,
    /// Stator phase resistance `R`, Ω.
    pub rs_ohm: f64,
    /// Direct-axis inductance `L_d`, H (incremental value at `i_d = 0`).
    pub ld_h: f64,
    /// Quadrature-axis inductance `L_q`, H.
    pub lq_h: f64,
    /// Peak magnet flux linkage `ψ`, V·s/rad electrical.
    pub flux_wb: f64,
    /// Torque constant `K_T`, N·m/A (peak `i_q`). Default `1.5 · p · ψ`.
    pub kt_nm_per_a: f64,
    /// Rotor and load inertia `J`, kg·m².
    pub j_kg_m2: f64,
    /// Viscous friction `B`, N·m·s/rad.
    pub b_nm_s: f64,
    /// Rated phase current, A RMS (nameplate), if known.
    pub rated_current_a: Option<f64>,
    /// Rated mechanical speed, r/min, if known.
    pub rated_speed_rpm: Option<f64>,
}

/// A parameter that is missing, not finite or out of its physical range.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct ParamError {
    /// The key of the offending parameter, as written in a motor or scenario file.
    pub key: &'static str,
    /// What is wrong with it.
    pub reason: ParamReason,
}

/// Why a parameter was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum ParamReason {
    /// NaN or infinite.
    NotFinite,
    /// Must be strictly positive.
    NotPositive,
    /// Must be zero or positive.
    Negative,
    /// Outside the supported range `[min, max]` (in the parameter's own unit).
    OutOfRange {
        /// Smallest accepted value.
        min: f64,
        /// Largest accepted value.
        max: f64,
    },
    /// Inconsistent with another parameter, named here.
    Inconsistent(&'static str),
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.reason {
            ParamReason::NotFinite => write!(f, "`{}` must be a finite number", self.key),
            ParamReason::NotPositive => write!(f, "`{}` must be greater than zero", self.key),
            ParamReason::Negative => write!(f, "`{}` must not be negative", self.key),
            ParamReason::OutOfRange { min, max } => {
                write!(f, "`{}` must lie in [{min:e}, {max:e}]", self.key)
            }
            ParamReason::Inconsistent(what) => {
                write!(f, "`{}` is inconsistent with {what}", self.key)
            }
        }
    }
}

/// Checks that `value` is finite and strictly positive.
pub fn positive(key: &'static str, value: f64) -> Result<f64, ParamError> {
    if !value.is_finite() {
        Err(ParamError {
            key,
            reason: ParamReason::NotFinite,
        })
    } else if value <= 0.0 {
        Err(ParamError {
            key,
            reason: ParamReason::NotPositive,
        })
    } else {
        Ok(value)
    }
}

/// Checks that `value` is finite and not negative.
pub fn non_negative(key: &'static str, value: f64) -> Result<f64, ParamError> {
    if !value.is_finite() {
        Err(ParamError {
            key,
            reason: ParamReason::NotFinite,
        })
    } else if value < 0.0 {
        Err(ParamError {
            key,
            reason: ParamReason::Negative,
        })
    } else {
        Ok(value)
    }
}

/// Checks that `value` is finite and in `[min, max]`.
pub fn in_range(key: &'static str, value: f64, min: f64, max: f64) -> Result<f64, ParamError> {
    if !value.is_finite() {
        Err(ParamError {
            key,
            reason: ParamReason::NotFinite,
        })
    } else if value < min || value > max {
        Err(ParamError {
            key,
            reason: ParamReason::OutOfRange { min, max },
        })
    } else {
        Ok(value)
    }
}

impl MotorParams {
    /// The saliency `|L_q − L_d|/(L_q + L_d)`: 0 on a surface motor (Khlaief, Boussak, Gossa
    /// (2012) eq. 10–13, `Δ/Σ`; docs/khlaief2012.md §3). Inlined: a firmware's constant motor
    /// then folds the choices made from it (estimator, start-up) and links only what they use.
    #[inline]
    pub fn saliency(&self) -> f64 {
        libm::fabs(self.lq_h - self.ld_h) / (self.lq_h + self.ld_h)
    }

    /// Surface or interior motor with `K_T = 1.5 p ψ`, no ratings; call [`MotorParams::validate`].
    #[allow(clippy::too_many_arguments)]
    pub fn new(
        pole_pairs: u32,
        rs_ohm: f64,
        ld_h: f64,
        lq_h: f64,
        flux_wb: f64,
        j_kg_m2: f64,
        b_nm_s: f64,
    ) -> Self {
        Self {
            pole_pairs,
            rs_ohm,
            ld_h,
            lq_h,
            flux_wb,
            kt_nm_per_a: 1.5 * pole_pairs as f64 * flux_wb,
            j_kg_m2,
            b_nm_s,
            rated_current_a: None,
            rated_speed_rpm: None,
        }
    }

    /// Checks every parameter; the error names the first offending key.
    ///
    /// Ranges are physical, not numerical: whether a motor fits the fixed-point envelope is
    /// decided by [`crate::units::PerUnit::new`].
    pub fn validate(&self) -> Result<(), ParamError> {
        if self.pole_pairs == 0 || self.pole_pairs > 100 {
            return Err(ParamError {
                key: "pole_pairs",
                reason: ParamReason::OutOfRange {
                    min: 1.0,
                    max: 100.0,
                },
            });
        }
        positive("rs_ohm", self.rs_ohm)?;
        positive("ld_h", self.ld_h)?;
        positive("lq_h", self.lq_h)?;
        positive("flux_wb", self.flux_wb)?;
        positive("kt_nm_per_a", self.kt_nm_per_a)?;
        positive("j_kg_m2", self.j_kg_m2)?;
        non_negative("b_nm_s", self.b_nm_s)?;
        if let Some(i) = self.rated_current_a {
            positive("rated_current_a", i)?;
        }
        if let Some(n) = self.rated_speed_rpm {
            positive("rated_speed_rpm", n)?;
        }
        Ok(())
    }

    /// True for a surface motor (`L_d = L_q` within 0.1 %).
    pub fn is_surface(&self) -> bool {
        libm::fabs(self.ld_h - self.lq_h) <= 1e-3 * self.lq_h
    }

    /// Pole pairs as `f64`.
    pub fn p(&self) -> f64 {
        self.pole_pairs as f64
    }
}

/// Parameters of the voltage-source inverter that feeds the motor.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverterParams {
    /// Nominal DC bus voltage, V.
    pub vdc_v: f64,
    /// PWM switching frequency, Hz.
    pub pwm_hz: f64,
    /// Dead time inserted at each switching edge, s.
    pub dead_time_s: f64,
    /// Largest current the phase-current sensing can measure (ADC full scale), A peak.
    pub current_full_scale_a: f64,
}

impl InverterParams {
    /// Checks every parameter; the error names the first offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        in_range("vdc_v", self.vdc_v, 1.0, 2000.0)?;
        in_range("pwm_hz", self.pwm_hz, 1.0e3, 200.0e3)?;
        non_negative("dead_time_s", self.dead_time_s)?;
        if self.dead_time_s * self.pwm_hz >= 0.1 {
            return Err(ParamError {
                key: "dead_time_s",
                reason: ParamReason::Inconsistent("pwm_hz (dead time over 10 % of the period)"),
            });
        }
        positive("current_full_scale_a", self.current_full_scale_a)?;
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn motor_a() -> MotorParams {
        let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
        m.kt_nm_per_a = 1.108;
        m
    }

    #[test]
    fn motor_a_is_valid_and_surface() {
        assert_eq!(motor_a().validate(), Ok(()));
        assert!(motor_a().is_surface());
    }

    #[test]
    fn each_bad_parameter_is_named() {
        type Spoil = fn(&mut MotorParams);
        let cases: [(Spoil, &str); 6] = [
            (|m| m.rs_ohm = 0.0, "rs_ohm"),
            (|m| m.ld_h = -1e-3, "ld_h"),
            (|m| m.lq_h = f64::NAN, "lq_h"),
            (|m| m.flux_wb = f64::INFINITY, "flux_wb"),
            (|m| m.pole_pairs = 0, "pole_pairs"),
            (|m| m.b_nm_s = -1.0, "b_nm_s"),
        ];
        for (spoil, key) in cases {
            let mut m = motor_a();
            spoil(&mut m);
            assert_eq!(m.validate().map_err(|e| e.key), Err(key));
        }
    }
}
