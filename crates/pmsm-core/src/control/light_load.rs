//! The light-load d-axis current (docs/drive.md, "light load").
//!
//! A motor at no load carries almost no current, and each phase current then stays within
//! the PWM ripple of zero, where an inverter's dead-time error fades from `±V_dead` to nothing
//! along a curve set by the ripple at each switching edge: a resistance of tens of ohms that
//! depends on the duties, the devices and the current itself. No compensation models that
//! curve exactly, and the error left over moves with every ripple of `i_q*`. Fed to the
//! estimator, it became a speed error, which the speed loop turned into more `i_q*` ripple: on
//! motor B at 800 r/min, a 60 Hz oscillation of ±18 r/min in the estimated speed.
//!
//! The drive therefore holds a small negative d-axis current while the load is light:
//! `i_d,LL = −max(0, min(I_LL, I_LL |ω̂|/ω_f) − |i_q*|_f)`, with `|i_q*|_f` the magnitude of
//! the q reference through a first-order filter of 16 ms (slow beside that oscillation, so the
//! d current does not follow it). (Held at its peaks instead, decaying in 64 ms, the level
//! followed the peaks of `i_q*`'s ripple at no load and the oscillation came back.)
//!
//! - `I_LL` is three times the compensation's ripple band `V_DC/(8 L_min f_PWM)`, at most a
//!   sixth of the current limit (0.57 A on motor B). The current vector's length then keeps
//!   each phase out of the band but near its zero crossings, which it sweeps through at the
//!   electrical frequency, where the compensation's errors average out. (At a quarter of the
//!   limit, two motors of the random family whose band is a tenth of their rated current lost
//!   the lock in a reversal under load.)
//! - It is gone from `|i_q*| = I_LL` on: a loaded motor is out of the band anyway. (Fading at
//!   `|i_q*| = 2 I_LL` instead, a 48 V motor of the family still carried 3 A on d at two
//!   thirds of its load.)
//! - It fades below `ω_f`, where the EMF is twice the compensation's largest error vector
//!   (`ψ ω_f = (8/3) V_dead`, 420 r/min on motor B). At low speed the error the compensation
//!   leaves on the d current's voltage turns the estimated angle (motor B at 30 r/min with the
//!   full current: 0.096 rad rms, against 0.019 without), while the oscillation it cures is
//!   one of the speed loop at speed.
//! - A negative `i_d` is the field-weakening direction: on an interior motor with
//!   `L_q > L_d` it adds torque with `i_q`, on a surface motor none. At no load it costs
//!   `(I_LL/I_max)²` of the rated copper loss (2.5 % on motor B). With MTPA or field
//!   weakening the drive takes the more negative of the two references.
//!
//! Formats: currents [`Pu`] (Q8.24) of `I_b`; the filter is a shift of its pole.

use crate::error::ConfigError;
use crate::num::{Pu, follow_shift, pu_from_f64};
use crate::params::in_range;
use crate::units::PerUnit;

/// Time constant of the filter on `|i_q*|`, s.
pub const LIGHT_LOAD_FILTER_S: f64 = 0.016;

/// Multiple of the dead-time compensation's band that [`LightLoadConfig`] holds by default.
pub const LIGHT_LOAD_BANDS: f64 = 3.0;

/// Largest default light-load current, as a fraction of the current limit.
pub const LIGHT_LOAD_MAX_PER_LIMIT: f64 = 1.0 / 6.0;

/// Largest light-load current a calibrated dead time raises it to, as a fraction of the
/// current limit ([`LightLoadConfig::scaled`]).
pub const LIGHT_LOAD_RAISED_PER_LIMIT: f64 = 0.2;

/// The light-load current's configuration.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct LightLoadConfig {
    /// `I_LL`, per unit; zero: off.
    current: Pu,
    /// The largest `I_LL` a calibrated dead time may raise it to ([`LightLoadConfig::scaled`]).
    cap: Pu,
    /// `ω_f`, [`Pu`] bits, at least 2¹² (2⁻¹² pu).
    fade: i32,
    /// `I_LL/ω_f` in [`Pu`] bits of current per 2⁻¹² pu of speed: `k (min(|ω|, ω_f) ≫ 12)`
    /// is at most `I_LL` (< 2²⁸ bits), a 32-bit product.
    per_speed: i32,
    /// The filter's shift, per update (every eighth sample).
    shift: u32,
}

impl LightLoadConfig {
    /// Off.
    pub const OFF: Self = Self {
        current: Pu::ZERO,
        cap: Pu::ZERO,
        fade: 1 << 12,
        per_speed: 0,
        shift: 0,
    };

    /// `I_LL = current_a` (A peak; 0 turns it off), full from the electrical speed
    /// `fade_rad_s` up (0: at every speed), in the bases `base`, updated every `every`
    /// samples; a calibrated dead time may raise it up to `cap_a`.
    ///
    /// Errors: [`ConfigError::Param`] for `light_load_id_a` outside `[0, 10 I_b]` or a
    /// negative `fade_rad_s`.
    pub fn new(
        current_a: f64,
        fade_rad_s: f64,
        cap_a: f64,
        base: &PerUnit,
        every: u32,
    ) -> Result<Self, ConfigError> {
        let i = in_range("light_load_id_a", current_a, 0.0, 10.0 * base.current_a)?;
        let fade = in_range("light_load_fade_rad_s", fade_rad_s, 0.0, f64::MAX)?;
        if i == 0.0 {
            return Ok(Self::OFF);
        }
        let current = pu_from_f64(i / base.current_a);
        // ω_f in units of 2⁻¹² pu, at least one (0: full at every speed).
        let fade_units = libm::round(fade / base.omega_e_rad_s * 4096.0).clamp(1.0, 1e9);
        Ok(Self {
            current,
            cap: pu_from_f64(cap_a.max(i) / base.current_a),
            fade: (fade_units as i32).saturating_mul(1 << 12),
            per_speed: per_speed(current.to_bits(), fade_units as i32),
            shift: follow_shift(LIGHT_LOAD_FILTER_S / (base.sample_s * f64::from(every)))
                .unwrap_or(0),
        })
    }

    /// `I_LL`, per unit (zero: off).
    pub fn current(&self) -> Pu {
        self.current
    }

    /// Updates of four time constants of the `|i_q*|` filter (`4·2^shift`).
    #[inline(always)]
    pub(crate) fn settled_updates(&self) -> u32 {
        4 << self.shift
    }

    /// The configuration for an inverter whose `V_dead` is `scale` (Q4.28) times the one it
    /// was designed for (the dead-time calibration's): `I_LL` and `ω_f` raised in proportion
    /// when `scale` > 1 (the error left to average out grows with `V_dead`; motor B with 3 µs
    /// of dead time for the 2 µs it was told needed 0.7 A, not 0.57 A), `I_LL` at most the
    /// cap; unchanged otherwise.
    pub fn scaled(&self, scale: i32) -> Self {
        if scale <= 1 << 28 || self.current == Pu::ZERO {
            return *self;
        }
        let up = |x: i32| crate::num::scale_q28(x, scale.min(4 << 28));
        let current = up(self.current.to_bits()).min(self.cap.to_bits());
        let fade = up(self.fade);
        Self {
            current: Pu::from_bits(current),
            fade,
            per_speed: per_speed(current, fade >> 12),
            ..*self
        }
    }

    /// The default `ω_f`, electrical rad/s: where the EMF `ψ ω_f` is `(8/3) V_dead` (twice the
    /// compensation's largest error vector, `(4/3) V_dead`); `flux_wb` the magnet flux,
    /// `v_dead_v` the compensation's `V_dead` at the nominal bus.
    pub fn default_fade_rad_s(flux_wb: f64, v_dead_v: f64) -> f64 {
        if flux_wb > 0.0 {
            8.0 / 3.0 * v_dead_v / flux_wb
        } else {
            0.0
        }
    }

    /// The default `I_LL` in A: [`LIGHT_LOAD_BANDS`] times the dead-time band `band_a`, at
    /// most [`LIGHT_LOAD_MAX_PER_LIMIT`] of the current limit `limit_a`; zero without dead
    /// time (`dead_time_s` 0: nothing to keep away from).
    pub fn default_current_a(band_a: f64, limit_a: f64, dead_time_s: f64) -> f64 {
        if dead_time_s > 0.0 {
            (LIGHT_LOAD_BANDS * band_a).min(LIGHT_LOAD_MAX_PER_LIMIT * limit_a)
        } else {
            0.0
        }
    }
}

/// `I_LL/ω_f` of [`LightLoadConfig`]: `current` [`Pu`] bits over `fade_units` (ω_f in units of
/// 2⁻¹² pu, taken at least one), rounded to nearest.
fn per_speed(current: i32, fade_units: i32) -> i32 {
    // c < 2²⁸ (at most 10 pu), n ≤ 10⁹: both sums fit 32 bits (no 64-bit division).
    let (c, n) = (current.max(0) as u32, fade_units.max(1) as u32);
    ((2 * c + n) / (2 * n)) as i32
}

/// `|x|` in [`Pu`] bits, at most 2³⁰ (64 pu, the speed loop's largest limit).
#[inline(always)]
fn magnitude(x: Pu) -> i32 {
    x.to_bits().unsigned_abs().min(1 << 30) as i32
}

/// The light-load current's state: the filtered `|i_q*|` and the reference it gives.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LightLoad {
    level: Pu,
    id_ref: Pu,
}

impl LightLoad {
    /// Starts from `|iq|` (the q reference handed over to the closed loop) at the speed
    /// `omega`.
    pub fn reset(&mut self, c: &LightLoadConfig, iq: Pu, omega: Pu) {
        self.level = Pu::from_bits(magnitude(iq));
        self.update(c, iq, omega);
    }

    /// One update (every eighth sample) from the q reference `iq` and the estimated speed
    /// `omega`.
    #[inline(always)]
    pub fn update(&mut self, c: &LightLoadConfig, iq: Pu, omega: Pu) {
        // Plain integer steps (a few instructions on the Cortex-M0, whose saturating ones are
        // several each), each within range: |i_q*| is taken at most 2³⁰ bits (64 pu), so the
        // filter's input, state and their difference lie within ±2³⁰.
        let y = self.level.to_bits();
        self.level = Pu::from_bits(y + ((magnitude(iq) - y) >> c.shift));
        // min(|ω|, ω_f) in units of 2⁻¹² pu times `I_LL/ω_f`: at most I_LL (< 2²⁸ bits), a
        // 32-bit product.
        let w = (omega.to_bits().unsigned_abs().min(c.fade as u32) >> 12) as i32;
        let full = (w * c.per_speed).min(c.current.to_bits());
        // −max(0, full − level): both terms in [0, 2³⁰].
        self.id_ref = Pu::from_bits(-(full - self.level.to_bits()).max(0));
    }

    /// The d-axis reference, `≤ 0`.
    #[inline(always)]
    pub fn id_ref(&self) -> Pu {
        self.id_ref
    }

    /// The filtered `|i_q*|`, per unit.
    #[inline(always)]
    pub fn level(&self) -> Pu {
        self.level
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fixtures::{inverter_b, motor_b};

    /// The fixed-point reference against the f64 law, through the filter's settling, over
    /// speeds through the fade and q references from no load to twice `I_LL`: within 5e−4 pu
    /// (1.8 mA on motor B; the fade's speed is held to 2⁻¹² pu, 0.1 % of it here, and a shift
    /// filter settles within `2^shift` LSB of its input).
    #[test]
    fn light_load_current_against_reference() {
        let base = PerUnit::new(&motor_b(), &inverter_b(), 14e3).unwrap();
        let (i_ll, fade) = (0.57, 130.0);
        let c = LightLoadConfig::new(i_ll, fade, 1.0, &base, 8).unwrap();
        let i_ll_pu = i_ll / base.current_a;
        let fade_pu = fade / base.omega_e_rad_s;
        let mut worst: f64 = 0.0;
        for w in [0.0, 0.25, 0.5, 1.0, 2.0, -3.0] {
            let omega = w * fade_pu;
            let mut l = LightLoad::default();
            l.reset(&c, Pu::ZERO, pu_from_f64(omega));
            let full = i_ll_pu * omega.abs().min(fade_pu) / fade_pu;
            worst = worst.max((l.id_ref().to_num::<f64>() + full).abs());
            for k in 0..=20 {
                let iq = 2.5 * i_ll_pu * k as f64 / 20.0;
                for _ in 0..4000 {
                    l.update(&c, pu_from_f64(-iq), pu_from_f64(omega));
                }
                let want = -(full - iq).max(0.0);
                worst = worst.max((l.id_ref().to_num::<f64>() - want).abs());
            }
        }
        assert!(worst < 5e-4, "{worst} pu");
        // Off: nothing.
        let mut l = LightLoad::default();
        l.reset(&LightLoadConfig::OFF, Pu::ZERO, Pu::ONE);
        assert_eq!(l.id_ref(), Pu::ZERO);
        // The filter: after one time constant from zero, 1 − 1/e of a step (the pole a
        // power of two: within a factor of √2 of 16 ms).
        let mut l = LightLoad::default();
        l.reset(&c, Pu::ZERO, Pu::ONE);
        let step = pu_from_f64(2.0 * i_ll_pu);
        let n = (LIGHT_LOAD_FILTER_S * 14e3 / 8.0) as u32;
        for _ in 0..n {
            l.update(&c, step, Pu::ONE);
        }
        let frac = l.level.to_num::<f64>() / (2.0 * i_ll_pu);
        assert!((0.45..0.8).contains(&frac), "{frac}");
        // Beyond the range: a named error.
        assert!(LightLoadConfig::new(-1.0, fade, 1.0, &base, 8).is_err());
        assert!(LightLoadConfig::new(100.0 * base.current_a, fade, 1.0, &base, 8).is_err());
        assert!(LightLoadConfig::new(i_ll, -1.0, 1.0, &base, 8).is_err());
    }

    #[test]
    fn defaults_follow_the_inverter() {
        assert!(LightLoadConfig::default_current_a(0.19, 3.58, 0.0).abs() < 1e-12);
        assert!((LightLoadConfig::default_current_a(0.19, 3.58, 2e-6) - 0.57).abs() < 1e-12);
        // Capped at a sixth of the limit.
        assert!((LightLoadConfig::default_current_a(5.0, 12.0, 2e-6) - 2.0).abs() < 1e-12);
        // Motor B: V_dead 15.12 V, ψ 0.305 Wb: 132 rad/s electrical, 420 r/min.
        let w = LightLoadConfig::default_fade_rad_s(0.305, 15.12);
        assert!(
            (w * 60.0 / core::f64::consts::TAU / 3.0 - 420.7).abs() < 1.0,
            "{w}"
        );
    }
}
