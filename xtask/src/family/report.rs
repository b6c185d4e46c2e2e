//! The family's tables: the counts per estimator and the runs that did not hold, and the
//! bars `--check` holds them to.

use super::{Motor, Outcome, RunResult};
use std::fmt::Write as _;

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
                Outcome::Silent(t, phase, by) => {
                    format!("**silent** ({by}) from {t:.3} s ({phase})")
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
