//! A random family of motors and the drive on each with its defaults only
//! (`cargo xtask family [N] [--seed S] [--estimator NAME]... [--control KEY=VALUE]... [--check]
//! [--write]`; with `--seeds A-B`, every seed from A to B summed: `family_seeds.rs`).
//!
//! Each motor is drawn from a bus-voltage class; its parameters follow from a few
//! dimensionless proportions (the module's `PROPORTIONS` text, printed into
//! docs/PERFORMANCE.md). Every applicable estimator runs the same manoeuvre from rest with
//! `startup = "auto"` and every other setting at the drive's default; each run is classified as
//! holding, a named fault, out of the bars without a fault, or silent (the worst: the rotor far
//! off its reference with no fault). `--check` fails unless the bars of [`check`] hold;
//! `--write` replaces the `## Random motor family` section of docs/PERFORMANCE.md.

use anyhow::{Result, bail};
use pmsm_cli::commands::simulate::stats::first_fault;
use pmsm_cli::commands::simulate::{Row, run_scenario};
use pmsm_cli::scenario_file;
use pmsm_core::DriveState;
use pmsm_tests::signals::SplitMix;
use std::f64::consts::{SQRT_2, TAU};
use std::fmt::Write as _;
use std::sync::Mutex;
use std::sync::atomic::{AtomicUsize, Ordering};

/// Motors of the full table (docs/PERFORMANCE.md) and its seed.
pub const DOC_MOTORS: usize = 40;
/// Seed of the full table and of `cargo xtask family` without `--seed`.
pub const DEFAULT_SEED: u64 = 1;
/// The sample CI checks (`.ci/run`).
const CI_MOTORS: usize = 6;
const CI_SEED: u64 = 2;

/// The proportions the family is drawn with (printed with the table).
const PROPORTIONS: &str = "\
- Bus classes (equally likely): 12 V (rated 3000–10000 r/min, 20–150 W, PWM 20–40 kHz, dead time 0.2–0.4 µs), \
24 V (2000–8000 r/min, 50–400 W, 20–40 kHz, 0.3–0.5 µs), 48 V (1500–6000 r/min, 0.2–2 kW, 16–32 kHz, 0.3–1 µs), \
320 V (1000–6000 r/min, 0.4–4 kW, 10–20 kHz, 1–2 µs), 540 V (1000–4000 r/min, 0.75–7.5 kW, 8–16 kHz, 1.5–3 µs); \
power log-uniform, the rest uniform; pole pairs 2–7.
- EMF at rated speed `ω_e ψ` = 55–90 % of the phase voltage limit `V_DC/√3` (gives ψ).
- Rated torque = power / rated speed; rated peak current `I = T/(1.5 p ψ)` (the file's `rated_current_a` is `I/√2`).
- Copper loss at rated current `1.5 R I²` = 4–15 % of the rated power (gives R).
- Armature reaction `L_d I/ψ` = 0.15–0.5 (gives L_d); half the motors surface (`L_q = L_d`), half interior with `L_q/L_d` = 1.1–2.5. \
The electrical time constant `L_d/R` follows; its range over the family is given below.
- Mechanical time constant (rest to rated speed at rated torque) `J ω_m/T` = 30–300 ms, log-uniform (gives J); \
friction `B ω_m` = 0.5–3 % of the rated torque.
- PWM drawn in the class's range, raised to at least 30 samples per electrical period at rated speed and to a \
full-voltage current step `V_DC T/(√3 L_d)` of at most half the rated peak current per period (the ripple a designer \
accepts); a motor that would need more than the class's highest PWM frequency is drawn again.
- Plant: linear magnetics but for the default d-axis saturation the scenario files give every motor, the \
switching-level inverter with the dead time, 12-bit current ADC; initial rotor angle uniform.";

/// A bus-voltage class: bus V, rated r/min, power W, PWM Hz, dead time s (each a range).
struct Class {
    vdc_v: f64,
    rpm: (f64, f64),
    power_w: (f64, f64),
    pwm_hz: (f64, f64),
    dead_time_s: (f64, f64),
}

const CLASSES: [Class; 5] = [
    Class {
        vdc_v: 12.0,
        rpm: (3000.0, 10000.0),
        power_w: (20.0, 150.0),
        pwm_hz: (20e3, 40e3),
        dead_time_s: (0.2e-6, 0.4e-6),
    },
    Class {
        vdc_v: 24.0,
        rpm: (2000.0, 8000.0),
        power_w: (50.0, 400.0),
        pwm_hz: (20e3, 40e3),
        dead_time_s: (0.3e-6, 0.5e-6),
    },
    Class {
        vdc_v: 48.0,
        rpm: (1500.0, 6000.0),
        power_w: (200.0, 2000.0),
        pwm_hz: (16e3, 32e3),
        dead_time_s: (0.3e-6, 1e-6),
    },
    Class {
        vdc_v: 320.0,
        rpm: (1000.0, 6000.0),
        power_w: (400.0, 4000.0),
        pwm_hz: (10e3, 20e3),
        dead_time_s: (1e-6, 2e-6),
    },
    Class {
        vdc_v: 540.0,
        rpm: (1000.0, 4000.0),
        power_w: (750.0, 7500.0),
        pwm_hz: (8e3, 16e3),
        dead_time_s: (1.5e-6, 3e-6),
    },
];

/// One motor of the family with its inverter.
#[derive(Clone, Debug)]
pub struct Motor {
    /// Index in the family.
    pub index: usize,
    pub vdc_v: f64,
    pub pole_pairs: u32,
    pub rated_rpm: f64,
    pub power_w: f64,
    pub rs_ohm: f64,
    pub ld_h: f64,
    pub lq_h: f64,
    pub flux_wb: f64,
    pub j_kg_m2: f64,
    pub b_nm_s: f64,
    /// Rated peak current, A.
    pub rated_peak_a: f64,
    pub rated_nm: f64,
    pub pwm_hz: f64,
    pub dead_time_s: f64,
    /// Initial electrical angle, degrees.
    pub theta0_deg: f64,
    /// Surface magnets (`L_q = L_d`).
    pub surface: bool,
}

impl Motor {
    fn surface(&self) -> bool {
        self.surface
    }

    /// Electrical time constant `L_d/R`, s.
    fn tau_e_s(&self) -> f64 {
        self.ld_h / self.rs_ohm
    }

    /// Rest to rated speed at rated torque, s.
    fn tau_m_s(&self) -> f64 {
        self.j_kg_m2 * self.rated_rpm * TAU / 60.0 / self.rated_nm
    }

    /// A short description for the lists.
    pub fn describe(&self) -> String {
        format!(
            "#{} {:.0} V {}, p={}, {:.0} r/min, {:.0} W, L_q/L_d {:.2}, τ_e {:.2} ms, τ_m {:.0} ms, {:.0} kHz",
            self.index,
            self.vdc_v,
            if self.surface() {
                "surface"
            } else {
                "interior"
            },
            self.pole_pairs,
            self.rated_rpm,
            self.power_w,
            self.lq_h / self.ld_h,
            1e3 * self.tau_e_s(),
            1e3 * self.tau_m_s(),
            self.pwm_hz / 1e3
        )
    }
}

/// Draws motor `index` (with redraws, counted in `redrawn`) from `rng`.
fn draw(rng: &mut SplitMix, index: usize, redrawn: &mut usize) -> Motor {
    loop {
        let class = &CLASSES[(rng.uniform(0.0, CLASSES.len() as f64) as usize).min(4)];
        let p = (rng.uniform(2.0, 8.0) as u32).min(7);
        let rated_rpm = rng.uniform(class.rpm.0, class.rpm.1).round();
        let power_w = log_uniform(rng, class.power_w);
        let w_m = rated_rpm * TAU / 60.0;
        let w_e = w_m * p as f64;
        let v_ph = class.vdc_v / 3f64.sqrt();
        let flux_wb = rng.uniform(0.55, 0.9) * v_ph / w_e;
        let rated_nm = power_w / w_m;
        let i_pk = rated_nm / (1.5 * p as f64 * flux_wb);
        let rs_ohm = rng.uniform(0.04, 0.15) * power_w / (1.5 * i_pk * i_pk);
        let ld_h = rng.uniform(0.15, 0.5) * flux_wb / i_pk;
        let surface = rng.uniform(0.0, 1.0) < 0.5;
        let ratio = if surface { 1.0 } else { rng.uniform(1.1, 2.5) };
        let j_kg_m2 = log_uniform(rng, (0.03, 0.3)) * rated_nm / w_m;
        let b_nm_s = rng.uniform(0.005, 0.03) * rated_nm / w_m;
        let pwm_drawn = rng.uniform(class.pwm_hz.0, class.pwm_hz.1);
        let dead_time_s = rng.uniform(class.dead_time_s.0, class.dead_time_s.1);
        let theta0_deg = rng.uniform(0.0, 360.0);
        // At least 30 samples per electrical period, and a full-voltage step of at most half
        // the rated current per period.
        let pwm_needed = (30.0 * w_e / TAU).max(2.0 * v_ph / (ld_h * i_pk));
        let pwm_hz = (pwm_drawn.max(pwm_needed) / 1e3).ceil() * 1e3;
        if pwm_hz > class.pwm_hz.1 {
            *redrawn += 1;
            continue;
        }
        return Motor {
            index,
            vdc_v: class.vdc_v,
            pole_pairs: p,
            rated_rpm,
            power_w,
            rs_ohm,
            ld_h,
            lq_h: ratio * ld_h,
            flux_wb,
            j_kg_m2,
            b_nm_s,
            rated_peak_a: i_pk,
            rated_nm,
            pwm_hz,
            dead_time_s: (dead_time_s * 1e8).round() / 1e8,
            theta0_deg,
            surface,
        };
    }
}

fn log_uniform(rng: &mut SplitMix, (lo, hi): (f64, f64)) -> f64 {
    (rng.uniform(lo.ln(), hi.ln())).exp()
}

/// The family of `n` motors from `seed`, and how many draws were redrawn.
pub fn family(n: usize, seed: u64) -> (Vec<Motor>, usize) {
    let mut rng = SplitMix(seed);
    let mut redrawn = 0;
    let motors = (0..n).map(|k| draw(&mut rng, k, &mut redrawn)).collect();
    (motors, redrawn)
}

/// The estimators the family runs: the current-model MRAS on every motor, the back-EMF
/// estimators of Solsona, Valla, Muravchik (2000) on surface motors.
pub const ESTIMATORS: [&str; 4] = ["mras-current", "nlo", "ao", "mras-emf"];

fn applies(estimator: &str, m: &Motor) -> bool {
    estimator == "mras-current" || m.surface()
}

/// Settling after each transient before a steady window, s, and the window, s.
const SETTLE_S: f64 = 0.3;
const WINDOW_S: f64 = 0.2;
/// The reference stays at zero this long (the alignment takes 0.5 s by default), s.
const START_S: f64 = 0.6;
/// Load torque of the manoeuvre, fraction of rated.
const LOAD_FRACTION: f64 = 0.6;
/// The reference ramps at the acceleration this fraction of rated torque gives the rotor.
const RAMP_TORQUE_FRACTION: f64 = 0.25;

/// The manoeuvre of one motor: the scenario's profiles and its steady windows.
struct Manoeuvre {
    duration_s: f64,
    /// `(t, r/min)` breakpoints.
    speed: Vec<(f64, f64)>,
    /// `(t, N·m)` breakpoints.
    load: Vec<(f64, f64)>,
    /// `(from, to, what)` steady windows.
    windows: Vec<(f64, f64, &'static str)>,
    /// `(from, what)`: the phases, for naming when something happened.
    phases: Vec<(f64, &'static str)>,
}

fn manoeuvre(m: &Motor) -> Manoeuvre {
    let half = 0.5 * m.rated_rpm;
    let load = LOAD_FRACTION * m.rated_nm;
    // Ramp time from 0 to `half` at the acceleration of `RAMP_TORQUE_FRACTION` of rated torque.
    let ramp = 0.5 * m.tau_m_s() / RAMP_TORQUE_FRACTION;
    let hold = SETTLE_S + WINDOW_S;
    let step = 1e-3;
    let mut t = START_S;
    let mut speed = vec![(0.0, 0.0), (t, 0.0)];
    let mut loads = vec![(0.0, 0.0)];
    let mut windows = Vec::new();
    let mut phases = vec![(0.0, "start-up"), (t, "ramp to half rated speed")];
    let mut window = |t_end: f64, what| windows.push((t_end - WINDOW_S, t_end, what));
    t += ramp;
    speed.push((t, half));
    phases.push((t, "at half rated speed, no load"));
    t += hold;
    window(t, "no load");
    loads.push((t, 0.0));
    loads.push((t + step, load));
    phases.push((t, "load step"));
    t += hold;
    window(t, "loaded");
    loads.push((t, load));
    loads.push((t + step, 0.0));
    phases.push((t, "load off"));
    t += hold;
    window(t, "unloaded");
    // The load back on, then the reversal: the load turns with the direction (it opposes the
    // motion), changing sign over the middle fifth of the ramp, as in Khlaief, Boussak, Gossa
    // (2012) Fig. 7.
    loads.push((t, 0.0));
    loads.push((t + step, load));
    phases.push((t, "load on again"));
    t += SETTLE_S;
    speed.push((t, half));
    phases.push((t, "reversal under load"));
    loads.push((t + 0.4 * 2.0 * ramp, load));
    loads.push((t + 0.6 * 2.0 * ramp, -load));
    t += 2.0 * ramp;
    speed.push((t, -half));
    phases.push((t, "at −half rated speed, loaded"));
    t += hold;
    window(t, "reversed, loaded");
    speed.push((t, -half));
    phases.push((t, "back under load"));
    loads.push((t + 0.4 * 2.0 * ramp, -load));
    loads.push((t + 0.6 * 2.0 * ramp, load));
    t += 2.0 * ramp;
    speed.push((t, half));
    phases.push((t, "at half rated speed, loaded"));
    t += hold;
    window(t, "back, loaded");
    Manoeuvre {
        duration_s: t,
        speed,
        load: loads,
        windows,
        phases,
    }
}

/// The scenario file's text for `m` with `estimator`: every setting at its default but the
/// dead-time compensation, which the file has off unless asked and the drive's own design
/// (`DriveDesign::default_for`) has on, and the `key = value` lines of `control` added to
/// `[control]`.
fn scenario_text(m: &Motor, estimator: &str, man: &Manoeuvre, control: &[String]) -> String {
    let list = |xs: &[(f64, f64)], f: fn(&(f64, f64)) -> f64| {
        xs.iter()
            .map(|x| format!("{:.6}", f(x)))
            .collect::<Vec<_>>()
            .join(", ")
    };
    format!(
        "duration_s = {:.6}\n\
         motor = {{ name = \"family {}\", pole_pairs = {}, rs_ohm = {}, ld_h = {}, lq_h = {}, flux_wb = {}, \
         j_kg_m2 = {}, b_nm_s = {}, rated_current_a = {}, rated_speed_rpm = {} }}\n\
         [inverter]\nvdc_v = {}\npwm_hz = {}\ndead_time_s = {}\nmodel = \"switching\"\n\
         [control]\nobserver = \"{estimator}\"\nstartup = \"auto\"\ndeadtime_compensation = true\n{}\
         [initial]\ntheta_e_deg = {:.3}\n\
         [speed_ref]\nt_s = [{}]\nrpm = [{}]\n\
         [load]\nt_s = [{}]\nnm = [{}]\n",
        man.duration_s,
        m.index,
        m.pole_pairs,
        m.rs_ohm,
        m.ld_h,
        m.lq_h,
        m.flux_wb,
        m.j_kg_m2,
        m.b_nm_s,
        m.rated_peak_a / SQRT_2,
        m.rated_rpm,
        m.vdc_v,
        m.pwm_hz,
        m.dead_time_s,
        control.iter().map(|c| format!("{c}\n")).collect::<String>(),
        m.theta0_deg,
        list(&man.speed, |x| x.0),
        list(&man.speed, |x| x.1),
        list(&man.load, |x| x.0),
        list(&man.load, |x| x.1),
    )
}

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
    /// The rotor more than 20 % of rated speed off the reference for 0.2 s, no fault by then,
    /// and the drive not saying why (at its current limit with the rotor where it estimates
    /// it): when that began, in which phase.
    Silent(f64, &'static str),
}

/// Speed error (fraction of rated) and angle error (rad rms) over a steady window that hold.
pub const HOLD_SPEED: f64 = 0.05;
pub const HOLD_ANGLE_RAD: f64 = 0.15;
/// Off the reference by this fraction of rated speed for [`SILENT_S`] without a fault: silent.
pub const SILENT_SPEED: f64 = 0.2;
pub const SILENT_S: f64 = 0.2;

fn phase_at(man: &Manoeuvre, t: f64) -> &'static str {
    man.phases
        .iter()
        .rev()
        .find(|(t0, _)| *t0 <= t)
        .map_or("start-up", |p| p.1)
}

fn classify(rows: &[Row], m: &Motor, man: &Manoeuvre) -> Outcome {
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
                return Outcome::Silent(t0, phase_at(man, t0));
            }
            (false, _) => since = None,
            _ => {}
        }
    }
    if let Some(r) = fault {
        return Outcome::Fault(r.fault(), r.t_s, phase_at(man, r.t_s));
    }
    let mut worst: Option<(&'static str, f64, f64)> = None;
    for &(a, b, what) in &man.windows {
        let w: Vec<&Row> = rows.iter().filter(|r| r.t_s >= a && r.t_s < b).collect();
        let speed = w
            .iter()
            .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs())
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

/// One run of the family.
pub struct RunResult {
    pub motor: usize,
    pub estimator: &'static str,
    pub outcome: Outcome,
}

/// Runs every applicable estimator of `estimators` on every motor of the family drawn with
/// `seed`, `threads` at a time, with the `key = value` lines of `control` in every run's
/// `[control]`.
pub fn run_all(
    motors: &[Motor],
    seed: u64,
    estimators: &[&'static str],
    threads: usize,
    control: &[String],
) -> Result<Vec<RunResult>> {
    let jobs: Vec<(usize, &'static str)> = motors
        .iter()
        .flat_map(|m| {
            estimators
                .iter()
                .filter(|e| applies(e, m))
                .map(move |e| (m.index, *e))
        })
        .collect();
    // One directory per seed: a seed whose runs all hold removes its own, not another's.
    let dir = std::env::temp_dir().join(format!("pmsm-family-{}-seed{seed}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let next = AtomicUsize::new(0);
    let results = Mutex::new(Vec::new());
    let errors = Mutex::new(Vec::new());
    std::thread::scope(|s| {
        for _ in 0..threads.max(1) {
            s.spawn(|| {
                loop {
                    let k = next.fetch_add(1, Ordering::Relaxed);
                    let Some(&(mi, est)) = jobs.get(k) else { break };
                    let m = &motors[mi];
                    match run_one(m, est, &dir.join(format!("m{mi}-{est}.toml")), control) {
                        Ok(outcome) => results.lock().unwrap().push(RunResult {
                            motor: mi,
                            estimator: est,
                            outcome,
                        }),
                        Err(e) => errors
                            .lock()
                            .unwrap()
                            .push(format!("{} {est}: {e:#}", m.describe())),
                    }
                }
            });
        }
    });
    let errors = errors.into_inner().unwrap();
    if !errors.is_empty() {
        bail!("runs that could not be built:\n{}", errors.join("\n"));
    }
    let mut results = results.into_inner().unwrap();
    if results.iter().all(|r| r.outcome == Outcome::Holds) {
        std::fs::remove_dir_all(&dir).ok();
    } else {
        eprintln!(
            "the scenarios of the runs that did not hold: {}",
            dir.display()
        );
    }
    results.sort_by_key(|r| {
        (
            r.motor,
            ESTIMATORS
                .iter()
                .position(|e| *e == r.estimator)
                .unwrap_or(0),
        )
    });
    Ok(results)
}

fn run_one(
    m: &Motor,
    estimator: &str,
    path: &std::path::Path,
    control: &[String],
) -> Result<Outcome> {
    let man = manoeuvre(m);
    std::fs::write(path, scenario_text(m, estimator, &man, control))?;
    let sc = scenario_file::read(path)?;
    let run = run_scenario(&sc)?;
    let outcome = classify(&run.rows, m, &man);
    if outcome != Outcome::Holds {
        // Kept for a look: `pmsm simulate` runs it as it is.
        let keep = path.with_file_name(format!("failed-m{}-{estimator}.toml", m.index));
        std::fs::copy(path, &keep).ok();
    }
    std::fs::remove_file(path).ok();
    Ok(outcome)
}

/// Counts of one estimator's runs: holds, faults by name, out of the bars, silent.
#[derive(Default)]
pub struct Tally {
    pub runs: usize,
    pub holds: usize,
    pub faults: Vec<(&'static str, usize)>,
    pub out_of_bars: usize,
    pub silent: usize,
}

impl Tally {
    /// Adds another tally's counts (the faults merged by name, sorted).
    pub fn add(&mut self, t: &Tally) {
        self.runs += t.runs;
        self.holds += t.holds;
        self.out_of_bars += t.out_of_bars;
        self.silent += t.silent;
        for &(name, k) in &t.faults {
            match self.faults.iter_mut().find(|f| f.0 == name) {
                Some(f) => f.1 += k,
                None => self.faults.push((name, k)),
            }
        }
        self.faults.sort();
    }
}

pub fn tally(results: &[RunResult], estimator: &str) -> Tally {
    let mut t = Tally::default();
    for r in results.iter().filter(|r| r.estimator == estimator) {
        t.runs += 1;
        match &r.outcome {
            Outcome::Holds => t.holds += 1,
            Outcome::Fault(name, ..) => match t.faults.iter_mut().find(|f| f.0 == *name) {
                Some(f) => f.1 += 1,
                None => t.faults.push((name, 1)),
            },
            Outcome::OutOfBars(..) => t.out_of_bars += 1,
            Outcome::Silent(..) => t.silent += 1,
        }
    }
    t.faults.sort();
    t
}

/// An estimator's row label in the tables: its name and the motors it runs on.
pub fn label(estimator: &str) -> String {
    if estimator == "mras-current" {
        format!("{estimator} (all motors)")
    } else {
        format!("{estimator} (surface motors)")
    }
}

fn pct(k: usize, n: usize) -> String {
    if n == 0 {
        "–".into()
    } else {
        format!("{k} ({:.0} %)", 100.0 * k as f64 / n as f64)
    }
}

/// The table per estimator of `estimators` and the list of runs that did not hold, Markdown.
pub fn report(
    motors: &[Motor],
    estimators: &[&'static str],
    redrawn: usize,
    seed: u64,
    results: &[RunResult],
) -> String {
    let mut s = String::new();
    let surface = motors.iter().filter(|m| m.surface()).count();
    let tau_e = motors.iter().map(Motor::tau_e_s);
    let (e_lo, e_hi) = tau_e.fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
    let _ = writeln!(
        s,
        "{} motors (seed {seed}; {surface} surface, {} interior; {redrawn} draws beyond their class's PWM range drawn again), \
         electrical time constants {:.2}–{:.1} ms.\n",
        motors.len(),
        motors.len() - surface,
        1e3 * e_lo,
        1e3 * e_hi
    );
    s.push_str(
        "| estimator | runs | holds | named fault | out of the bars, no fault | silent |\n|---|---:|---:|---|---:|---:|\n",
    );
    for &est in estimators {
        let t = tally(results, est);
        let faults = if t.faults.is_empty() {
            "0".to_string()
        } else {
            t.faults
                .iter()
                .map(|(n, k)| format!("{n} {}", pct(*k, t.runs)))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {faults} | {} | {} |",
            label(est),
            t.runs,
            pct(t.holds, t.runs),
            pct(t.out_of_bars, t.runs),
            pct(t.silent, t.runs),
        );
    }
    let failed: Vec<&RunResult> = results
        .iter()
        .filter(|r| r.outcome != Outcome::Holds)
        .collect();
    if failed.is_empty() {
        s.push_str("\nEvery run holds.\n");
    } else {
        s.push_str("\nRuns that do not hold:\n\n");
        for r in failed {
            let what = match &r.outcome {
                Outcome::Holds => String::new(),
                Outcome::Fault(name, t, phase) => format!("`{name}` at {t:.3} s ({phase})"),
                Outcome::OutOfBars(w, sp, a) => format!(
                    "out of the bars, {w}: speed error {:.1} % of rated, angle error {a:.3} rad rms",
                    100.0 * sp
                ),
                Outcome::Silent(t, phase) => {
                    format!("**silent** from {t:.3} s ({phase})")
                }
            };
            let _ = writeln!(
                s,
                "- {}, {}: {what}",
                r.estimator,
                motors[r.motor].describe()
            );
        }
    }
    s
}

/// The bars: at least 90 % of the runs hold with the current-model MRAS and with the NLO, no
/// run is silent. The failures, one line each.
pub fn check(results: &[RunResult]) -> Vec<String> {
    let mut bad = Vec::new();
    for est in ["mras-current", "nlo"] {
        let t = tally(results, est);
        if t.runs > 0 && (t.holds as f64) < 0.9 * t.runs as f64 {
            bad.push(format!(
                "{est}: {} of {} runs hold, below 90 %",
                t.holds, t.runs
            ));
        }
    }
    let silent = results
        .iter()
        .filter(|r| matches!(r.outcome, Outcome::Silent(..)))
        .count();
    if silent > 0 {
        bad.push(format!("{silent} silent runs"));
    }
    bad
}

/// The section of docs/PERFORMANCE.md from `n` motors drawn with `seed`, and the bars it
/// misses ([`check`]); `control` holds `key = value` lines added to every run's `[control]`
/// (none for the documented table: the drive's defaults); `estimators` those to run (all of
/// [`ESTIMATORS`] for the documented table).
pub fn section(
    n: usize,
    seed: u64,
    estimators: &[&'static str],
    control: &[String],
) -> Result<(String, Vec<String>)> {
    let (motors, redrawn) = family(n, seed);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let started = std::time::Instant::now();
    let results = run_all(&motors, seed, estimators, threads, control)?;
    let wall = started.elapsed().as_secs_f64();
    let mut s = String::from(SECTION_TITLE);
    let _ = write!(
        s,
        "\n\n`cargo xtask family {n} --seed {seed} --write` ({threads} threads, {wall:.0} s): random motors, \
         each driven with the drive's defaults only (`startup = \"auto\"`, every gain, limit and the start-up designed \
         from the motor by `DriveDesign::default_for`; dead-time compensation on, as that design has it). The \
         manoeuvre: rest, {START_S} s at zero, ramp to half rated speed (at the acceleration {RAMP_TORQUE_FRACTION} of \
         rated torque gives), a load step to {LOAD_FRACTION} of rated torque, load off, load on again, reversal to \
         −half rated speed under that load (opposing the motion, changing sign mid-ramp), back to +half rated. \
         **Holds**: no fault, and in each of the five steady windows ({WINDOW_S} s after {SETTLE_S} s of settling) the \
         speed within {:.0} % of rated of the reference at every sample and the angle error within \
         {HOLD_ANGLE_RAD} rad rms. **Silent**: the rotor more than {:.0} % of rated speed off the reference the \
         drive holds for {SILENT_S} s in the closed loop with no fault yet, and the drive not saying why (`Drive::speed_ref_limit`: \
         at its current limit, with its estimated speed within that margin of the rotor's). CI runs `cargo xtask family {CI_MOTORS} --seed {CI_SEED} \
         --check` (six other motors, a regression check: that sample meets the bars today), which fails unless at \
         least 90 % of the runs hold with the current-model MRAS and with the NLO and none is silent. The next \
         section sums thirty seeds (`--seeds`).\n\n{PROPORTIONS}\n\n",
        100.0 * HOLD_SPEED,
        100.0 * SILENT_SPEED
    );
    if !control.is_empty() {
        let _ = write!(
            s,
            "**Not the defaults**: every run's `[control]` also sets `{}`.\n\n",
            control.join("`, `")
        );
    }
    if estimators.len() < ESTIMATORS.len() {
        let _ = write!(
            s,
            "**Not every estimator**: only `{}` ran.\n\n",
            estimators.join("`, `")
        );
    }
    s.push_str(&report(&motors, estimators, redrawn, seed, &results));
    s.push('\n');
    Ok((s, check(&results)))
}

/// The title the section starts with (`--write` finds it there).
pub const SECTION_TITLE: &str = "## Random motor family";

/// Where the section titled `title` lies in `doc`: from its title to the next `## ` title
/// (or the end).
pub fn section_span(doc: &str, title: &str) -> Option<(usize, usize)> {
    let a = doc.find(title)?;
    let from = a + title.len();
    Some((
        a,
        doc[from..]
            .find("\n## ")
            .map_or(doc.len(), |k| from + k + 1),
    ))
}

/// Replaces the section in `doc` (up to the next `## ` title), or appends it.
pub fn replace_section(doc: &str, section: &str) -> String {
    match section_span(doc, SECTION_TITLE) {
        Some((a, b)) => format!("{}{section}{}", &doc[..a], &doc[b..]),
        // Where `cargo xtask perf` puts it: before the instruction counts.
        None => match doc.find("## Instructions per call") {
            Some(k) => format!("{}{section}{}", &doc[..k], &doc[k..]),
            None => format!("{}\n\n{section}", doc.trim_end_matches('\n')),
        },
    }
}

/// The arguments of `cargo xtask family`.
pub const USAGE: &str = "family [N] [--seed S] [--estimator NAME]... [--control KEY=VALUE]... [--check] [--write] | family [N] --seeds A-B [--write]";

/// `cargo xtask family` ([`USAGE`]).
pub fn main(args: &[String]) -> Result<()> {
    let mut n = DOC_MOTORS;
    let mut seed = DEFAULT_SEED;
    let mut seeds = None;
    let (mut check_bars, mut write) = (false, false);
    let mut control = Vec::new();
    let mut estimators: Vec<&'static str> = Vec::new();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        match a.as_str() {
            "--seed" => match it.next().and_then(|s| s.parse().ok()) {
                Some(s) => seed = s,
                None => bail!("--seed needs a number"),
            },
            "--seeds" => match it.next().and_then(|s| crate::family_seeds::parse_seeds(s)) {
                Some(s) => seeds = Some(s),
                None => bail!("--seeds needs A-B, two seeds with A ≤ B"),
            },
            "--control" => match it.next().and_then(|s| s.split_once('=')) {
                Some((k, v)) if !k.trim().is_empty() && !v.trim().is_empty() => {
                    control.push(format!("{} = {}", k.trim(), v.trim()));
                }
                _ => bail!("--control needs KEY=VALUE (a [control] key of the scenario file)"),
            },
            "--estimator" => match it
                .next()
                .and_then(|e| ESTIMATORS.iter().find(|k| **k == e.as_str()))
            {
                Some(e) if !estimators.contains(e) => estimators.push(e),
                Some(_) => {}
                None => bail!("--estimator needs one of {}", ESTIMATORS.join(", ")),
            },
            "--check" => check_bars = true,
            "--write" => write = true,
            x => match x.parse() {
                Ok(k) => n = k,
                Err(_) => bail!("usage: cargo xtask {USAGE}"),
            },
        }
    }
    if let Some(seeds) = seeds {
        if !control.is_empty() || !estimators.is_empty() || check_bars {
            bail!(
                "--seeds runs the defaults with every estimator: leave out --control, --estimator, --check"
            );
        }
        let section = crate::family_seeds::section(n, seeds)?;
        print!("{section}");
        if write {
            let path = crate::root().join("docs/PERFORMANCE.md");
            let doc = std::fs::read_to_string(&path)?;
            std::fs::write(&path, crate::family_seeds::replace_section(&doc, &section))?;
            eprintln!("wrote the section to {}", path.display());
        }
        return Ok(());
    }
    if write && !control.is_empty() {
        bail!("--write records the drive's defaults: leave out --control");
    }
    if estimators.is_empty() {
        estimators = ESTIMATORS.to_vec();
    } else if write {
        bail!("--write records every estimator: leave out --estimator");
    }
    let (section, missed) = section(n, seed, &estimators, &control)?;
    print!("{section}");
    if write {
        let path = crate::root().join("docs/PERFORMANCE.md");
        let doc = std::fs::read_to_string(&path)?;
        std::fs::write(&path, replace_section(&doc, &section))?;
        eprintln!("wrote the section to {}", path.display());
    }
    if check_bars && !missed.is_empty() {
        bail!("the family misses its bars: {}", missed.join("; "));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_family_has_the_documented_proportions() {
        let (motors, _) = family(200, DEFAULT_SEED);
        for m in &motors {
            let w_m = m.rated_rpm * TAU / 60.0;
            let w_e = w_m * m.pole_pairs as f64;
            let emf = w_e * m.flux_wb / (m.vdc_v / 3f64.sqrt());
            let cu = 1.5 * m.rs_ohm * m.rated_peak_a.powi(2) / m.power_w;
            let x_d = m.ld_h * m.rated_peak_a / m.flux_wb;
            let tau_m = m.tau_m_s();
            let class = CLASSES
                .iter()
                .find(|c| (c.vdc_v - m.vdc_v).abs() < 1e-9)
                .unwrap();
            assert!((0.55..0.9).contains(&emf), "{}: EMF {emf}", m.describe());
            assert!((0.04..0.15).contains(&cu), "{}: copper {cu}", m.describe());
            assert!(
                (0.15..0.5).contains(&x_d),
                "{}: L_d I/ψ {x_d}",
                m.describe()
            );
            assert!((0.03..0.3).contains(&tau_m), "{}", m.describe());
            assert!((1.0..=2.5).contains(&(m.lq_h / m.ld_h)), "{}", m.describe());
            assert!((2..=7).contains(&m.pole_pairs));
            assert!(m.pwm_hz <= class.pwm_hz.1 && m.pwm_hz >= class.pwm_hz.0);
            assert!(m.pwm_hz >= 30.0 * w_e / TAU, "{}", m.describe());
            let step = m.vdc_v / 3f64.sqrt() / (m.ld_h * m.pwm_hz);
            assert!(step <= 0.5 * m.rated_peak_a * 1.0001, "{}", m.describe());
        }
        // Both kinds and every class are drawn.
        assert!(motors.iter().any(|m| m.surface) && motors.iter().any(|m| !m.surface));
        for c in &CLASSES {
            assert!(
                motors.iter().any(|m| (m.vdc_v - c.vdc_v).abs() < 1e-9),
                "{} V",
                c.vdc_v
            );
        }
    }

    #[test]
    fn control_keys_reach_every_runs_scenario() {
        let (motors, _) = family(1, DEFAULT_SEED);
        let m = &motors[0];
        let man = manoeuvre(m);
        let path =
            std::env::temp_dir().join(format!("pmsm-family-test-{}.toml", std::process::id()));
        let read = |control: &[String]| {
            std::fs::write(&path, scenario_text(m, "mras-current", &man, control)).unwrap();
            scenario_file::read(&path).unwrap().control
        };
        let with = read(&[
            "mras_low_speed_schedule = true".into(),
            "mras_bandwidth_hz = 30".into(),
        ]);
        let without = read(&[]);
        std::fs::remove_file(&path).ok();
        assert_eq!(with.mras_low_speed_schedule, Some(true));
        assert_eq!(with.mras_bandwidth_hz, Some(30.0));
        assert_eq!(without.mras_low_speed_schedule, None);
        assert_eq!(without.mras_bandwidth_hz, None);
    }

    #[test]
    fn the_section_is_replaced_in_place() {
        let doc = "# P\n\n## A\n\na\n\n## Instructions per call\n\nb\n";
        let first = replace_section(doc, "## Random motor family\n\nx\n\n");
        assert_eq!(
            first,
            "# P\n\n## A\n\na\n\n## Random motor family\n\nx\n\n## Instructions per call\n\nb\n"
        );
        let second = replace_section(&first, "## Random motor family\n\ny\n\n");
        assert_eq!(second, first.replace("\nx\n", "\ny\n"));
    }
}
