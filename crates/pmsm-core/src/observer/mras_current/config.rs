//! The fixed-point configuration of the current-model MRAS, computed once from the motor, the
//! bases and the gains (module docs, "Discretisation" and "Formats").

use super::*;
use crate::error::ConfigError;
use crate::num::{Coef, Pu, pu_from_f64};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Configuration of the [`MrasCurrent`] estimator.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct MrasCurrentConfig {
    /// Weights of the composed Strang step (module docs, "Discretisation"):
    /// `X_d = xd_i î_d + xd_v v_d + Ψ_d`, `X_q = xq_i î_q + xq_v v_q`,
    /// `Y_q = yq_i î_q + yq_v v_q`, `Y_d = yd_i î_d + yd_v v_d + Ψ_q`.
    pub(super) xd_i: Coef<MODEL_FRAC>,
    pub(super) xd_v: Coef<MODEL_FRAC>,
    pub(super) xq_i: Coef<MODEL_FRAC>,
    pub(super) xq_v: Coef<MODEL_FRAC>,
    pub(super) yq_i: Coef<MODEL_FRAC>,
    pub(super) yq_v: Coef<MODEL_FRAC>,
    pub(super) yd_i: Coef<MODEL_FRAC>,
    pub(super) yd_v: Coef<MODEL_FRAC>,
    /// `Ψ_d = a_d ψ/L_d` in Q8.24, and the same in the weights' accumulator (`× 2^MODEL_FRAC`).
    pub(super) off_d: Pu,
    pub(super) off_d_acc: i64,
    /// `Ψ_q = a_q ψ/L_q` in the weights' accumulator.
    pub(super) off_q_acc: i64,
    /// `w ρ² = w (L_q/L_d)²` (`w` the d-axis error's weight) and `ψ/L_d` of ξ̃ (eq. 22 ×
    /// L_q/L_d).
    pub(super) rho2: Coef<26>,
    pub(super) psi_ld: Pu,
    /// `ξ' = (L_d/ψ) ξ̃`, for [`MrasCurrent::xi`] only.
    pub(super) xi_scale: Coef<24>,
    /// Angle step per unit of speed: `ω_b T_s 2³³/(2π)`; times `2^TURN_SHIFT` gives 2⁻⁶⁴ turns.
    pub(super) turn_per_speed: i32,
    /// Speed integrator (Q9.55 increments, beside the schedule's `K_i T_s`):
    /// `T_s p K_T I_b/(J ω_b)`, `T_s B/J`.
    pub(super) accel: Coef<31>,
    pub(super) friction: Coef<31>,
    /// The back-calculation gain `min(1, K_i T_s/K_p)` (zero: `K_p = 0`, conditional
    /// integration): the same at every level of the schedule.
    pub(super) kt: Coef<30>,
    /// The gains in use: a level of the low-speed schedule, rewritten by
    /// [`MrasCurrent::schedule`] between updates (as [`MrasCurrent::set_model`] rewrites the
    /// model), kept here where the update reads its other coefficients.
    pub(super) gains: Gains,
    /// The design gains (level 0).
    pub(super) design: Gains,
    /// The low-speed schedule (module docs, "Low-speed schedule"): level `j` holds below
    /// `above[j − 1]` (per unit of speed, descending) down to `above[j]`; at most level `top`
    /// (the highest whose gains fit their formats; 0 with the schedule off).
    pub(super) above: [Pu; BOOST_LEVELS - 1],
    /// (`u32`, not `usize`: the drive image of the C interface has the same layout on the
    /// host and the target.)
    pub(super) top: u32,
    /// Speed clamp, per unit, and in Q9.55.
    pub(super) omega_max: Pu,
    pub(super) omega_max_wide: i64,
}

/// The adaptation gains the update uses, in their formats: the design's, or a level of the
/// low-speed schedule.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
pub(super) struct Gains {
    /// `K_p` on ξ̃ (Q8.24 gain), `K_i T_s` on ξ̃, and the load estimate's `T_s K_L I_b/ρ`.
    pub(super) kp: Coef<24>,
    pub(super) ki_ts: Coef<31>,
    pub(super) load_gain: Coef<27>,
}

impl Gains {
    /// The gains times the factor `b_j` of level `j` (1, 3/2, 2, 3, 4): shifts and adds, which
    /// cannot wrap up to the level `top` the configuration allows.
    #[inline(always)]
    fn boosted(self, j: usize) -> Self {
        let b = |x: i32| match j {
            0 => x,
            1 => x + (x >> 1),
            2 => x << 1,
            3 => (x << 1) + x,
            _ => x << 2,
        };
        Self {
            kp: Coef::from_bits(b(self.kp.bits())),
            ki_ts: Coef::from_bits(b(self.ki_ts.bits())),
            load_gain: Coef::from_bits(b(self.load_gain.bits())),
        }
    }
}

/// `value` as a `Coef<F>` if it is in `[min, max]` and representable, else the typed error
/// naming `key` (the motor parameter or gain the coefficient comes from).
pub(super) fn coef<const F: u32>(
    key: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<Coef<F>, ConfigError> {
    let err = ConfigError::Gain {
        key,
        value,
        min,
        max,
    };
    if !(value >= min && value <= max) {
        return Err(err);
    }
    Coef::new(value).ok_or(err)
}

/// A per-unit constant in `[min, max]` as [`Pu`], else the typed error naming `key`.
pub(super) fn pu_in(key: &'static str, value: f64, min: f64, max: f64) -> Result<Pu, ConfigError> {
    if value >= min && value <= max {
        Ok(pu_from_f64(value))
    } else {
        Err(ConfigError::Gain {
            key,
            value,
            min,
            max,
        })
    }
}

impl MrasCurrentConfig {
    /// Estimator for `motor` sampled as in `base`, with adaptation gains `gains`
    /// ([`MrasCurrentGains::default_for`] for the defaults).
    ///
    /// Errors: [`ConfigError::Param`] for a bad motor parameter; [`ConfigError::Gain`] naming
    /// `mras_current.kp`, `mras_current.ki` or `mras_current.kl` outside the ranges of the
    /// module docs or `mras_current.d_weight` outside `[0, 1]`, or naming the motor parameter
    /// (`ld_h`, `lq_h`, `j_kg_m2`, `b_nm_s`, `sample_hz`) of a coefficient outside its format
    /// (module docs, "Formats").
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        gains: MrasCurrentGains,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let ts = base.sample_s;
        let k_inf = MrasCurrentGains::k_inf(motor);
        let kp_max = 1.0 / (k_inf * ts);
        let ki_max = 0.25 / (k_inf * ts * ts);
        let a = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        let kl_max = 0.1 / (a * k_inf * ts * ts * ts);
        for (key, v, max) in [
            ("mras_current.kp", gains.kp, kp_max),
            ("mras_current.ki", gains.ki, ki_max),
            ("mras_current.kl", gains.kl, kl_max),
        ] {
            if !(v >= 0.0 && v <= max) {
                return Err(ConfigError::Gain {
                    key,
                    value: v,
                    min: 0.0,
                    max,
                });
            }
        }
        // Apart from the gains' loop: a fourth entry there deepened this frame (measured on
        // the Cortex-M0 PIL harness's stack, then 12 bytes short of the micro:bit's RAM).
        let d_weight = f64::from(gains.d_weight);
        if !(0.0..=1.0).contains(&d_weight) {
            return Err(ConfigError::Gain {
                key: "mras_current.d_weight",
                value: d_weight,
                min: 0.0,
                max: 1.0,
            });
        }
        let mech = gains.kl > 0.0;
        let model = MrasModel::new(motor, base)?;
        let rho = (motor.lq_h / base.inductance_h) / (motor.ld_h / base.inductance_h);
        // ξ̃ = (L_q/L_d) ξ: gains on ξ̃ are the SI gains times I_b²/(ρ ω_b) (ξ in A², ω in pu).
        let scale = base.current_a * base.current_a / (rho * base.omega_e_rad_s);
        let omega_max = MAX_SPEED_PU.min(1.0 / (base.omega_e_rad_s * ts));
        // The per-unit formats bound the SI gains too (errors in SI units, as given).
        let kp = Coef::<24>::new(gains.kp * scale).ok_or(gain_err(
            "mras_current.kp",
            gains.kp,
            Coef::<24>::limit() / scale,
        ))?;
        let ki_ts = Coef::<31>::new(gains.ki * ts * scale).ok_or(gain_err(
            "mras_current.ki",
            gains.ki,
            Coef::<31>::limit() / (ts * scale),
        ))?;
        let load_scale = ts * base.current_a / rho;
        let load_gain = Coef::<27>::new(gains.kl * load_scale).ok_or(gain_err(
            "mras_current.kl",
            gains.kl,
            Coef::<27>::limit() / load_scale,
        ))?;
        // Back-calculation gain from the stored values (as the f64 model of a PI would).
        let kt = if kp.bits() > 0 {
            Coef::new((ki_ts.to_f64() / kp.to_f64()).min(1.0)).unwrap_or(Coef::ZERO)
        } else {
            Coef::ZERO
        };
        let design = Gains {
            kp,
            ki_ts,
            load_gain,
        };
        let (above, top) = low_speed_schedule(motor, base, &design, gains.low_speed_schedule);
        let accel = if mech {
            ts * motor.p() * motor.kt_nm_per_a * base.current_a
                / (motor.j_kg_m2 * base.omega_e_rad_s)
        } else {
            0.0
        };
        let friction = if mech {
            ts * motor.b_nm_s / motor.j_kg_m2
        } else {
            0.0
        };
        // ω_b T_s ≤ 1.5 rad (the envelope of `PerUnit`) keeps this below 2^31 (2.05e9).
        let turn =
            libm::round(base.omega_e_rad_s * ts * libm::ldexp(1.0, 33) / core::f64::consts::TAU);
        let turn_max = i32::MAX as f64;
        if !(turn >= 0.0 && turn <= turn_max) {
            return Err(ConfigError::Gain {
                key: "sample_hz",
                value: 1.0 / ts,
                min: base.omega_e_rad_s * libm::ldexp(1.0, 33)
                    / (core::f64::consts::TAU * turn_max),
                max: f64::INFINITY,
            });
        }
        let turn_per_speed = turn as i32;
        Ok(Self {
            xd_i: model.xd_i,
            xd_v: model.xd_v,
            xq_i: model.xq_i,
            xq_v: model.xq_v,
            yq_i: model.yq_i,
            yq_v: model.yq_v,
            yd_i: model.yd_i,
            yd_v: model.yd_v,
            off_d: model.off_d,
            off_d_acc: model.off_d_acc,
            off_q_acc: model.off_q_acc,
            rho2: coef("lq_h", d_weight * rho * rho, 0.0, 16.0)?,
            psi_ld: model.psi_ld,
            xi_scale: model.xi_scale,
            turn_per_speed,
            accel: coef("j_kg_m2", accel, 0.0, MECH_MAX)?,
            friction: coef("b_nm_s", friction, 0.0, MECH_MAX)?,
            kt,
            gains: design,
            design,
            above,
            top,
            omega_max: pu_from_f64(omega_max),
            omega_max_wide: (pu_from_f64(omega_max).to_bits() as i64) << INTEG_EXTRA,
        })
    }
}

impl MrasCurrentConfig {
    /// The schedule's level for the estimated speed `omega`: the number of thresholds above
    /// `|ω̂|`, at most `top`. Out of line: every eighth sample and at a reset.
    #[inline(never)]
    pub(super) fn level(&self, omega: Pu) -> usize {
        let speed = omega.saturating_abs();
        self.above
            .iter()
            .take_while(|a| speed < **a)
            .count()
            .min(self.top as usize)
    }

    /// The gains of the schedule's level for the estimated speed `omega`.
    #[inline(always)]
    pub(super) fn gains_at(&self, omega: Pu) -> Gains {
        self.design.boosted(self.level(omega))
    }
}

/// The low-speed schedule's thresholds `c_j ω_c` (per unit, descending) and its top level
/// for the design gains `design` (module docs, "Low-speed schedule"); level 0 only when `on`
/// is false. Out of line: built once, and kept out of the constructors it would swell.
#[inline(never)]
fn low_speed_schedule(
    motor: &MotorParams,
    base: &PerUnit,
    design: &Gains,
    on: bool,
) -> ([Pu; BOOST_LEVELS - 1], u32) {
    // The corner `R/√(L_d L_q)` of ξ's sensitivity at zero current, per unit of ω_b.
    let corner = motor.rs_ohm / (libm::sqrt(motor.ld_h * motor.lq_h) * base.omega_e_rad_s);
    let mut above = [Pu::ZERO; BOOST_LEVELS - 1];
    for (a, c) in above.iter_mut().zip(BOOST_ABOVE) {
        *a = threshold(c, corner);
    }
    // The highest level whose gains (`b_j` times, at most 4) all fit their formats.
    let largest = design
        .kp
        .bits()
        .max(design.ki_ts.bits())
        .max(design.load_gain.bits()) as i64;
    let top = if on {
        [(3, 2), (2, 1), (3, 1), (4, 1)]
            .iter()
            .take_while(|(n, d)| largest * n <= i32::MAX as i64 * d)
            .count() as u32
    } else {
        0
    };
    (above, top)
}

/// The speed `c ω_c` (per unit) from which a level of the schedule holds. Out of line: a
/// loop of four calls stays small in the image.
#[inline(never)]
fn threshold(c: f64, corner: f64) -> Pu {
    pu_from_f64((c * corner).min(MAX_SPEED_PU))
}

/// The error for an SI gain whose per-unit coefficient does not fit its format.
fn gain_err(key: &'static str, value: f64, max: f64) -> ConfigError {
    ConfigError::Gain {
        key,
        value,
        min: 0.0,
        max,
    }
}
