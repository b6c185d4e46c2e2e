//! Project automation.
//!
//! - `cargo xtask perf`: measures and rewrites `docs/PERFORMANCE.md` (accuracy of the
//!   fixed-point numerics against f64, speed of the plant model).
//! - `cargo xtask figures`: regenerates the paper figures under `docs/figures/`.
//! - `cargo xtask examples`: regenerates the generated example inputs under `examples/`.
//! - `cargo xtask sweep [N]`: N random healthy scenarios (default 200), none may fault.
//! - `cargo xtask family [N] [--seed S] [--check] [--write]`: the drive with its defaults on
//!   N random motors (default 40); `--check` fails below the bars, `--write` rewrites the
//!   section of `docs/PERFORMANCE.md`.
//! - `cargo xtask robustness`: prints the parameter-error table of `docs/PERFORMANCE.md`.

mod accuracy;
mod board;
mod cffi;
mod drive_motor_b;
mod examples;
mod family;
mod observers_motor_a;
mod pil;
mod plant_speed;
mod sweep;

use anyhow::{Result, bail};
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
        "family" => family::main(&std::env::args().skip(2).collect::<Vec<_>>()),
        "robustness" => {
            print!("{}", drive_motor_b::robustness_section()?);
            Ok(())
        }
        _ => bail!(
            "usage: cargo xtask perf | figures | examples | robustness | sweep [N] | family [N] [--seed S] [--check] [--write]"
        ),
    }
}

fn perf() -> Result<()> {
    let mut doc = String::new();
    doc.push_str(
        "# Performance\n\n\
         Regenerate with `cargo xtask perf` (release build, a few minutes on 2 cores). \
         Every figure below is measured by that command; none is typed by hand.\n\n",
    );
    eprintln!("measuring the accuracy of the fixed-point numerics ...");
    doc.push_str(&accuracy::section());
    eprintln!("running the estimators of Solsona, Valla, Muravchik (2000) ...");
    doc.push_str(&observers_motor_a::section());
    eprintln!("running the drive of Khlaief, Boussak, Gossa (2012) ...");
    doc.push_str(&drive_motor_b::section()?);
    eprintln!("robustness to parameter errors ...");
    doc.push_str(&drive_motor_b::robustness_section()?);
    eprintln!("the drive on a random family of motors ...");
    doc.push_str(&family::section(family::DOC_MOTORS, family::DEFAULT_SEED)?.0);
    eprintln!("counting instructions in QEMU (scripts/pil.sh) ...");
    doc.push_str(&pil::section());
    eprintln!("measuring the board firmware (scripts/firmware-size.sh) ...");
    doc.push_str(&board::section());
    eprintln!("measuring the C library (scripts/c-firmware.sh) ...");
    doc.push_str(&cffi::section());
    eprintln!("measuring the speed of the plant model ...");
    doc.push_str(&plant_speed::section()?);
    let path = root().join("docs/PERFORMANCE.md");
    std::fs::write(&path, doc)?;
    eprintln!("wrote {}", path.display());
    Ok(())
}
