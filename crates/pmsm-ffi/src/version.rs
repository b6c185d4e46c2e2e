//! The library's version, in the header and at run time: a firmware built against one
//! `pmsm.h` and linked with another `libpmsm_ffi.a` can tell (`pmsm_version() ==
//! PMSM_VERSION`). Semantic versioning of the crate: a change of `PMSM_VERSION_MAJOR` (or, while
//! it is 0, of `PMSM_VERSION_MINOR`) may change the C types and the drive images.
// `no_mangle` is an unsafe attribute: the one C symbol of this module.
#![allow(unsafe_code)]

/// Major part of the library's version (the crate's `CARGO_PKG_VERSION_MAJOR`).
pub const PMSM_VERSION_MAJOR: u32 = 0;
/// Minor part of the library's version.
pub const PMSM_VERSION_MINOR: u32 = 1;
/// Patch part of the library's version.
pub const PMSM_VERSION_PATCH: u32 = 0;
/// The version as one number, `major << 16 | minor << 8 | patch` (each part below 256), as
/// `pmsm_version()` returns it.
pub const PMSM_VERSION: u32 =
    (PMSM_VERSION_MAJOR << 16) | (PMSM_VERSION_MINOR << 8) | PMSM_VERSION_PATCH;

/// A decimal part of the crate's version, at compile time.
const fn parse(s: &str) -> u32 {
    let b = s.as_bytes();
    let mut i = 0;
    let mut n = 0;
    while i < b.len() {
        n = n * 10 + (b[i] - b'0') as u32;
        i += 1;
    }
    n
}

// The header's literals (cbindgen writes literals) are the crate's version.
const _: () = assert!(
    PMSM_VERSION_MAJOR == parse(env!("CARGO_PKG_VERSION_MAJOR"))
        && PMSM_VERSION_MINOR == parse(env!("CARGO_PKG_VERSION_MINOR"))
        && PMSM_VERSION_PATCH == parse(env!("CARGO_PKG_VERSION_PATCH"))
        && PMSM_VERSION_MINOR < 256
        && PMSM_VERSION_PATCH < 256,
    "PMSM_VERSION_* differ from the crate's version: update them (and regenerate pmsm.h)"
);

/// The version of the linked library, `major << 16 | minor << 8 | patch`: compare it with the
/// header's `PMSM_VERSION` at start-up. Callable from any context.
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_version() -> u32 {
    PMSM_VERSION
}
