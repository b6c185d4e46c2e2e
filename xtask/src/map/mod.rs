//! The drive's operating map over the torque–speed plane (`cargo xtask map`): motors A, B and
//! C with MTPA and field weakening on, steady at each speed × load of a grid; heat maps in
//! `docs/figures/map-motor-*.svg` and the `## Operating map` section of `docs/PERFORMANCE.md`.
//!
//! Each point is one `pmsm simulate` scenario built here: start-up (the motor's), the speed
//! reference ramped to the point's speed, then the load ramped to the point's torque, then a
//! settling time and the steady window the figures are taken over. [`doc`] writes the
//! section, [`svg`] the heat maps.

pub mod doc;
pub mod svg;

pub use doc::kept_section;

use crate::progress;
use anyhow::{Context, Result, anyhow};
use indicatif::ProgressBar;
use pmsm_cli::commands::simulate::stats::first_fault;
use pmsm_cli::commands::simulate::{Row, build_drive, run_scenario};
use pmsm_cli::scenario_file::{self, Scenario};
use pmsm_core::DriveState;
use rayon::prelude::*;
use std::f64::consts::TAU;

/// A motor of the map: its drive and its rated point.
#[derive(Clone, Copy, Debug)]
pub struct Case {
    /// `a`, `b`, `c`: the figure is `map-motor-{key}.svg`.
    pub key: &'static str,
    /// For captions.
    pub title: &'static str,
    /// Motor file under `examples/`.
    pub motor_file: &'static str,
    /// Bus, V.
    pub vdc_v: f64,
    /// PWM and control sample rate, Hz.
    pub pwm_hz: f64,
    /// Dead time, s (compensated).
    pub dead_time_s: f64,
    /// `[control] observer`.
    pub observer: &'static str,
    /// `[control] startup`.
    pub startup: &'static str,
    /// More `[control]` lines.
    pub control_extra: &'static str,
    /// Rated speed, r/min (100 % of the speed axis).
    pub rated_rpm: f64,
    /// Rated torque, N·m (100 % of the load axis).
    pub rated_nm: f64,
    /// How long the reference stays at zero while the drive starts, s.
    pub start_s: f64,
    /// Slope of the speed reference, r/min per second.
    pub accel_rpm_s: f64,
}

/// Motor A on the NLO, B on the current-model MRAS at 540 V, C on 24 V; the settings of the
/// shipped field-weakening scenarios (`examples/a-nlo-fw-2300rpm.toml`, `b-3000rpm-fw.toml`,
/// `c-24v-fw-3900rpm.toml`).
pub const CASES: [Case; 3] = [
    Case {
        key: "a",
        title: "motor A (surface, 300 V), NLO of Solsona, Valla, Muravchik (2000)",
        motor_file: "motor-a.toml",
        vdc_v: 300.0,
        pwm_hz: 20e3,
        dead_time_s: 1e-6,
        observer: "nlo",
        startup: "align",
        control_extra: "observer_gain = 1000.0\n",
        rated_rpm: 1200.0,
        // 1.2 kW at 1200 r/min (examples/motor-a.toml).
        rated_nm: 9.55,
        start_s: 0.8,
        accel_rpm_s: 1300.0,
    },
    Case {
        key: "b",
        title: "motor B (interior, 540 V), current-model MRAS of Khlaief, Boussak, Gossa (2012)",
        motor_file: "motor-b.toml",
        vdc_v: 540.0,
        pwm_hz: 14e3,
        dead_time_s: 2e-6,
        observer: "mras-current",
        startup: "ipd",
        control_extra: "",
        rated_rpm: 3000.0,
        // The paper's rated torque (examples/motor-b.toml).
        rated_nm: 4.0,
        start_s: 0.1,
        accel_rpm_s: 2000.0,
    },
    Case {
        key: "c",
        title: "motor C (interior, 24 V, 4 pole pairs), current-model MRAS",
        motor_file: "motor-c-24v.toml",
        vdc_v: 24.0,
        pwm_hz: 20e3,
        dead_time_s: 5e-7,
        observer: "mras-current",
        startup: "align",
        control_extra: "",
        rated_rpm: 3000.0,
        // Rated current at i_d = 0 (examples/motor-c-24v.toml).
        rated_nm: 2.81,
        start_s: 0.6,
        accel_rpm_s: 8000.0,
    },
];

/// Speeds of the grid, % of rated; one more column is 110 % of the drive's maximum speed.
pub const SPEEDS_PCT: [f64; 9] = [0.0, 10.0, 20.0, 40.0, 60.0, 80.0, 100.0, 115.0, 130.0];
/// Loads of the grid, % of rated torque.
pub const LOADS_PCT: [f64; 5] = [0.0, 25.0, 50.0, 75.0, 100.0];
/// The extra column's reference, times the maximum speed.
const ABOVE_MAX: f64 = 1.1;

/// The reference reached, the load is ramped in this long, s.
const LOAD_RAMP_S: f64 = 0.1;
/// From the end of the speed ramp to the load, s.
const BEFORE_LOAD_S: f64 = 0.15;
/// From the end of the load ramp to the window, s.
const SETTLE_S: f64 = 0.5;
/// The steady window at the end of each run, s.
const WINDOW_S: f64 = 0.3;

/// "Held": no fault, no refusal, and over the window the position error below this, rad rms…
const HELD_ANGLE_RAD: f64 = 0.2;
/// …and the mean speed error below this fraction of the reference (of 10 % of rated speed
/// for references below that).
const HELD_SPEED: f64 = 0.05;

/// What the drive did at a point.
#[derive(Clone, Debug, PartialEq)]
pub enum Outcome {
    /// Ran at the reference.
    Held,
    /// Refused the reference below the back-EMF estimator's least speed
    /// (`below_estimator_minimum`) and held this speed instead, r/min.
    BelowMinimum(f64),
    /// Refused the reference above the maximum speed (`above_max_speed`) and used this one,
    /// r/min.
    AboveMax(f64),
    /// Tripped: the fault's name, when (s) and in which stage of the run.
    Fault(&'static str, f64, &'static str),
    /// No fault and no refusal, but off the reference or the angle beyond the bounds of
    /// "held".
    Missed(Miss),
}

impl Outcome {
    /// The cell's mark in the figures.
    pub fn mark(&self) -> &'static str {
        match self {
            Outcome::Held => "",
            Outcome::BelowMinimum(_) => "min",
            Outcome::AboveMax(_) => "max",
            Outcome::Fault(..) => "F",
            Outcome::Missed(_) => "×",
        }
    }

    /// In words, for the table.
    pub fn describe(&self) -> String {
        match self {
            Outcome::Held => "held".into(),
            Outcome::BelowMinimum(n) => {
                format!("refused: below_estimator_minimum, held at {n:.0} r/min")
            }
            Outcome::AboveMax(n) => format!("refused: above_max_speed, clamped to {n:.0} r/min"),
            Outcome::Fault(name, t, stage) => format!("fault: {name} at {t:.2} s, {stage}"),
            Outcome::Missed(m) => m.describe(),
        }
    }
}

/// How a point missed its reference.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Miss {
    /// The least and the largest speed over the window, r/min.
    pub speed_rpm: (f64, f64),
    /// The speed at the window's start and end, r/min.
    pub drift_rpm: (f64, f64),
    /// The mean current magnitude was at the drive's current limit (within 2 %).
    pub current_limit: bool,
    /// The mean voltage was at the modulator's circle (beyond 95 % of it).
    pub voltage_limit: bool,
}

impl Miss {
    /// In words, for the table.
    pub fn describe(&self) -> String {
        let (lo, hi) = self.speed_rpm;
        let limits = match (self.current_limit, self.voltage_limit) {
            (true, true) => "at the current and voltage limits",
            (true, false) => "at the current limit",
            (false, true) => "at the voltage limit",
            (false, false) => "within both limits",
        };
        let (first, last) = self.drift_rpm;
        let spread = hi - lo;
        if spread > 0.02 * hi.abs().max(lo.abs()) && (last - first).abs() > 0.9 * spread {
            let way = if last < first { "falling" } else { "rising" };
            format!("missed: {way} {first:.0} → {last:.0} r/min, {limits}")
        } else if spread > 0.02 * hi.abs().max(lo.abs()) {
            format!("missed: swung {lo:.0}–{hi:.0} r/min, {limits}")
        } else {
            format!("missed: ran at {:.0} r/min, {limits}", 0.5 * (lo + hi))
        }
    }
}

/// One point of the map; the figures are means over the steady window (NaN after a fault).
#[derive(Clone, Debug)]
pub struct Point {
    /// Load, N·m.
    pub load_nm: f64,
    /// What the drive did.
    pub outcome: Outcome,
    /// Position error, rad rms.
    pub angle_rms_rad: f64,
    /// Mean true speed, r/min.
    pub speed_rpm: f64,
    /// Mean |n − n*|, r/min, against the reference or, when the drive refused it, against the
    /// speed it held instead.
    pub speed_err_rpm: f64,
    /// The same, % of that speed (NaN for zero).
    pub speed_err_pct: f64,
    /// Mean |i_dq| (amplitude-invariant, i.e. the phase current's peak), A.
    pub i_mag_a: f64,
    /// Mean i_d, A.
    pub i_d_a: f64,
    /// Mean |v|/(V_DC/√3) of the commanded voltage.
    pub modulation: f64,
    /// Mean 1.5·R·|i_dq|², W.
    pub copper_w: f64,
}

/// A motor's map: rows by load, columns by speed (the last column above the maximum speed).
#[derive(Clone, Debug)]
pub struct Grid {
    /// The motor.
    pub case: Case,
    /// The drive's maximum speed, r/min.
    pub max_rpm: f64,
    /// The least speed of the closed loop, r/min (0 for the current-model MRAS).
    pub min_rpm: f64,
    /// Speed references of the columns, r/min.
    pub speeds_rpm: Vec<f64>,
    /// Column headings.
    pub speed_labels: Vec<String>,
    /// `points[load][speed]`.
    pub points: Vec<Vec<Point>>,
}

fn examples_dir() -> std::path::PathBuf {
    super::root().join("examples")
}

/// When the stages of a point's run begin, s.
#[derive(Clone, Copy, Debug)]
pub struct Timing {
    /// The reference starts to rise (the start-up before).
    pub start_s: f64,
    /// The reference reached.
    pub ramp_end_s: f64,
    /// The load starts to rise.
    pub load_s: f64,
    /// The steady window.
    pub window_s: f64,
    /// The load, N·m.
    pub load_nm: f64,
}

impl Timing {
    /// The stage of the run at `t_s`, in words.
    pub fn stage(&self, t_s: f64) -> &'static str {
        if t_s < self.start_s {
            "at start-up"
        } else if t_s < self.ramp_end_s {
            "on the speed ramp"
        } else if t_s < self.load_s || self.load_nm == 0.0 {
            "at the speed reached, no load"
        } else if t_s < self.load_s + LOAD_RAMP_S {
            "while the load rises"
        } else {
            "under load"
        }
    }
}

/// The scenario of `case` at `speed_rpm` and `load_nm`, and its timing; the
/// rotor starts at `θ_e = 0`, where the alignment pulls it (the start-up from other angles is
/// [`startup_check`]'s).
pub fn scenario(case: &Case, speed_rpm: f64, load_nm: f64) -> Result<(Scenario, Timing)> {
    scenario_at(case, speed_rpm, load_nm, 0.0)
}

/// [`scenario`] from the initial electrical angle `theta_deg`.
fn scenario_at(
    case: &Case,
    speed_rpm: f64,
    load_nm: f64,
    theta_deg: f64,
) -> Result<(Scenario, Timing)> {
    use std::sync::atomic::{AtomicUsize, Ordering};
    // A file name of its own for each scenario: the points run at the same time.
    static N: AtomicUsize = AtomicUsize::new(0);
    let ramp_s = (speed_rpm.abs() / case.accel_rpm_s).max(0.01);
    let t_ref = case.start_s + ramp_s;
    let t_load = t_ref + BEFORE_LOAD_S;
    let duration = t_load + LOAD_RAMP_S + SETTLE_S + WINDOW_S;
    let motor = examples_dir()
        .join(case.motor_file)
        .canonicalize()
        .with_context(|| format!("examples/{}", case.motor_file))?;
    let text = format!(
        "duration_s = {duration}\nmotor = \"{}\"\n\
         [inverter]\nvdc_v = {}\npwm_hz = {}\ndead_time_s = {}\nmodel = \"switching\"\n\
         [control]\nobserver = \"{}\"\nstartup = \"{}\"\ndeadtime_compensation = true\n\
         mtpa = true\nfield_weakening = true\n{}\
         [initial]\ntheta_e_deg = {theta_deg}\n\
         [speed_ref]\nt_s = [0.0, {}, {t_ref}]\nrpm = [0.0, 0.0, {speed_rpm}]\n\
         [load]\nt_s = [0.0, {t_load}, {}]\nnm = [0.0, 0.0, {load_nm}]\n",
        motor.display(),
        case.vdc_v,
        case.pwm_hz,
        case.dead_time_s,
        case.observer,
        case.startup,
        case.control_extra,
        case.start_s,
        t_load + LOAD_RAMP_S,
    );
    let path = std::env::temp_dir().join(format!(
        "pmsm-map-{}-{}-{}.toml",
        std::process::id(),
        N.fetch_add(1, Ordering::Relaxed),
        case.key
    ));
    std::fs::write(&path, text)?;
    let sc = scenario_file::read(&path);
    std::fs::remove_file(&path).ok();
    Ok((
        sc?,
        Timing {
            start_s: case.start_s,
            ramp_end_s: t_ref,
            load_s: t_load,
            window_s: duration - WINDOW_S,
            load_nm,
        },
    ))
}

/// The drive's maximum speed (`FluxConfig::max_speed`) and the least speed of its closed loop
/// (the handover speed of the back-EMF estimators, 0 for the current-model MRAS), r/min.
pub fn speed_limits_rpm(case: &Case) -> Result<(f64, f64)> {
    let (sc, _) = scenario(case, 0.0, 0.0)?;
    let setup = build_drive(&sc)?;
    let to_rpm = |pu| setup.base.speed_rad_s(pu) / setup.model.p() * 60.0 / TAU;
    let config = &setup.config;
    let min = if case.observer == "mras-current" {
        0.0
    } else {
        config.design.open_loop.handover_speed_rad_s / setup.model.p() * 60.0 / TAU
    };
    Ok((to_rpm(config.flux().max_speed()), min))
}

/// Runs `case` at one point.
pub fn run_point(case: &Case, speed_rpm: f64, load_nm: f64) -> Result<Point> {
    let (sc, timing) = scenario(case, speed_rpm, load_nm)?;
    let t0 = timing.window_s;
    let run = run_scenario(&sc)?;
    let rs_ohm = sc.motor.model.params.rs_ohm;
    let v_b = sc.inverter.vdc_v / 3f64.sqrt();
    let fault = first_fault(&run.rows).map(|r| (r.fault(), r.t_s));
    let w: Vec<&Row> = run.rows.iter().filter(|r| r.t_s >= t0).collect();
    let last = w.last().ok_or_else(|| anyhow!("no rows in the window"))?;
    let mean = |f: &dyn Fn(&Row) -> f64| w.iter().map(|r| f(r)).sum::<f64>() / w.len() as f64;
    let running: Vec<f64> = w
        .iter()
        .filter(|r| r.state == DriveState::Run)
        .map(|r| r.angle_error_rad())
        .collect();
    let angle_rms_rad = if running.is_empty() {
        f64::NAN
    } else {
        (running.iter().map(|x| x * x).sum::<f64>() / running.len() as f64).sqrt()
    };
    // A refused reference is measured against the speed the drive took instead.
    let refused = if let Some(held) = last.speed_ref_held_rpm {
        Some(Outcome::BelowMinimum(held))
    } else {
        run.speed_ref_limited
            .map(|(_, _, used)| Outcome::AboveMax(used))
    };
    let reference_rpm = match refused {
        Some(Outcome::BelowMinimum(n) | Outcome::AboveMax(n)) => n,
        _ => speed_rpm,
    };
    let mean_speed_rpm = mean(&|r| r.speed_rpm);
    let speed_err_rpm = mean(&|r| (r.speed_rpm - reference_rpm).abs());
    let speed_err_pct = if reference_rpm == 0.0 {
        f64::NAN
    } else {
        100.0 * speed_err_rpm / reference_rpm.abs()
    };
    let i_sq = |r: &Row| r.i_dq_a[0].powi(2) + r.i_dq_a[1].powi(2);
    let tolerance = HELD_SPEED * reference_rpm.abs().max(0.1 * case.rated_rpm);
    let outcome = match (fault, refused) {
        (Some((name, t)), _) => Outcome::Fault(name, t, timing.stage(t)),
        (None, Some(r)) => r,
        (None, None) if angle_rms_rad < HELD_ANGLE_RAD && speed_err_rpm < tolerance => {
            Outcome::Held
        }
        (None, None) => {
            let (lo, hi) = w
                .iter()
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), r| {
                    (a.min(r.speed_rpm), b.max(r.speed_rpm))
                });
            let limit_a = build_drive(&sc)?.config.design.speed.current_limit_a;
            Outcome::Missed(Miss {
                speed_rpm: (lo, hi),
                drift_rpm: (w[0].speed_rpm, last.speed_rpm),
                current_limit: mean(&|r| i_sq(r).sqrt()) > 0.98 * limit_a,
                voltage_limit: mean(&|r| r.v_ab_v[0].hypot(r.v_ab_v[1])) > 0.95 * v_b,
            })
        }
    };
    let mut p = Point {
        load_nm,
        outcome,
        angle_rms_rad,
        speed_rpm: mean_speed_rpm,
        speed_err_rpm,
        speed_err_pct,
        i_mag_a: mean(&|r| i_sq(r).sqrt()),
        i_d_a: mean(&|r| r.i_dq_a[0]),
        modulation: mean(&|r| r.v_ab_v[0].hypot(r.v_ab_v[1])) / v_b,
        copper_w: mean(&|r| 1.5 * rs_ohm * i_sq(r)),
    };
    if matches!(p.outcome, Outcome::Fault(..)) {
        // After a trip the window shows a motor coasting or shorted, not the drive.
        for x in [
            &mut p.speed_rpm,
            &mut p.angle_rms_rad,
            &mut p.speed_err_rpm,
            &mut p.speed_err_pct,
            &mut p.i_mag_a,
            &mut p.i_d_a,
            &mut p.modulation,
            &mut p.copper_w,
        ] {
            *x = f64::NAN;
        }
    }
    Ok(p)
}

/// Runs the grid of `case` over all cores; `bar` advances by one per point.
pub fn run_grid(case: &Case, bar: &ProgressBar) -> Result<Grid> {
    let (max_rpm, min_rpm) = speed_limits_rpm(case)?;
    let mut speeds_rpm: Vec<f64> = SPEEDS_PCT
        .iter()
        .map(|p| p / 100.0 * case.rated_rpm)
        .collect();
    let mut speed_labels: Vec<String> = SPEEDS_PCT.iter().map(|p| format!("{p:.0} %")).collect();
    speeds_rpm.push((ABOVE_MAX * max_rpm).round());
    speed_labels.push(format!("{ABOVE_MAX}·n_max"));
    let points = (0..LOADS_PCT.len())
        .into_par_iter()
        .map(|l| {
            let load_nm = LOADS_PCT[l] / 100.0 * case.rated_nm;
            speeds_rpm
                .par_iter()
                .map(|&speed_rpm| {
                    let p = run_point(case, speed_rpm, load_nm).with_context(|| {
                        format!(
                            "motor {}, {speed_rpm} r/min, load {} %",
                            case.key, LOADS_PCT[l]
                        )
                    });
                    bar.inc(1);
                    p
                })
                .collect::<Result<Vec<Point>>>()
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(Grid {
        case: *case,
        max_rpm,
        min_rpm,
        speeds_rpm,
        speed_labels,
        points,
    })
}

/// Start-up outside the map: from `n` initial angles, no load, to half the rated speed; the
/// angles from which the drive tripped (degrees) and the fault's name. `bar` advances by one
/// per angle.
pub fn startup_check(case: &Case, n: usize, bar: &ProgressBar) -> Result<Vec<(f64, &'static str)>> {
    let faults = (0..n)
        .into_par_iter()
        .map(|k| {
            let theta = 360.0 * k as f64 / n as f64;
            let (sc, _) = scenario_at(case, 0.5 * case.rated_rpm, 0.0, theta)?;
            let run = run_scenario(&sc)?;
            bar.inc(1);
            Ok(first_fault(&run.rows).map(|r| (theta, r.fault())))
        })
        .collect::<Result<Vec<_>>>()?;
    Ok(faults.into_iter().flatten().collect())
}

/// `cargo xtask map`: every motor's grid, the figures, the section of `docs/PERFORMANCE.md`.
/// `cargo xtask map point a|b|c RPM NM`: one point, printed.
pub fn main(args: &[String]) -> Result<()> {
    let usage = || anyhow!("usage: cargo xtask map [point a|b|c RPM NM]");
    if args.first().map(String::as_str) == Some("point") {
        let case = args
            .get(1)
            .and_then(|k| CASES.iter().find(|c| c.key == k))
            .ok_or_else(usage)?;
        let num = |i: usize| -> Result<f64> {
            args.get(i).and_then(|x| x.parse().ok()).ok_or_else(usage)
        };
        let p = run_point(case, num(2)?, num(3)?)?;
        println!("{p:#?}\n{}", p.outcome.describe());
        return Ok(());
    }
    if !args.is_empty() {
        return Err(usage());
    }
    let dir = super::root().join("docs/figures");
    const STARTUP_ANGLES: usize = 12;
    let points = LOADS_PCT.len() * (SPEEDS_PCT.len() + 1) + STARTUP_ANGLES;
    let bar = progress::bar(CASES.len() * points, "map: motors a, b, c");
    // The three motors share the cores; their tables and figures follow in order.
    let grids = CASES
        .par_iter()
        .map(|case| {
            progress::eprintln(format_args!("operating map of motor {} ...", case.key));
            let g = run_grid(case, &bar)?;
            let failed = startup_check(case, STARTUP_ANGLES, &bar)?;
            Ok((g, failed))
        })
        .collect::<Result<Vec<_>>>()?;
    drop(bar);
    for (g, _) in &grids {
        print!("{}", doc::compact(g));
        let path = dir.join(format!("map-motor-{}.svg", g.case.key));
        std::fs::write(&path, svg::draw(g))?;
        eprintln!("wrote {}", path.display());
    }
    let path = super::root().join("docs/PERFORMANCE.md");
    let text = std::fs::read_to_string(&path).unwrap_or_default();
    std::fs::write(
        &path,
        doc::splice(&text, &doc::section(&grids, STARTUP_ANGLES)),
    )?;
    eprintln!("wrote the operating map into {}", path.display());
    Ok(())
}

#[cfg(test)]
mod tests;
