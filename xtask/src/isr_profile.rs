//! `cargo xtask isr-profile [--write] [--lines] [--bench NAME]`: where the interrupt step's
//! instructions go, on both machines of `scripts/pil.sh` (`--lines`: also the source lines that
//! cost most; `--bench isr_nlo`, `isr_ao` or `isr_mras_emf`: a back-EMF estimator's drive, in
//! the image of feature `identify`, instead of the current-model MRAS's recorded run).
//!
//! The PIL firmware (`examples/qemu`, built as `scripts/pil.sh` builds it) runs in QEMU with
//! one instruction per translation block and the execution log on (`-singlestep -d
//! exec,nochain`, filtered to the core's code and the meter's), which names the address of
//! every instruction executed. Between the firmware's `profile_begin` and `profile_end` (the
//! `isr_mras_current` benchmark: motor B's recorded run, current-model MRAS) every call of
//! `DriveIsr::step` that updates the estimator (the closed loop, as the benchmark counts) is
//! followed from its entry to its return into the meter; each address is attributed, by the
//! chain of functions inlined at it (`addr2line -i`), to the outermost of them that names a
//! part of the step; an instruction of an out-of-line helper that names none (the Cortex-M0's
//! wide products) goes to the part of its call site, which the trace follows (a jump to a
//! function's first address is a call, a landing after a call site its return). The sum over
//! the parts is the step without the meter's overhead, so a little below `scripts/pil.sh`'s
//! mean. The steps that end a task period (they run `DriveIsr::end_period`) are also counted
//! apart from the others, and the most costly call that enters no mode (runs no
//! `DriveIsr::enter`: the benchmark counts the steps in `Run`, and the step that enters it is
//! not one) is attributed part by part beside the mean: the anatomy of the worst case the bars
//! are on.

use anyhow::{Context, Result, bail};
use std::collections::{BTreeMap, HashMap};
use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

mod elf;
use elf::{Frame, Sites, chains, symbols, trace_pc};

/// The section's title in docs/PERFORMANCE.md.
pub const TITLE: &str = "## Where the interrupt step's instructions go";

/// The parts of the step, each with the function names (substrings of the demangled names
/// `addr2line` gives) that belong to it, in the order they are matched.
const PARTS: [(&str, &[&str]); 8] = [
    (
        "estimator",
        &["as pmsm_core::observer::Estimator>::update", "AnyEstimator"],
    ),
    ("sin/cos (the estimator's next frame)", &["sin_cos"]),
    ("current loops", &["CurrentController"]),
    ("dead-time vector", &["deadtime_vector", "DeadTimeConfig"]),
    (
        "modulator (SVPWM, the estimator's voltage, delay line)",
        &["modulate", "svpwm::", "delayed"],
    ),
    (
        "Clarke, Park, mid-period frame",
        &[
            "frames::clarke",
            "frames::park",
            "inverse_park",
            "mid_frame",
        ],
    ),
    (
        "trips (overcurrent, bus, sum, overspeed)",
        &["protection", "overspeed"],
    ),
    (
        "the task's command and the window",
        &["end_period", "::take", "handoff::", "window"],
    ),
];

/// The rest: the phase dispatch, telemetry, the period's sums.
const REST: &str = "dispatch, telemetry, the period's sums";

/// The two machines: Rust target, QEMU's `-cpu` and `-machine`.
const MACHINES: [(&str, &str, &str); 2] = [
    ("thumbv7em-none-eabihf", "cortex-m4", "mps2-an386"),
    ("thumbv6m-none-eabi", "cortex-m0", "microbit"),
];

/// The benchmarks the profile follows, what each runs and its estimator: the default one's
/// (recorded, in the image with the recording) and the back-EMF estimators' (in the image of
/// feature `identify`).
const BENCHES: [(&str, &str, &str); 4] = [
    (
        "isr_mras_current",
        "motor B's recorded closed loop, current-model MRAS, defaults",
        "current-model MRAS",
    ),
    ("isr_nlo", "light motor A's closed loop with the NLO", "NLO"),
    ("isr_ao", "light motor A's closed loop with the AO", "AO"),
    (
        "isr_mras_emf",
        "light motor A's closed loop with the MRAS on the EMF",
        "MRAS on the EMF",
    ),
];

pub fn main(args: &[String]) -> Result<()> {
    let write = args.iter().any(|a| a == "--write");
    let lines = args.iter().any(|a| a == "--lines");
    let bench = match args.iter().position(|a| a == "--bench") {
        Some(k) => {
            let name = args.get(k + 1).map(String::as_str).unwrap_or("");
            BENCHES.iter().position(|b| b.0 == name).with_context(|| {
                let names: Vec<_> = BENCHES.iter().map(|b| b.0).collect();
                format!("--bench takes one of {}, not `{name}`", names.join(", "))
            })?
        }
        None => 0,
    };
    if write && bench != 0 {
        bail!("--write writes the section of {} only", BENCHES[0].0);
    }
    let (section, columns) = section(bench)?;
    print!("{section}");
    if lines {
        for (cpu, p) in &columns {
            println!("{cpu}: the lines of each part, instructions per call");
            let mut v: Vec<_> = p.lines.iter().collect();
            v.sort_by(|a, b| b.1.total_cmp(a.1));
            for ((part, at), n) in v.iter().take(60) {
                let part = label(part, bench);
                println!("{:7.1}  {part}: {at}", *n / p.calls as f64);
            }
        }
    }
    if write {
        crate::family::write_performance(|doc| crate::family::put_section(doc, TITLE, &section))?;
    }
    Ok(())
}

/// A part's name as benchmark `bench` shows it: the estimator's by the benchmark's estimator;
/// the back-EMF estimators' sin/cos are out of line, their own with the drive's.
fn label(name: &str, bench: usize) -> String {
    if name == PARTS[0].0 {
        format!("estimator ({})", BENCHES[bench].2)
    } else if name == PARTS[1].0 && bench != 0 {
        "sin/cos (out of line: the estimator's, the drive's)".to_owned()
    } else {
        name.to_owned()
    }
}

/// The section of `cargo xtask perf`'s document, kept as it is (`isr-profile --write`
/// writes it).
pub fn kept_section() -> String {
    let doc =
        std::fs::read_to_string(crate::root().join("docs/PERFORMANCE.md")).unwrap_or_default();
    crate::family::section_span(&doc, TITLE).map_or(String::new(), |(a, b)| doc[a..b].to_owned())
}

/// Builds, traces and attributes on both machines the benchmark `BENCHES[bench]`; the
/// markdown section and the profiles.
fn section(bench: usize) -> Result<(String, Vec<(&'static str, Profile)>)> {
    let qemu = crate::root().join("examples/qemu");
    let recording = recording(&qemu)?;
    let mut columns = Vec::new();
    for (target, cpu, machine) in MACHINES {
        eprintln!("isr-profile: {cpu}: building and tracing (a few minutes)");
        let elf = build(&qemu, target, &recording, bench)?;
        columns.push((cpu, profile(&elf, cpu, machine)?));
    }
    let (name, what, _) = BENCHES[bench];
    let mut s = format!(
        "{TITLE}\n\n`cargo xtask isr-profile --write` (the execution log of QEMU, one \
         instruction per block, over the `{name}` benchmark of `scripts/pil.sh`: {what}; \
         `--bench isr_nlo`, `isr_ao` or `isr_mras_emf` follows a back-EMF estimator's instead): \
         instructions per call of \
         `DriveIsr::step` in the closed loop, by part, each instruction counted in the outermost \
         function inlined at it that names a part (in an out-of-line helper that names none, a \
         wide product on the Cortex-M0, its caller's). Without the meter's overhead, so a little \
         below the benchmark's mean; beside it, the most costly call followed that enters no mode \
         (the benchmark's worst case). `--lines` lists \
         the source lines that cost most.\n\n| part | {0}, mean | {0}, worst step | {1}, mean | \
         {1}, worst step |\n|---|--:|--:|--:|--:|\n",
        columns[0].0, columns[1].0
    );
    let names = PARTS.iter().map(|p| p.0).chain([REST]);
    for name in names {
        let cell = |c: &Profile| c.parts.get(name).map_or(0.0, |n| n / c.calls as f64);
        let worst = |c: &Profile| c.worst.get(name).copied().unwrap_or(0.0);
        let label = label(name, bench);
        s += &format!(
            "| {label} | {:.0} | {:.0} | {:.0} | {:.0} |\n",
            cell(&columns[0].1),
            worst(&columns[0].1),
            cell(&columns[1].1),
            worst(&columns[1].1)
        );
    }
    let total = |c: &Profile| c.parts.values().sum::<f64>() / c.calls.max(1) as f64;
    let worst = |c: &Profile| c.worst.values().sum::<f64>();
    let ends = |c: &Profile| {
        if c.worst_ends {
            "ends a period"
        } else {
            "does not end a period"
        }
    };
    s += &format!(
        "| **total** | **{:.0}** | **{:.0}** | **{:.0}** | **{:.0}** |\n\nCalls followed: {} and \
         {}. The worst step {} on the {}, {} on the {}.\n\n",
        total(&columns[0].1),
        worst(&columns[0].1),
        total(&columns[1].1),
        worst(&columns[1].1),
        columns[0].1.calls,
        columns[1].1.calls,
        ends(&columns[0].1),
        columns[0].0,
        ends(&columns[1].1),
        columns[1].0,
    );
    fn mean((n, k): (u64, u64)) -> f64 {
        n as f64 / k.max(1) as f64
    }
    let (a, b) = (&columns[0].1, &columns[1].1);
    s += &format!(
        "By step: one in eight ends a task period and publishes the window there (the \
         bars are on the worst case).\n\n| step | {} | {} |\n|---|--:|--:|\n\
         | ends a task period, mean | {:.0} | {:.0} |\n\
         | the others, mean | {:.0} | {:.0} |\n\n",
        columns[0].0,
        columns[1].0,
        mean(a.period_end),
        mean(b.period_end),
        mean(a.others),
        mean(b.others),
    );
    Ok((s, columns))
}

/// The host's recording of the replay cases, written as `scripts/pil.sh` writes it.
fn recording(qemu: &Path) -> Result<PathBuf> {
    let out = qemu.join("target/pil");
    std::fs::create_dir_all(&out)?;
    let path = out.join("recording.bin");
    run(Command::new("cargo")
        .current_dir(qemu)
        .args([
            "run",
            "--release",
            "-q",
            "-p",
            "pmsm-pil-host",
            "--",
            "--output",
        ])
        .arg(&path))
    .context("the host recorder")?;
    Ok(path)
}

/// The PIL firmware for `target` that runs the benchmark `BENCHES[bench]` between the
/// profile's marks (the image with `recording` embedded, or that of feature `identify` built
/// with `PIL_PROFILE`); its ELF.
fn build(qemu: &Path, target: &str, recording: &Path, bench: usize) -> Result<PathBuf> {
    let mut cmd = Command::new("cargo");
    cmd.current_dir(qemu)
        .env("PIL_RECORDING", recording)
        .args(["build", "--release", "-q", "-p", "pmsm-pil-firmware"])
        .args(["--target", target]);
    // The default benchmark's marks are in the image as `scripts/pil.sh` builds it.
    if bench != 0 {
        cmd.env("PIL_PROFILE", BENCHES[bench].0)
            .args(["--features", "identify"]);
    }
    run(&mut cmd).with_context(|| format!("the firmware for {target}"))?;
    Ok(qemu.join("target").join(target).join("release/pil"))
}

fn run(cmd: &mut Command) -> Result<()> {
    let status = cmd.status()?;
    if !status.success() {
        bail!("{cmd:?} failed: {status}");
    }
    Ok(())
}

/// Instructions by part, summed over the calls followed, and by the source line of the
/// outermost function inlined at each address (in the step's own code).
#[derive(Default)]
struct Profile {
    calls: u64,
    /// Instructions and calls of the steps that end a task period (they publish the window),
    /// and of the others.
    period_end: (u64, u64),
    others: (u64, u64),
    parts: BTreeMap<&'static str, f64>,
    /// The most costly call followed that enters no mode: its parts, and whether it ended a
    /// task period.
    worst: BTreeMap<&'static str, f64>,
    worst_ends: bool,
    lines: BTreeMap<(&'static str, String), f64>,
}

/// Runs the firmware in QEMU with the execution log and attributes the calls followed.
fn profile(elf: &Path, cpu: &str, machine: &str) -> Result<Profile> {
    let sym = symbols(elf)?;
    let filter = format!(
        "{:#x}..{:#x},{:#x}..{:#x},{:#x}..{:#x},{:#x}..{:#x}",
        sym.core.0,
        sym.core.1 - 1,
        sym.meter.0,
        sym.meter.1 - 1,
        sym.begin,
        sym.begin + 1,
        sym.end,
        sym.end + 1
    );
    let mut child = Command::new("qemu-system-arm")
        .args(["-cpu", cpu, "-machine", machine, "-nographic"])
        .args([
            "-semihosting-config",
            "enable=on,target=native",
            "-icount",
            "shift=8",
        ])
        .args([
            "-singlestep",
            "-d",
            "exec,nochain",
            "-dfilter",
            &filter,
            "-kernel",
        ])
        .arg(elf)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .context("qemu-system-arm (apt-get install qemu-system-arm)")?;
    let log = BufReader::with_capacity(1 << 20, child.stderr.take().context("QEMU's log")?);
    // Per address and the call site of the out-of-line function it is in (the innermost
    // call not yet returned from, if any), the instructions of the calls followed.
    let mut counts: Counts = HashMap::new();
    let mut call: Counts = HashMap::new();
    let mut sites = Sites::default();
    let (mut window, mut inside, mut closed, mut ends) = (false, false, false, false);
    let mut enters = false;
    let (mut calls, mut last) = (0u64, 0u32);
    // The most costly call that enters no mode: its instructions, whether it ended a period,
    // its addresses.
    let mut worst: (u64, bool, Counts) = (0, false, HashMap::new());
    let (mut period_end, mut others) = ((0u64, 0u64), (0u64, 0u64));
    for line in log.split(b'\n') {
        let line = line?;
        let Some(pc) = trace_pc(&line) else {
            continue;
        };
        if pc == sym.begin {
            window = true;
        } else if pc == sym.end {
            window = false;
        }
        if window && !inside && pc == sym.step {
            inside = true;
            closed = false;
            ends = false;
            enters = false;
            call.clear();
            sites = Sites::default();
            last = pc;
        }
        if !inside {
            continue;
        }
        if (sym.meter.0..sym.meter.1).contains(&pc) {
            inside = false;
            if closed {
                calls += 1;
                let n: u64 = call.values().sum();
                let kind = if ends { &mut period_end } else { &mut others };
                *kind = (kind.0 + n, kind.1 + 1);
                if n > worst.0 && !enters {
                    worst = (n, ends, call.clone());
                }
                for (a, n) in call.drain() {
                    *counts.entry(a).or_default() += n;
                }
            }
            continue;
        }
        sites.follow(pc, last, pc != sym.step && sym.entries.contains(&pc));
        last = pc;
        closed |= sym.updates.iter().any(|(a, b)| (*a..*b).contains(&pc));
        ends |= sym.end_period.contains(&pc);
        enters |= sym.enter.contains(&pc);
        *call.entry((pc, sites.innermost())).or_default() += 1;
    }
    let status = child.wait()?;
    if !status.success() || calls == 0 {
        bail!(
            "QEMU's run of {} ended {status}, {calls} calls followed",
            elf.display()
        );
    }
    let mut profile = Profile {
        calls,
        period_end,
        others,
        worst_ends: worst.1,
        ..Profile::default()
    };
    let mut pcs: Vec<u32> = counts.keys().map(|k| k.0).collect();
    pcs.extend(counts.keys().filter_map(|k| k.1));
    pcs.sort_unstable();
    pcs.dedup();
    let chains: HashMap<u32, Vec<Frame>> = chains(elf, pcs.into_iter())?.into_iter().collect();
    let none = Vec::new();
    // An out-of-line helper (a wide product, a reciprocal) names no part: its caller's.
    let part_at = |pc: u32, site: Option<u32>| {
        let part = part_of(chains.get(&pc).unwrap_or(&none));
        match site {
            Some(site) if part == REST => part_of(chains.get(&site).unwrap_or(&none)),
            _ => part,
        }
    };
    for ((pc, site), n) in &worst.2 {
        *profile.worst.entry(part_at(*pc, *site)).or_default() += *n as f64;
    }
    for ((pc, site), n) in counts {
        let chain = chains.get(&pc).unwrap_or(&none);
        let part = part_at(pc, site);
        let n = n as f64;
        *profile.parts.entry(part).or_default() += n;
        // The chain of calls below the step (or the out-of-line function), outermost first:
        // each function's short name and the line in it, to three levels.
        let at = chain
            .iter()
            .rev()
            .skip(1)
            .take(3)
            .map(|f| {
                let short = f.name.rsplit("::").next().unwrap_or(&f.name);
                format!("{short}@{}", f.at)
            })
            .collect::<Vec<_>>()
            .join(" > ");
        *profile.lines.entry((part, at)).or_default() += n;
    }
    Ok(profile)
}

/// Instructions by executed address and the call site of the out-of-line function it is in.
type Counts = HashMap<(u32, Option<u32>), u64>;

/// The part of the outermost function of `chain` (innermost first) that names one.
fn part_of(chain: &[Frame]) -> &'static str {
    chain
        .iter()
        .rev()
        .find_map(|f| {
            PARTS
                .iter()
                .find(|(_, names)| names.iter().any(|n| f.name.contains(n)))
                .map(|p| p.0)
        })
        .unwrap_or(REST)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_trace_line_gives_its_address_and_a_chain_its_outermost_part() {
        let line = b"Trace 0: 0x7fa21458a780 [00800400/0000aef0/00000010/ff020201] _ZN9pmsm_core";
        assert_eq!(trace_pc(line), Some(0xaef0));
        assert_eq!(trace_pc(b"IN: foo"), None);
        let chain = |names: &[&str]| {
            names
                .iter()
                .map(|s| Frame {
                    name: s.to_string(),
                    at: String::new(),
                })
                .collect::<Vec<_>>()
        };
        // Innermost first: a saturating add inlined in the PI inlined in the current loops.
        assert_eq!(
            part_of(&chain(&[
                "<i32>::saturating_add",
                "pmsm_core::control::pi::Pi::finish",
                "pmsm_core::control::current::CurrentController::step_on",
                "pmsm_core::drive::isr::DriveIsr::sample",
            ])),
            "current loops"
        );
        assert_eq!(
            part_of(&chain(&["pmsm_core::drive::isr::DriveIsr::sample"])),
            REST
        );
    }

    #[test]
    fn call_sites_follow_calls_returns_and_tail_calls() {
        let mut s = Sites::default();
        // A `bl` at 0x100 to 0x500; inside it a tail call (`b`) at 0x510 to 0x600, which
        // returns straight to 0x104.
        s.follow(0x500, 0x100, true);
        assert_eq!(s.innermost(), Some(0x100));
        s.follow(0x502, 0x500, false);
        s.follow(0x600, 0x510, true);
        assert_eq!(s.innermost(), Some(0x510));
        s.follow(0x104, 0x620, false);
        assert_eq!(s.innermost(), None);
        // A `blx` (2 bytes) at 0x200 to 0x700, back at 0x202.
        s.follow(0x700, 0x200, true);
        s.follow(0x202, 0x708, false);
        assert_eq!(s.innermost(), None);
    }
}
