//! Designs the drive on the host and links the firmware for the STM32G431CB.
//!
//! The drive: `src/motor.rs`'s motor and inverter with `motor::options()`, designed here with
//! pmsm-core in double precision and written as its image (`DriveConfig::write_image`) to
//! `$OUT_DIR/drive_image.rs`, which the firmware loads at start (`DriveConfig::from_image`).
//! The firmware thus carries neither the design nor software floating point for it, and a
//! motor the drive cannot run fails the build, saying why.
//!
//! The link: the memory map is the root's `memory.x` (the one copy), and the linker arguments
//! are given here, for this crate's binaries only, rather than as
//! `target.thumbv7em-none-eabihf.rustflags` in a `.cargo/config.toml`, which cargo would merge
//! into every other build for that target under the root (examples/qemu, the core).
use pmsm_core::{DriveConfig, EstimatorKind};
use std::fmt::Write as _;
use std::{env, fs, path::PathBuf};

#[allow(dead_code)] // the firmware's constants: the design reads some
#[path = "src/motor.rs"]
mod motor;
#[allow(dead_code)]
#[path = "src/sensing.rs"]
mod sensing;

/// The image of `motor.rs`'s drive, as Rust source.
fn drive_image() -> String {
    let (m, inv) = (motor::motor(), motor::inverter());
    let config = DriveConfig::from_params(&m, &inv, f64::from(motor::PWM_HZ), motor::options())
        .unwrap_or_else(|e| {
            // The one estimator built in (Cargo.toml) must be the one the defaults choose for
            // the motor (`EstimatorKind::for_motor`): `nlo` for a surface motor, started by the
            // alignment; `mras-current` and `ipd` (its start) for an interior one.
            panic!(
                "src/motor.rs: the drive cannot be designed: {e}. The defaults drive this motor \
                 with {:?}: give pmsm-core its feature (`nlo` for a surface motor, \
                 `mras-current` and `ipd` for an interior one) under [dependencies] and \
                 [build-dependencies] in Cargo.toml (README.md, \"Size\")",
                EstimatorKind::for_motor(&m)
            )
        });
    let mut words = [0u32; DriveConfig::IMAGE_WORDS];
    config.write_image(&mut words);
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/// The drive of `src/motor.rs`, designed on the host by build.rs \
         ({:?}, {:?} start).\npub static DRIVE_IMAGE: [u32; {}] = [",
        config.design.estimator,
        config.design.startup,
        words.len()
    );
    for row in words.chunks(8) {
        s.push_str("   ");
        for w in row {
            let _ = write!(s, " {w:#010x},");
        }
        s.push('\n');
    }
    s.push_str("];\n");
    let _ = writeln!(
        s,
        "/// Its schema (`DriveConfig::IMAGE_SCHEMA` of the host's build).\n\
         pub const DRIVE_IMAGE_SCHEMA: u32 = {:#010x};",
        DriveConfig::IMAGE_SCHEMA
    );
    s
}

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::write(out.join("drive_image.rs"), drive_image()).expect("write drive_image.rs");
    let memory = manifest.join("../../memory.x");
    fs::copy(&memory, out.join("memory.x")).expect("copy ../../memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    // cortex-m-rt's link.x (which INCLUDEs memory.x), defmt's symbols; --icf=all folds
    // identical functions (rust-lld). flip-link is not used (not installed in CI).
    for arg in ["-Tlink.x", "-Tdefmt.x", "--icf=all"] {
        println!("cargo:rustc-link-arg-bins={arg}");
    }
    println!("cargo:rerun-if-changed={}", memory.display());
    for f in ["build.rs", "src/motor.rs", "src/sensing.rs"] {
        println!("cargo:rerun-if-changed={f}");
    }
}
