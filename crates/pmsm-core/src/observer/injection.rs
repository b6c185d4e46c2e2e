//! Square-wave high-frequency injection: the rotor angle of a salient motor at standstill and
//! low speed, from the saliency (docs/injection.md).
//!
//! ```text
//! inject   v_d̂ += s_n V_h,  s_n = ±1 alternating every sample (a square wave at f_s/2)
//! measure  d2_n = i_n − 2 i_{n−1} + i_{n−2}       (αβ; the fundamental's slope cancels)
//!          ε_n = sign(d̂(d2_n)) · q̂(d2_n)             (= s_{n−1−d} q̂(d2_n), d the PWM delay)
//!              = V_h T_s (1/L_d − 1/L_q) sin 2(θ − θ̂)   ≈ 4K (θ − θ̂),  K = V_h T_s (1/L_d − 1/L_q)/2
//! track    θ̂_{n+1} = θ̂_n + ω̂_n T_s + l₁ T_s e_n                   e_n = ε_n/4K
//!          ω̂_{n+1} = ω̂_n + (b î_q − â_n) T_s + l₂ T_s e_n           b = p K_T/J
//!          â_{n+1} = â_n − l₃ T_s e_n                                 (the load's deceleration)
//!          (l₁, l₂, l₃) = (3ω_p, 3ω_p², ω_p³): the error's three poles at −ω_p
//! control  the current loops get (i_n + i_{n−1})/2 in the frame θ̂_n: the injected ripple
//!          (a triangle at f_s/2) averaged out
//! ```
//!
//! A voltage step `s V_h` along the estimated d axis `d̂`, an angle `Δθ = θ − θ̂` from the
//! rotor's, moves the current in one period by `V_h T_s (cos Δθ/L_d, −sin Δθ/L_q)` in the
//! rotor frame, whose component across `d̂` is `V_h T_s (1/L_d − 1/L_q) sin 2Δθ / 2`: zero on
//! the axis, positive when `θ̂` lags. The injection alternates, so the second difference of
//! the current doubles it and removes what moves slowly (the EMF, the resistive drop, the
//! current loops' own voltage).
//!
//! The torque current drives the speed estimate through the mechanics (`b`, the motor's
//! `p K_T/J`), and the loop learns the load as a deceleration `â`: a speed estimate without the
//! lag of a plain phase-locked loop, which a speed loop around it would otherwise ring with.
//!
//! The loop locks on the d axis or on its opposite (`sin 2Δθ` has both zeros): it must be
//! started at the magnet's polarity, which the initial position detection gives from the
//! saturation (Khlaief, Boussak, Gossa (2012) §4), and the drive hands it the estimator's
//! angle whenever it takes over.
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | currents, `d2`, `ε` | [`Pu`] Q8.24 of `I_b` | `d2` within ±128 pu (saturated) |
//! | `V_h` | [`Pu`] of `V_b` | at most half of `V_b` |
//! | `θ̂` | [`Angle`] (2³² per turn) | wrapping |
//! | `ω̂` | [`Pu`] of `ω_b` | within ±`ω_max` |
//! | `l₁` | `Coef<12>`, Angle LSB per `Pu` LSB of `ε` | below 2¹⁹ |
//! | `l₂` | `Coef<30>`, `Pu` LSB of speed per `Pu` LSB of `ε` | below 2 |
//! | `l₃` | `Coef<24>`, 2⁻⁸ `Pu` LSB of speed per sample per `Pu` LSB of `ε` | below 2⁷ |
//! | `b` | `Coef<30>`, `Pu` LSB of speed per sample per `Pu` LSB of current | below 2 |
//! | `â T_s` | `i32`, 2⁻⁸ `Pu` LSB of speed per sample | saturated: ±0.5 pu per sample |
#![cfg_attr(not(feature = "injection"), allow(dead_code))]

use crate::angle::{Angle, SinCos};
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, park};
use crate::num::{Coef, Pu, pu_from_f64};
use crate::observer::{Estimate, Frame};
use crate::params::{InverterParams, MotorParams, ParamError, ParamReason};
use crate::units::PerUnit;

/// How the injection is designed; [`InjectionDesign::default`] computes everything from the
/// motor and the inverter.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct InjectionDesign {
    /// Injected amplitude `V_h`, V; `None`: the least that moves the current by
    /// [`InjectionDesign::signal_lsb`] ADC steps across the axis at 45° of error.
    pub amplitude_v: Option<f64>,
    /// The response `K` the amplitude is designed for, in steps of the current ADC.
    pub signal_lsb: f64,
    /// Resolution of the current ADC, bits (its full scale is the inverter's).
    pub adc_bits: u32,
    /// Natural frequency `ω_p` of the tracking loop, rad/s; `None`: the least that holds the
    /// angle within 0.1 rad through a rated load step, within `0.01/T_s` and `0.02/T_s`
    /// (docs/injection.md, "The design"), lowered in proportion where the bus limits the
    /// response below [`InjectionDesign::signal_lsb`] (the error's noise is the ADC's steps
    /// over the response).
    pub bandwidth_rad_s: Option<f64>,
    /// The injection takes over below this share of the rated electrical speed…
    pub on_below: f64,
    /// …and hands back to the estimator above this one.
    pub off_above: f64,
    /// On a motor the injection cannot serve (saliency below [`MIN_SALIENCY`], a gain out of
    /// range), design the drive without it and say why (`DriveConfig::injection_declined`,
    /// with the feature `injection`) instead of refusing the design. On in the default; a
    /// user who asks for the injection by name gets the error.
    pub fallback: bool,
}

impl Default for InjectionDesign {
    fn default() -> Self {
        Self {
            amplitude_v: None,
            signal_lsb: 8.0,
            adc_bits: 12,
            bandwidth_rad_s: None,
            on_below: 0.06,
            off_above: 0.1,
            fallback: true,
        }
    }
}

impl InjectionDesign {
    /// The default design asked for by name: a motor it cannot serve is refused (no
    /// [`InjectionDesign::fallback`]).
    pub fn required() -> Self {
        Self {
            fallback: false,
            ..Self::default()
        }
    }
}

/// Least `ω_p T_s` of the tracking loop: the angle it reads steps by `1/4K` rad per ADC step
/// of the response, each step a speed transient of `ω_p` times it, so the loop is as slow as
/// a load step allows (`LOAD_STEP_RAD_S2_PER_W2`; docs/injection.md, "The design").
pub const BANDWIDTH_TS: f64 = 0.01;

/// The tracking loop's angle error under a step of deceleration `a` peaks at `0.27 a/ω_p²`
/// (three poles at `−ω_p`): `ω_p²` of at least `a/LOAD_STEP_RAD_S2_PER_W2` keeps it within
/// 0.1 rad for a step of rated torque, up to twice [`BANDWIDTH_TS`] (light rotors).
const LOAD_STEP_RAD_S2_PER_W2: f64 = 0.1 / 0.27;

/// Held at low speed on the injection, the speed loop's bandwidth is at most this share of
/// the tracking loop's `ω_p` (a loop around a sensor runs inside the sensor's bandwidth), and
/// no less than a light rotor's stiff loop.
pub const SPEED_SHARE: f64 = 0.25;

/// Least saliency `L_q/L_d` the injection is designed for: below it the response across the
/// axis is a few ADC steps only at an amplitude that shakes the rotor.
pub const MIN_SALIENCY: f64 = 1.1;

/// The injection's fixed-point configuration.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub(crate) struct InjectionConfig {
    v_h: Pu,
    k_theta: Coef<12>,
    k_omega: Coef<30>,
    k_load: Coef<24>,
    accel: Coef<30>,
    /// Angle LSB per sample per `Pu` LSB of speed, as the open loop's.
    turn_per_speed: Coef<24>,
    /// Samples after a restart before the error is read: the injection's first response
    /// reaches the second difference `d + 3` samples later.
    settle: u8,
    omega_max: Pu,
    /// Hysteresis of the hand-over, per unit of `ω_b`.
    pub(crate) on_below: Pu,
    pub(crate) off_above: Pu,
}

/// The injection as designed ([`crate::DriveConfig::injection`]).
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct InjectionFigures {
    /// Injected amplitude along the estimated d axis, V.
    pub amplitude_v: f64,
    /// The square wave's frequency, Hz (half the sampling rate).
    pub frequency_hz: f64,
    /// The current across the axis at 45° of angle error, A (`K` of docs/injection.md).
    pub response_a: f64,
    /// Peak-to-peak current ripple along the d axis, A.
    pub ripple_a: f64,
    /// The tracking loop's natural frequency `ω_p`, rad/s.
    pub bandwidth_rad_s: f64,
}

impl InjectionConfig {
    /// Designs the injection for `motor` on `inverter`, the bases `base` and a PWM update
    /// delay of `pwm_delay` samples; with it, its figures.
    ///
    /// Errors: [`ConfigError::Param`] for `injection` on a motor whose `L_q/L_d` is below
    /// [`MIN_SALIENCY`]; [`ConfigError::Gain`] for `injection.amplitude_v`
    /// (outside `(0, V_b/2]`), `injection.bandwidth_rad_s` (outside `(0, 0.05/T_s]`) and
    /// `injection.hand_over` (`on_below` not below `off_above`, or beyond 0.5).
    pub fn new(
        motor: &MotorParams,
        inverter: &InverterParams,
        base: &PerUnit,
        design: InjectionDesign,
        pwm_delay: u8,
    ) -> Result<(Self, InjectionFigures), ConfigError> {
        let ts = base.sample_s;
        let saliency = motor.lq_h / motor.ld_h;
        if saliency.is_nan() || saliency < MIN_SALIENCY {
            return Err(ParamError {
                key: "injection",
                reason: ParamReason::Inconsistent(
                    "a surface motor: it needs L_q/L_d of at least 1.1 (the angle is read from \
                     the saliency)",
                ),
            }
            .into());
        }
        let contrast = 1.0 / motor.ld_h - 1.0 / motor.lq_h;
        let v_max = 0.5 * base.voltage_v;
        let lsb =
            2.0 * inverter.current_full_scale_a / libm::ldexp(1.0, design.adc_bits.min(24) as i32);
        let amplitude = design
            .amplitude_v
            .unwrap_or((2.0 * design.signal_lsb * lsb / (ts * contrast)).min(v_max));
        if !(amplitude > 0.0 && amplitude <= v_max) {
            return Err(ConfigError::Gain {
                key: "injection.amplitude_v",
                value: amplitude,
                min: 0.0,
                max: v_max,
            });
        }
        let w_max = 0.05 / ts;
        let signal = amplitude * ts * contrast / 2.0 / lsb;
        // A step of rated torque decelerates the rotor by `a` (electrical): `ω_p² ≥ a/LOAD_STEP_RAD_S2_PER_W2`
        // keeps the angle within 0.1 rad through it, between the default and twice it.
        let a = motor.p() * motor.kt_nm_per_a * base.current_a / motor.j_kg_m2;
        // max/min, not `f64::clamp`: its check of the bounds would link float formatting.
        let stiff = libm::sqrt(a / LOAD_STEP_RAD_S2_PER_W2)
            .max(BANDWIDTH_TS / ts)
            .min(2.0 * BANDWIDTH_TS / ts);
        let wp = design
            .bandwidth_rad_s
            .unwrap_or(stiff * (signal / design.signal_lsb).min(1.0));
        if !(wp > 0.0 && wp <= w_max) {
            return Err(ConfigError::Gain {
                key: "injection.bandwidth_rad_s",
                value: wp,
                min: 0.0,
                max: w_max,
            });
        }
        if !(design.on_below > 0.0 && design.on_below < design.off_above && design.off_above <= 0.5)
        {
            return Err(ConfigError::Gain {
                key: "injection.hand_over",
                value: design.on_below,
                min: 0.0,
                max: design.off_above.min(0.5),
            });
        }
        // K per unit: ε ≈ 4K Δθ.
        let k = amplitude * ts * contrast / 2.0 / base.current_a;
        let (l1, l2, l3) = (3.0 * wp, 3.0 * wp * wp, wp * wp * wp);
        let k_theta = l1 * ts / (4.0 * k * Angle::RAD_PER_LSB * 16_777_216.0);
        let k_omega = l2 * ts / (4.0 * k * base.omega_e_rad_s);
        let k_load = l3 * ts * ts / (4.0 * k * base.omega_e_rad_s) * 256.0;
        let accel = motor.p() * motor.kt_nm_per_a / motor.j_kg_m2 * base.current_a * ts
            / base.omega_e_rad_s;
        let gain = |key, value: f64| ConfigError::Gain {
            key,
            value,
            min: 0.0,
            max: 32768.0,
        };
        let rated = crate::drive::rated_e_rad_s(motor, base);
        let figures = InjectionFigures {
            amplitude_v: amplitude,
            frequency_hz: 0.5 / ts,
            response_a: k * base.current_a,
            ripple_a: amplitude * ts / motor.ld_h,
            bandwidth_rad_s: wp,
        };
        let config = Self {
            v_h: pu_from_f64(amplitude / base.voltage_v),
            k_theta: Coef::new(k_theta).ok_or(gain("injection.bandwidth_rad_s", wp))?,
            k_omega: Coef::new(k_omega).ok_or(gain("injection.bandwidth_rad_s", wp))?,
            k_load: Coef::new(k_load).ok_or(gain("injection.bandwidth_rad_s", wp))?,
            accel: Coef::new(accel).ok_or(gain("j_kg_m2", motor.j_kg_m2))?,
            turn_per_speed: Coef::new(
                base.omega_e_rad_s * ts / (Angle::RAD_PER_LSB * 16_777_216.0),
            )
            .ok_or(gain("sample_hz", 1.0 / ts))?,
            settle: pwm_delay + 3,
            omega_max: pu_from_f64(design.off_above * 2.0 * rated / base.omega_e_rad_s),
            on_below: pu_from_f64(design.on_below * rated / base.omega_e_rad_s),
            off_above: pu_from_f64(design.off_above * rated / base.omega_e_rad_s),
        };
        Ok((config, figures))
    }
}

/// The injection's state: the tracking loop and the last two currents.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Injection {
    theta: Angle,
    sc: SinCos,
    omega: Pu,
    /// The load's deceleration per sample, 2⁻⁸ `Pu` LSB.
    load: i32,
    i1: AlphaBeta,
    i2: AlphaBeta,
    /// The injection's amplitude (the configuration's, kept at hand for the modulation).
    v_h: Pu,
    /// The sign of the next injection.
    positive: bool,
    /// Samples left before the error is read.
    settle: u8,
}

impl Injection {
    /// Restarts the loop at `theta`, `omega` (the estimator's, or the detection's angle).
    #[cold]
    #[inline(never)]
    pub fn restart(&mut self, c: &InjectionConfig, theta: Angle, omega: Pu) {
        *self = Self {
            theta,
            sc: theta.sin_cos(),
            omega: omega.max(-c.omega_max).min(c.omega_max),
            v_h: c.v_h,
            settle: c.settle,
            ..Self::default()
        };
    }

    /// One sample: the estimate and the frame of this sample (the current without the
    /// injected ripple), and the loop advanced to the next.
    #[inline(always)]
    pub(crate) fn update(&mut self, c: &InjectionConfig, i: AlphaBeta) -> (Estimate, Frame) {
        let half = |a: Pu, b: Pu| Pu::from_bits((a.to_bits() >> 1) + (b.to_bits() >> 1));
        let mean = AlphaBeta {
            alpha: half(i.alpha, self.i1.alpha),
            beta: half(i.beta, self.i1.beta),
        };
        let second =
            |x: Pu, x1: Pu, x2: Pu| x.saturating_sub(x1).saturating_sub(x1.saturating_sub(x2));
        let d2 = AlphaBeta {
            alpha: second(i.alpha, self.i1.alpha, self.i2.alpha),
            beta: second(i.beta, self.i1.beta, self.i2.beta),
        };
        let i_dq = park(mean, self.sc);
        let d2 = park(d2, self.sc);
        // The injection that made this response, by its own sign along the axis (which
        // `(cos² Δθ/L_d + sin² Δθ/L_q) > 0` keeps): whatever delay the PWM puts between the
        // command and the current, the demodulation follows the voltage that acted.
        let error = if self.settle > 0 {
            self.settle -= 1;
            0
        } else if d2.d >= Pu::ZERO {
            d2.q.to_bits()
        } else {
            d2.q.to_bits().saturating_neg()
        };
        let estimate = Estimate {
            theta: self.theta,
            omega: self.omega,
            emf: AlphaBeta::default(),
        };
        let step = c.turn_per_speed.apply_bits(self.omega.to_bits());
        let next = self.theta + Angle(step.wrapping_add(c.k_theta.apply_bits(error)));
        self.load = self.load.saturating_sub(c.k_load.apply_bits(error));
        let change = c
            .accel
            .apply_bits(i_dq.q.to_bits())
            .saturating_sub(self.load >> 8)
            .saturating_add(c.k_omega.apply_bits(error));
        self.omega = Pu::from_bits(self.omega.to_bits().saturating_add(change))
            .max(-c.omega_max)
            .min(c.omega_max);
        let sc_next = next.sin_cos();
        let frame = Frame {
            sc: self.sc,
            i_dq,
            sc_next,
        };
        self.theta = next;
        self.sc = sc_next;
        self.i2 = self.i1;
        self.i1 = i;
        (estimate, frame)
    }

    /// The voltage to add along the estimated d axis this sample, `±V_h`; the sign alternates.
    #[inline(always)]
    pub fn voltage(&mut self) -> Pu {
        let v = if self.positive { self.v_h } else { -self.v_h };
        self.positive = !self.positive;
        v
    }

    /// The estimated angle and speed the loop will give at its next sample.
    pub fn estimate(&self) -> (Angle, Pu) {
        (self.theta, self.omega)
    }
}

pub(crate) mod polarity;

#[cfg(test)]
mod tests;
