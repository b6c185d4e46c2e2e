//! How a run of the family (or of the published motors) ended: holding, a named fault, out of
//! the bars without a fault, or silent, by speed or by angle.

use super::{Manoeuvre, Motor};
use pmsm_cli::commands::simulate::Row;
use pmsm_cli::commands::simulate::stats::first_fault;
use pmsm_core::DriveState;

/// How a run ended.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Every steady window within the bars, no fault.
    Holds,
    /// A named fault: its name, when, in which phase.
    Fault(&'static str, f64, &'static str),
    /// No fault, no silent stretch, but a steady window out of the bars: which, speed error
    /// (fraction of rated), angle error rms (rad).
    OutOfBars(&'static str, f64, f64),
    /// No fault where one was due: the rotor more than 20 % of rated speed off the reference
    /// for 0.2 s and the drive not saying why (at its current limit with the rotor where it
    /// estimates it), or the estimated angle slipping a quarter turn off the rotor's
    /// ([`slipping`]) with no fault within [`SLIP_FAULT_S`]: when that began, in which phase,
    /// and by which criterion ("speed" or "angle").
    Silent(f64, &'static str, &'static str),
}

/// Speed error (fraction of rated) and angle error (rad rms) over a steady window that hold.
pub const HOLD_SPEED: f64 = 0.05;
pub const HOLD_ANGLE_RAD: f64 = 0.15;
/// Off the reference by this fraction of rated speed for [`SILENT_S`] without a fault: silent.
pub const SILENT_SPEED: f64 = 0.2;
pub const SILENT_S: f64 = 0.2;
/// A slip: the estimated angle more than a quarter turn (electrical) off the rotor's.
pub const SLIP_RAD: f64 = std::f64::consts::FRAC_PI_2;
/// Slipping that goes on for longer than this must have ended in a named fault, s.
pub const SLIP_FAULT_S: f64 = 0.05;
/// Slips this close together are one series ("again and again"), s.
const SLIP_SERIES_S: f64 = 0.5;

/// When the rotor began slipping poles in the closed loop without a named fault in time:
/// the first sample of a series of closed-loop samples whose angle error is beyond
/// [`SLIP_RAD`] (each less than [`SLIP_SERIES_S`] of closed-loop time after the last), the
/// series lasting longer than [`SLIP_FAULT_S`] of closed-loop time, and the fault (`t_fault`)
/// coming later. Time is counted in the closed loop only: the estimate a back-EMF drive
/// ignores in its open loop (a start, a reversal) may be anywhere, and the blips of closed
/// loop between an open loop's failed handovers are no slipping of its own. A slip the drive
/// recovers from within that time (a transient) is not silent.
pub fn slipping(rows: &[Row], t_fault: f64) -> Option<f64> {
    // Closed-loop time, and the series' first and last slips on that clock (with the first's
    // time of day).
    let (mut clock, mut last_t) = (0.0, None::<f64>);
    let (mut first, mut last, mut first_t) = (f64::NEG_INFINITY, f64::NEG_INFINITY, 0.0);
    for r in rows.iter().take_while(|r| r.t_s < t_fault) {
        if r.state != DriveState::Run {
            last_t = None;
            continue;
        }
        clock += last_t.map_or(0.0, |t| r.t_s - t);
        last_t = Some(r.t_s);
        if r.angle_error_rad().abs() <= SLIP_RAD {
            continue;
        }
        if clock - last >= SLIP_SERIES_S {
            first = clock;
            first_t = r.t_s;
        }
        last = clock;
        if last - first > SLIP_FAULT_S {
            return Some(first_t);
        }
    }
    None
}

fn phase_at(man: &Manoeuvre, t: f64) -> &'static str {
    man.phases
        .iter()
        .rev()
        .find(|(t0, _)| *t0 <= t)
        .map_or("start-up", |p| p.1)
}

pub(crate) fn classify(rows: &[Row], m: &Motor, man: &Manoeuvre) -> Outcome {
    let fault = first_fault(rows);
    let t_fault = fault.map_or(f64::INFINITY, |r| r.t_s);
    // Silent: in the closed loop, the rotor off the reference the drive holds.
    let mut since: Option<f64> = None;
    for r in rows.iter().take_while(|r| r.t_s < t_fault) {
        let reference = r.speed_ref_held_rpm.unwrap_or(r.speed_ref_rpm);
        // At the current limit and right about the rotor, the drive says why it is off.
        let said = r
            .current_limited_est_rpm
            .is_some_and(|est| (est - r.speed_rpm).abs() <= SILENT_SPEED * m.rated_rpm);
        let off = r.state == DriveState::Run
            && !said
            && (r.speed_rpm - reference).abs() > SILENT_SPEED * m.rated_rpm;
        match (off, since) {
            (true, None) => since = Some(r.t_s),
            (true, Some(t0)) if r.t_s - t0 >= SILENT_S => {
                return Outcome::Silent(t0, phase_at(man, t0), "speed");
            }
            (false, _) => since = None,
            _ => {}
        }
    }
    if let Some(t0) = slipping(rows, t_fault) {
        return Outcome::Silent(t0, phase_at(man, t0), "angle");
    }
    if let Some(r) = fault {
        return Outcome::Fault(r.fault(), r.t_s, phase_at(man, r.t_s));
    }
    let mut worst: Option<(&'static str, f64, f64)> = None;
    for &(a, b, what) in &man.windows {
        let w: Vec<&Row> = rows.iter().filter(|r| r.t_s >= a && r.t_s < b).collect();
        let reference = |r: &Row| match r.speed_ref_held_rpm {
            Some(held) if man.against_held => held,
            _ => r.speed_ref_rpm,
        };
        let speed = w
            .iter()
            .map(|r| (r.speed_rpm - reference(r)).abs())
            .fold(0.0, f64::max)
            / m.rated_rpm;
        let rms = (w.iter().map(|r| r.angle_error_rad().powi(2)).sum::<f64>()
            / w.len().max(1) as f64)
            .sqrt();
        if (speed > HOLD_SPEED || rms > HOLD_ANGLE_RAD) && worst.is_none() {
            worst = Some((what, speed, rms));
        }
    }
    match worst {
        Some((what, s, a)) => Outcome::OutOfBars(what, s, a),
        None => Outcome::Holds,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Rows at 10 kHz over `seconds`, in `Run`, the angle error `error(t)`.
    fn rows(seconds: f64, error: impl Fn(f64) -> f64) -> Vec<Row> {
        (0..(seconds * 1e4) as usize)
            .map(|k| {
                let t_s = k as f64 * 1e-4;
                Row {
                    t_s,
                    speed_ref_rpm: 0.0,
                    speed_rpm: 0.0,
                    speed_est_rpm: 0.0,
                    theta_e_rad: 0.0,
                    theta_e_est_rad: error(t_s),
                    i_dq_a: [0.0; 2],
                    i_q_ref_a: 0.0,
                    v_ab_v: [0.0; 2],
                    duties: [0.5; 3],
                    pwm_on: true,
                    state: DriveState::Run,
                    i_peak_a: 0.0,
                    health: 0.0,
                    speed_ref_held_rpm: None,
                    current_limited_est_rpm: None,
                    model_rs_flux: [0.0; 2],
                    tracker: None,
                }
            })
            .collect()
    }

    #[test]
    fn slipping_is_a_quarter_turn_lasting_beyond_50_ms_without_a_fault() {
        // Half a turn off from 0.1 s on: silent from 0.1 s unless a fault comes by 0.15 s.
        let mirror = rows(0.5, |t| if t >= 0.1 { 3.0 } else { 0.0 });
        assert_eq!(slipping(&mirror, f64::INFINITY), Some(0.1));
        assert_eq!(slipping(&mirror, 0.14), None);
        assert_eq!(slipping(&mirror, 0.16), Some(0.1));
        // Slipping a pole every 20 ms (each slip back within a quarter turn in between): the
        // series lasts beyond 50 ms.
        let poles = rows(0.5, |t| {
            if t >= 0.2 && (t * 50.0).fract() < 0.2 {
                2.0
            } else {
                0.1
            }
        });
        let first = slipping(&poles, f64::INFINITY).expect("silent");
        assert!((first - 0.2).abs() < 1e-9, "{first}");
        // A 5 ms swing through the mirror that the drive recovers from is no slip, nor are two
        // a second apart.
        let swing = rows(2.0, |t| {
            if (0.3..0.305).contains(&t) || (1.3..1.305).contains(&t) {
                3.0
            } else {
                0.0
            }
        });
        assert_eq!(slipping(&swing, f64::INFINITY), None);
        // Out of the closed loop (an open-loop start or reversal) nothing counts.
        let mut open = rows(0.5, |_| 3.0);
        for r in &mut open {
            r.state = DriveState::OpenLoop;
        }
        assert_eq!(slipping(&open, f64::INFINITY), None);
        // Blips of closed loop (1 ms every 100 ms) between an open loop's failed handovers,
        // half a turn off each time: 5 ms of closed loop, not silent.
        for (k, r) in open.iter_mut().enumerate() {
            if k % 1000 < 10 {
                r.state = DriveState::Run;
            }
        }
        assert_eq!(slipping(&open, f64::INFINITY), None);
    }
}
