//! What the processor-in-the-loop host recorder and the QEMU firmware share, so that both run
//! literally the same code around `pmsm-core`:
//!
//! - [`setup`]: motor A (examples/motor-a.toml) on a 300 V bus at 20 kHz, its per-unit bases and the
//!   estimator configurations (built in `f64`, on the host and on the target alike);
//! - [`cases`]: the functions whose steps are recorded on the host and replayed on the target
//!   ([`cases::Case`]: a step maps a list of `i32` input words to a list of `i32` output
//!   words, the bits of the fixed-point values);
//! - [`format`]: the binary recording the host writes and the firmware embeds;
//! - [`loops`]: drives in a closed loop with a simple plant, run on both and compared by
//!   digest.
#![no_std]

pub mod cases;
pub mod format;
pub mod loops;
pub mod setup;
