//! dq current controllers of Khlaief, Boussak, Gossa (2012) (§1, Fig. 5; docs/khlaief2012.md §6–7).
//!
//! Two PI controllers ([`super::pi::Pi`]) in the rotor frame, `i_d* = 0` by default (Khlaief, Boussak, Gossa (2012) §1), with the
//! optional decoupling feed-forward of the dq model (Khlaief, Boussak, Gossa (2012) eq. 3–4, docs/khlaief2012.md §1):
//!
//! ```text
//! v_d = PI_d(i_d* − i_d) − ω L_q i_q
//! v_q = PI_q(i_q* − i_q) + ω (L_d i_d + ψ)
//! ```
//!
//! # Gains (pole–zero cancellation)
//!
//! `K_p = ω_c L`, `K_i = ω_c R` per axis (`L_d` on d, `L_q` on q): the PI zero
//! `K_i/K_p = R/L` cancels the winding's pole, and the loop `(K_p s + K_i)/s · 1/(L s + R)`
//! becomes `ω_c/s`, a first-order closed loop of bandwidth `ω_c` (10–90 % rise time
//! `ln 9/ω_c`). With the current sampled at `t_k` and the voltage applied over `[t_k, t_{k+1})`
//! the discrete pole is at `1 − ω_c T_s` (to first order in `R T_s/L`), so `ω_c T_s` must stay
//! well below 1: the default is `ω_c = 0.1/T_s` (1400 rad/s at 14 kHz; with the PWM update's
//! period of delay and the hold's half period the loop keeps about 81° of phase margin), and
//! `K_p` is accepted up to `L/T_s` (`ω_c T_s = 1`, a deadbeat loop). Against `0.05/T_s` the
//! faster loop leaves less of a voltage error (the inverter's, a model's) to the estimators:
//! docs/khlaief2012.md §6 gives the measurements.
//!
//! # Voltage limit: circle, d axis first
//!
//! The available voltage is the linear range of SVPWM, `V_max = m · V_DC/√3` with the
//! measured bus and a margin `m ≤ 1` ([`CurrentDesign::modulation`]). d is limited to
//! `±V_max`, then q to `±√(V_max² − v_d²)`: the d axis, which sets the flux and (at
//! `i_d* = 0`) needs little voltage, keeps its authority, and the q axis gets what is left.
//! Each PI sees its own axis limit, so its anti-windup (back-calculation and integrator
//! clamping, [`super::pi`]) acts exactly when the vector reaches the circle. The dead-time
//! compensation added after this stage may carry it past the circle; the modulator passes it
//! whole up to its hexagon, and only beyond (or after a bus drop between the two) shortens it
//! and sets its `saturated` flag, which is fed back as [`CurrentInput::hold`] and stops both
//! integrators from winding outward.
//!
//! The room needs no root: it is `V_max √(1 − t²)` with `t = |v_d|/V_max`, interpolated on the
//! arc from inside ([`super::arc_room`]): never beyond the circle, short of it by at most
//! `10⁻⁴ V_max` for `t ≤ ½`, `5·10⁻⁴ V_max` for `t ≤ 0.9` (an exact root cost the saturated
//! step ~130 instructions on a Cortex-M4, some 400 on a Cortex-M0). `t` is taken at or above
//! its value, within 1.8·10⁻⁴ at `m = 1`, from 32-bit products alone: `|v_d|/v_DC` in Q16 from
//! the top bits of the bus's reciprocal (which the drive keeps from one reading to the next),
//! then times `√3/m` in Q15; the room that costs is at most `1.1·10⁻⁴ V_max` more for
//! `t ≤ ½` (`3.7·10⁻⁴ V_max` at `t = 0.9`).
//! It is read only when the q axis comes near the circle: the q PI first finishes its step
//! with the inner bound `V_max − |v_d|` (`(V_max − |v_d|)² ≤ V_max² − v_d²`), and only if a
//! limit took part (`Pi::finish`) again with the room, from the same products (`Pi::prepare`);
//! an output beyond the bound before the limits goes to the room at once.
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | currents, voltages, `ω`, `v_DC`, `ψ` | [`Pu`] Q8.24 | ±128 |
//! | `L_d`, `L_q` (per unit, `= X/Z_b` at base speed) | [`Coef<24>`](Coef) | [2⁻⁸, 64] (envelope), resolution 6e−8 |
//! | `m/√3` | [`Coef<31>`](Coef) | (0, 0.578] |
//! | `|v_d|/v_DC`, `√3/m`, `t` (the room's) | Q16 (`u32`), Q15 (`u32`), Q2.30 | `t` in `[0, 1 + 2⁻²)`; `√3/m < 2²⁶` |
//! | `K_p`, `K_i T_s` | [`PiConfig`] | `K_p` [2⁻⁹, 2¹⁴) pu, `K_i T_s` 0 or [2⁻²², 1) pu |
//! | `V_max` | [`Pu`] | ≤ 1.16 · `m` at nominal bus |
//!
//! `K_p` up to 2¹⁴ covers the deadbeat gain `L/T_s` of every motor of the per-unit envelope;
//! `K_i T_s < 1` per unit (`K_i T_s < Z_b`) is far above any useful design (the default is
//! `0.05 R/Z_b`).

use super::gain_in;
use super::pi::{Pi, PiConfig, coef_in};
use super::{arc_room, frac_mul};
use crate::error::ConfigError;
use crate::frames::Dq;
use crate::num::{Coef, Pu, Reciprocal, mul, pu_from_f64};
use crate::params::{MotorParams, in_range};
use crate::units::PerUnit;

/// How the current controllers are designed; [`CurrentDesign::default_for`] gives the
/// defaults.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct CurrentDesign {
    /// Closed-loop bandwidth `ω_c`, rad/s (used when the gains are not given).
    pub bandwidth_rad_s: f64,
    /// d-axis gains `(K_p` in V/A, `K_i` in V/(A·s)`)`, overriding `ω_c L_d`, `ω_c R`.
    pub gains_d: Option<(f64, f64)>,
    /// q-axis gains `(K_p, K_i)`, overriding `ω_c L_q`, `ω_c R`.
    pub gains_q: Option<(f64, f64)>,
    /// Add the decoupling feed-forward `−ω L_q i_q` (d) and `ω (L_d i_d + ψ)` (q).
    pub decoupling: bool,
    /// Fraction `m` of the linear SVPWM range `V_DC/√3` the loops may use, in (0, 1].
    pub modulation: f64,
}

impl CurrentDesign {
    /// `ω_c = 0.1/T_s`, pole–zero-cancelling gains, decoupling on, `m = 1`.
    pub fn default_for(base: &PerUnit) -> Self {
        Self {
            bandwidth_rad_s: DEFAULT_BANDWIDTH_TS / base.sample_s,
            gains_d: None,
            gains_q: None,
            decoupling: true,
            modulation: 1.0,
        }
    }
}

/// Default `ω_c T_s`: 1400 rad/s at 14 kHz, a decade below the sampling limit.
pub const DEFAULT_BANDWIDTH_TS: f64 = 0.1;

/// Configuration of the [`CurrentController`].
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct CurrentConfig {
    pi_d: PiConfig,
    pi_q: PiConfig,
    /// `L_d` per unit.
    ld: Coef<24>,
    /// `−L_q` per unit (negated: `ff_d = −ω L_q i_q` without a negation per sample).
    neg_lq: Coef<24>,
    /// `ψ` per unit.
    psi: Pu,
    /// `m/√3`: `V_max = m/√3 · v_DC` (both per unit of `V_b`).
    vmax_per_vdc: Coef<31>,
    /// `√3/m` in Q15, rounded up (below 2²⁶): `x/V_max = x/v_DC · √3/m`, from the bus's
    /// reciprocal, in one 32-bit product with `x/v_DC` to Q16.
    vdc_per_vmax_q15: u32,
    decoupling: bool,
}

impl CurrentConfig {
    /// `ψ` of the feed-forward, per unit.
    pub(crate) fn psi(&self) -> Pu {
        self.psi
    }

    /// The gains in use, SI, from their fixed-point values in the bases `base` the
    /// configuration was built in: `[K_p,d, K_i,d, K_p,q, K_i,q]` (V/A, V/(A·s)).
    pub fn gains_si(&self, base: &PerUnit) -> [f64; 4] {
        let z_b = base.impedance_ohm;
        let ki = z_b / base.sample_s;
        [
            self.pi_d.kp() * z_b,
            self.pi_d.ki_ts() * ki,
            self.pi_q.kp() * z_b,
            self.pi_q.ki_ts() * ki,
        ]
    }

    /// Designs the two current controllers for `motor` sampled as in `base`.
    ///
    /// Errors: a motor parameter ([`ConfigError::Param`]); `bandwidth_rad_s` outside
    /// `(0, 1/T_s]`, a `K_p` outside `(0, L/T_s]` or `K_i` outside `[0, K_p/T_s]`, or a
    /// gain outside the fixed-point ranges (`K_p/Z_b` in [2⁻⁹, 2¹⁴), `K_i T_s/Z_b` 0 or in
    /// [2⁻²², 1)) ([`ConfigError::Gain`] naming `current.bandwidth_rad_s`, `current.kp_d`,
    /// ..., in SI units); `modulation` outside `(0, 1.5]` (above 1 for an overmodulating
    /// modulator only).
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        design: CurrentDesign,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let ts = base.sample_s;
        let z_b = base.impedance_ohm;
        let r = motor.rs_ohm;
        // Up to 1.5: an overmodulating modulator takes requests beyond its circle.
        let m = in_range("current.modulation", design.modulation, 1e-3, 1.5)?;
        let (kp_d, ki_d, kp_q, ki_q) = {
            let need_bw = design.gains_d.is_none() || design.gains_q.is_none();
            let wc = if need_bw {
                gain_in(
                    "current.bandwidth_rad_s",
                    design.bandwidth_rad_s,
                    1e-9,
                    1.0 / ts,
                )?
            } else {
                design.bandwidth_rad_s
            };
            let (kp_d, ki_d) = design.gains_d.unwrap_or((wc * motor.ld_h, wc * r));
            let (kp_q, ki_q) = design.gains_q.unwrap_or((wc * motor.lq_h, wc * r));
            (kp_d, ki_d, kp_q, ki_q)
        };
        gain_in("current.kp_d", kp_d, 1e-12, motor.ld_h / ts)?;
        gain_in("current.kp_q", kp_q, 1e-12, motor.lq_h / ts)?;
        gain_in("current.ki_d", ki_d, 0.0, kp_d / ts)?;
        gain_in("current.ki_q", ki_q, 0.0, kp_q / ts)?;
        let pi_d = PiConfig::new(
            kp_d / z_b,
            ki_d * ts / z_b,
            ["current.kp_d", "current.ki_d"],
            [z_b, z_b / ts],
        )?;
        let pi_q = PiConfig::new(
            kp_q / z_b,
            ki_q * ts / z_b,
            ["current.kp_q", "current.ki_q"],
            [z_b, z_b / ts],
        )?;
        let l_b = base.inductance_h;
        Ok(Self {
            pi_d,
            pi_q,
            ld: coef_in("ld_h", motor.ld_h / l_b, (0.0, f64::MAX), true, l_b)?,
            // The negation of a representable non-negative value is representable.
            neg_lq: Coef::new(
                -coef_in::<24>("lq_h", motor.lq_h / l_b, (0.0, f64::MAX), true, l_b)?.to_f64(),
            )
            .unwrap_or(Coef::ZERO),
            psi: pu_from_f64(motor.flux_wb / base.flux_wb),
            vmax_per_vdc: coef_in(
                "current.modulation",
                m / libm::sqrt(3.0),
                (0.0, 1.0),
                true,
                1.0,
            )?,
            // √3/m ≤ √3/10⁻³ < 2¹¹: below 2²⁶ in Q15; rounded up so that x/V_max is never short.
            vdc_per_vmax_q15: libm::ceil(libm::ldexp(libm::sqrt(3.0) / m, 15)) as u32,
            decoupling: design.decoupling,
        })
    }
}

/// What the current controllers see at one sample, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CurrentInput {
    /// Current reference (`i_d* = 0` for Khlaief, Boussak, Gossa's (2012) drive).
    pub i_ref: Dq,
    /// Measured current in the (estimated) rotor frame.
    pub i: Dq,
    /// Electrical speed used by the decoupling, per unit of `ω_b`.
    pub omega: Pu,
    /// Measured bus voltage, per unit of `V_b` (√3 at the nominal bus).
    pub vdc: Pu,
    /// The modulator saturated at the previous sample: do not integrate outward.
    pub hold: bool,
}

/// Output of the current controllers.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CurrentOutput {
    /// Voltage command in the rotor frame, per unit; `|v| ≤ V_max` (within 1 LSB).
    pub v: Dq,
    /// The available voltage `V_max = m v_DC/√3` at this sample.
    pub v_max: Pu,
    /// The d controller hit its limit.
    pub saturated_d: bool,
    /// The q controller hit its limit.
    pub saturated_q: bool,
}

/// The dq current controllers: configuration and state.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CurrentController {
    config: CurrentConfig,
    pi_d: Pi,
    pi_q: Pi,
}

impl CurrentController {
    /// Replaces the magnet flux of the decoupling feed-forward, per unit (on-line tracking,
    /// docs/tracking.md); the integrators are kept.
    pub fn set_psi(&mut self, psi: Pu) {
        self.config.psi = psi;
    }

    /// Controllers with zero integral state.
    pub fn new(config: CurrentConfig) -> Self {
        Self {
            pi_d: Pi::new(config.pi_d),
            pi_q: Pi::new(config.pi_q),
            config,
        }
    }

    /// The configuration.
    pub fn config(&self) -> &CurrentConfig {
        &self.config
    }

    /// Clears the integrators (before the inverter is enabled).
    pub fn reset(&mut self) {
        self.pi_d.reset(Pu::ZERO);
        self.pi_q.reset(Pu::ZERO);
    }

    /// One control sample. Integer only; never panics; a bus at or below zero gives a zero
    /// voltage and both `saturated` flags.
    pub fn step(&mut self, input: &CurrentInput) -> CurrentOutput {
        self.step_on(input, Reciprocal::default())
    }

    /// [`CurrentController::step`] with the reciprocal of the bus reading `input.vdc` given
    /// (the drive keeps it from one reading to the next), or zero to take it here when the
    /// arc is read. Inlined into the drive, except on the Cortex-M0: there the inlined copy
    /// beside the public step's ran the processor-in-the-loop image 260 bytes over the
    /// micro:bit's flash (`scripts/pil.sh`).
    #[cfg_attr(
        not(all(target_arch = "arm", not(target_has_atomic = "32"))),
        inline(always)
    )]
    pub(crate) fn step_on(&mut self, input: &CurrentInput, inv_vdc: Reciprocal) -> CurrentOutput {
        let c = &self.config;
        let vdc = input.vdc.max(Pu::ZERO);
        // m/√3 < 1 and vdc ≥ 0: the product cannot saturate.
        let v_max = Pu::from_bits(frac_mul(c.vmax_per_vdc, vdc.to_bits()));
        let (ff_d, ff_q) = if c.decoupling {
            let w = input.omega;
            // −ω L_q i_q and ω (L_d i_d + ψ): speed voltages of Khlaief, Boussak, Gossa (2012) eq. 3–4.
            let ff_d = c.neg_lq.apply(mul(w, input.i.q));
            let flux_d = c.ld.apply(input.i.d).saturating_add(c.psi);
            (ff_d, mul(w, flux_d))
        } else {
            (Pu::ZERO, Pu::ZERO)
        };
        let e_d = input.i_ref.d.saturating_sub(input.i.d);
        let e_q = input.i_ref.q.saturating_sub(input.i.q);
        // v_max ≥ 0 (a non-negative coefficient of a non-negative bus).
        let (d, _, integ_d) = self.pi_d.eval(e_d, ff_d, v_max, input.hold);
        self.pi_d.commit(integ_d);
        // The q limit is the room left on the circle, √(V_max² − v_d²). It is at least
        // V_max − |v_d| (as (V_max − |v_d|)² ≤ V_max² − v_d²), and when the q PI stays
        // strictly inside that bound its step is the same for the room itself (see
        // `Pi::eval`): the arc is read only when the q axis comes near the circle, and the
        // step is finished with the bound only when its output before the limits is inside.
        // |v_d| ≤ v_max: the difference is in [0, v_max], no saturation needed.
        let x = d.u.to_bits().wrapping_abs();
        let lower = Pu::from_bits(v_max.to_bits() - x);
        let terms = self.pi_q.prepare(e_q, ff_q);
        let mut within = None;
        if terms.raw_abs() < lower.to_bits() as u32 {
            let (q, inside, integ) = self.pi_q.finish(&terms, lower, input.hold);
            if inside {
                within = Some((q, integ));
            }
        }
        let (q, integ) = match within {
            Some(q) => q,
            None => {
                // |v_d|/V_max in Q2.30 (|v_d| ≤ V_max < v_DC, a fraction of the bus), from the
                // bus's reciprocal (if not given, a 32-bit division and two Newton steps, on
                // this path only).
                let inv_vdc = if inv_vdc.is_zero() {
                    Reciprocal::of(vdc.to_bits())
                } else {
                    inv_vdc
                };
                // t ≥ |v_d|/V_max: |v_d|/v_DC in Q16 rounded up (a ≤ 2¹⁶ m/√3 + 6, as
                // |v_d| ≤ V_max), times √3/m rounded up (k < 2¹⁵ √3/m + 1): a k < 2³¹ + 2²⁹ for
                // every m ≥ 10⁻³, one 32-bit product; halved, plus one: below 2³¹ (at or
                // beyond one the arc gives no room). Over by at most (√3/m) 6·2⁻¹⁶ + 2⁻¹⁵/√3
                // + 2⁻³⁰: 1.8e−4 at m = 1.
                let a = inv_vdc.fraction_q16_up(x);
                let t = ((a.wrapping_mul(c.vdc_per_vmax_q15) >> 1) + 1) as i32;
                let room = arc_room(v_max, t).max(lower);
                let (q, _, integ) = self.pi_q.finish(&terms, room, input.hold);
                (q, integ)
            }
        };
        self.pi_q.commit(integ);
        CurrentOutput {
            v: Dq { d: d.u, q: q.u },
            v_max,
            saturated_d: d.saturated || v_max == Pu::ZERO,
            saturated_q: q.saturated || v_max == Pu::ZERO,
        }
    }
}
