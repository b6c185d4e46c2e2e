//! The d-axis current reference: maximum torque per ampere (MTPA) below base speed, field
//! weakening by voltage feedback above it (docs/field-weakening.md).
//!
//! ```text
//! i_d,MTPA = a − sgn(a) √(a² + i_q*²),   a = ψ / (2 (L_q − L_d))        (interior motor)
//! Δ       ← clamp(Δ + K_fw ((k V_max)² − |v|²), −I_d,lim − i_d,MTPA, 0)  (field weakening)
//! i_d*    = i_d,MTPA + Δ,     |i_q*| ≤ √(I_max² − i_d*²)
//! ```
//!
//! `|v|` is the vector the modulator made at the last sample, `V_max` the radius of its circle,
//! `k` the margin ([`VOLTAGE_MARGIN`], 31/32) that keeps the current loops some room to act. When the
//! vector stays inside `k V_max` the error is positive and `Δ` bleeds back to zero (the MTPA
//! current); outside it drives `Δ` negative, which lowers the flux `ψ + L_d i_d` and with it
//! the voltage. `Δ` is clamped so that `i_d*` never goes below `−I_d,lim = −min(I_max, ψ/L_d)`:
//! beyond `ψ/L_d` the flux reverses and the voltage grows again (anti-windup by clamping).
//!
//! With the modulator overmodulating (docs/overmodulation.md) `v` is the vector its duties apply
//! and `V_max` its longest, the hexagon's vertex `2 V_DC/3`: the loop then regulates the mean
//! of the applied vector's squared length to `(k · 2 V_DC/3)²`, which grows monotonically with
//! the request through both overmodulation regions and is reached in the second (fundamental
//! about 98.8 % of six-step's `2/π V_DC`), inside the current loops' limit `0.75 V_DC`. The
//! integrator's pole (below) is far slower than the six-per-period ripple of `|v|²` on the
//! hexagon, which it averages. The maximum speed then uses six-step's fundamental,
//! [`SIX_STEP_PER_CIRCLE`] times the circle.
//!
//! # Discretisation and cost
//!
//! The drive runs it in its task, once per task period of eight samples (docs/drive.md, "two
//! rates"): the MTPA current and the `i_q` limit once, the integrator twice (every
//! `T = 4 T_s`), [`FluxController::update`]. Neither square root is taken: both are tracked by one
//! iteration per update whose fixed point is the root (a square root costs ~60 instructions,
//! and the configuration must stay a few words for the 16 KiB of the smallest target). MTPA:
//! `f = i_q² − i_d² + 2a i_d` vanishes on the law and grows with `i_d`, so
//! `i_d ← i_d − g f/(2|a|)` converges to it (pole `1 − g(1 − i_d/a)`, `g` = 51/128). Circle:
//! `y ← y + g (I_max² − i_d² − y²)/(2 I_max)` converges to `√(I_max² − i_d²)`. Every square is
//! a 32-bit product of shifted values, and each update has at most one 64-bit product (the
//! gain): on the Cortex-M0 a 64-bit product is a call of some 25 instructions. The
//! integrator's margin and gain are shifts, `(k V_max)²` being kept from the last bus reading.
//!
//! With `|v| ≈ ω (ψ + L_d i_d)` the loop is `d|v|²/dΔ ≈ 2 |v| ω L_d`, and the gain
//! `K_fw = ω_fw T / 2` (per unit, `T = 4 T_s`) puts its pole near `ω_fw` where `|v| ω L_d ≈ 1`
//! (`K_fw = 5/128`: `ω_fw ≈ 0.02/T_s`, 273 rad/s at 14 kHz, below the current loops' 1400 rad/s).
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | `i_q*`, `i_d*`, `i_d,MTPA`, `Δ`, `I_max`, `−I_d,lim`, `|i_q|` limit | [`Pu`] Q8.24 of `I_b` | `[−I_max, I_max]` |
//! | `I_max²` | [`Pu`] (pu²) | `I_max` ≤ 11 with MTPA or field weakening on |
//! | `v`, `V_max` | [`Pu`] of `V_b` | ≤ 2 |
//! | `|v|²`, `(k V_max)²` | `(v ≫ 11)²` in `i32`: units of 2⁻²⁶ pu² | ≤ 2²⁹ |
//! | `i_q²`, `i_d²`, `y²` | `(i ≫ s)²` in `i32` (`I_max ≫ s` < 2¹⁵), sums to `Pu` of pu² | < 2³¹ |
//! | `sgn(2a)`, `2a = ψ/(L_q − L_d)` | `i32` ±1 (0: no MTPA) | `|2a| < 2048` (else treated as surface) |
//! | `g/(2|a|)`, `g/(2 I_max)` | [`Coef<24>`](Coef) | < 128 |
//! | `k`, `K_fw`, `g` | shifts | 31/32, 5/128, 51/128 |

use super::gain_in;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, Dq};
use crate::num::{Coef, Pu, pu_from_f64};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Below this relative saliency `|L_q − L_d| / L_d` a motor is treated as surface: `i_d = 0`
/// below base speed (MTPA would gain less than 0.1 % of current).
const SALIENCY_MIN: f64 = 0.02;

/// Cap of the maximum speed, times the base speed `ω_b = V_b/ψ`, for motors whose
/// characteristic current `ψ/L_d` is within the current limit (infinite in theory).
pub const SPEED_CAP_PER_BASE: f64 = 4.0;

/// The six-step's fundamental over the circle's radius, `(2/π V_DC)/(V_DC/√3) = 2√3/π`: the
/// voltage an overmodulating drive can hold, per unit of the linear one.
pub const SIX_STEP_PER_CIRCLE: f64 = 1.102_657_790_843_584_4;

/// Pole of the MTPA and circle iterations per update (`g`, one update every eight samples):
/// about 1.4 ms to settle at 14 kHz. 51/128: `g i_d` is a shift and a 32-bit product.
const TRACK_POLE: f64 = 0.398_437_5;

/// Fraction `k` of the modulator's circle the field weakening holds the voltage at: 31/32, so
/// that `k V_max` is a shift and a subtraction.
pub const VOLTAGE_MARGIN: f64 = 0.968_75;

/// The same, overmodulating, of the hexagon's vertex: 15/16. At 31/32 the current loops had
/// too little room near six-step and the speed swung (motor C unloaded at 3800–4000 r/min:
/// ±90 r/min, current peaks of 60 A).
pub const VOLTAGE_MARGIN_OVERMODULATING: f64 = 0.937_5;

/// The voltages' shift before squaring: `|v| ≤ 2` per unit (2²⁵ bits) becomes 2¹⁴, its
/// square ≤ 2²⁸, so that `|v|²` and `(k V_max)²` are 32-bit products (a 64-bit product is
/// a call of some 25 instructions on ARMv6-M).
const V_SHIFT: u32 = 11;

/// How the d-axis reference is made. `Default` is both off (the paper's `i_d = 0`);
/// [`crate::DriveDesign::default_for`] turns both on ([`FluxDesign::ON`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
pub struct FluxDesign {
    /// MTPA below base speed for interior motors (surface motors keep `i_d = 0`).
    pub mtpa: bool,
    /// Field weakening by voltage feedback, and the speed reference clamped to the maximum
    /// speed.
    pub field_weakening: bool,
}

impl FluxDesign {
    /// MTPA and field weakening on.
    pub const ON: Self = Self {
        mtpa: true,
        field_weakening: true,
    };
}

/// Configuration of the [`FluxController`]: eleven words, because the smallest target (the
/// micro:bit's 16 KiB) holds the drive on its stack several times.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct FluxConfig {
    /// `sgn(2a)`: 1 for `L_q > L_d`, −1 for `L_q < L_d`, 0 without MTPA.
    sign_a: i32,
    /// MTPA iteration gain `g/(2|a|)`; zero: `i_d,MTPA = 0` (surface motor or MTPA off).
    k_mtpa: Coef<24>,
    /// The currents' shift before squaring, `s`: `I_max` in [`Pu`] bits shifted right by
    /// `s` is below 2¹⁵, so that its square is a 32-bit product, in units of 2^(2s − 48) pu².
    i_shift: u32,
    /// `24 − 2s`: a square's shift right to [`Pu`] bits of pu² (left when negative).
    sq_shift: i32,
    /// `I_max²` in [`Pu`] bits (`I_max` ≤ 11: below 2³¹).
    i_max_sq: i32,
    /// `g/(2 I_max)`, the circle iteration's gain.
    k_circle: Coef<24>,
    /// `I_max`.
    i_max: Pu,
    /// `k = 1 − 2^−margin_shift`: 5 ([`VOLTAGE_MARGIN`]), 4 overmodulating
    /// ([`VOLTAGE_MARGIN_OVERMODULATING`]).
    margin_shift: u32,
    /// `−I_d,lim`; zero without field weakening.
    id_min: Pu,
    /// Largest speed reference accepted, per unit ([`FluxConfig::max_speed`]).
    speed_max: Pu,
    /// Estimated speed beyond which the drive trips on overspeed, per unit.
    pub(crate) overspeed: Pu,
}

/// `i_d` of the MTPA law for `i_q` (any sign), f64 reference: zero for equal inductances.
pub fn mtpa_id_f64(psi: f64, ld: f64, lq: f64, iq: f64) -> f64 {
    let dl = lq - ld;
    if dl == 0.0 {
        return 0.0;
    }
    let a = psi / (2.0 * dl);
    // Written as −i_q²/(a + sgn(a)√(a² + i_q²)): no cancellation for small i_q.
    let r = libm::sqrt(a * a + iq * iq);
    -iq * iq / (a + a.signum() * r)
}

/// The deepest d current field weakening uses, `I_d,lim` (all per unit or all SI
/// consistently): the current limit `i_max`, no more than `ψ/L_d` (the flux cancelled), and no
/// more than `L_d v_lim²/(R² ψ)`, beyond which the resistive drop of the d current costs more
/// voltage than its flux frees (the maximum over `i` of `√(v_lim² − (R i)²)/(ψ − L_d i)`, the
/// no-load speed at `i_d = −i`; docs/field-weakening.md §3). A gimbal motor, whose `R I_max`
/// is most of the bus, stops there well short of its current limit.
pub fn weakening_current_f64(psi: f64, ld: f64, r: f64, i_max: f64, v_lim: f64) -> f64 {
    let best = if r > 0.0 && psi > 0.0 {
        ld * v_lim * v_lim / (r * r * psi)
    } else {
        f64::INFINITY
    };
    i_max.min(psi / ld).min(best)
}

/// The speed at which the no-load voltage at `i_d = −i_d_lim` reaches `v_lim` (all per unit
/// or all SI consistently), capped at `cap`.
pub fn max_speed_f64(psi: f64, ld: f64, r: f64, id_lim: f64, v_lim: f64, cap: f64) -> f64 {
    let flux = psi - ld * id_lim;
    let vq2 = v_lim * v_lim - (r * id_lim) * (r * id_lim);
    if flux <= 0.0 || vq2 <= 0.0 {
        return cap;
    }
    (libm::sqrt(vq2) / flux).min(cap)
}

impl FluxConfig {
    /// The d-axis reference for `motor` with current limit `i_max_a` (A peak); `v_lim_pu` is
    /// the fundamental voltage the drive holds at the nominal bus, per unit of `V_b` (1, or
    /// `SIX_STEP_PER_CIRCLE` overmodulating), for the maximum speed; `overspeed_pu` is the
    /// overspeed trip threshold.
    ///
    /// Errors: [`ConfigError::Gain`] for a current limit beyond 11 `I_b` (`I_max²` in Q8.24)
    /// with MTPA or field weakening on.
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        i_max_a: f64,
        design: FluxDesign,
        v_lim_pu: f64,
        overspeed_pu: f64,
    ) -> Result<Self, ConfigError> {
        // Checked only when used (the speed loop accepts up to 64 I_b).
        let i_max = if design.mtpa || design.field_weakening {
            gain_in(
                "speed.current_limit_a",
                i_max_a,
                base.current_a / 64.0,
                11.0 * base.current_a,
            )?
        } else {
            // max/min, not clamp: clamp can panic, which costs the small target 20 KiB of
            // formatting code.
            i_max_a
                .max(base.current_a / 64.0)
                .min(11.0 * base.current_a)
        } / base.current_a;
        let ld = motor.ld_h / base.inductance_h;
        let lq = motor.lq_h / base.inductance_h;
        let r = motor.rs_ohm / base.impedance_ohm;
        let psi = motor.flux_wb / base.flux_wb;
        let salient = design.mtpa && libm::fabs(lq - ld) > SALIENCY_MIN * ld;
        // The squares' format: a current x as (x ≫ s) with I_max ≫ s < 2¹⁵, so that its
        // square is a 32-bit product.
        let i_max_bits = pu_from_f64(i_max).to_bits().max(1) as u32;
        // I_max ≤ 11 pu < 2²⁸ bits: s ≤ 13.
        let i_shift = (32 - i_max_bits.leading_zeros()).saturating_sub(15);
        // 2|a| beyond 2048 (saliency below 1/1000 per unit): no MTPA either.
        let two_a = psi / (lq - ld);
        let (sign_a, k_mtpa) = if salient && libm::fabs(two_a) < 2048.0 {
            match Coef::new(TRACK_POLE / libm::fabs(two_a)) {
                Some(k) => (if two_a > 0.0 { 1 } else { -1 }, k),
                None => (0, Coef::ZERO),
            }
        } else {
            (0, Coef::ZERO)
        };
        // The nominal bus: V_max = V_b (m = 1), or six-step's fundamental.
        let overmodulating = v_lim_pu > 1.0;
        let margin = if overmodulating {
            VOLTAGE_MARGIN_OVERMODULATING
        } else {
            VOLTAGE_MARGIN
        };
        let id_lim = if design.field_weakening {
            weakening_current_f64(psi, ld, r, i_max, margin * v_lim_pu)
        } else {
            0.0
        };
        let max_pu = max_speed_f64(psi, ld, r, id_lim, margin * v_lim_pu, SPEED_CAP_PER_BASE);
        Ok(Self {
            sign_a,
            k_mtpa,
            i_shift,
            sq_shift: 24 - 2 * i_shift as i32,
            i_max_sq: pu_from_f64(i_max * i_max).to_bits(),
            k_circle: Coef::new(TRACK_POLE / (2.0 * i_max)).unwrap_or(Coef::ZERO),
            i_max: pu_from_f64(i_max),
            margin_shift: if overmodulating { 4 } else { 5 },
            id_min: pu_from_f64(-id_lim),
            speed_max: if design.field_weakening {
                pu_from_f64(max_pu)
            } else {
                Pu::MAX
            },
            overspeed: pu_from_f64(overspeed_pu),
        })
    }

    /// Whether the controller does anything (MTPA on an interior motor, or field weakening).
    #[inline(always)]
    pub fn enabled(&self) -> bool {
        self.sign_a != 0 || self.id_min != Pu::ZERO
    }

    /// Largest speed reference accepted, electrical, per unit (`Pu::MAX` with field
    /// weakening off): the speed at which the no-load voltage at `i_d = −I_d,lim` reaches
    /// `k V_max` at the nominal bus, capped at [`SPEED_CAP_PER_BASE`] times base speed.
    pub fn max_speed(&self) -> Pu {
        self.speed_max
    }

    /// A sum of the currents' squares (each `≤ I_max²`, the sum at most twice that) in the
    /// squares' format, as [`Pu`] bits of pu² (saturated).
    #[inline(always)]
    fn squares_to_pu(&self, x: i32) -> i32 {
        if self.sq_shift >= 0 {
            x >> self.sq_shift
        } else {
            x.saturating_mul(1 << (-self.sq_shift).min(8))
        }
    }
}

/// State of the d-axis reference.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FluxController {
    /// `i_d,MTPA`, tracked.
    id_mtpa: Pu,
    /// `Δ`, the field-weakening offset (≤ 0).
    delta: Pu,
    /// `|i_q*|` limit.
    iq_max: Pu,
    /// `i_d* = i_d,MTPA + Δ` after the last update.
    id_ref: Pu,
    /// The circle's radius of the last update and `(k V_max)²` from it (`V_max ≫ 11`
    /// squared).
    v_max: Pu,
    lim_sq: i32,
}

impl FluxController {
    /// Back to `i_d* = 0`, `|i_q*| ≤ I_max`.
    pub fn reset(&mut self, c: &FluxConfig) {
        *self = Self {
            iq_max: c.i_max,
            ..Self::default()
        };
    }

    /// The field-weakening offset `Δ`.
    pub fn delta(&self) -> Pu {
        self.delta
    }

    /// `i_d* = i_d,MTPA + Δ` as the last update left it.
    #[inline(always)]
    pub fn id_ref(&self) -> Pu {
        self.id_ref
    }

    /// The MTPA current as tracked.
    pub fn mtpa_id(&self) -> Pu {
        self.id_mtpa
    }

    /// The `|i_q*|` limit as tracked.
    pub fn iq_limit(&self) -> Pu {
        self.iq_max
    }

    /// The current reference for the speed loop's `iq` as the last updates left it:
    /// `i_d* = i_d,MTPA + Δ`, `i_q*` within the current circle.
    #[inline(always)]
    pub fn reference(&self, iq: Pu) -> Dq {
        Dq {
            d: self.id_ref,
            q: iq.min(self.iq_max).max(self.iq_max.saturating_neg()),
        }
    }

    /// One update of the MTPA current for the speed loop's `iq`. Out of
    /// line, as the two below: their 64-bit temporaries would otherwise enlarge the drive
    /// step's frame on ARMv6-M even when off.
    #[inline(never)]
    pub fn update_mtpa(&mut self, c: &FluxConfig, iq: Pu) {
        // MTPA: f = i_q² − i_d² + 2a i_d is zero on the law and grows with i_d (for
        // i_d < a): one step of i_d ← i_d − g f/(2|a|) per update, that is
        // i_d ← i_d − g sgn(a) i_d − k (i_q² − i_d²) with k = g/(2|a|), the squares 32-bit
        // products in the configuration's format.
        // |i_q| and |i_d,MTPA| ≤ I_max: below 2¹⁵ shifted, each square below 2³⁰.
        let m = c.i_max.to_bits() >> c.i_shift;
        let q = (iq.to_bits() >> c.i_shift).max(-m).min(m);
        let d = self.id_mtpa.to_bits() >> c.i_shift;
        let x = c.squares_to_pu(q * q - d * d);
        let id = self.id_mtpa.to_bits();
        // g · i_d with g = 51/128 (rounded toward −∞; 2⁻¹⁷ pu).
        let g_d = (id >> 7) * 51;
        let step = c.k_mtpa.apply_bits(x).saturating_add(c.sign_a * g_d);
        let id_mtpa = self.id_mtpa.saturating_sub(Pu::from_bits(step));
        // Within [−I_max, 0] for L_q > L_d (a > 0), [0, I_max] otherwise.
        self.id_mtpa = if c.sign_a >= 0 {
            id_mtpa.min(Pu::ZERO).max(c.i_max.saturating_neg())
        } else {
            id_mtpa.min(c.i_max).max(Pu::ZERO)
        };
        self.id_ref = self.id_mtpa.saturating_add(self.delta);
    }

    /// One update of the field-weakening integrator from the vector `v` the modulator made
    /// at the last sample and its circle's radius `v_max` (twice per task period).
    #[inline(never)]
    pub fn update_fw(&mut self, c: &FluxConfig, v: &AlphaBeta, v_max: Pu) {
        // Field weakening: (k V_max)² − |v|² with k = 31/32 (15/16 overmodulating), each voltage shifted right by 11
        // (≤ 2¹⁴ for ≤ 2 pu) and squared in 32 bits: the error in units of 2⁻²⁶ pu²;
        // (k V_max)² is recomputed only when the bus reading changes.
        if v_max != self.v_max {
            let m = v_max.to_bits().clamp(0, 2 << 24);
            let lim = (m - (m >> c.margin_shift)) >> V_SHIFT;
            self.v_max = v_max;
            self.lim_sq = lim * lim;
        }
        let lim = 1 << (25 - V_SHIFT);
        let a = (v.alpha.to_bits() >> V_SHIFT).clamp(-lim, lim);
        let b = (v.beta.to_bits() >> V_SHIFT).clamp(-lim, lim);
        // Each square ≤ 2²⁸: the difference fits.
        let err = self.lim_sq - (a * a + b * b);
        // K_fw = 5/128 per Pu bit of pu² (docs/field-weakening.md), per unit of this error
        // (four of those) 5/512: two shifts.
        let step = (err >> 7) + (err >> 9);
        // Anti-windup: Δ within [−I_d,lim − i_d,MTPA, 0].
        let lo = c.id_min.saturating_sub(self.id_mtpa).min(Pu::ZERO);
        self.delta = Pu::from_bits(self.delta.to_bits().saturating_add(step))
            .min(Pu::ZERO)
            .max(lo);
        self.id_ref = self.id_mtpa.saturating_add(self.delta);
    }

    /// One update of the `|i_q*|` limit; returns it.
    #[inline(never)]
    pub fn update_circle(&mut self, c: &FluxConfig) -> Pu {
        // √(I_max² − i_d²) by one iteration y ← y + g (I_max² − i_d² − y²)/(2 I_max)
        // per update (the fixed point is the root; i_d moves slowly). |i_d|, y ≤ I_max: the
        // squares' difference lies in [−I_max², I_max²], within 32 bits.
        let m = c.i_max.to_bits() >> c.i_shift;
        let d = (self.id_ref.to_bits() >> c.i_shift).max(-m).min(m);
        let y = (self.iq_max.to_bits() >> c.i_shift).max(-m).min(m);
        let e = c.i_max_sq - c.squares_to_pu(d * d + y * y);
        self.iq_max = self
            .iq_max
            .saturating_add(Pu::from_bits(c.k_circle.apply_bits(e)))
            .min(c.i_max)
            .max(Pu::ZERO);
        self.iq_max
    }

    /// The updates of one task period: the MTPA current for the speed loop's `iq`, the
    /// field-weakening integrator twice on the modulator's vector `v` and circle `v_max` of
    /// the period's last sample, the `|i_q*|` limit (returned: the speed loop's new limit).
    pub fn update(&mut self, c: &FluxConfig, iq: Pu, v: &AlphaBeta, v_max: Pu) -> Pu {
        self.update_mtpa(c, iq);
        self.update_fw(c, v, v_max);
        self.update_fw(c, v, v_max);
        self.update_circle(c)
    }

    /// [`FluxController::update`], then [`FluxController::reference`].
    pub fn step(&mut self, c: &FluxConfig, iq: Pu, v: AlphaBeta, v_max: Pu) -> Dq {
        self.update(c, iq, &v, v_max);
        self.reference(iq)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::InverterParams;

    fn motor_c() -> (MotorParams, PerUnit) {
        let mut m = MotorParams::new(4, 0.1, 0.3e-3, 0.5e-3, 0.01323, 1e-4, 1e-5);
        m.rated_current_a = Some(25.0);
        let inv = InverterParams {
            vdc_v: 24.0,
            pwm_hz: 20e3,
            dead_time_s: 0.0,
            current_full_scale_a: 100.0,
        };
        let base = PerUnit::new(&m, &inv, 20e3).unwrap();
        (m, base)
    }

    fn settle(f: &mut FluxController, c: &FluxConfig, iq: f64, v: f64) -> Dq {
        let inside = AlphaBeta {
            alpha: pu_from_f64(v),
            beta: Pu::ZERO,
        };
        let mut out = Dq::default();
        // 40 000 samples, a task period at a time.
        for _ in 0..5_000 {
            out = f.step(c, pu_from_f64(iq), inside, Pu::from_num(1));
        }
        out
    }

    /// The MTPA law: the f64 reference maximises torque on its current circle, and the
    /// fixed-point iteration settles within 2e−4 pu of it for either torque sign.
    #[test]
    fn mtpa_against_reference() {
        let (m, base) = motor_c();
        let c = FluxConfig::new(&m, &base, 2.0 * base.current_a, FluxDesign::ON, 1.0, 2.0).unwrap();
        let (psi, ld, lq) = (1.0, m.ld_h / base.inductance_h, m.lq_h / base.inductance_h);
        let torque = |id: f64, iq: f64| iq * (psi + (ld - lq) * id);
        let mut f = FluxController::default();
        f.reset(&c);
        let mut worst: f64 = 0.0;
        for k in -20..=20 {
            let iq = 1.9 * k as f64 / 20.0;
            let id_ref = mtpa_id_f64(psi, ld, lq, iq);
            let mag = id_ref.hypot(iq);
            let t0 = torque(id_ref, iq).abs();
            for dth in [-0.01, 0.01] {
                let th = f64::atan2(iq, id_ref) + dth;
                assert!(torque(mag * th.cos(), mag * th.sin()).abs() <= t0 + 1e-12);
            }
            // Well inside the circle: no field weakening.
            let out = settle(&mut f, &c, iq, 0.5);
            assert_eq!(f.delta(), Pu::ZERO);
            worst = worst.max((out.d.to_num::<f64>() - id_ref).abs());
        }
        assert!(worst < 2e-4, "MTPA error {worst} pu");
        // A surface motor (or MTPA off) keeps i_d = 0.
        let mut off = FluxDesign::ON;
        off.mtpa = false;
        let c0 = FluxConfig::new(&m, &base, base.current_a, off, 1.0, 2.0).unwrap();
        f.reset(&c0);
        assert_eq!(settle(&mut f, &c0, 0.8, 0.5).d, Pu::ZERO);
    }

    /// Field weakening: a vector on the circle drives Δ down to its clamp (i_d* at
    /// −min(I_max, ψ/L_d)) with |i_q*| on the current circle; room brings Δ back to zero.
    #[test]
    fn field_weakening_enters_and_exits() {
        let (m, base) = motor_c();
        let c = FluxConfig::new(&m, &base, base.current_a, FluxDesign::ON, 1.0, 2.0).unwrap();
        let mut f = FluxController::default();
        f.reset(&c);
        let out = settle(&mut f, &c, 0.2, 1.0);
        let id_lim = 1.0f64.min(1.0 / (m.ld_h / base.inductance_h));
        let id = out.d.to_num::<f64>();
        assert!((id + id_lim).abs() < 1e-6, "{id}");
        let iq_max = f.iq_limit().to_num::<f64>();
        let exact = (1.0 - id * id).max(0.0).sqrt();
        // At i_d = −I_max the root is 0, where the iteration converges only as 2 I_max/(g n).
        assert!(
            iq_max >= exact && iq_max - exact < 5e-3,
            "{iq_max} vs {exact}"
        );
        let out = settle(&mut f, &c, 0.2, 0.9);
        assert_eq!(f.delta(), Pu::ZERO);
        assert!(
            (out.d.to_num::<f64>()
                - mtpa_id_f64(
                    1.0,
                    m.ld_h / base.inductance_h,
                    m.lq_h / base.inductance_h,
                    0.2
                ))
            .abs()
                < 2e-4
        );
        // Speed limit: finite here (ψ/L_d above I_max) and above base speed.
        let w = c.max_speed().to_num::<f64>();
        assert!(w > 1.5 && w <= SPEED_CAP_PER_BASE, "{w}");
    }
}
