//! Project automation.
//!
//! - `cargo xtask perf`: measures and rewrites `docs/PERFORMANCE.md` (accuracy of the
//!   fixed-point numerics against f64, speed of the plant model).
//! - `cargo xtask figures`: regenerates the paper figures under `docs/figures/`.
//! - `cargo xtask examples`: regenerates the generated example inputs under `examples/`.
//! - `cargo xtask sweep [N]`: N random healthy scenarios (default 200), none may fault.
//! - `cargo xtask family [N] [--seed S] [--estimator NAME]... [--control KEY=VALUE]... [--check]
//!   [--write]`: the drive with its defaults on N random motors (default 40); `--estimator`
//!   runs only the estimators named, `--control` adds a `[control]` key to every run (to
//!   measure an option against the defaults), `--check` fails below the bars, `--write`
//!   rewrites the section of `docs/PERFORMANCE.md`. `cargo xtask family [N] --seeds A-B
//!   [--write]`: the same on every seed from A to B, summed (its own section, which `perf`
//!   keeps). `cargo xtask family --published [--held-out | --file PATH] [--check] [--write]`:
//!   the motors of `examples/published/` (`published.rs`); `cargo xtask family [N] --widened
//!   [--seeds A-B] [--check] [--write]`: motors drawn from classes written from them.
//! - `cargo xtask robustness [R L PSI]`: prints the parameter-error table of
//!   `docs/PERFORMANCE.md` (tracking off and on) and the heating run, or one cell's details.
//! - `cargo xtask injection [N] [--seeds A-B] [--off]`: the high-frequency injection on the
//!   random family's interior motors at standstill and creeping under load (`injection.rs`).
//! - `cargo xtask web [--port N] [--no-build] [--no-serve]`: builds the workbench (the drive in
//!   WebAssembly and its page) and serves it on 127.0.0.1 (`web.rs`, docs/workbench.md).
//! - `cargo xtask map`: the operating map of motors A, B, C (figures and its section of
//!   `docs/PERFORMANCE.md`).
//! - `cargo xtask isr-profile [--write] [--lines] [--bench NAME]`: where the interrupt step's
//!   instructions go on the Cortex-M4 and the Cortex-M0, from QEMU's execution log
//!   (`isr_profile.rs`).

mod accuracy;
mod board;
mod cffi;
mod drive_motor_b;
mod examples;
mod family;
mod family_seeds;
mod identify_family;
mod injection;
mod isr_profile;
mod light_load;
mod map;
mod observers_motor_a;
mod pil;
mod plant_speed;
mod progress;
mod published;
mod robustness;
mod sweep;
mod web;

use anyhow::{Result, bail};
use rayon::prelude::*;
use std::path::PathBuf;

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("..")
}

fn main() -> Result<()> {
    let task = std::env::args().nth(1).unwrap_or_default();
    match task.as_str() {
        "perf" => perf(),
        "examples" => examples::write_all(&root().join("examples")),
        "figures" => {
            let dir = root().join("docs/figures");
            observers_motor_a::figures(&dir)?;
            drive_motor_b::figures(&dir)?;
            eprintln!("wrote the figures of both papers to {}", dir.display());
            Ok(())
        }
        "sweep" => {
            let n = std::env::args()
                .nth(2)
                .and_then(|x| x.parse().ok())
                .unwrap_or(200);
            sweep::run(n)
        }
        "map" => map::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "isr-profile" => isr_profile::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "family" => family::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "identify-family" => identify_family::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "robustness" => {
            let cell: Vec<f64> = std::env::args()
                .skip(2)
                .filter_map(|x| x.parse().ok())
                .collect();
            match cell[..] {
                [r, l, f] => robustness::one(r, l, f),
                [inverter_averaged] => {
                    let inverter = if inverter_averaged > 0.0 {
                        "averaged"
                    } else {
                        "switching"
                    };
                    let bar = progress::bar(2, format!("robustness: heating, {inverter}"));
                    let runs = [false, true]
                        .into_par_iter()
                        .map(|tracking| {
                            let run = robustness::heating(inverter, tracking);
                            bar.inc(1);
                            run
                        })
                        .collect::<Result<Vec<_>>>()?;
                    drop(bar);
                    for (tracking, (o, last)) in [false, true].into_iter().zip(runs) {
                        println!(
                            "heating, {inverter}, tracking {tracking}: {} R̂ {:.3} ψ̂ {:.4}",
                            o.cell(),
                            last[0],
                            last[1]
                        );
                    }
                    Ok(())
                }
                _ => {
                    print!("{}", robustness::section()?);
                    Ok(())
                }
            }
        }
        "light-load" => {
            print!(
                "{}",
                light_load::section(Some(&root().join("docs/figures")))?
            );
            Ok(())
        }
        "injection" => injection::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "web" => web::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "plant-speed" => {
            print!("{}", plant_speed::section()?);
            Ok(())
        }
        _ => bail!(
            "usage: cargo xtask perf | figures | examples | robustness [R L PSI] | light-load | plant-speed | sweep [N] | map | isr-profile [--write] [--lines] [--bench NAME] | {} | identify-family [N] [--seed S] | {} | {}",
            family::USAGE,
            injection::USAGE,
            web::USAGE
        ),
    }
}

/// A stage of `cargo xtask perf`: what it measures (none for a section kept as it is) and its
/// section.
type Stage = (&'static str, fn() -> Result<String>);

fn perf() -> Result<()> {
    let mut doc = String::new();
    doc.push_str(
        "# Performance\n\n\
         Regenerate with `cargo xtask perf` (release build, a few minutes on 2 cores). \
         Every figure below is measured by that command; none is typed by hand.\n\n",
    );
    let stages: [Stage; 15] = [
        ("measuring the accuracy of the fixed-point numerics", || {
            Ok(accuracy::section())
        }),
        (
            "running the estimators of Solsona, Valla, Muravchik (2000)",
            || Ok(observers_motor_a::section()),
        ),
        (
            "running the drive of Khlaief, Boussak, Gossa (2012)",
            drive_motor_b::section,
        ),
        ("motor B at light load", || {
            light_load::section(Some(&root().join("docs/figures")))
        }),
        ("robustness to parameter errors", robustness::section),
        // The operating map is `cargo xtask map`'s (a minute more): kept as it is.
        ("", || Ok(map::kept_section())),
        ("the drive on a random family of motors", || {
            let estimators = &family::ESTIMATORS;
            Ok(family::section(family::DOC_MOTORS, family::DEFAULT_SEED, estimators, &[])?.0)
        }),
        // The family on many seeds is `cargo xtask family 40 --seeds 1-30`'s (a quarter of an
        // hour): kept as it is.
        ("", || Ok(family_seeds::kept_section())),
        ("the drive on published motors", || {
            let (table, _) = published::section(published::MOTORS, &[])?;
            Ok(format!("{}\n\n{table}\n", published::SECTION_TITLE))
        }),
        ("the drive on the widened family", || {
            let (table, _) =
                published::widened_section(published::WIDENED_MOTORS, published::WIDENED_SEEDS)?;
            Ok(format!("{}\n\n{table}\n", published::WIDENED_TITLE))
        }),
        ("counting instructions in QEMU (scripts/pil.sh)", || {
            Ok(pil::section())
        }),
        // The interrupt step's profile is `cargo xtask isr-profile`'s (minutes of QEMU's
        // execution log): kept as it is.
        ("", || Ok(isr_profile::kept_section())),
        (
            "measuring the board firmware (scripts/firmware-size.sh)",
            || Ok(board::section()),
        ),
        ("measuring the C library (scripts/c-firmware.sh)", || {
            Ok(cffi::section())
        }),
        (
            "measuring the speed of the plant model",
            plant_speed::section,
        ),
    ];
    let bar = progress::bar(stages.len(), "perf");
    for (what, section) in stages {
        if !what.is_empty() {
            progress::eprintln(format_args!("{what} ..."));
            bar.set_message(format!("perf: {what}"));
        }
        doc.push_str(&section()?);
        bar.inc(1);
    }
    drop(bar);
    let path = root().join("docs/PERFORMANCE.md");
    std::fs::write(&path, doc)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
