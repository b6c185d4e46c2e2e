//! The inverter as it switches: every edge of the six devices over a period, integrated
//! piecewise with the motor (the `Switching` model of the module above).

use super::{Conduction, InverterKind, InverterModel, clamp_duty, hard_sign};
use crate::motor::Motor;
use crate::{PlantError, clarke, inverse_clarke};
use pmsm_core::ParamError;

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
