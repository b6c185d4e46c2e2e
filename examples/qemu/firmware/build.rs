//! Selects the memory map of the QEMU machine of the target, names the CPU for the reports,
//! and points the firmware at the host's recording.
//!
//! - `thumbv7em-none-eabihf` → `mps2-an386` (Cortex-M4F), reported as `cortex-m4`;
//! - `thumbv6m-none-eabi` → `microbit` (nRF51, Cortex-M0), reported as `cortex-m0`.
//!
//! The recording (written by `pil-record`, see `host/`) is `$PIL_RECORDING`, by default
//! `examples/qemu/target/pil/recording.bin`; beside it, `loops.bin`, the digests of the host's
//! closed loops (`pmsm_pil::loops`).

use std::path::PathBuf;

fn main() {
    let target = std::env::var("TARGET").unwrap_or_default();
    let (memory, cpu) = match target.as_str() {
        "thumbv7em-none-eabihf" | "thumbv7em-none-eabi" => ("memory-mps2-an386.x", "cortex-m4"),
        "thumbv6m-none-eabi" => ("memory-microbit.x", "cortex-m0"),
        other => panic!(
            "pmsm-pil-firmware builds for thumbv7em-none-eabihf (mps2-an386) or \
             thumbv6m-none-eabi (microbit), not {other:?}"
        ),
    };
    let manifest = PathBuf::from(std::env::var("CARGO_MANIFEST_DIR").unwrap_or_default());
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap_or_default());
    std::fs::copy(manifest.join(memory), out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-env=PIL_CPU={cpu}");
    println!("cargo:rerun-if-changed={memory}");
    println!("cargo:rerun-if-changed=build.rs");

    println!("cargo:rerun-if-env-changed=PIL_RECORDING");
    let recording = std::env::var_os("PIL_RECORDING")
        .map(PathBuf::from)
        .unwrap_or_else(|| manifest.join("../target/pil/recording.bin"));
    let recording = std::fs::canonicalize(&recording).unwrap_or_else(|_| {
        panic!(
            "no PIL recording at {}: run `cargo run --release -p pmsm-pil-host` in examples/qemu \
             first (or scripts/pil.sh), or set PIL_RECORDING",
            recording.display()
        )
    });
    println!("cargo:rerun-if-changed={}", recording.display());
    println!("cargo:rustc-env=PIL_RECORDING_PATH={}", recording.display());
    let loops = recording.with_file_name("loops.bin");
    if !loops.exists() {
        panic!(
            "no closed-loop digests at {}: run `cargo run --release -p pmsm-pil-host` in \
             examples/qemu first (or scripts/pil.sh); it writes them beside the recording",
            loops.display()
        );
    }
    println!("cargo:rerun-if-changed={}", loops.display());
    println!("cargo:rustc-env=PIL_LOOPS_PATH={}", loops.display());
    let image = recording.with_file_name("drive_image.bin");
    if !image.exists() {
        panic!(
            "no drive image at {}: run `cargo run --release -p pmsm-pil-host` in examples/qemu \
             first (or scripts/pil.sh); it writes it beside the recording",
            image.display()
        );
    }
    println!("cargo:rerun-if-changed={}", image.display());
    println!("cargo:rustc-env=PIL_IMAGE_PATH={}", image.display());
}
