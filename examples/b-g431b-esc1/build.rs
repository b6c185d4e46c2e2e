//! Links the firmware for the STM32G431CB, the same from this folder and from the repository
//! root (`cargo firmware`): the memory map is the root's `memory.x` (the one copy), and the
//! linker arguments are given here, for this crate's binaries only, rather than as
//! `target.thumbv7em-none-eabihf.rustflags` in a `.cargo/config.toml`, which cargo would merge
//! into every other build for that target under the root (examples/qemu, the core).
use std::{env, fs, path::PathBuf};

fn main() {
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("CARGO_MANIFEST_DIR"));
    let memory = manifest.join("../../memory.x");
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("OUT_DIR"));
    fs::copy(&memory, out.join("memory.x")).expect("copy ../../memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    // cortex-m-rt's link.x (which INCLUDEs memory.x), defmt's symbols; --icf=all folds
    // identical functions (rust-lld). flip-link is not used (not installed in CI).
    for arg in ["-Tlink.x", "-Tdefmt.x", "--icf=all"] {
        println!("cargo:rustc-link-arg-bins={arg}");
    }
    println!("cargo:rerun-if-changed={}", memory.display());
    println!("cargo:rerun-if-changed=build.rs");
}
