//! C ABI of the sensorless drive: a `no_std` static library (`libpmsm_ffi.a`) and its
//! generated header `include/pmsm.h`, for vendor C firmware.
//!
//! Only `#[repr(C)]` structs of integers and doubles, C enums as integers and one opaque
//! handle cross the boundary. The caller provides the storage of a drive (no allocation).
//! Every function checks its pointers for null and alignment and its integer codes for range,
//! and returns a [`pmsm_status_t`]; none panics.
//!
//! Units: configuration in SI doubles (once, at init); the per-sample [`pmsm_step`] is integer
//! only: currents and bus voltage as `int32_t` Q8.24 per unit (`2^24` = 1 pu), duties as Q2.30
//! fractions of the period (`2^30` = 1) and as timer compare values.
//!
//! Modules: `types` (the C types), `handle` (the opaque drive and the pointer checks), `drive`
//! (init, commands, step), `read` (state, estimate, telemetry, initial position, fault
//! record), `scale` (ADC conversions), `image` (drives built on the host, loaded without the
//! design code), `version` (the library's version), `convert` (C configuration and codes to
//! and from the core). The cargo features `mras-current`, `nlo`, `ao`, `mras-emf` (default:
//! all) select the estimators built in.
#![no_std]
#![allow(non_camel_case_types)]

// The host build (tests, the host static library) links std, which provides the panic
// handler; the bare-metal build brings its own, below.
#[cfg(not(target_os = "none"))]
extern crate std;

mod convert;
mod drive;
mod handle;
mod image;
mod read;
mod scale;
mod types;
mod version;

pub use convert::{fault_code, state_code};
pub use drive::*;
pub use handle::pmsm_drive_t;
pub use image::*;
pub use read::*;
pub use scale::*;
pub use types::*;
pub use version::*;

#[cfg(not(any(
    feature = "mras-current",
    feature = "nlo",
    feature = "ao",
    feature = "mras-emf"
)))]
compile_error!("pmsm-ffi needs at least one estimator feature: mras-current, nlo, ao, mras-emf");

/// The panic handler of the bare-metal static library. Nothing in the library panics on
/// purpose (the core has no panic paths on the control path and every argument is checked);
/// should one be reached, the CPU spins here with the PWM left to the firmware's watchdog or
/// break input. It is an internal lang item (`rust_begin_unwind`), not a C symbol: it cannot
/// clash with the firmware's `HardFault_Handler`, `abort` or the like. The thumb targets
/// compile with `panic = "abort"` (their target default), so no unwinding code is linked.
#[cfg(all(target_os = "none", not(test)))]
#[panic_handler]
fn panic(_info: &core::panic::PanicInfo) -> ! {
    loop {
        core::hint::spin_loop();
    }
}
