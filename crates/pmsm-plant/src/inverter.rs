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

use pmsm_core::{InverterParams, ParamError, ParamReason, in_range, non_negative};

use crate::motor::Motor;
use crate::{PlantError, clarke, inverse_clarke};

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

/// What a leg remembers from the previous period: its command level at the end and when that
/// level was last commanded (relative to the start of the next period, s, ≤ 0), so that a dead
/// time running across a period boundary is honoured.
#[derive(Clone, Copy, Debug)]
struct LegMemory {
    high: bool,
    last_edge_s: f64,
}

/// One leg's command over one period `[0, T)`.
#[derive(Clone, Copy, Debug)]
struct LegPlan {
    /// Command at `0⁺` and the time of its last edge (≤ 0).
    start_high: bool,
    start_edge_s: f64,
    /// Rising and falling command edges inside the period, if the leg switches (`0 < d < 1`).
    edges: Option<(f64, f64)>,
}

impl LegPlan {
    fn new(mem: LegMemory, d: f64, period_s: f64) -> Self {
        let start_high = d >= 1.0;
        // A level change across the boundary is an edge at 0.
        let start_edge_s = if start_high != mem.high {
            0.0
        } else {
            mem.last_edge_s
        };
        let edges = if d > 0.0 && d < 1.0 {
            // Centre-aligned: the high pulse of width d T is centred at T/2.
            Some((0.5 * (1.0 - d) * period_s, 0.5 * (1.0 + d) * period_s))
        } else {
            None
        };
        Self {
            start_high,
            start_edge_s,
            edges,
        }
    }

    /// Command level at `t` and the time of its last edge.
    fn command(&self, t: f64) -> (bool, f64) {
        match self.edges {
            Some((_, fall)) if t >= fall => (false, fall),
            Some((rise, _)) if t >= rise => (true, rise),
            _ => (self.start_high, self.start_edge_s),
        }
    }

    /// Which device conducts at `t`: turn-on edges are delayed by the effective dead time.
    fn conduction(&self, t: f64, t_dead_s: f64) -> Conduction {
        let (high, edge) = self.command(t);
        if t - edge < t_dead_s {
            Conduction::Dead
        } else if high {
            Conduction::Upper
        } else {
            Conduction::Lower
        }
    }

    /// Memory for the next period.
    fn end(&self, period_s: f64) -> LegMemory {
        let (high, edge) = self.command(period_s);
        LegMemory {
            high,
            last_edge_s: edge - period_s,
        }
    }
}

/// An inverter: its model and the switching state carried from one period to the next.
#[derive(Clone, Debug)]
pub struct Inverter {
    model: InverterModel,
    legs: [LegMemory; 3],
    /// Period average of each leg's voltage over the last period, V.
    leg_average_v: [f64; 3],
}

impl Inverter {
    /// Inverter with all legs low (lower switches on) since long ago. Validates the model.
    pub fn new(model: InverterModel) -> Result<Self, ParamError> {
        model.validate()?;
        // "Long ago": further back than any dead time.
        let idle = LegMemory {
            high: false,
            last_edge_s: -1.0,
        };
        Ok(Self {
            model,
            legs: [idle; 3],
            leg_average_v: [0.0; 3],
        })
    }

    /// The model.
    pub fn model(&self) -> &InverterModel {
        &self.model
    }

    /// Period average of each leg's voltage against the negative rail over the last period,
    /// V: integrated edge by edge by the switching model, the averaged model's value at the
    /// start of the period otherwise.
    pub fn leg_average_v(&self) -> [f64; 3] {
        self.leg_average_v
    }

    /// Switches between the averaged and the switching-level model.
    pub fn set_kind(&mut self, kind: InverterKind) {
        self.model.kind = kind;
    }

    /// Applies duties `duties` (each clamped to `[0, 1]`, NaN rejected) on bus `vdc_v` for
    /// one PWM period, advancing `motor` with load torque `load_nm`. On error the motor may
    /// have been advanced part of the period; the leg memory is unchanged.
    pub fn step_period(
        &mut self,
        motor: &mut Motor,
        duties: [f64; 3],
        vdc_v: f64,
        load_nm: f64,
    ) -> Result<(), PlantError> {
        for d in duties {
            if d.is_nan() {
                return Err(PlantError::NonFinite("duty"));
            }
        }
        if !vdc_v.is_finite() {
            return Err(PlantError::NonFinite("vdc_v"));
        }
        let d = duties.map(clamp_duty);
        let period_s = self.model.period_s();
        let plans = [
            LegPlan::new(self.legs[0], d[0], period_s),
            LegPlan::new(self.legs[1], d[1], period_s),
            LegPlan::new(self.legs[2], d[2], period_s),
        ];
        match self.model.kind {
            InverterKind::Averaged => {
                let m = self.model;
                let h = m.averaged_substep_limit_s(vdc_v, motor.min_inductance_h());
                let i0 = motor.i_abc();
                self.leg_average_v =
                    [0, 1, 2].map(|k| m.leg_voltage_averaged_v(d[k], vdc_v, i0[k]));
                match m.period_signs(i0) {
                    None => motor.step_with_limit(period_s, load_nm, h, |i| {
                        m.averaged_alpha_beta_v(d, vdc_v, i)
                    })?,
                    Some(s) => {
                        let v = clarke(
                            [0, 1, 2].map(|k| m.leg_voltage_averaged_signed_v(d[k], vdc_v, s[k])),
                        );
                        motor.step_with_limit(period_s, load_nm, h, |_| v)?
                    }
                }
            }
            InverterKind::Switching => {
                self.leg_average_v = self.switching_period(motor, &plans, vdc_v, load_nm)?
            }
        }
        self.legs = plans.map(|p| p.end(period_s));
        Ok(())
    }

    /// One PWM period with all six switches off (a fault, or the drive idle): each phase
    /// current freewheels through a diode, to the upper rail when it flows into the leg
    /// (`V_DC + V_f`) and to the lower one when it flows out (`−V_f`), so it decays against the
    /// bus and stays at zero once there (unless the back-EMF exceeds the bus). The smooth sign
    /// of the averaged model holds a phase at zero: a blocked diode pair.
    pub fn step_off(
        &mut self,
        motor: &mut Motor,
        vdc_v: f64,
        load_nm: f64,
    ) -> Result<(), PlantError> {
        if !vdc_v.is_finite() {
            return Err(PlantError::NonFinite("vdc_v"));
        }
        let m = self.model.off_model();
        let period_s = m.period_s();
        let leg = move |i: f64| {
            let s = m.smooth_sign(i);
            0.5 * (1.0 + s) * (-m.v_f_v) + 0.5 * (1.0 - s) * (vdc_v + m.v_f_v)
        };
        // The band acts like a resistance V_DC/(2 i_ε): limit the sub-step as for the
        // averaged model, with the whole bus across it.
        let h = m.averaged_substep_limit_s(vdc_v, motor.min_inductance_h());
        self.leg_average_v = motor.i_abc().map(leg);
        motor.step_with_limit(period_s, load_nm, h, |i| {
            clarke([leg(i[0]), leg(i[1]), leg(i[2])])
        })?;
        // Both switches of every leg have been off for longer than any dead time.
        self.legs = [LegMemory {
            high: false,
            last_edge_s: -1.0,
        }; 3];
        Ok(())
    }

    /// Integrates one period edge by edge: between consecutive edges every leg's conduction is
    /// fixed. With the hard sign (`sign_band_a = 0`) a conducting switch or diode pair follows
    /// the sign of the instantaneous current at the start of the interval (it only selects
    /// `V_sat` or `V_f`), and a leg in its dead time is integrated event by event
    /// ([`Inverter::dead_interval`]); with a band, every leg takes the smooth sign at the start
    /// of the interval. Returns the period average of each leg's voltage, V.
    fn switching_period(
        &self,
        motor: &mut Motor,
        plans: &[LegPlan; 3],
        vdc_v: f64,
        load_nm: f64,
    ) -> Result<[f64; 3], PlantError> {
        let period_s = self.model.period_s();
        let t_dead_s = self.model.effective_dead_time_s();
        // Breakpoints: 0, T, every command edge and every delayed turn-on (≤ 5 per leg).
        let mut times = [0.0_f64; 18];
        let mut n = 0;
        let mut push = |t: f64| {
            if t > 0.0 && t < period_s && n < times.len() {
                times[n] = t;
                n += 1;
            }
        };
        for p in plans {
            push(p.start_edge_s + t_dead_s);
            if let Some((rise, fall)) = p.edges {
                push(rise);
                push(fall);
                push(rise + t_dead_s);
                push(fall + t_dead_s);
            }
        }
        // The period end closes the last interval (3 × 5 + 1 = 16 ≤ 18 entries).
        if let Some(slot) = times.get_mut(n) {
            *slot = period_s;
            n += 1;
        }
        let times = &mut times[..n];
        times.sort_unstable_by(f64::total_cmp);

        let mut t0 = 0.0;
        let mut area = [0.0; 3];
        // Diode state of each leg in its dead time, kept across the intervals that other
        // legs' edges cut it into: ±1 the diode of that current sign conducts, 0 both block.
        let mut diode = [None::<f64>; 3];
        for &t1 in times.iter() {
            let dt = t1 - t0;
            if dt <= 0.0 {
                continue;
            }
            let mid = 0.5 * (t0 + t1);
            let c = plans.map(|p| p.conduction(mid, t_dead_s));
            let i = motor.i_abc();
            for k in 0..3 {
                diode[k] = match (c[k], diode[k]) {
                    (Conduction::Dead, Some(s)) => Some(s),
                    (Conduction::Dead, None) => Some(entry_sign(i[k], plans[k].command(mid).0)),
                    _ => None,
                };
            }
            let band = self.model.sign_band_a > 0.0;
            if band || diode.iter().all(Option::is_none) {
                // With a band every leg takes the smooth sign of its current at the start of
                // the interval (a dead leg's diode then conducts part way for a current
                // within the band).
                let sign = |x: f64| {
                    if band {
                        self.model.smooth_sign(x)
                    } else {
                        hard_sign(x)
                    }
                };
                let v = [0, 1, 2].map(|k| self.model.leg_voltage_v(c[k], vdc_v, sign(i[k])));
                let v_ab = clarke(v);
                motor.step(v_ab[0], v_ab[1], load_nm, dt)?;
                for k in 0..3 {
                    area[k] += v[k] * dt;
                }
            } else {
                self.dead_interval(motor, c, &mut diode, vdc_v, load_nm, dt, &mut area)?;
            }
            t0 = t1;
        }
        Ok(area.map(|a| a / period_s))
    }

    /// One interval in which at least one leg is in its dead time. The current of such a leg
    /// picks its diode by its sign; when it reaches zero both diodes block and the phase
    /// floats: its leg voltage is whatever keeps its current at zero (solved from the motor's
    /// current rate, which is affine in the voltage), until that voltage would leave the
    /// rails, when the diode of the current it then drives conducts. The interval is cut at
    /// each zero crossing, predicted from the current rate (the rate hardly changes over a
    /// dead time, and the prediction is checked before a leg is held).
    #[allow(clippy::too_many_arguments)]
    fn dead_interval(
        &self,
        motor: &mut Motor,
        c: [Conduction; 3],
        diode: &mut [Option<f64>; 3],
        vdc_v: f64,
        load_nm: f64,
        dt: f64,
        area: &mut [f64; 3],
    ) -> Result<(), PlantError> {
        let m = &self.model;
        let (lo, hi) = (-m.v_f_v, vdc_v + m.v_f_v);
        let mut left = dt;
        for event in 0..MAX_DEAD_EVENTS {
            let i = motor.i_abc();
            let mut v = [0.0; 3];
            for k in 0..3 {
                v[k] = match diode[k] {
                    Some(s) => m.leg_voltage_v(c[k], vdc_v, s),
                    None => m.leg_voltage_v(c[k], vdc_v, hard_sign(i[k])),
                };
            }
            // Floating legs: the voltages that hold their currents at zero.
            let floating: [bool; 3] = diode.map(|s| s == Some(0.0));
            if floating.iter().any(|&f| f) {
                solve_floating(motor, &mut v, &floating, 0.5 * (lo + hi));
                for k in 0..3 {
                    if floating[k] && !(lo..=hi).contains(&v[k]) {
                        // Even at a rail the current leaves zero: that rail's diode conducts.
                        let s = if v[k] < lo { 1.0 } else { -1.0 };
                        diode[k] = Some(s);
                        v[k] = m.leg_voltage_v(c[k], vdc_v, s);
                    }
                }
            }
            // The first conducting diode whose current reaches zero within the interval.
            let r = inverse_clarke(motor.current_rate_ab(clarke(v)));
            let mut tau = left;
            let mut hit = None;
            for k in 0..3 {
                if let Some(s) = diode[k]
                    && s != 0.0
                    && s * r[k] < 0.0
                {
                    let t = (-i[k] / r[k]).max(0.0);
                    if t < tau {
                        tau = t;
                        hit = Some(k);
                    }
                }
            }
            if event + 1 == MAX_DEAD_EVENTS {
                // Out of events (never seen): finish the interval with these voltages.
                tau = left;
                hit = None;
            }
            let v_ab = clarke(v);
            motor.step(v_ab[0], v_ab[1], load_nm, tau)?;
            for k in 0..3 {
                area[k] += v[k] * tau;
            }
            left -= tau;
            if let Some(k) = hit {
                // Held at zero only if the linear prediction did reach it.
                let i_now = motor.i_abc()[k];
                if diode[k].is_some_and(|s| s * i_now <= ZERO_TOLERANCE * libm::fabs(i[k])) {
                    diode[k] = Some(0.0);
                }
            }
            if left <= 0.0 {
                return Ok(());
            }
        }
        Ok(())
    }
}

/// Most events (zero crossings, diode turn-ons) handled in one interval: three legs can each
/// reach zero and start conducting again.
const MAX_DEAD_EVENTS: usize = 8;

/// Relative current left at a predicted zero crossing that still counts as zero.
const ZERO_TOLERANCE: f64 = 1e-3;

/// Current below which a leg entering its dead time counts as carrying none, A.
const ZERO_CURRENT_A: f64 = 1e-9;

/// The diode state of a leg entering its dead time with current `i_a`, its command now
/// `high`. Without current nothing moves the output node (its capacitance holds it): the leg
/// stays at the rail it was switched to, as the diode of that rail would hold it; if the
/// other legs then drive the current the other way, the event loop lets it float.
fn entry_sign(i_a: f64, high: bool) -> f64 {
    if libm::fabs(i_a) > ZERO_CURRENT_A {
        hard_sign(i_a)
    } else if high {
        // Was low: the lower rail, as the lower diode (i > 0) holds it.
        1.0
    } else {
        -1.0
    }
}

/// Phase-current rates `d i_abc/dt`, A/s, of `motor` under leg voltages `v`.
fn rate_abc(motor: &Motor, v: [f64; 3]) -> [f64; 3] {
    inverse_clarke(motor.current_rate_ab(clarke(v)))
}

/// Sets the voltages of the `floating` legs of `v` so that their current rates vanish (not
/// clamped to the rails). The rates are affine in the voltages, so one evaluation per
/// unknown plus one gives them exactly. With all three legs floating (every current zero)
/// only the differences matter: the first keeps `v_mid`.
fn solve_floating(motor: &Motor, v: &mut [f64; 3], floating: &[bool; 3], v_mid: f64) {
    let mut ks = [0usize; 3];
    let mut n = 0;
    for k in 0..3 {
        if floating[k] {
            v[k] = v_mid;
            ks[n] = k;
            n += 1;
        }
    }
    let ks = if n == 3 { &ks[1..3] } else { &ks[..n] };
    let r0 = rate_abc(motor, *v);
    // Columns of the rate's sensitivity to each unknown leg voltage, per volt.
    let dv = v_mid.abs().max(1.0);
    let col = |j: usize| {
        let mut w = *v;
        w[j] += dv;
        let r = rate_abc(motor, w);
        [0, 1, 2].map(|k| (r[k] - r0[k]) / dv)
    };
    match *ks {
        [a] => {
            let m = col(a)[a];
            if m != 0.0 {
                v[a] -= r0[a] / m;
            }
        }
        [a, b] => {
            let (ca, cb) = (col(a), col(b));
            let det = ca[a] * cb[b] - cb[a] * ca[b];
            if det != 0.0 {
                v[a] += (-r0[a] * cb[b] + r0[b] * cb[a]) / det;
                v[b] += (-ca[a] * r0[b] + ca[b] * r0[a]) / det;
            }
        }
        _ => {}
    }
}
