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

mod draw;
pub(crate) mod judge;
mod report;

use crate::progress;
use anyhow::{Result, bail};
use indicatif::ProgressBar;
use pmsm_cli::commands::simulate::run_scenario;
use pmsm_cli::scenario_file;
use rayon::prelude::*;
use std::fmt::Write as _;

/// Motors of the full table (docs/PERFORMANCE.md) and its seed.
pub const DOC_MOTORS: usize = 40;
/// Seed of the full table and of `cargo xtask family` without `--seed`.
pub const DEFAULT_SEED: u64 = 1;
/// The sample CI checks (`.ci/run`).
const CI_MOTORS: usize = 6;
const CI_SEED: u64 = 2;

pub use draw::{Motor, PROPORTIONS, family};
pub(crate) use judge::classify;
pub use judge::{HOLD_ANGLE_RAD, HOLD_SPEED, Outcome, SILENT_S, SILENT_SPEED};
pub use report::{Tally, check, label, report, tally};

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
pub(crate) struct Manoeuvre {
    pub duration_s: f64,
    /// `(t, r/min)` breakpoints.
    pub speed: Vec<(f64, f64)>,
    /// `(t, N·m)` breakpoints.
    pub load: Vec<(f64, f64)>,
    /// `(from, to, what)` steady windows.
    pub windows: Vec<(f64, f64, &'static str)>,
    /// `(from, what)`: the phases, for naming when something happened.
    pub phases: Vec<(f64, &'static str)>,
    /// The windows judge the speed against the reference the drive holds
    /// (`Drive::speed_ref_limit`) rather than the one asked for.
    pub against_held: bool,
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
        against_held: false,
    }
}

/// One coordinate of breakpoints, as a TOML array's items.
pub(crate) fn list(xs: &[(f64, f64)], f: fn(&(f64, f64)) -> f64) -> String {
    xs.iter()
        .map(|x| format!("{:.6}", f(x)))
        .collect::<Vec<_>>()
        .join(", ")
}

/// A scenario file's `[initial]`, `[speed_ref]` and `[load]` tables: the rotor at
/// `theta0_deg`, the manoeuvre's breakpoints.
pub(crate) fn manoeuvre_tables(man: &Manoeuvre, theta0_deg: f64) -> String {
    format!(
        "[initial]\ntheta_e_deg = {theta0_deg:.3}\n\
         [speed_ref]\nt_s = [{}]\nrpm = [{}]\n\
         [load]\nt_s = [{}]\nnm = [{}]\n",
        list(&man.speed, |x| x.0),
        list(&man.speed, |x| x.1),
        list(&man.load, |x| x.0),
        list(&man.load, |x| x.1),
    )
}

/// The scenario file's text for `m` with `estimator`: every setting at its default but the
/// dead-time compensation, which the file has off unless asked and the drive's own design
/// (`DriveDesign::default_for`) has on, and the `key = value` lines of `control` added to
/// `[control]`.
fn scenario_text(m: &Motor, estimator: &str, man: &Manoeuvre, control: &[String]) -> String {
    format!(
        "duration_s = {:.6}\n{}\
         [control]\nobserver = \"{estimator}\"\nstartup = \"auto\"\ndeadtime_compensation = true\n{}{}",
        man.duration_s,
        m.hardware_toml(),
        control.iter().map(|c| format!("{c}\n")).collect::<String>(),
        manoeuvre_tables(man, m.theta0_deg),
    )
}

/// One run of the family.
pub struct RunResult {
    pub motor: usize,
    pub estimator: &'static str,
    pub outcome: Outcome,
}

/// The runs of the family: every applicable estimator of `estimators` on every motor, by
/// motor, then in the order of `estimators`.
pub fn jobs(motors: &[Motor], estimators: &[&'static str]) -> Vec<(usize, &'static str)> {
    motors
        .iter()
        .flat_map(|m| {
            estimators
                .iter()
                .filter(|e| applies(e, m))
                .map(move |e| (m.index, *e))
        })
        .collect()
}

/// Runs the [`jobs`] of the family drawn with `seed` over all cores, with the `key = value`
/// lines of `control` in every run's `[control]`; `bar` advances by one per run. The results
/// are by motor, then in the order of [`ESTIMATORS`], whichever run ends first.
pub fn run_all(
    motors: &[Motor],
    seed: u64,
    estimators: &[&'static str],
    control: &[String],
    bar: &ProgressBar,
) -> Result<Vec<RunResult>> {
    let jobs = jobs(motors, estimators);
    // One directory per seed: a seed whose runs all hold removes its own, not another's.
    let dir = std::env::temp_dir().join(format!("pmsm-family-{}-seed{seed}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let outcomes: Vec<Result<Outcome>> = jobs
        .par_iter()
        .map(|&(mi, est)| {
            let outcome = run_one(
                &motors[mi],
                est,
                &dir.join(format!("m{mi}-{est}.toml")),
                control,
            );
            bar.inc(1);
            outcome
        })
        .collect();
    let mut results = Vec::new();
    let mut errors = Vec::new();
    for (&(mi, est), outcome) in jobs.iter().zip(outcomes) {
        match outcome {
            Ok(outcome) => results.push(RunResult {
                motor: mi,
                estimator: est,
                outcome,
            }),
            Err(e) => errors.push(format!("{} {est}: {e:#}", motors[mi].describe())),
        }
    }
    if !errors.is_empty() {
        bail!("runs that could not be built:\n{}", errors.join("\n"));
    }
    keep_failed(&dir, results.iter().all(|r| r.outcome == Outcome::Holds));
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
    let threads = rayon::current_num_threads();
    let started = std::time::Instant::now();
    let bar = progress::bar(
        jobs(&motors, estimators).len(),
        format!("family {n} --seed {seed}"),
    );
    let results = run_all(&motors, seed, estimators, control, &bar)?;
    drop(bar);
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
         at its current limit, with its estimated speed within that margin of the rotor's); or, by angle, the estimated angle \
         more than a quarter turn (electrical) off the rotor's, again and again, over more than {:.0} ms without a fault by then. CI runs `cargo xtask family {CI_MOTORS} --seed {CI_SEED} \
         --check` (six other motors, a regression check: that sample meets the bars today), which fails unless at \
         least 90 % of the runs hold with the current-model MRAS and with the NLO and none is silent. The next \
         section sums thirty seeds (`--seeds`).\n\n{PROPORTIONS}\n\n",
        100.0 * HOLD_SPEED,
        100.0 * SILENT_SPEED,
        1e3 * judge::SLIP_FAULT_S
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
    put_section(doc, SECTION_TITLE, section)
}

/// The arguments of `cargo xtask family`.
pub const USAGE: &str = "family [N] [--seed S] [--estimator NAME]... [--control KEY=VALUE]... [--check] [--write] | family [N] --seeds A-B [--write] | family --published [--held-out | --file PATH] [--control KEY=VALUE]... [--check] [--write] | family [N] --widened [--seeds A-B] [--check] [--write]";

/// `doc` with the section titled `title` replaced by `section`, or `section` put where
/// `cargo xtask perf` puts it: before the instruction counts (or at the end).
pub(crate) fn put_section(doc: &str, title: &str, section: &str) -> String {
    match section_span(doc, title) {
        Some((a, b)) => format!("{}{section}{}", &doc[..a], &doc[b..]),
        None => match doc.find("## Instructions per call") {
            Some(k) => format!("{}{section}{}", &doc[..k], &doc[k..]),
            None => format!("{}\n\n{section}", doc.trim_end_matches('\n')),
        },
    }
}

/// Rewrites docs/PERFORMANCE.md with `doc_with(its text)` and says so (`--write`).
pub(crate) fn write_performance(doc_with: impl FnOnce(&str) -> String) -> Result<()> {
    let path = crate::root().join("docs/PERFORMANCE.md");
    let doc = std::fs::read_to_string(&path)?;
    std::fs::write(&path, doc_with(&doc))?;
    eprintln!("wrote the section to {}", path.display());
    Ok(())
}

/// Removes a run's scratch directory of scenarios when every run held, else says where the
/// scenarios of the runs that did not hold are kept.
pub(crate) fn keep_failed(dir: &std::path::Path, all_held: bool) {
    if all_held {
        std::fs::remove_dir_all(dir).ok();
    } else {
        progress::eprintln(format_args!(
            "the scenarios of the runs that did not hold: {}",
            dir.display()
        ));
    }
}

/// `cargo xtask family` ([`USAGE`]).
pub fn main(args: &[String]) -> Result<()> {
    if args.iter().any(|a| a == "--published") {
        return crate::published::published_main(args);
    }
    if args.iter().any(|a| a == "--widened") {
        return crate::published::widened_main(args);
    }
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
            write_performance(|doc| crate::family_seeds::replace_section(doc, &section))?;
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
        write_performance(|doc| replace_section(doc, &section))?;
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
