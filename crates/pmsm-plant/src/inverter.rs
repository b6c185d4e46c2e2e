//! Three-phase voltage-source inverter with dead time and device drops (Khlaief, Boussak, Gossa (2012) eq. 7–8,
//! docs/khlaief2012.md §4).
//!
//! Each leg `x` is commanded with a duty `d_x ∈ [0, 1]` of a centre-aligned PWM of period `T`.
//! Two models:
//!
//! - [`InverterKind::Averaged`]: the period average of the leg voltage,
//!   `v_x = d_x V_DC + (½ − d_x)(V_sat − V_f) − V_dead sgn(i_x)` (for `δ < d_x < 1 − δ`,
//!   `δ = T_eff/T`), with a smooth sign so that the integration does not chatter at current
//!   zero crossings. The middle term vanishes for `V_sat = V_f` (the defaults); it is the exact
//!   average of the switching model, which it therefore matches period by period.
//! - [`InverterKind::Switching`]: every edge of the six devices, integrated piecewise. The
//!   high-side command of leg `x` is a pulse of width `d_x T` centred at `T/2`; every turn-on
//!   (of either device) is delayed by `T_eff = T_dead + T_on − T_off` (the common delay
//!   `T_off` of all edges is neglected), and while both devices are off a diode conducts:
//!   the lower one (`−V_f`) for `i_x > 0`, the upper one (`V_DC + V_f`) for `i_x < 0`. A
//!   conducting switch drops `V_sat`, a conducting diode `V_f`. With `sign_band_a = 0` the
//!   sign is the hard sign of the instantaneous current, ripple included: when a leg's
//!   current reaches zero within its dead time both diodes block and the phase floats, its
//!   leg voltage the one that holds its current at zero, until a switch turns on again (or
//!   that voltage would leave the rails). The fading of the dead-time error at mean currents
//!   within the ripple then comes out of the physics, and so does the zero-current clamp:
//!   from zero current, legs whose edges lie closer than the dead time drive no current at
//!   all (a dead zone of `±2 T_eff/T` in duty difference). With a band (the default,
//!   [`DEFAULT_SIGN_BAND`]) the sign is the smooth sign of the current at the start of each
//!   interval between edges, which has neither. A duty of exactly 0 or 1 does not switch.
//!
//! Motor phase voltages are taken relative to the isolated neutral; the amplitude-invariant
//! Clarke transform ([`crate::clarke`]) discards the common mode, so the leg voltages are
//! transformed directly. The dead-time error vector of Khlaief, Boussak, Gossa (2012) eq. 7,
//! `V_dt = (2/3) V_dead [sgn i_a + a sgn i_b + a² sgn i_c]`, is then exactly the difference
//! between the commanded and the applied αβ voltage (Khlaief, Boussak, Gossa (2012) eq. 9), and has length
//! `(4/3) V_dead` whenever no current is near zero.

use pmsm_core::validate::{in_range, non_negative};
use pmsm_core::{InverterParams, ParamError, ParamReason};

use crate::clarke;

mod switching;
pub use switching::Inverter;

/// Default width of the smooth current sign, relative to the current-sensing full scale.
///
/// A real leg's dead-time error does not switch at the zero crossing of the *average* current
/// but fades over the band where the PWM ripple makes the instantaneous current change sign;
/// for motor B at 14 kHz and 540 V the ripple amplitude is about 0.2 A, 1 % of a 20 A sensor.
/// Used by the averaged model only: the switching model gets the fading from the ripple.
pub const DEFAULT_SIGN_BAND: f64 = 0.01;

/// Which inverter model a [`Plant`](crate::Plant) integrates.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum InverterKind {
    /// Period-averaged leg voltages with a smooth dead-time error (fast).
    Averaged,
    /// Every switching edge, dead time and device drop (slow, exact ripple).
    Switching,
}

/// Inverter parameters beyond [`InverterParams`]: device drops and delays.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct InverterModel {
    /// Bus voltage, PWM frequency, dead time, current full scale.
    pub params: InverterParams,
    /// On-state drop of a conducting switch `V_sat`, V.
    pub v_sat_v: f64,
    /// Forward drop of a conducting diode `V_f`, V.
    pub v_f_v: f64,
    /// Switch turn-on delay `T_on`, s.
    pub t_on_s: f64,
    /// Switch turn-off delay `T_off`, s.
    pub t_off_s: f64,
    /// Width `i_ε` of the smooth current sign `clamp(i/i_ε, −1, 1)`, A. Zero: the hard sign.
    /// The averaged model takes it once per PWM period at its start, so that a current at zero
    /// does not flip the dead-time voltage between the Runge–Kutta stages of one step. The
    /// switching model takes it from the instantaneous current, ripple included, and lets a
    /// dead leg whose current reaches zero float (the module documentation); with a band it
    /// takes the smooth sign at the start of each interval between edges instead.
    pub sign_band_a: f64,
    /// Averaged or switching-level model.
    pub kind: InverterKind,
}

/// Which device of a leg conducts.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Conduction {
    /// Upper switch gated on.
    Upper,
    /// Lower switch gated on.
    Lower,
    /// Both gated off (dead time): a diode conducts, chosen by the current.
    Dead,
}

impl InverterModel {
    /// Ideal devices (`V_sat = V_f = 0`, `T_on = T_off = 0`), so the only non-ideality is
    /// the dead time of `params`; sign band [`DEFAULT_SIGN_BAND`] of the current full scale.
    pub fn new(params: InverterParams, kind: InverterKind) -> Self {
        Self {
            params,
            v_sat_v: 0.0,
            v_f_v: 0.0,
            t_on_s: 0.0,
            t_off_s: 0.0,
            sign_band_a: DEFAULT_SIGN_BAND * params.current_full_scale_a,
            kind,
        }
    }

    /// Checks every parameter; the error names the first offending key.
    pub fn validate(&self) -> Result<(), ParamError> {
        self.params.validate()?;
        in_range("v_sat_v", self.v_sat_v, 0.0, 50.0)?;
        in_range("v_f_v", self.v_f_v, 0.0, 50.0)?;
        non_negative("t_on_s", self.t_on_s)?;
        non_negative("t_off_s", self.t_off_s)?;
        let t_eff = self.effective_dead_time_s();
        if t_eff < 0.0 {
            return Err(ParamError {
                key: "t_off_s",
                reason: ParamReason::Inconsistent("dead_time_s + t_on_s (shoot-through)"),
            });
        }
        if t_eff * self.params.pwm_hz >= 0.1 {
            return Err(ParamError {
                key: "t_on_s",
                reason: ParamReason::Inconsistent("pwm_hz (effective dead time over 10 %)"),
            });
        }
        non_negative("sign_band_a", self.sign_band_a)?;
        Ok(())
    }

    /// PWM period `T = 1/pwm_hz`, s.
    pub fn period_s(&self) -> f64 {
        1.0 / self.params.pwm_hz
    }

    /// Effective dead time `T_eff = T_dead + T_on − T_off`, s: how much later than commanded a
    /// leg's output follows a turn-on edge.
    pub fn effective_dead_time_s(&self) -> f64 {
        self.params.dead_time_s + self.t_on_s - self.t_off_s
    }

    /// Dead-time voltage (Khlaief, Boussak, Gossa (2012) eq. 8, docs/khlaief2012.md §4), V:
    /// `V_dead = (T_dead + T_on − T_off)/T_PWM · (V_DC − V_sat + V_f) + (V_sat + V_f)/2`.
    pub fn dead_voltage_v(&self, vdc_v: f64) -> f64 {
        self.effective_dead_time_s() * self.params.pwm_hz * (vdc_v - self.v_sat_v + self.v_f_v)
            + 0.5 * (self.v_sat_v + self.v_f_v)
    }

    /// Smooth current sign `clamp(i/i_ε, −1, 1)`, the hard sign (0 at 0) for `i_ε = 0`; NaN
    /// reads as 0.
    pub fn smooth_sign(&self, i_a: f64) -> f64 {
        if self.sign_band_a <= 0.0 {
            return hard_sign(i_a);
        }
        let s = i_a / self.sign_band_a;
        if s.is_nan() { 0.0 } else { s.clamp(-1.0, 1.0) }
    }

    /// With the hard sign (`i_ε = 0`), the signs of `i_abc_a` that hold over a whole period
    /// (taken at its start); `None` with a band, whose smooth sign follows the current.
    pub fn period_signs(&self, i_abc_a: [f64; 3]) -> Option<[f64; 3]> {
        (self.sign_band_a <= 0.0).then(|| i_abc_a.map(hard_sign))
    }

    /// The model for a period with every switch off: the hard sign cannot hold a blocked
    /// diode pair at zero (a current held at its start's sign for a period overshoots zero
    /// by up to `V_DC T/(2L)` and swings between the rails), so such a period uses the band
    /// [`DEFAULT_SIGN_BAND`] of the full scale instead.
    fn off_model(&self) -> Self {
        let mut m = *self;
        if m.sign_band_a <= 0.0 {
            m.sign_band_a = DEFAULT_SIGN_BAND * m.params.current_full_scale_a;
        }
        m
    }

    /// Period-average voltage of one leg against the negative bus rail, V, for duty `duty`
    /// (clamped to `[0, 1]`), bus `vdc_v` and leg current `i_a` (positive out of the leg into
    /// the motor). Exact average of the switching model at constant duty and current sign;
    /// a duty of exactly 0 or 1 does not switch and has no dead time.
    pub fn leg_voltage_averaged_v(&self, duty: f64, vdc_v: f64, i_a: f64) -> f64 {
        self.leg_voltage_averaged_signed_v(duty, vdc_v, self.smooth_sign(i_a))
    }

    /// [`InverterModel::leg_voltage_averaged_v`] for a given current sign `s ∈ [−1, 1]`.
    pub fn leg_voltage_averaged_signed_v(&self, duty: f64, vdc_v: f64, s: f64) -> f64 {
        let d = clamp_duty(duty);
        let delta = self.effective_dead_time_s() * self.params.pwm_hz;
        // Fraction of the period with the output at the upper rail, for i > 0 and i < 0.
        let (f_pos, f_neg) = if d <= 0.0 || d >= 1.0 {
            (d, d)
        } else {
            ((d - delta).max(0.0), (d + delta).min(1.0))
        };
        let v_pos = f_pos * (vdc_v - self.v_sat_v) - (1.0 - f_pos) * self.v_f_v;
        let v_neg = f_neg * (vdc_v + self.v_f_v) + (1.0 - f_neg) * self.v_sat_v;
        let s = if s.is_nan() { 0.0 } else { s.clamp(-1.0, 1.0) };
        0.5 * (1.0 + s) * v_pos + 0.5 * (1.0 - s) * v_neg
    }

    /// Period-average stator voltage `[v_α, v_β]`, V, of the averaged model.
    pub fn averaged_alpha_beta_v(
        &self,
        duties: [f64; 3],
        vdc_v: f64,
        i_abc_a: [f64; 3],
    ) -> [f64; 2] {
        clarke([
            self.leg_voltage_averaged_v(duties[0], vdc_v, i_abc_a[0]),
            self.leg_voltage_averaged_v(duties[1], vdc_v, i_abc_a[1]),
            self.leg_voltage_averaged_v(duties[2], vdc_v, i_abc_a[2]),
        ])
    }

    /// Commanded (ideal) stator voltage `[v_α, v_β]` = Clarke of `d_x V_DC`, V.
    pub fn ideal_alpha_beta_v(duties: [f64; 3], vdc_v: f64) -> [f64; 2] {
        clarke([
            clamp_duty(duties[0]) * vdc_v,
            clamp_duty(duties[1]) * vdc_v,
            clamp_duty(duties[2]) * vdc_v,
        ])
    }

    /// Dead-time error vector of Khlaief, Boussak, Gossa (2012) eq. 7, `[V_dt,α, V_dt,β]`, V:
    /// `(2/3) V_dead [s_a + a s_b + a² s_c]` with the smooth signs of `i_abc_a`. The applied
    /// voltage is the commanded one minus this (Khlaief, Boussak, Gossa (2012) eq. 9).
    pub fn dead_time_error_alpha_beta_v(&self, vdc_v: f64, i_abc_a: [f64; 3]) -> [f64; 2] {
        let v = self.dead_voltage_v(vdc_v);
        // The amplitude-invariant Clarke transform of (s_a, s_b, s_c) is (2/3)(s_a + a s_b + a² s_c).
        clarke([
            v * self.smooth_sign(i_abc_a[0]),
            v * self.smooth_sign(i_abc_a[1]),
            v * self.smooth_sign(i_abc_a[2]),
        ])
    }

    /// Longest RK4 sub-step that keeps the averaged model's sign band accurate for a motor of
    /// smallest inductance `l_min_h`, s: within the band the dead-time error acts like a
    /// resistance of up to `2 V_dead/i_ε`, whose time constant gets two sub-steps. No limit
    /// for the hard sign (`i_ε = 0`), which is held over the period.
    pub fn averaged_substep_limit_s(&self, vdc_v: f64, l_min_h: f64) -> f64 {
        if self.sign_band_a <= 0.0 {
            return f64::INFINITY;
        }
        let r_band = 2.0 * libm::fabs(self.dead_voltage_v(vdc_v)) / self.sign_band_a;
        if r_band > 0.0 {
            0.5 * l_min_h / r_band
        } else {
            f64::INFINITY
        }
    }

    /// Leg voltage against the negative rail, V, of a leg in state `c`, smooth sign `s`.
    fn leg_voltage_v(&self, c: Conduction, vdc_v: f64, s: f64) -> f64 {
        let (pos, neg) = (0.5 * (1.0 + s), 0.5 * (1.0 - s));
        match c {
            // i > 0 through the upper switch; i < 0 through the upper diode.
            Conduction::Upper => pos * (vdc_v - self.v_sat_v) + neg * (vdc_v + self.v_f_v),
            // i > 0 through the lower diode; i < 0 through the lower switch.
            Conduction::Lower => -pos * self.v_f_v + neg * self.v_sat_v,
            // Both off: the current picks the diode, lower for i > 0, upper for i < 0.
            Conduction::Dead => -pos * self.v_f_v + neg * (vdc_v + self.v_f_v),
        }
    }
}

/// `sgn(i)`, 0 at 0 and for NaN.
fn hard_sign(i: f64) -> f64 {
    if i > 0.0 {
        1.0
    } else if i < 0.0 {
        -1.0
    } else {
        0.0
    }
}

/// Duty clamped to `[0, 1]`; NaN reads as 0 (callers reject NaN before).
fn clamp_duty(d: f64) -> f64 {
    if d.is_nan() { 0.0 } else { d.clamp(0.0, 1.0) }
}
