//! The coefficients of the current-model MRAS that depend on the motor's resistance and magnet
//! flux: computed once from the motor in `f64` ([`MrasModel::new`], the reference), and again
//! in `f32` for a tracked `R` and `ψ` ([`MrasModelScaling::model`], the task's, docs/tracking.md,
//! "The model's coefficients").

use super::config::{coef, pu_in};
use super::*;
use crate::error::ConfigError;
use crate::num::{Coef, Pu, f64_to_bits_sat};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// The coefficients of [`MrasCurrentConfig`] that depend on the motor's resistance and magnet
/// flux (the model weights, the offsets `Ψ_d`, `Ψ_q`, `ψ/L_d` of ξ̃ and the scale of
/// [`MrasCurrent::xi`]): what on-line tracking of `R` and `ψ` rewrites
/// ([`MrasCurrent::set_model`], docs/tracking.md). Built by [`MrasModel::new`] with the same
/// expressions as [`MrasCurrentConfig::new`], so the same motor gives the same bits.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrasModel {
    pub(super) xd_i: Coef<MODEL_FRAC>,
    pub(super) xd_v: Coef<MODEL_FRAC>,
    pub(super) xq_i: Coef<MODEL_FRAC>,
    pub(super) xq_v: Coef<MODEL_FRAC>,
    pub(super) yq_i: Coef<MODEL_FRAC>,
    pub(super) yq_v: Coef<MODEL_FRAC>,
    pub(super) yd_i: Coef<MODEL_FRAC>,
    pub(super) yd_v: Coef<MODEL_FRAC>,
    pub(super) off_d: Pu,
    pub(super) off_d_acc: i64,
    pub(super) off_q_acc: i64,
    pub(super) psi_ld: Pu,
    pub(super) xi_scale: Coef<24>,
}

impl MrasModel {
    /// The coefficients for `motor` sampled as in `base` (module docs, "Discretisation").
    ///
    /// Errors: [`ConfigError::Gain`] naming `ld_h` or `lq_h` for a weight or offset outside
    /// its format (module docs, "Formats"); `motor` is not otherwise validated here.
    pub fn new(motor: &MotorParams, base: &PerUnit) -> Result<Self, ConfigError> {
        let ts = base.sample_s;
        let (r, ld, lq, psi) = (
            motor.rs_ohm / base.impedance_ohm,
            motor.ld_h / base.inductance_h,
            motor.lq_h / base.inductance_h,
            motor.flux_wb / base.flux_wb,
        );
        let rho = lq / ld;
        let a_d = libm::exp(-0.5 * motor.rs_ohm * ts / motor.ld_h);
        let a_q = libm::exp(-0.5 * motor.rs_ohm * ts / motor.lq_h);
        let (g_d, g_q) = ((1.0 - a_d) / r, (1.0 - a_q) / r);
        let (psi_d, psi_q) = (psi / ld, psi / lq);
        let m = |key, v| coef::<MODEL_FRAC>(key, v, 0.0, MODEL_MAX);
        let off_d = pu_in("ld_h", a_d * psi_d, 0.0, OFFSET_MAX)?;
        let off_q = pu_in("lq_h", a_q * psi_q, 0.0, OFFSET_MAX)?;
        Ok(Self {
            xd_i: m("ld_h", a_d * a_d)?,
            xd_v: m("ld_h", (1.0 + a_d) * g_d)?,
            xq_i: m("lq_h", a_d * a_q * rho)?,
            xq_v: m("lq_h", a_d * rho * g_q + g_d)?,
            yq_i: m("lq_h", a_q * a_q)?,
            yq_v: m("lq_h", (1.0 + a_q) * g_q)?,
            yd_i: m("ld_h", a_q * a_d / rho)?,
            yd_v: m("ld_h", a_q * g_d / rho + g_q)?,
            off_d,
            off_d_acc: (off_d.to_bits() as i64) << MODEL_FRAC,
            off_q_acc: (off_q.to_bits() as i64) << MODEL_FRAC,
            psi_ld: pu_in("ld_h", psi_d, 0.0, OFFSET_MAX)?,
            xi_scale: coef("ld_h", ld / psi, 0.0, Coef::<24>::limit())?,
        })
    }
}

impl MrasCurrentConfig {
    /// The coefficients of `R` and `ψ` it holds ([`MrasCurrent::set_model`]'s).
    #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
    pub(crate) fn model(&self) -> MrasModel {
        MrasModel {
            xd_i: self.xd_i,
            xd_v: self.xd_v,
            xq_i: self.xq_i,
            xq_v: self.xq_v,
            yq_i: self.yq_i,
            yq_v: self.yq_v,
            yd_i: self.yd_i,
            yd_v: self.yd_v,
            off_d: self.off_d,
            off_d_acc: self.off_d_acc,
            off_q_acc: self.off_q_acc,
            psi_ld: self.psi_ld,
            xi_scale: self.xi_scale,
        }
    }
}

#[cfg(test)]
impl MrasModel {
    /// The coefficients in order, as bits (the accumulators' offsets without their shift).
    pub(crate) fn bits(&self) -> [i64; 13] {
        [
            self.xd_i.bits().into(),
            self.xd_v.bits().into(),
            self.xq_i.bits().into(),
            self.xq_v.bits().into(),
            self.yq_i.bits().into(),
            self.yq_v.bits().into(),
            self.yd_i.bits().into(),
            self.yd_v.bits().into(),
            self.off_d.to_bits().into(),
            self.off_d_acc >> MODEL_FRAC,
            self.off_q_acc >> MODEL_FRAC,
            self.psi_ld.to_bits().into(),
            self.xi_scale.bits().into(),
        ]
    }
}

/// Words of a [`MrasModel`] in the drive's handoff.
pub(crate) const MRAS_MODEL_WORDS: usize = 15;

impl MrasModel {
    /// The coefficients as words (the drive's handoff from its task to its interrupt).
    pub(crate) fn write_words<const N: usize>(&self, w: &mut crate::drive::Packer<N>) {
        for c in [
            self.xd_i, self.xd_v, self.xq_i, self.xq_v, self.yq_i, self.yq_v, self.yd_i, self.yd_v,
        ] {
            w.i32(c.bits());
        }
        w.i32(self.off_d.to_bits());
        for x in [self.off_d_acc, self.off_q_acc] {
            w.u32(x as u32);
            w.u32((x >> 32) as u32);
        }
        w.i32(self.psi_ld.to_bits());
        w.i32(self.xi_scale.bits());
    }

    /// [`MrasModel::write_words`]'s coefficients.
    pub(crate) fn read_words<const N: usize>(r: &mut crate::drive::Unpacker<N>) -> Self {
        let mut c = || Coef::from_bits(r.i32());
        let (xd_i, xd_v, xq_i, xq_v, yq_i, yq_v, yd_i, yd_v) =
            (c(), c(), c(), c(), c(), c(), c(), c());
        let off_d = Pu::from_bits(r.i32());
        let mut wide = || i64::from(r.u32()) | (i64::from(r.u32()) << 32);
        let (off_d_acc, off_q_acc) = (wide(), wide());
        Self {
            xd_i,
            xd_v,
            xq_i,
            xq_v,
            yq_i,
            yq_v,
            yd_i,
            yd_v,
            off_d,
            off_d_acc,
            off_q_acc,
            psi_ld: Pu::from_bits(r.i32()),
            xi_scale: Coef::from_bits(r.i32()),
        }
    }
}

impl MrasCurrent {
    /// Replaces the coefficients that depend on `R` and `ψ` (a dozen words; the state is
    /// kept, so the model current carries on from where it is). Not for the control path:
    /// call it between two updates (docs/tracking.md).
    pub fn set_model(&mut self, m: &MrasModel) {
        let c = &mut self.config;
        c.xd_i = m.xd_i;
        c.xd_v = m.xd_v;
        c.xq_i = m.xq_i;
        c.xq_v = m.xq_v;
        c.yq_i = m.yq_i;
        c.yq_v = m.yq_v;
        c.yd_i = m.yd_i;
        c.yd_v = m.yd_v;
        c.off_d = m.off_d;
        c.off_d_acc = m.off_d_acc;
        c.off_q_acc = m.off_q_acc;
        c.psi_ld = m.psi_ld;
        c.xi_scale = m.xi_scale;
    }
}

/// [`MrasModel::new`] for the motor with `R = s_R R₀` and `ψ = s_ψ ψ₀`, in `f32` from
/// constants computed once from the motor: the tracker's rewrite of the model in the drive's
/// task, a few hundred `f32` operations where the `f64` reference costs tens of thousands of
/// instructions of software `f64` on a Cortex-M4 (three times that on a Cortex-M0).
///
/// Every weight is the reference's within a few LSB of its format (tests). The weights near
/// one keep all their bits: `a² = 1 + e (2 + e)` with `e = a − 1 = expm1(−R T_s/(2L))` computed
/// as such, and `a_d a_q ρ = ρ + ρ (e_d + e_q + e_d e_q)` with `ρ`'s bits from the `f64` design,
/// so `1 − a²`, the model's pole, is as exact as `e` (`f32`'s 2⁻²⁴ of itself) however slow the
/// motor's electrical time constant.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct MrasModelScaling {
    /// `R₀ T_s/(2 L_d)`, `R₀ T_s/(2 L_q)`: half a sample's decay at `R₀`.
    half_decay: [f32; 2],
    /// `R₀`, per unit.
    r0: f32,
    /// `ρ = L_q/L_d` and `1/ρ`, and their bits in the weights' format.
    rho: [f32; 2],
    rho_bits: [i32; 2],
    /// `ψ₀/L_d`, `ψ₀/L_q` (per unit) and `L_d/ψ₀`.
    psi_l: [f32; 2],
    l_psi: f32,
}

impl MrasModelScaling {
    /// The constants of `motor` sampled as in `base` (not validated here: the model's
    /// coefficients are checked where [`MrasModelScaling::model`] computes them).
    pub(crate) fn new(motor: &MotorParams, base: &PerUnit) -> Self {
        let ts = base.sample_s;
        let (ld, lq, psi) = (
            motor.ld_h / base.inductance_h,
            motor.lq_h / base.inductance_h,
            motor.flux_wb / base.flux_wb,
        );
        let rho = lq / ld;
        Self {
            half_decay: [
                (0.5 * motor.rs_ohm * ts / motor.ld_h) as f32,
                (0.5 * motor.rs_ohm * ts / motor.lq_h) as f32,
            ],
            r0: (motor.rs_ohm / base.impedance_ohm) as f32,
            rho: [rho as f32, (1.0 / rho) as f32],
            rho_bits: [
                f64_to_bits_sat(rho, MODEL_FRAC),
                f64_to_bits_sat(1.0 / rho, MODEL_FRAC),
            ],
            psi_l: [(psi / ld) as f32, (psi / lq) as f32],
            l_psi: (ld / psi) as f32,
        }
    }

    /// The coefficients at `R = s_r R₀` and `ψ = s_psi ψ₀` (module docs, "Discretisation";
    /// the names as in [`MrasModel::new`]): [`MrasModelScaling::decay`], then
    /// [`MrasModelScaling::weights`].
    ///
    /// Errors: [`ConfigError::Gain`] naming `ld_h` or `lq_h` for a weight or offset outside its
    /// format, as [`MrasModel::new`] for the same motor.
    #[cfg(test)]
    pub(crate) fn model(&self, s_r: f32, s_psi: f32) -> Result<MrasModel, ConfigError> {
        self.weights(&self.decay(s_r), s_psi)
    }

    /// The half-sample decay of each axis at `R = s_r R₀`: `e = a − 1` and `g = (1 − a)/R`.
    pub(crate) fn decay(&self, s_r: f32) -> MrasDecay {
        let e_d = libm::expm1f(-self.half_decay[0] * s_r);
        let e_q = libm::expm1f(-self.half_decay[1] * s_r);
        let r = self.r0 * s_r;
        MrasDecay {
            e: [e_d, e_q],
            g: [-e_d / r, -e_q / r],
        }
    }

    /// The coefficients from the decay at `R` and `ψ = s_psi ψ₀`.
    ///
    /// Errors: as [`MrasModelScaling::model`].
    pub(crate) fn weights(&self, decay: &MrasDecay, s_psi: f32) -> Result<MrasModel, ConfigError> {
        let ([e_d, e_q], [g_d, g_q]) = (decay.e, decay.g);
        let (a_d, a_q) = (1.0 + e_d, 1.0 + e_q);
        let [rho, inv_rho] = self.rho;
        let cross = e_d + e_q + e_d * e_q;
        let (psi_d, psi_q) = (self.psi_l[0] * s_psi, self.psi_l[1] * s_psi);
        let off_d = offset("ld_h", a_d * psi_d)?;
        let off_q = offset("lq_h", a_q * psi_q)?;
        Ok(MrasModel {
            xd_i: weight("ld_h", ONE_BITS.saturating_add(bits(e_d * (2.0 + e_d))))?,
            xd_v: weight("ld_h", bits((2.0 + e_d) * g_d))?,
            xq_i: weight("lq_h", self.rho_bits[0].saturating_add(bits(rho * cross)))?,
            xq_v: weight("lq_h", bits(a_d * rho * g_q + g_d))?,
            yq_i: weight("lq_h", ONE_BITS.saturating_add(bits(e_q * (2.0 + e_q))))?,
            yq_v: weight("lq_h", bits((2.0 + e_q) * g_q))?,
            yd_i: weight(
                "ld_h",
                self.rho_bits[1].saturating_add(bits(inv_rho * cross)),
            )?,
            yd_v: weight("ld_h", bits(a_q * g_d * inv_rho + g_q))?,
            off_d,
            off_d_acc: (off_d.to_bits() as i64) << MODEL_FRAC,
            off_q_acc: (off_q.to_bits() as i64) << MODEL_FRAC,
            psi_ld: offset("ld_h", psi_d)?,
            // Below `Coef<24>`'s limit, 2³¹ LSB: any non-negative `i32`.
            xi_scale: Coef::from_bits(in_format(
                "ld_h",
                scaled(self.l_psi / s_psi, 24),
                24,
                i64::from(i32::MAX),
                Coef::<24>::limit(),
            )?),
        })
    }
}

/// The half-sample decay of both axes at a resistance: `e = a − 1 = expm1(−R T_s/(2L))` and
/// `g = (1 − a)/R` (per unit), `d` then `q`.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub(crate) struct MrasDecay {
    e: [f32; 2],
    g: [f32; 2],
}

/// One in the weights' format.
const ONE_BITS: i32 = 1 << MODEL_FRAC;

/// `round(x 2^frac)` (half away from zero, as `roundf`), saturated to `i32` (NaN and ±∞
/// give the saturated value of their sign bit), from `x`'s bits: an exact conversion without
/// the float multiply, round and conversion that cost a few hundred instructions of software
/// float on a Cortex-M0.
fn scaled(x: f32, frac: u32) -> i32 {
    let b = x.to_bits();
    let negative = b >> 31 != 0;
    let exp = ((b >> 23) & 0xff) as i32;
    if exp == 0 {
        // Zero and subnormals (below 2⁻¹²⁶): zero in any format here.
        return 0;
    }
    let m = i64::from((b & 0x007f_ffff) | 0x0080_0000);
    // x = m 2^(exp − 150): round(x 2^frac) = m 2^shift.
    let shift = exp - 150 + frac as i32;
    let v = if shift >= 0 {
        if shift > 8 { i64::MAX } else { m << shift }
    } else if shift < -25 {
        0
    } else {
        (m + (1 << (-shift - 1))) >> -shift
    };
    let v = if negative { -v } else { v };
    v.clamp(i64::from(i32::MIN), i64::from(i32::MAX)) as i32
}

/// `x` in the weights' format.
fn bits(x: f32) -> i32 {
    scaled(x, MODEL_FRAC)
}

/// A weight's bits if in `[0, MODEL_MAX]`, else the error naming `key`.
fn weight(key: &'static str, b: i32) -> Result<Coef<MODEL_FRAC>, ConfigError> {
    const MAX_BITS: i64 = (MODEL_MAX * (1u64 << MODEL_FRAC) as f64) as i64;
    in_format(key, b, MODEL_FRAC, MAX_BITS, MODEL_MAX).map(Coef::from_bits)
}

/// An offset `ψ/L` as [`Pu`] if in `[0, OFFSET_MAX]`, else the error naming `key`.
fn offset(key: &'static str, x: f32) -> Result<Pu, ConfigError> {
    const MAX_BITS: i64 = (OFFSET_MAX * (1u64 << PU_FRAC) as f64) as i64;
    in_format(key, scaled(x, PU_FRAC), PU_FRAC, MAX_BITS, OFFSET_MAX).map(Pu::from_bits)
}

/// `b` (a value times `2^frac`) if in `[0, max_bits]`, else the error naming `key` and the
/// value against `max` (in `f64` on that path only).
fn in_format(
    key: &'static str,
    b: i32,
    frac: u32,
    max_bits: i64,
    max: f64,
) -> Result<i32, ConfigError> {
    if b >= 0 && i64::from(b) <= max_bits {
        Ok(b)
    } else {
        Err(ConfigError::Gain {
            key,
            value: libm::ldexp(f64::from(b), -(frac as i32)),
            min: 0.0,
            max,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::scaled;

    /// The conversion from bits is `roundf(x 2^frac)` saturated, on values across the
    /// formats, halves, and the edges.
    #[test]
    fn the_conversion_from_bits_rounds_as_roundf() {
        let mut worst = 0i64;
        let mut x = 1.0e-9f32;
        while x < 1.0e3 {
            for v in [x, -x, x * 1.000_000_1, 0.5 + x] {
                for frac in [24u32, 28] {
                    let want = libm::roundf(v * (1u32 << frac) as f32);
                    let want = (want as i64).clamp(i32::MIN.into(), i32::MAX.into());
                    worst = worst.max((i64::from(scaled(v, frac)) - want).abs());
                }
            }
            x *= 1.37;
        }
        assert_eq!(worst, 0);
        // Halves round away from zero; beyond the format saturates; NaN is not a number of
        // the format but saturates by its sign bit, as ±∞ do.
        assert_eq!(scaled(2.5 / (1u32 << 24) as f32, 24), 3);
        assert_eq!(scaled(-2.5 / (1u32 << 24) as f32, 24), -3);
        assert_eq!(scaled(200.0, 24), i32::MAX);
        assert_eq!(scaled(-200.0, 24), i32::MIN);
        assert_eq!(scaled(f32::INFINITY, 28), i32::MAX);
        assert_eq!(scaled(0.0, 28), 0);
    }
}
