//! The random family on many seeds (`cargo xtask family N --seeds A-B [--write]`): the same
//! draw and manoeuvre as `cargo xtask family`, once per seed, summed into one table per
//! estimator, with the lowest share of holding runs of any one seed and the named faults by
//! phase of the manoeuvre. A library is judged on motors it was not tuned for; one seed's
//! table could be a lucky draw, thirty are not. `--write` replaces the section of
//! docs/PERFORMANCE.md, which `cargo xtask perf` keeps as it is (a quarter of an hour on 2
//! cores).

use crate::family::{self, ESTIMATORS, Outcome, RunResult, tally};
use crate::progress;
use anyhow::Result;
use rayon::prelude::*;
use std::fmt::Write as _;

/// The section's title (`--write` finds it there).
pub const TITLE: &str = "## Random families on many seeds";

/// One seed's runs.
struct Seed {
    seed: u64,
    motors: usize,
    surface: usize,
    results: Vec<RunResult>,
}

fn share(k: usize, n: usize) -> String {
    if n == 0 {
        "–".into()
    } else {
        format!("{k} ({:.1} %)", 100.0 * k as f64 / n as f64)
    }
}

/// Runs `n` motors of every seed in `seeds` with every estimator; the section. The runs of
/// all seeds share the cores; each seed's results are those it gets alone.
pub fn section(n: usize, seeds: std::ops::RangeInclusive<u64>) -> Result<String> {
    let threads = rayon::current_num_threads();
    let started = std::time::Instant::now();
    let draws: Vec<(u64, Vec<family::Motor>)> = seeds
        .clone()
        .map(|seed| (seed, family::family(n, seed).0))
        .collect();
    let bar = progress::bar(
        draws
            .iter()
            .map(|(_, motors)| family::jobs(motors, &ESTIMATORS).len())
            .sum(),
        format!("family {n} --seeds {}-{}", seeds.start(), seeds.end()),
    );
    let ran = draws
        .into_par_iter()
        .map(|(seed, motors)| {
            let results = family::run_all(&motors, seed, &ESTIMATORS, &[], &bar)?;
            Ok((seed, motors, results))
        })
        .collect::<Result<Vec<_>>>()?;
    drop(bar);
    let mut runs = Vec::new();
    for (seed, motors, results) in ran {
        for r in results.iter().filter(|r| r.outcome != Outcome::Holds) {
            eprintln!(
                "seed {seed}: {}, {}: {:?}",
                r.estimator,
                motors[r.motor].describe(),
                r.outcome
            );
        }
        runs.push(Seed {
            seed,
            motors: motors.len(),
            surface: motors.iter().filter(|m| m.surface).count(),
            results,
        });
    }
    let wall = started.elapsed().as_secs_f64();
    let (a, b) = (seeds.start(), seeds.end());
    let total: usize = runs.iter().map(|s| s.motors).sum();
    let surface: usize = runs.iter().map(|s| s.surface).sum();
    let mut s = format!(
        "{TITLE}\n\n`cargo xtask family {n} --seeds {a}-{b} --write` ({threads} threads, {wall:.0} s; \
         `cargo xtask perf` keeps this section as it is): the family and the manoeuvre of the section above, \
         drawn with each of the seeds {a} to {b}, {total} motors ({surface} surface, {} interior), the drive's \
         defaults only. One seed's table could be a lucky draw; this one is the sum. \"Lowest seed\": the smallest \
         share of holding runs of any one seed, and which.\n\n\
         | estimator | runs | holds | lowest seed | named fault | out of the bars, no fault | silent |\n\
         |---|---:|---:|---:|---|---:|---:|\n",
        total - surface
    );
    let all: Vec<&RunResult> = runs.iter().flat_map(|s| &s.results).collect();
    for est in ESTIMATORS {
        let mut sum = family::Tally::default();
        let mut lowest: Option<(f64, u64)> = None;
        for seed in &runs {
            let t = tally(&seed.results, est);
            if t.runs > 0 {
                let f = t.holds as f64 / t.runs as f64;
                if lowest.is_none_or(|(g, _)| f < g) {
                    lowest = Some((f, seed.seed));
                }
            }
            sum.add(&t);
        }
        let faults = if sum.faults.is_empty() {
            "0".to_string()
        } else {
            sum.faults
                .iter()
                .map(|(name, k)| format!("{name} {k}"))
                .collect::<Vec<_>>()
                .join(", ")
        };
        let _ = writeln!(
            s,
            "| {} | {} | {} | {} | {faults} | {} | {} |",
            family::label(est),
            sum.runs,
            share(sum.holds, sum.runs),
            lowest.map_or("–".into(), |(f, k)| format!(
                "{:.0} % (seed {k})",
                100.0 * f
            )),
            share(sum.out_of_bars, sum.runs),
            share(sum.silent, sum.runs),
        );
    }
    // The named faults by the phase of the manoeuvre they came in.
    let mut phases: Vec<&'static str> = Vec::new();
    for r in &all {
        if let Outcome::Fault(_, _, phase) = r.outcome
            && !phases.contains(&phase)
        {
            phases.push(phase);
        }
    }
    if !phases.is_empty() {
        s.push_str("\nNamed faults by the phase of the manoeuvre they came in:\n\n| phase |");
        for est in ESTIMATORS {
            let _ = write!(s, " {est} |");
        }
        s.push_str("\n|---|");
        s.push_str(&"---:|".repeat(ESTIMATORS.len()));
        s.push('\n');
        for phase in phases {
            let _ = write!(s, "| {phase} |");
            for est in ESTIMATORS {
                let k = all
                    .iter()
                    .filter(|r| {
                        r.estimator == est
                            && matches!(r.outcome, Outcome::Fault(_, _, p) if p == phase)
                    })
                    .count();
                let _ = write!(s, " {k} |");
            }
            s.push('\n');
        }
    }
    s.push('\n');
    Ok(s)
}

/// Replaces the section in `doc` (up to the next `## ` title), or puts it after the single
/// family's.
pub fn replace_section(doc: &str, section: &str) -> String {
    let at = family::section_span(doc, TITLE)
        .or_else(|| family::section_span(doc, family::SECTION_TITLE).map(|(_, b)| (b, b)));
    match at {
        Some((a, b)) => format!("{}{section}{}", &doc[..a], &doc[b..]),
        None => format!("{}\n\n{section}", doc.trim_end_matches('\n')),
    }
}

/// The section of the `docs/PERFORMANCE.md` at hand, for `cargo xtask perf` to keep.
pub fn kept_section() -> String {
    let doc =
        std::fs::read_to_string(crate::root().join("docs/PERFORMANCE.md")).unwrap_or_default();
    family::section_span(&doc, TITLE).map_or(String::new(), |(a, b)| doc[a..b].to_owned())
}

/// Parses `A-B` (or one seed `A`).
pub fn parse_seeds(text: &str) -> Option<std::ops::RangeInclusive<u64>> {
    let (a, b) = text.split_once('-').unwrap_or((text, text));
    let (a, b): (u64, u64) = (a.trim().parse().ok()?, b.trim().parse().ok()?);
    (a <= b).then_some(a..=b)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_parse_and_the_section_goes_after_the_family() {
        assert_eq!(parse_seeds("1-30"), Some(1..=30));
        assert_eq!(parse_seeds("7"), Some(7..=7));
        assert_eq!(parse_seeds("9-2"), None);
        assert_eq!(parse_seeds("x"), None);
        let doc = "# P\n\n## Random motor family\n\nf\n\n## Instructions per call\n\nb\n";
        let first = replace_section(doc, &format!("{TITLE}\n\nx\n\n"));
        assert_eq!(
            first,
            format!(
                "# P\n\n## Random motor family\n\nf\n\n{TITLE}\n\nx\n\n## Instructions per call\n\nb\n"
            )
        );
        let second = replace_section(&first, &format!("{TITLE}\n\ny\n\n"));
        assert_eq!(second, first.replace("\nx\n", "\ny\n"));
    }
}
