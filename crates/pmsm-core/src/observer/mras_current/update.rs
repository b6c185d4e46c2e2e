//! One update of the current-model MRAS: the measured current in the estimated frame, the
//! adjustable model, the adaptation law and the integration of the angle (module docs).

use super::*;
use crate::angle::{Angle, SinCos, sin_cos_frame};
use crate::frames::{AlphaBeta, Dq, park_on_grid};
use crate::num::{Coef, FRAME_SHIFT, Pu, UNIT_FRAC, Unit, round_shift_sat, wmul_inline};
use crate::observer::{Estimate, Estimator, ObserverInput};

/// The current-model MRAS estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct MrasCurrent {
    pub(super) config: MrasCurrentConfig,
    /// Adjustable-model current in the estimated frame.
    pub(super) i_hat: Dq,
    /// Estimated angle of the last update, 2⁶⁴ per turn.
    pub(super) theta: u64,
    /// sin/cos of the angle of the last update taken to 2⁻¹⁴ (the frame of `i_hat`).
    pub(super) sc: SinCos,
    /// The angle of the next update, `θ̂ + ω̂ T_s` (eq. 23 with the speed held over the
    /// coming period), 2⁶⁴ per turn, and its sin/cos (to 2⁻¹⁴): computed at the end of an update, so
    /// that the drive turns its voltage to the coming period's mid angle from the two frames
    /// without a sin/cos of its own (see [`MrasCurrent::next_frame`]).
    pub(super) theta_next: u64,
    pub(super) sc_next: SinCos,
    /// The measured current of the last update in that frame (`park_frame(i, sc)`).
    pub(super) i_dq: Dq,
    /// Speed integrator `I`, Q9.55, within `±ω_max`.
    pub(super) integ: i64,
    /// Adaptation signal ξ̃ = (L_q/L_d) ξ of the last update.
    pub(super) xi: Pu,
    /// Load-current estimate of the mechanical model, per unit of `I_b`.
    pub(super) i_load: Pu,
    /// Updates left that seed the model with the measured current and do not adapt: one
    /// after a reset, more through a zero crossing ([`MrasCurrent::hold`]); all but the last
    /// move the speed by the mechanical model.
    pub(super) seed: u8,
    pub(super) last: Estimate,
}

impl MrasCurrent {
    /// Estimator at `θ̂ = 0`, `ω̂ = 0`; call [`Estimator::reset`] with the initial position.
    pub fn new(config: MrasCurrentConfig) -> Self {
        let mut s = Self {
            config,
            i_hat: Dq::default(),
            theta: 0,
            sc: Angle::ZERO.sin_cos(),
            theta_next: 0,
            sc_next: Angle::ZERO.sin_cos(),
            i_dq: Dq::default(),
            integ: 0,
            xi: Pu::ZERO,
            i_load: Pu::ZERO,
            seed: 1,
            last: Estimate::default(),
        };
        s.reset(Angle::ZERO, Pu::ZERO);
        s
    }

    /// Takes the adaptation gains of the low-speed schedule's level for the speed `omega`
    /// (module docs, "Low-speed schedule"). Off the update's path: the drive calls it every
    /// eighth sample with the estimated speed.
    pub fn schedule(&mut self, omega: Pu) {
        // Off (no level above the design's), there is nothing to pick.
        if self.config.top != 0 {
            self.config.gains = self.config.gains_at(omega);
        }
    }

    /// Holds the adaptation over the next `updates` updates (at most 254): each takes the
    /// model to the measured current, leaves `ξ` at zero and moves the speed by the mechanical
    /// model alone; the update after them starts afresh as the first after a reset does. The
    /// drive calls it through a phase current's zero crossing at low speed and light load
    /// (docs/drive.md, "zero crossings at low speed").
    pub fn hold(&mut self, updates: u8) {
        self.seed = updates.saturating_add(1);
    }

    /// The configuration.
    pub fn config(&self) -> &MrasCurrentConfig {
        &self.config
    }

    /// The adaptation signal of the last update, `ξ' = (L_q/ψ) ξ`, per unit of `I_b`
    /// (rounded from the ξ̃ the update works with).
    pub fn xi(&self) -> Pu {
        self.config.xi_scale.apply(self.xi)
    }

    /// The frame of the last estimate: `sin_cos(θ̂)` of [`Estimator::estimate`]'s angle taken
    /// to 2⁻¹⁴ as the control path's transforms take it ([`sin_cos_frame`]), and the measured
    /// current of the last update rotated into it (bit for bit `park_frame(i, sin_cos(θ̂))`;
    /// zero after a reset). The drive reuses both instead of computing them again.
    #[cfg_attr(feature = "select-estimators", allow(dead_code))] // the drive's, with the MRAS
    pub(crate) fn frame(&self) -> (SinCos, Dq) {
        (self.sc, self.i_dq)
    }

    /// sin/cos of the next update's frame angle, `θ̂ + ω̂ T_s` with the last estimate: the
    /// rotor frame at the end of the coming PWM period.
    #[cfg_attr(feature = "select-estimators", allow(dead_code))] // the drive's, with the MRAS
    pub(crate) fn next_frame(&self) -> SinCos {
        self.sc_next
    }

    /// Advances the next frame from the last update's angle by the speed `omega` held over the
    /// coming period.
    #[inline(always)]
    fn prepare_next(&mut self, omega: Pu) {
        let step = (wide(omega.to_bits(), self.config.turn_per_speed) as u64) << TURN_SHIFT;
        self.theta_next = self.theta.wrapping_add(step);
        self.sc_next = sin_cos_frame(angle_of(self.theta_next));
    }

    fn angle(&self) -> Angle {
        angle_of(self.theta)
    }

    /// The estimate: angle and speed. The EMF is left at zero (the model does not estimate it;
    /// it is `ψ ω̂ (−sin θ̂, cos θ̂)` of these, for a caller that wants it).
    #[inline(always)]
    fn make_estimate(&self, omega: Pu) -> Estimate {
        Estimate {
            theta: self.angle(),
            omega,
            emf: AlphaBeta::default(),
        }
    }
}

/// The 2⁻⁶⁴ turn rounded to the nearest 2⁻³² turn.
#[inline(always)]
fn angle_of(theta: u64) -> Angle {
    Angle((theta.wrapping_add(1 << 31) >> 32) as u32 as i32)
}

// The products of one update, all inlined (also on ARMv6-M, where `wmul_inline` is the
// 16-bit-halves product: measured, calls to out-of-line kernels cost more than they save in
// register spills).

/// `x y`, exact.
#[inline(always)]
fn wide(x: i32, y: i32) -> i64 {
    wmul_inline(x, y)
}

/// `c x` rounded to nearest and saturated (a [`Coef`] times a [`Pu`] signal, in bits).
#[inline(always)]
fn apply<const F: u32>(c: i32, x: i32) -> i32 {
    round_shift_sat(wmul_inline(x, c), F)
}

/// `a x + b y + offset`, one rounding (`offset` in the accumulator's LSB, `2^−(24+F)`).
#[inline(always)]
fn mac<const F: u32>(a: i32, x: i32, b: i32, y: i32, offset: i64) -> i32 {
    // |a|, |b| ≤ 2^30 and |offset| ≤ 2^57 (module docs): the sum is below 2^62.
    round_shift_sat(wmul_inline(x, a) + wmul_inline(y, b) + offset, F)
}

/// `a u + b v` rounded by 2³⁰: a signal (or sin/cos) times sin/cos, whose magnitude is at
/// most 2³⁰ + 2²² in bits, so each product is below 2⁶¹.
#[inline(always)]
fn dot30(a: i32, u: i32, b: i32, v: i32) -> i32 {
    round_shift_sat(wmul_inline(a, u) + wmul_inline(b, v), UNIT_FRAC)
}

/// `−u` for a sin or cos (magnitude at most 2³⁰ + 2²² in bits: cannot wrap).
#[inline(always)]
fn neg(u: Unit) -> i32 {
    u.to_bits().wrapping_neg()
}

/// `c x` for a [`Coef`] and a [`Pu`] signal.
#[inline(always)]
fn coef_mul<const F: u32>(c: Coef<F>, x: Pu) -> Pu {
    Pu::from_bits(apply::<F>(c.bits(), x.to_bits()))
}

/// `a x + b y + offset` for two model weights.
#[inline(always)]
fn model_mac(a: Coef<MODEL_FRAC>, x: Pu, b: Coef<MODEL_FRAC>, y: Pu, offset: i64) -> Pu {
    Pu::from_bits(mac::<MODEL_FRAC>(
        a.bits(),
        x.to_bits(),
        b.bits(),
        y.to_bits(),
        offset,
    ))
}

/// Park's rotation to the frame of `sc`, kept on the grid of the frames ([`sin_cos_frame`]).
#[inline(always)]
fn park_in(v: AlphaBeta, sc: SinCos) -> Dq {
    park_on_grid(v, sc.sin.to_bits(), sc.cos.to_bits())
}

/// A sin or cos of the frames ([`sin_cos_frame`]), on the grid of 2⁻¹⁴, in Q2.14.
#[inline(always)]
fn q14(u: Unit) -> i32 {
    u.to_bits() >> FRAME_SHIFT
}

/// The rotation that takes the model from the frame of `prev` to that of `now`, as the
/// transforms take the frames (to 2⁻¹⁴, [`q14`]). A frame so taken is a rotation by its
/// angle `φ` times its length `ρ`, within 10⁻⁴ of 1: the measured currents come scaled by
/// `ρ_k`, the voltage by `ρ_{k−1}`. The model follows if its rotation is
/// `(ρ_k/ρ_{k−1}) (cos Δφ, sin Δφ)`: the products `c_k c_{k−1} + s_k s_{k−1}` and
/// `s_k c_{k−1} − c_k s_{k−1}` (exact in Q2.28: each below 2²⁸) divided by `ρ²_{k−1}`, taken
/// as the factor `2 − ρ²_{k−1}` (within 10⁻⁸): its error would otherwise act on the model
/// at every sample, as a resistance error of `L/(R T_s)` times it. All 32-bit products.
#[inline(always)]
fn advance(prev: SinCos, now: SinCos) -> SinCos {
    let (s, c) = (q14(now.sin), q14(now.cos));
    let (sp, cp) = (q14(prev.sin), q14(prev.cos));
    // 1 − ρ², Q2.28: each component taken down by less than 2⁻¹⁴, so |1 − ρ²| < 2√2·2⁻¹⁴
    // and |e| < 2¹⁵·⁵; with |x >> 13| ≤ 2¹⁵ + 4 the product stays below 2³¹.
    let e = (1 << 28) - (cp * cp + sp * sp);
    // x (2 − ρ²) = x + x (1 − ρ²), the small product from x's top bits (|x| < 2²⁸·1.001).
    let unit = |x: i32| Unit::from_bits((x + (((x >> 13) * e) >> 15)) << (UNIT_FRAC - 28));
    SinCos {
        sin: unit(s * cp - c * sp),
        cos: unit(c * cp + s * sp),
    }
}

/// Whether `−hi < x < hi` can be told from the high words alone (`hi ≥ 0`): so when
/// `|x_h| < h_h`, as then `x < (x_h + 1) 2³² ≤ h_h 2³² ≤ hi` and
/// `x ≥ x_h 2³² ≥ (1 − h_h) 2³² > −hi`. A 32-bit test for the common case of the speed
/// integrator's limits, whose exact 64-bit comparisons are the rare case.
#[inline(always)]
pub(super) fn within_high_word(x: i64, hi: i64) -> bool {
    (((x >> 32) as i32).unsigned_abs()) < (hi >> 32) as u32
}

/// The integrator step when the output before the clamp, `raw = K_p ξ̃ + I`, is on or beyond
/// `±ω_max` (the PI's anti-windup, module docs "Gains"): with `K_p > 0` back-calculation,
/// `I ← I + K_i T_s ξ̃ + k_t (clamp(raw) − raw)`, `k_t = min(1, K_i T_s/K_p)`; with `K_p = 0`
/// conditional integration (no integration that pushes further out). Rare, so out of line.
#[cold]
#[inline(never)]
fn integrate_saturated(c: &MrasCurrentConfig, raw: i64, integ: i64, xi: Pu) -> i64 {
    let hi = c.omega_max_wide;
    // |integ| < 2^59 and |K_i T_s ξ̃| < 2^62 (see `update`): the sum fits.
    let with_i = integ + wide(xi.to_bits(), c.gains.ki_ts.bits());
    if c.kt.bits() == 0 {
        let pushes = (raw >= hi && xi > Pu::ZERO) || (raw <= -hi && xi < Pu::ZERO);
        if pushes { integ } else { with_i }
    } else {
        // |raw| < 2^62 + 2^59, so the excess fits; k_t ≤ 1 keeps the product below it.
        let excess = raw.max(-hi).min(hi) - raw;
        let pull = (excess as i128 * c.kt.bits() as i128 + (1 << 29)) >> 30;
        with_i.saturating_add(pull as i64)
    }
}

impl Estimator for MrasCurrent {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        let omega = self.last.omega;
        // Frame advance over [t_{k−1}, t_k) with the speed held over it (eq. 23): prepared at
        // the end of the last update (an exact product, shifted; the angle wraps by design).
        self.theta = self.theta_next;
        let sc_prev = self.sc;
        let sc = self.sc_next;
        self.sc = sc;
        let c = &self.config;
        let i = park_in(input.i, sc);
        self.i_dq = i;
        let xi = if self.seed == 0 {
            // Model, eq. 15: the Strang step (half R–L step, exact rotation, half R–L step)
            // composed into one affine map (module docs, "Discretisation"): the weights act in
            // the frame at θ̂_{k−1}, the rotation by Δ takes them to the frame at θ̂_k.
            let v = park_in(input.v, sc_prev);
            let ih = self.i_hat;
            let xd = model_mac(c.xd_i, ih.d, c.xd_v, v.d, c.off_d_acc);
            let xq = model_mac(c.xq_i, ih.q, c.xq_v, v.q, 0);
            let yq = model_mac(c.yq_i, ih.q, c.yq_v, v.q, 0);
            let yd = model_mac(c.yd_i, ih.d, c.yd_v, v.d, c.off_q_acc);
            let r = advance(sc_prev, sc);
            let (rc, rs) = (r.cos.to_bits(), r.sin.to_bits());
            let i_hat = Dq {
                d: Pu::from_bits(dot30(xd.to_bits(), rc, xq.to_bits(), rs)).saturating_sub(c.off_d),
                q: Pu::from_bits(dot30(yq.to_bits(), rc, yd.to_bits(), neg(r.sin))),
            };
            self.i_hat = i_hat;
            // ε = i − î (eq. 16); ξ̃ = (L_q/L_d) ξ = w ρ² i_q ε_d − (i_d + ψ/L_d) ε_q (eq. 21–22
            // × L_q/L_d: one weight fewer; w the d-axis error's weight, module docs). Each
            // product is below 2^62 in magnitude; halved, their difference meets the rounding's
            // contract (the dropped bit is 2^-25 LSB).
            let e_d = i.d.saturating_sub(i_hat.d);
            let e_q = i.q.saturating_sub(i_hat.q);
            let w_d = coef_mul(c.rho2, i.q);
            let w_q = i.d.saturating_add(c.psi_ld);
            let acc = (wide(w_d.to_bits(), e_d.to_bits()) >> 1)
                - (wide(w_q.to_bits(), e_q.to_bits()) >> 1);
            Pu::from_bits(round_shift_sat(acc, PU_FRAC - 1))
        } else {
            // After a reset, or held, the model starts from the measured current: no error to
            // adapt on.
            self.seed -= 1;
            self.i_hat = i;
            if self.seed == 0 {
                // The last seeded update (a reset's) keeps the speed.
                self.xi = Pu::ZERO;
                self.last = self.make_estimate(omega);
                self.prepare_next(omega);
                return self.last;
            }
            // Those of a hold before it: the speed follows the mechanical model alone.
            Pu::ZERO
        };
        self.xi = xi;
        // Mechanical model: the torque current less the load estimate accelerates the rotor;
        // the load estimate moves against ξ (module docs, "Through zero speed").
        let g = c.gains;
        let i_load = self.i_load.saturating_sub(coef_mul(g.load_gain, xi));
        self.i_load = i_load;
        let torque = i.q.saturating_sub(i_load);
        // Speed, eq. 22, in Q9.55 with exact increments: |I| ≤ 2^57 (clamped to ±4 pu),
        // |T_s a τ| < 2^58 and |T_s B/J ω̂| < 2^53 (both weights ≤ 2^27 in bits, |ω̂| ≤ 2^26),
        // |K_i T_s ξ̃| < 2^62, |K_p ξ̃| < 2^62 in Q9.55: no sum below can wrap.
        let integ = self.integ + wide(torque.to_bits(), c.accel.bits())
            - wide(omega.to_bits(), c.friction.bits());
        let p = coef_mul(g.kp, xi);
        let raw = ((p.to_bits() as i64) << INTEG_EXTRA) + integ;
        let hi = c.omega_max_wide;
        let integ = if within_high_word(raw, hi) || (-hi < raw && raw < hi) {
            // Inside the limits: no anti-windup term.
            integ + wide(xi.to_bits(), g.ki_ts.bits())
        } else {
            integrate_saturated(c, raw, integ, xi)
        };
        let integ = if within_high_word(integ, hi) {
            integ
        } else {
            integ.max(-hi).min(hi)
        };
        self.integ = integ;
        // Rounded to Q8.24: |I| ≤ ω_max ≤ 4 pu, so the shifted value fits without a test.
        let i_pu = Pu::from_bits(((integ + (1 << (INTEG_EXTRA - 1))) >> INTEG_EXTRA) as i32);
        let omega = p.saturating_add(i_pu).max(-c.omega_max).min(c.omega_max);
        self.last = self.make_estimate(omega);
        self.prepare_next(omega);
        self.last
    }

    fn estimate(&self) -> Estimate {
        self.last
    }

    /// `|i_d − î_d| + |i_q − î_q|` of the last update (eq. 16), computed on request from the
    /// stored currents: nothing on the update's path.
    fn health(&self) -> Pu {
        let (i, m) = (self.i_dq, self.i_hat);
        i.d.saturating_sub(m.d)
            .saturating_abs()
            .saturating_add(i.q.saturating_sub(m.q).saturating_abs())
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        let omega = omega.max(-self.config.omega_max).min(self.config.omega_max);
        self.theta = (theta.0 as u32 as u64) << 32;
        self.sc = sin_cos_frame(theta);
        self.i_dq = Dq::default();
        self.integ = (omega.to_bits() as i64) << INTEG_EXTRA;
        self.i_hat = Dq::default();
        self.xi = Pu::ZERO;
        self.i_load = Pu::ZERO;
        self.config.gains = self.config.gains_at(omega);
        self.seed = 1;
        self.last = self.make_estimate(omega);
        self.prepare_next(omega);
    }
}
