//! Current-model MRAS speed and position estimator of seed 001 (eq. 14–23, equations.md §4.1).
//!
//! The measured currents are taken to the **estimated** rotor frame (`θ̂`) and compared with
//! an adjustable model of the motor run in that frame at the estimated speed:
//!
//! ```text
//! dî_d/dt = −(R/L_d) î_d + (L_q/L_d) ω̂ î_q + v_d/L_d                      (eq. 15)
//! dî_q/dt = −(R/L_q) î_q − (L_d/L_q) ω̂ î_d − (ψ/L_q) ω̂ + v_q/L_q
//! ε_d = i_d − î_d,   ε_q = i_q − î_q                                          (eq. 16)
//! ξ = (L_q/L_d) i_q ε_d − (L_d/L_q) i_d ε_q − (ψ/L_q) ε_q                     (eq. 21–22)
//! ω̂ = K_i ∫ξ dt + K_p ξ,   θ̂ = ∫ω̂ dt + θ_0                                   (eq. 22–23)
//! ```
//!
//! # Sign of ξ
//!
//! With `ε = i − î`, a rotor ahead of the estimate (`δ = θ − θ̂ > 0`) or faster than it
//! (`ω > ω̂`) gives `ξ > 0` at any speed away from zero: the back-EMF error they cause,
//! `ψ ω (−sin δ, cos δ) − ψ ω̂ (0, 1)`, drives `ε_q < 0` through the q inductance, and
//! `−(ψ/L_q) ε_q` dominates ξ. So `ω̂` grows and `θ̂` catches up: the stated sign is the
//! stable one. Checked against the plant (`tests/drive_parts_mras.rs`: the estimate converges
//! from ±20° at ±800 r/min, motoring and generating).
//!
//! # Discretisation
//!
//! In flux coordinates, `λ = (L_d î_d + ψ, L_q î_q)`, the model is a decay through `R`, a drive
//! by `v`, and a pure rotation by `−ω̂ t` (the frame turning under a fixed flux):
//! `dλ/dt = −R î + v + ω̂ (λ_q, −λ_d)`. One sample is a Strang splitting of the two parts, each
//! solved exactly:
//!
//! 1. half an R–L step in the frame at `θ̂_{k−1}`: `î ← a î + g v_dq(θ̂_{k−1})`,
//!    `a = e^{−R T_s/(2L)}`, `g = (1 − a)/R` (zero-order hold: matched pole, exact for a held
//!    voltage);
//! 2. the exact rotation of `λ` by `−Δ`, `Δ = ω̂ T_s`, written in currents:
//!    `î_d ← c î_d + s (L_q/L_d) î_q − (1 − c) ψ/L_d`, `î_q ← c î_q − s (L_d/L_q) î_d − s ψ/L_q`
//!    (`s, c = sin Δ, cos Δ`);
//! 3. half an R–L step in the frame at `θ̂_k = θ̂_{k−1} + Δ`.
//!
//! The splitting error is third order per step; forward Euler on eq. 15 would instead inflate
//! the model's EMF by `√(1 + Δ²)` and mis-damp it by `R T_s/L`, both of which the adaptation
//! reads as a speed and position error. The f64 reference of this scheme (in
//! `tests/support/drive_ref.rs`) settles within 0.004° at 800 r/min on motor B.
//!
//! The voltage of the input was applied over `[t_{k−1}, t_k)` (see [`super`]'s timing
//! convention) and is constant in the stationary frame: its rotor-frame value is taken at the
//! frame angle of each half step. `θ̂` advances with the `ω̂` held over the same interval, so
//! the model frame and the estimate are the same frame.
//!
//! # Gains
//!
//! Near `δ = 0` and away from zero speed, `ξ ≈ k_δ δ + k_ω (ω − ω̂)`; at high speed
//! `k_δ → k_∞ = (ψ/L_q)²` (A²/rad). The PI on ξ closes a phase-locked loop on `θ`; at high
//! speed its characteristic polynomial is `s² + K_p k_∞ s + K_i k_∞`, so for a natural
//! frequency `ω_n` and damping 1:
//!
//! ```text
//! K_p = 2 ω_n / k_∞,   K_i = ω_n² / k_∞,   k_∞ = (ψ/L_q)²
//! ```
//!
//! Default `ω_n = 0.02/T_s` (280 rad/s at 14 kHz). At low speed `k_δ` falls roughly as
//! `ω² L_q²/(R² + ω² L_q²)` and the loop slows (the slowest mode tends to `ω² L_q/R` as the
//! gains grow), which is the MRAS's known weakness near standstill; the position error at
//! steady state is still zero with exact parameters. Accepted range:
//! `K_p ∈ [0, 1/(k_∞ T_s)]`, `K_i ∈ [0, 0.25/(k_∞ T_s²)]`.
//!
//! # Through zero speed
//!
//! Near standstill ξ carries almost no information on the position (the EMF error vanishes
//! with ω), and a speed that changes sign under load drags the estimate away. The mechanical
//! model knows how the speed changes: the measured torque current accelerates the rotor by
//! `a (i_q − i_L) − (B/J) ω̂`, `a = p K_T/J` (equations.md §1), where `i_L` is the load seen as
//! a current. Every sample that acceleration is added to the speed integrator, and the load
//! estimate follows `dî_L/dt = −K_L ξ` (a rotor ahead of the estimate means less load than
//! assumed). Linearised, `ξ ≈ k δ`, the position error obeys
//! `δ‴ + K_p k δ″ + K_i k δ′ + a K_L k δ = 0`; [`MrasCurrentGains::design`] places its poles.
//! Through zero speed `k → 0`: the loop opens, and the model carries the estimate with the load
//! learned before, so a reversal under a load that does not reverse with it keeps its lock.
//! `K_L = 0` gives the plain MRAS of seed 001.
//!
//! # Formats
//!
//! | signal | format | note |
//! |---|---|---|
//! | `î`, `i`, `v`, `ε` | [`Pu`] Q8.24 | per unit of `I_b`, `V_b` |
//! | `ξ' = (L_q/ψ) ξ` | [`Pu`] Q8.24 | the adaptation signal scaled so its dominant term is `−ε_q`; `K_p`, `K_i` are rescaled to match, so this is eq. 22 exactly |
//! | `ω̂` | [`Pu`] Q8.24 | per unit of `ω_b`, clamped to `±ω_max` |
//! | `θ̂` | `u64` turn, 2⁶⁴ per turn | the top 32 bits are the [`Angle`]; the low 32 keep the sub-LSB part of `ω̂ T_s` |
//! | coefficients | [`WideGain`] | `a`, `g`, `L_q/L_d`, `L_d/L_q`, `ψ/L_d`, `ψ/L_q`, ξ' weights |

use super::{Estimate, Estimator, ObserverInput};
use crate::angle::{Angle, SinCos};
use crate::control::pi::{Limits, Pi, PiConfig};
use crate::control::{WideGain, gain_in, wide_gain};
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, Dq, park};
use crate::num::{Pu, UNIT_FRAC, Unit, mul, mul_unit, pu_from_f64, round_shift_sat, wmul_inline};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// Default `ω_n T_s` of the adaptation loop.
pub const DEFAULT_BANDWIDTH_TS: f64 = 0.02;

/// Largest estimated speed, per unit of `ω_b` (also at most 1 rad per sample).
pub const MAX_SPEED_PU: f64 = 4.0;

/// Adaptation gains of eq. 22 in SI units (ξ in A²): `K_p` in (rad/s)/A², `K_i` in
/// (rad/s²)/A², electrical speed; and the gain of the load-current estimate of the mechanical
/// model (module docs, "Through zero speed").
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrasCurrentGains {
    /// Proportional gain `K_pω_r-est`.
    pub kp: f64,
    /// Integral gain `K_iω_r-est`.
    pub ki: f64,
    /// Gain `K_L` of the load-current estimate, A/(A²·s); zero turns the mechanical model off
    /// (the plain MRAS of seed 001).
    pub kl: f64,
}

impl MrasCurrentGains {
    /// High-speed sensitivity of ξ to the position error, `k_∞ = (ψ/L_q)²`, A²/rad.
    pub fn k_inf(motor: &MotorParams) -> f64 {
        let r = motor.flux_wb / motor.lq_h;
        r * r
    }

    /// Design for natural frequency `ω_n = bandwidth_rad_s` (module docs): a critically damped
    /// pair at `ω_n` and the load estimate's pole at `ω_L = ω_n/4`,
    /// `(s² + 2ω_n s + ω_n²)(s + ω_L)`, with `a = p K_T/J`:
    /// `K_p = (2ω_n + ω_L)/k_∞`, `K_i = (ω_n² + 2ω_n ω_L)/k_∞`, `K_L = ω_n² ω_L/(a k_∞)`.
    pub fn design(motor: &MotorParams, bandwidth_rad_s: f64) -> Self {
        let k = Self::k_inf(motor);
        let (wn, wl) = (bandwidth_rad_s, 0.25 * bandwidth_rad_s);
        let a = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        Self {
            kp: (2.0 * wn + wl) / k,
            ki: (wn * wn + 2.0 * wn * wl) / k,
            kl: wn * wn * wl / (a * k),
        }
    }

    /// The plain MRAS of seed 001, critically damped at `bandwidth_rad_s`, without the
    /// mechanical model: `K_p = 2ω_n/k_∞`, `K_i = ω_n²/k_∞`, `K_L = 0`.
    pub fn design_plain(motor: &MotorParams, bandwidth_rad_s: f64) -> Self {
        let k = Self::k_inf(motor);
        Self {
            kp: 2.0 * bandwidth_rad_s / k,
            ki: bandwidth_rad_s * bandwidth_rad_s / k,
            kl: 0.0,
        }
    }

    /// [`MrasCurrentGains::design`] at `ω_n = 0.02/T_s`.
    pub fn default_for(motor: &MotorParams, base: &PerUnit) -> Self {
        Self::design(motor, DEFAULT_BANDWIDTH_TS / base.sample_s)
    }
}

/// Configuration of the [`MrasCurrent`] estimator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct MrasCurrentConfig {
    /// `e^{−R T_s/(2 L_d)}`, `e^{−R T_s/(2 L_q)}`.
    a_d: WideGain,
    a_q: WideGain,
    /// `(1 − a)/R`, per unit.
    g_d: WideGain,
    g_q: WideGain,
    /// `L_q/L_d`, `L_d/L_q`.
    lq_ld: WideGain,
    ld_lq: WideGain,
    /// `ψ/L_d`, `ψ/L_q` per unit (applied to Q2.30 sin/cos bits).
    psi_ld: WideGain,
    psi_lq: WideGain,
    /// Weights of ξ' = (L_q/ψ) ξ: `L_q²/(L_d ψ)` on `i_q ε_d`, `L_d/ψ` on `i_d ε_q`.
    w_qd: WideGain,
    w_dq: WideGain,
    /// `ψ` per unit (EMF of the estimate).
    psi: Pu,
    /// Angle step per unit of speed: `ω_b T_s 2¹⁶/(2π)`, so that `apply_wide` gives 2⁻⁶⁴ turns.
    turn_per_speed: WideGain,
    /// The adaptation PI on ξ'.
    pi: PiConfig,
    /// Speed clamp, per unit.
    omega_max: Pu,
    /// Mechanical model: speed change per sample per unit of torque current,
    /// `T_s p K_T I_b/(J ω_b)`, and per unit of speed, `T_s B/J` (both zero when off).
    accel: WideGain,
    friction: WideGain,
    /// Load-current estimate change per sample per unit of ξ', `T_s K_L I_b ψ/L_q` (per unit).
    load_gain: WideGain,
    /// Gains it was built with.
    pub gains: MrasCurrentGains,
}

impl MrasCurrentConfig {
    /// Estimator for `motor` sampled as in `base`, with adaptation gains `gains`
    /// ([`MrasCurrentGains::default_for`] for the defaults).
    ///
    /// Errors: [`ConfigError::Param`] for a bad motor parameter; [`ConfigError::Gain`] naming
    /// `mras_current.kp` or `mras_current.ki` outside the ranges of the module docs.
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        gains: MrasCurrentGains,
    ) -> Result<Self, ConfigError> {
        motor.validate()?;
        let ts = base.sample_s;
        let k_inf = MrasCurrentGains::k_inf(motor);
        gain_in("mras_current.kp", gains.kp, 0.0, 1.0 / (k_inf * ts))?;
        gain_in("mras_current.ki", gains.ki, 0.0, 0.25 / (k_inf * ts * ts))?;
        let a = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2;
        gain_in(
            "mras_current.kl",
            gains.kl,
            0.0,
            0.1 / (a * k_inf * ts * ts * ts),
        )?;
        let mech = gains.kl > 0.0;
        let (r, ld, lq, psi) = (
            motor.rs_ohm / base.impedance_ohm,
            motor.ld_h / base.inductance_h,
            motor.lq_h / base.inductance_h,
            motor.flux_wb / base.flux_wb,
        );
        let a_d = libm::exp(-0.5 * motor.rs_ohm * ts / motor.ld_h);
        let a_q = libm::exp(-0.5 * motor.rs_ohm * ts / motor.lq_h);
        let c = |key, v| wide_gain(key, v, 1e6);
        // ξ' = (L_q/ψ) ξ: gains on ξ' are the SI gains times I_b² ψ_pu/(ω_b L_q,pu).
        let scale = base.current_a * base.current_a * psi / (base.omega_e_rad_s * lq);
        let omega_max = MAX_SPEED_PU.min(1.0 / (base.omega_e_rad_s * ts));
        Ok(Self {
            a_d: c("ld_h", a_d)?,
            a_q: c("lq_h", a_q)?,
            g_d: c("ld_h", (1.0 - a_d) / r)?,
            g_q: c("lq_h", (1.0 - a_q) / r)?,
            lq_ld: c("lq_h", lq / ld)?,
            ld_lq: c("ld_h", ld / lq)?,
            psi_ld: c("ld_h", psi / ld)?,
            psi_lq: c("lq_h", psi / lq)?,
            w_qd: c("lq_h", lq * lq / (ld * psi))?,
            w_dq: c("ld_h", ld / psi)?,
            psi: pu_from_f64(psi),
            turn_per_speed: c(
                "sample_hz",
                base.omega_e_rad_s * ts * 65536.0 / core::f64::consts::TAU,
            )?,
            pi: PiConfig::new(
                gains.kp * scale,
                gains.ki * ts * scale,
                ["mras_current.kp", "mras_current.ki"],
            )?,
            omega_max: pu_from_f64(omega_max),
            accel: c(
                "j_kg_m2",
                if mech {
                    ts * motor.p() * motor.kt_nm_per_a * base.current_a
                        / (motor.j_kg_m2 * base.omega_e_rad_s)
                } else {
                    0.0
                },
            )?,
            friction: c(
                "b_nm_s",
                if mech {
                    ts * motor.b_nm_s / motor.j_kg_m2
                } else {
                    0.0
                },
            )?,
            load_gain: c("mras_current.kl", ts * gains.kl * base.current_a * psi / lq)?,
            gains,
        })
    }
}

/// The current-model MRAS estimator (configuration and state).
#[derive(Clone, Copy, Debug)]
pub struct MrasCurrent {
    config: MrasCurrentConfig,
    /// Adjustable-model current in the estimated frame.
    i_hat: Dq,
    /// Estimated angle, 2⁶⁴ per turn.
    theta: u64,
    /// sin/cos of the angle of the last update (the frame of `i_hat`).
    sc: SinCos,
    /// The measured current of the last update in that frame (`park(i, sc)`).
    i_dq: Dq,
    pi: Pi,
    /// Adaptation signal ξ' of the last update.
    xi: Pu,
    /// Load-current estimate of the mechanical model, per unit of `I_b`.
    i_load: Pu,
    /// The next update seeds the model with the measured current (after a reset).
    seed: bool,
    last: Estimate,
}

impl MrasCurrent {
    /// Estimator at `θ̂ = 0`, `ω̂ = 0`; call [`Estimator::reset`] with the initial position.
    pub fn new(config: MrasCurrentConfig) -> Self {
        let mut s = Self {
            pi: Pi::new(config.pi),
            config,
            i_hat: Dq::default(),
            theta: 0,
            sc: Angle::ZERO.sin_cos(),
            i_dq: Dq::default(),
            xi: Pu::ZERO,
            i_load: Pu::ZERO,
            seed: true,
            last: Estimate::default(),
        };
        s.reset(Angle::ZERO, Pu::ZERO);
        s
    }

    /// The configuration.
    pub fn config(&self) -> &MrasCurrentConfig {
        &self.config
    }

    /// The adaptation signal of the last update, `ξ' = (L_q/ψ) ξ`, per unit of `I_b`.
    pub fn xi(&self) -> Pu {
        self.xi
    }

    /// The adjustable model's current `î` in the estimated frame.
    pub fn model_current(&self) -> Dq {
        self.i_hat
    }

    /// The frame of the last estimate: `sin_cos(θ̂)` of [`Estimator::estimate`]'s angle (bit for
    /// bit what `estimate().theta.sin_cos()` gives) and the measured current of the last
    /// update rotated into it (bit for bit `park(i, sin_cos(θ̂))`; zero after a reset). The
    /// drive reuses both instead of computing them again.
    pub fn frame(&self) -> (SinCos, Dq) {
        (self.sc, self.i_dq)
    }

    /// `î ← a î + g v`, one R–L half step.
    fn half_step(&mut self, v: Dq) {
        let c = &self.config;
        self.i_hat = Dq {
            d: c.a_d.apply(self.i_hat.d).saturating_add(c.g_d.apply(v.d)),
            q: c.a_q.apply(self.i_hat.q).saturating_add(c.g_q.apply(v.q)),
        };
    }

    /// Exact rotation of the model flux by `−Δ` (the frame advancing by `Δ`).
    fn rotate(&mut self, sc: SinCos) {
        let c = &self.config;
        let (id, iq) = (self.i_hat.d, self.i_hat.q);
        let one_minus_c = Unit::from_bits((1i32 << UNIT_FRAC).saturating_sub(sc.cos.to_bits()));
        let d = mul_unit(id, sc.cos)
            .saturating_add(c.lq_ld.apply(mul_unit(iq, sc.sin)))
            .saturating_sub(c.psi_ld.apply_unit(one_minus_c));
        let q = mul_unit(iq, sc.cos)
            .saturating_sub(c.ld_lq.apply(mul_unit(id, sc.sin)))
            .saturating_sub(c.psi_lq.apply_unit(sc.sin));
        self.i_hat = Dq { d, q };
    }

    fn angle(&self) -> Angle {
        // Round the 2^-64 turn to the nearest 2^-32 turn.
        Angle((self.theta.wrapping_add(1 << 31) >> 32) as u32 as i32)
    }

    fn make_estimate(&self, omega: Pu) -> Estimate {
        let m = mul(self.config.psi, omega);
        Estimate {
            theta: self.angle(),
            omega,
            emf: AlphaBeta {
                alpha: mul_unit(m, self.sc.sin).saturating_neg(),
                beta: mul_unit(m, self.sc.cos),
            },
        }
    }
}

/// sin/cos of the frame advance `Δ = θ̂_k − θ̂_{k−1}` from the sin/cos of the two frames
/// (`sin Δ = s_k c_{k−1} − c_k s_{k−1}`, `cos Δ = c_k c_{k−1} + s_k s_{k−1}`, one rounding each)
/// instead of a third `sin_cos`; exactly `(0, 1)` when the frame did not move. The two
/// products carry the sin/cos error of both frames (a few LSB of Q2.30, as `sin_cos(Δ)` has).
#[inline(always)]
fn advance(prev: SinCos, now: SinCos) -> SinCos {
    if prev == now {
        return SinCos {
            sin: Unit::ZERO,
            cos: Unit::from_bits(1 << UNIT_FRAC),
        };
    }
    let dot = |a: Unit, b: Unit, c: Unit, d: Unit| {
        let acc = wmul_inline(a.to_bits(), b.to_bits()) + wmul_inline(c.to_bits(), d.to_bits());
        Unit::from_bits(round_shift_sat(acc, UNIT_FRAC))
    };
    SinCos {
        sin: dot(now.sin, prev.cos, now.cos.saturating_neg(), prev.sin),
        cos: dot(now.cos, prev.cos, now.sin, prev.sin),
    }
}

impl Estimator for MrasCurrent {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        let omega = self.last.omega;
        // Frame advance over [t_{k−1}, t_k) with the speed held over it.
        let step = self.config.turn_per_speed.apply_wide(omega) as u64;
        self.theta = self.theta.wrapping_add(step);
        let sc_prev = self.sc;
        let sc = self.angle().sin_cos();
        self.sc = sc;
        let i = park(input.i, sc);
        self.i_dq = i;
        if self.seed {
            // After a reset the model starts from the measured current: no error to adapt on.
            self.seed = false;
            self.i_hat = i;
            self.xi = Pu::ZERO;
            self.last = self.make_estimate(omega);
            return self.last;
        }
        self.half_step(park(input.v, sc_prev));
        self.rotate(advance(sc_prev, sc));
        self.half_step(park(input.v, sc));
        let c = &self.config;
        let e_d = i.d.saturating_sub(self.i_hat.d);
        let e_q = i.q.saturating_sub(self.i_hat.q);
        // ξ' = (L_q/ψ) ξ = (L_q²/(L_d ψ)) i_q ε_d − (L_d/ψ) i_d ε_q − ε_q   (eq. 22 × L_q/ψ)
        self.xi = c
            .w_qd
            .apply(mul(i.q, e_d))
            .saturating_sub(c.w_dq.apply(mul(i.d, e_q)))
            .saturating_sub(e_q);
        // Mechanical model: the torque current less the load estimate accelerates the rotor;
        // the load estimate moves against ξ (module docs, "Through zero speed").
        self.i_load = self.i_load.saturating_sub(c.load_gain.apply(self.xi));
        let torque = i.q.saturating_sub(self.i_load);
        let ff = c
            .accel
            .apply_wide(torque)
            .saturating_sub(c.friction.apply_wide(omega));
        self.pi.add_to_integral(ff);
        let out = self
            .pi
            .step(self.xi, Pu::ZERO, Limits::symmetric(c.omega_max), false);
        self.last = self.make_estimate(out.u);
        self.last
    }

    fn estimate(&self) -> Estimate {
        self.last
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        let omega = omega.max(-self.config.omega_max).min(self.config.omega_max);
        self.theta = (theta.0 as u32 as u64) << 32;
        self.sc = theta.sin_cos();
        self.i_dq = Dq::default();
        self.pi.reset(omega);
        self.i_hat = Dq::default();
        self.xi = Pu::ZERO;
        self.i_load = Pu::ZERO;
        self.seed = true;
        self.last = self.make_estimate(omega);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::params::InverterParams;

    fn motor_b() -> (MotorParams, PerUnit) {
        let mut m = MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011);
        m.rated_current_a = Some(2.53);
        let inv = InverterParams {
            vdc_v: 540.0,
            pwm_hz: 14e3,
            dead_time_s: 2e-6,
            current_full_scale_a: 10.0,
        };
        let base = PerUnit::new(&m, &inv, 14e3).unwrap();
        (m, base)
    }

    #[test]
    fn gains_out_of_range_are_named() {
        let (m, b) = motor_b();
        let mut g = MrasCurrentGains::default_for(&m, &b);
        g.kp = -1.0;
        assert!(matches!(
            MrasCurrentConfig::new(&m, &b, g),
            Err(ConfigError::Gain {
                key: "mras_current.kp",
                ..
            })
        ));
        let mut g = MrasCurrentGains::default_for(&m, &b);
        g.ki = 1e12;
        assert!(matches!(
            MrasCurrentConfig::new(&m, &b, g),
            Err(ConfigError::Gain {
                key: "mras_current.ki",
                ..
            })
        ));
    }

    #[test]
    fn model_at_rest_stays_at_rest_and_reset_seeds() {
        let (m, b) = motor_b();
        let cfg = MrasCurrentConfig::new(&m, &b, MrasCurrentGains::default_for(&m, &b)).unwrap();
        let mut e = MrasCurrent::new(cfg);
        e.reset(Angle::from_deg(30.0), Pu::ZERO);
        for _ in 0..1000 {
            let out = e.update(&ObserverInput::default());
            assert_eq!(out.theta, Angle::from_deg(30.0));
            assert_eq!(out.omega, Pu::ZERO);
        }
        // Wild inputs saturate, never panic.
        let wild = ObserverInput {
            i: AlphaBeta {
                alpha: Pu::MAX,
                beta: Pu::MIN,
            },
            v: AlphaBeta {
                alpha: Pu::MIN,
                beta: Pu::MAX,
            },
        };
        for _ in 0..100 {
            let out = e.update(&wild);
            assert!(out.omega.abs() <= cfg.omega_max);
        }
    }
}
