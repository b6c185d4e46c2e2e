//! The summary of a run: its phases between the breakpoints of the references, printed as a
//! table.

use super::{Row, Run, wrap};
use crate::scenario_file::{ObserverKind, Scenario};
use pmsm_core::DriveState;
use std::fmt::Write as _;

/// Statistics of one phase of a run (between two breakpoints of the references).
#[derive(Clone, Debug)]
pub struct Phase {
    /// Start and end, s.
    pub span_s: (f64, f64),
    /// Mean |speed − reference| over the last half of the phase, r/min.
    pub speed_err_rpm: f64,
    /// The same relative to the reference, when it is not zero.
    pub speed_err_rel: Option<f64>,
    /// RMS and max |angle error| while running closed loop, rad.
    pub angle_err_rms_rad: f64,
    /// See `angle_err_rms_rad`.
    pub angle_err_max_rad: f64,
    /// Largest phase current, A.
    pub i_peak_a: f64,
    /// Faults that occurred.
    pub faults: Vec<&'static str>,
}

/// Splits a run at the breakpoints of its references and summarises each phase.
pub fn phases(sc: &Scenario, rows: &[Row]) -> Vec<Phase> {
    phase_cuts(sc)
        .windows(2)
        .filter_map(|w| {
            let span: Vec<&Row> = rows
                .iter()
                .filter(|r| r.t_s >= w[0] && r.t_s < w[1])
                .collect();
            summarise((w[0], w[1]), &span)
        })
        .collect()
}

/// Start, end and the breakpoints of the speed reference and the load between, merged when
/// closer than 20 ms.
fn phase_cuts(sc: &Scenario) -> Vec<f64> {
    let mut cuts: Vec<f64> = sc
        .speed_ref
        .times()
        .iter()
        .chain(sc.load.times())
        .copied()
        .filter(|t| *t > 0.0 && *t < sc.duration_s)
        .collect();
    cuts.push(0.0);
    cuts.push(sc.duration_s);
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 0.02);
    cuts
}

/// The statistics of the rows `span` of the phase `span_s`; `None` for no rows.
fn summarise(span_s: (f64, f64), span: &[&Row]) -> Option<Phase> {
    if span.is_empty() {
        return None;
    }
    let tail = &span[span.len() / 2..];
    let speed_err_rpm = tail
        .iter()
        .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs())
        .sum::<f64>()
        / tail.len() as f64;
    let reference = tail.iter().map(|r| r.speed_ref_rpm.abs()).sum::<f64>() / tail.len() as f64;
    let running: Vec<f64> = span
        .iter()
        .filter(|r| r.state == DriveState::Run)
        .map(|r| r.angle_error_rad())
        .collect();
    let rms = if running.is_empty() {
        0.0
    } else {
        (running.iter().map(|x| x * x).sum::<f64>() / running.len() as f64).sqrt()
    };
    let mut faults: Vec<&'static str> = span
        .iter()
        .map(|r| r.fault())
        .filter(|f| !f.is_empty())
        .collect();
    faults.dedup();
    Some(Phase {
        span_s,
        speed_err_rpm,
        speed_err_rel: (reference > 1.0).then(|| speed_err_rpm / reference),
        angle_err_rms_rad: rms,
        angle_err_max_rad: running.iter().fold(0.0, |a, x| a.max(x.abs())),
        i_peak_a: span.iter().fold(0.0, |a, r| a.max(r.i_peak_a)),
        faults,
    })
}

/// Prints [`summary`].
pub(super) fn print_summary(sc: &Scenario, result: &Run) {
    crate::out::emit(format_args!("{}", summary(sc, result)));
}

/// What was run, the initial position found, one line per phase and the first fault: the
/// report of `pmsm simulate` (and of the workbench in a browser), one line each.
pub fn summary(sc: &Scenario, result: &Run) -> String {
    let mut s = String::new();
    let _ = writeln!(
        s,
        "pmsm simulate: {} on {}, {:?} estimator{}, start-up {}, {:.3} s at {:.0} Hz",
        sc.path.display(),
        sc.motor.name,
        sc.control.observer,
        if sc.control.observer_auto {
            " (auto)"
        } else {
            ""
        },
        startup_name(result.startup),
        sc.duration_s,
        sc.control.sample_hz.unwrap_or(sc.inverter.pwm_hz)
    );
    if let Some(pmsm_core::IpdFault::NoPolarity { along, opposite }) = result.ipd_fallback {
        let _ = writeln!(
            s,
            "  initial position: the axis found, not the polarity (saturation along {along:.3}, \
             opposite {opposite:.3}): aligned instead"
        );
    }
    if let Some((est, truth)) = result.ipd {
        let err = wrap((est - truth).to_radians()).to_degrees();
        let _ = writeln!(
            s,
            "  initial position: detected {est:.1}°, true {truth:.1}° (error {err:+.1}° electrical)"
        );
    }
    if let Some(f) = result.injection {
        let _ = writeln!(
            s,
            "  injection: {:.1} V at {:.0} Hz along the estimated d axis, {:.3} A across it at 45° \
             of error, {:.3} A peak to peak of ripple along d",
            f.amplitude_v, f.frequency_hz, f.response_a, f.ripple_a
        );
    }
    let p = result.polarity;
    if p.checks > 0 {
        let _ = writeln!(
            s,
            "  polarity checked {} time(s) back at zero speed, turned {} time(s); last contrast \
             {:+.1} % (positive: the angle held was north)",
            p.checks,
            p.turns,
            100.0 * p.contrast.to_num::<f64>()
        );
    }
    if let Some((why, id, rpm, loss)) = result.injection_declined {
        let _ = write!(s, "  no injection: {why}");
        if id > 0.0 {
            let _ = write!(
                s,
                "; below {rpm:.0} r/min a d current of {id:.2} A holds the rotor ({loss:.1} W \
                 of copper loss at standstill)"
            );
        }
        s.push('\n');
    }
    if (result.deadtime_scale - 1.0).abs() > 1e-9 {
        let _ = writeln!(
            s,
            "  dead-time compensation: V_dead {:.3} times the one the drive was told (measured at standstill and while running)",
            result.deadtime_scale
        );
    }
    print_phases(&mut s, &phases(sc, &result.rows));
    if let Some((t, asked, used)) = result.speed_ref_limited {
        let _ = writeln!(
            s,
            "  speed reference above the maximum speed (above_max_speed) from t = {t:.4} s: \
             {asked:.0} r/min asked, {used:.0} r/min used"
        );
    }
    if let Some(notice) = speed_ref_notice(sc, &result.rows) {
        let _ = writeln!(s, "  {notice}");
    }
    if let Some(notice) = current_limit_notice(&result.rows) {
        let _ = writeln!(s, "  {notice}");
    }
    if let Some(r) = result
        .rows
        .iter()
        .find(|r| matches!(r.state, DriveState::Fault(_)))
    {
        let _ = writeln!(s, "  first fault at t = {:.4} s: {:?}", r.t_s, r.state);
    }
    s
}

fn print_phases(s: &mut String, phases: &[Phase]) {
    let _ = writeln!(
        s,
        "  {:>15} {:>14} {:>9} {:>16} {:>10}  faults",
        "phase (s)", "speed err", "(%)", "angle err rms/max", "I peak (A)"
    );
    for ph in phases {
        let _ = writeln!(
            s,
            "  {:>6.3} – {:>6.3} {:>10.2} rpm {:>9} {:>7.4}/{:<7.4} rad {:>8.2}   {}",
            ph.span_s.0,
            ph.span_s.1,
            ph.speed_err_rpm,
            ph.speed_err_rel
                .map_or("-".to_owned(), |x| format!("{:.2}", 100.0 * x)),
            ph.angle_err_rms_rad,
            ph.angle_err_max_rad,
            ph.i_peak_a,
            if ph.faults.is_empty() {
                "none".to_owned()
            } else {
                ph.faults.join(", ")
            }
        );
    }
}

/// When the closed loop held another speed than the reference (a back-EMF estimator below its
/// least speed, `pmsm_core::SpeedRefLimit`): "speed reference X r/min below the NLO's minimum
/// Y r/min: held at Y" with the last such reference, from the first such sample, and for how
/// long.
pub fn speed_ref_notice(sc: &Scenario, rows: &[Row]) -> Option<String> {
    let (first, total_s) = extent(rows, |r| r.speed_ref_held_rpm.is_some())?;
    let last = rows.iter().rev().find(|r| r.speed_ref_held_rpm.is_some())?;
    let held = last.speed_ref_held_rpm?;
    let name = match sc.control.observer {
        ObserverKind::Auto => "chosen estimator",
        ObserverKind::Nlo => "NLO",
        ObserverKind::Ao => "AO",
        ObserverKind::MrasEmf => "MRAS on the EMF",
        ObserverKind::MrasCurrent => "current-model MRAS",
    };
    Some(format!(
        "speed reference {:.2} r/min below the {name}'s minimum {:.1} r/min: held at {:.1} r/min \
         (from t = {:.3} s, {:.3} s in all)",
        last.speed_ref_rpm,
        held.abs(),
        held,
        first.t_s,
        total_s
    ))
}

/// The first row where `holds` does and the time it holds in all, s (samples times the
/// sample period); `None` if it never does.
fn extent(rows: &[Row], holds: impl Fn(&Row) -> bool) -> Option<(&Row, f64)> {
    let first = rows.iter().find(|r| holds(r))?;
    let n = rows.iter().filter(|r| holds(r)).count();
    let dt = rows.get(1).map_or(0.0, |r| r.t_s - rows[0].t_s);
    Some((first, n as f64 * dt))
}

/// When the speed loop gave all the current it may (`pmsm_core::SpeedRefLimit::AtCurrentLimit`):
/// "at the current limit (at_current_limit) from t = X s, Y s in all", and the largest gap
/// between the reference and the estimated speed meanwhile.
pub fn current_limit_notice(rows: &[Row]) -> Option<String> {
    let (first, total_s) = extent(rows, |r| r.current_limited_est_rpm.is_some())?;
    let gap = rows
        .iter()
        .filter_map(|r| {
            r.current_limited_est_rpm
                .map(|est| (r.speed_ref_rpm - est).abs())
        })
        .fold(0.0f64, f64::max);
    Some(format!(
        "speed loop at the current limit (at_current_limit) from t = {:.3} s, {total_s:.3} s in \
         all; the estimated speed up to {gap:.0} r/min from the reference meanwhile",
        first.t_s
    ))
}

/// The start-up as the scenario file names it (`auto` shown resolved).
fn startup_name(mode: pmsm_core::StartupMode) -> &'static str {
    match mode {
        pmsm_core::StartupMode::Ipd => "ipd",
        pmsm_core::StartupMode::Align => "align",
        pmsm_core::StartupMode::Known(_) => "known",
        pmsm_core::StartupMode::Auto => "auto",
    }
}
