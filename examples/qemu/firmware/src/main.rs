//! Processor-in-the-loop firmware: runs pmsm-core on an emulated Cortex-M4 (`mps2-an386`) or
//! Cortex-M0 (`microbit`) in `qemu-system-arm -icount shift=8`, and prints, through
//! semihosting:
//!
//! ```text
//! PIL <cpu> calibration ticks_per_insn=<x> overhead_insn=<n> exact=true
//! PIL <cpu> <component> insn_mean=<n> insn_max=<n>        (one line per component)
//! PIL <cpu> replay bit_exact=true steps=<n>
//! PIL cortex-m4 image bit_exact=true words=<n>
//! ```
//!
//! then exits QEMU with status 0 if the calibration is exact and the replay (and on the
//! Cortex-M4 the drive image) bit-exact, 1 otherwise. Lines starting with `#` are information.
//! See `examples/qemu/README.md`.
#![no_std]
#![no_main]

mod bench;
mod meter;
mod replay;
mod stack;

use cortex_m_rt::{ExceptionFrame, entry, exception};
use cortex_m_semihosting::{debug, hprintln};
use pmsm_pil::setup::Setup;

use crate::replay::{Invalid, Outcome};

/// `cortex-m4` or `cortex-m0` (from the target, see `build.rs`).
const CPU: &str = env!("PIL_CPU");

/// Configuration errors are not printed on the target: their messages format `f64`, which
/// would link 25 KiB of float formatting into the micro:bit's 256 KiB. The host recorder
/// builds the same configurations and prints the message.
const NO_FLOAT_FMT: &str = "run pil-record on the host for the message";

#[entry]
fn main() -> ! {
    let ok = run();
    let (peak, size) = stack::peak();
    hprintln!("# {CPU} stack: peak {peak} of {size} bytes");
    exit(ok)
}

fn run() -> bool {
    let Some(p) = cortex_m::Peripherals::take() else {
        hprintln!("# {CPU}: peripherals already taken");
        return false;
    };
    meter::start(p.SYST);
    let meter = match meter::Meter::calibrate() {
        Ok(m) => m,
        Err(e) => {
            hprintln!("PIL {CPU} calibration exact=false");
            hprintln!("# {CPU} calibration failed: {e}");
            return false;
        }
    };
    let k = meter.ticks_per_insn_e6();
    hprintln!(
        "PIL {CPU} calibration ticks_per_insn={}.{:06} overhead_insn={} exact=true",
        k / 1_000_000,
        k % 1_000_000,
        meter.overhead
    );
    hprintln!(
        "# {CPU} calibration: {} ticks over {} instructions; nop blocks of 1..1000 measure exactly",
        meter.ref_ticks,
        meter.ref_insn
    );
    if cfg!(feature = "injection") {
        return injection(&meter);
    }
    if cfg!(feature = "identify") {
        return identify(&meter);
    }
    memory_report();

    let setup = match Setup::motor_a() {
        Ok(s) => s,
        Err(_) => {
            hprintln!("# {CPU}: motor A set-up failed ({NO_FLOAT_FMT})");
            return false;
        }
    };

    let benches = bench::run_all(&meter, &setup, &mut |name, st| {
        hprintln!(
            "PIL {CPU} {name} insn_mean={} insn_max={}",
            st.mean(),
            st.max
        );
    });
    if benches.is_err() {
        hprintln!("# {CPU}: a benchmark configuration failed ({NO_FLOAT_FMT})");
        return false;
    }

    let outcome = replay::run(&setup, &mut |name, steps| {
        if pmsm_pil::cases::SKIPPED.contains(&name) {
            hprintln!("# {CPU} replay {name}: not built for this core");
        } else {
            hprintln!("# {CPU} replay {name}: {steps} steps bit-exact");
        }
        if name == "closed_loop" && steps > 0 {
            // The drive and the plant both ran here, and agree with the host's run.
            hprintln!(
                "PIL {CPU} closed_loop bit_exact=true steps={}",
                steps * pmsm_pil::cases::CLOSED_LOOP_CHUNK
            );
        }
    });
    let image = image_check();
    image
        & match outcome {
            Outcome::Exact { steps, cases } => {
                hprintln!("PIL {CPU} replay bit_exact=true steps={steps}");
                cases > 0
            }
            Outcome::Mismatch { steps, at } => {
                hprintln!(
                    "PIL {CPU} replay bit_exact=false steps={steps} case={} step={} output={} target={} host={}",
                    at.case,
                    at.step,
                    at.output,
                    at.target,
                    at.host
                );
                false
            }
            Outcome::Invalid { steps, reason } => {
                hprintln!("PIL {CPU} replay bit_exact=false steps={steps}");
                match reason {
                    Invalid::Format(e) => hprintln!("# {CPU} replay: recording: {e}"),
                    Invalid::Empty => hprintln!("# {CPU} replay: the recording has no cases"),
                    Invalid::UnknownCase(c) => hprintln!("# {CPU} replay: unknown case {c}"),
                    Invalid::Shape(c) => hprintln!("# {CPU} replay: case {c}: word counts differ"),
                    Invalid::Config(c) => {
                        hprintln!("# {CPU} replay: case {c}: configuration failed")
                    }
                    Invalid::Short(c) => hprintln!("# {CPU} replay: case {c}: ran short"),
                }
                false
            }
        }
}

/// The image of the `drive` case's configuration the host wrote (`pmsm-pil-host`, 32-bit
/// little-endian words, docs/image.md).
#[cfg(target_has_atomic = "32")]
static HOST_IMAGE: &[u8] = include_bytes!(env!("PIL_IMAGE_PATH"));

/// On the Cortex-M4 (the board's core): the host's image of the `drive` case's configuration
/// read here (`DriveConfig::from_image`) and written again, and this target's own design of
/// it written, word for word the host's: `PIL <cpu> image bit_exact=… words=…`. The
/// micro:bit's flash does not hold the image's code beside the recording: true there.
fn image_check() -> bool {
    #[cfg(target_has_atomic = "32")]
    {
        use pmsm_core::DriveConfig;
        const N: usize = DriveConfig::IMAGE_WORDS;
        let mut host = [0u32; N];
        let mut n = 0;
        for (w, b) in host.iter_mut().zip(HOST_IMAGE.chunks_exact(4)) {
            *w = u32::from_le_bytes([b[0], b[1], b[2], b[3]]);
            n += 1;
        }
        let (mut read, mut own) = ([0u32; N], [0u32; N]);
        let loaded = n == N && HOST_IMAGE.len() == 4 * N;
        let loaded = loaded
            && match DriveConfig::from_image(&host) {
                Ok(c) => {
                    c.write_image(&mut read);
                    true
                }
                Err(_) => false,
            };
        let designed = match pmsm_pil::cases::DriveCase::config() {
            Ok(c) => {
                c.write_image(&mut own);
                true
            }
            Err(_) => false,
        };
        let exact = loaded && designed && read == host && own == host;
        hprintln!("PIL {CPU} image bit_exact={exact} words={N}");
        if !exact {
            hprintln!(
                "# {CPU} image: host's {} bytes, read {loaded}, designed {designed}, read back {}, own design {}",
                HOST_IMAGE.len(),
                read == host,
                own == host
            );
        }
        exact
    }
    #[cfg(not(target_has_atomic = "32"))]
    true
}

/// The image of feature `identify`: the identification's benchmarks and the back-EMF
/// estimators' drives in a closed loop (no recording, no replay). Succeeds if the
/// identification identified its plant.
fn identify(meter: &meter::Meter) -> bool {
    let mut print = |name: &str, st: &bench::Stats| {
        hprintln!(
            "PIL {CPU} {name} insn_mean={} insn_max={}",
            st.mean(),
            st.max
        );
    };
    bench::run_estimators(meter, &mut print);
    if !motors(meter) {
        return false;
    }

    let mut ok = false;
    let run = bench::run_identify(meter, &mut print, &mut |end, samples| {
        // Relative errors in per mille of R, L_d, L_q, ψ, J when it identified the plant.
        hprintln!("# {CPU} identify: {end:?} after {samples} samples");
        ok = matches!(end, bench::IdentifyEnd::Identified(_));
    });
    if run.is_err() {
        hprintln!("# {CPU}: the identification's configuration failed ({NO_FLOAT_FMT})");
        return false;
    }
    ok
}

/// The digests of the host's closed loops (`pmsm_pil::loops::digest_file`).
static HOST_LOOPS: &[u8] = include_bytes!(env!("PIL_LOOPS_PATH"));

/// The closed loops of the low-inductance and the high-pole-count motor (in the image of
/// feature `identify`): their two steps measured, `PIL <cpu> loop_<name> bit_exact=… held=…`.
/// Succeeds if each loop computed the host's bits and held its rotor.
fn motors(meter: &meter::Meter) -> bool {
    let mut ok = true;
    let run = bench::run_motors(
        meter,
        HOST_LOOPS,
        &mut |side, name, st| {
            hprintln!(
                "PIL {CPU} {side}_{name} insn_mean={} insn_max={}",
                st.mean(),
                st.max
            );
        },
        &mut |m, end, exact| {
            let held = m.held(end);
            ok &= exact && held;
            // The angle error in milliradians, the speed in per mille of the reference.
            let mrad = (end.error.0 as i64 * 6_283_185 / (1i64 << 32) / 1000) as i32;
            hprintln!(
                "# {CPU} loop {}: state {}, angle off by {} mrad, digest {:#010x}",
                m.name,
                end.state,
                mrad,
                end.digest
            );
            hprintln!("PIL {CPU} loop_{} bit_exact={exact} held={held}", m.name);
        },
    );
    if run.is_err() {
        hprintln!("# {CPU}: a closed loop's configuration failed ({NO_FLOAT_FMT})");
        return false;
    }
    ok
}

/// The image of feature `injection`: motor B's drive with the high-frequency injection in a
/// closed loop (no recording, no replay). Succeeds if the drive could be built and run.
fn injection(meter: &meter::Meter) -> bool {
    #[cfg(feature = "injection")]
    {
        let mut ran = false;
        bench::run_injection(meter, &mut |name: &str, st: &bench::Stats| {
            ran = true;
            hprintln!(
                "PIL {CPU} {name} insn_mean={} insn_max={}",
                st.mean(),
                st.max
            );
        });
        ran
    }
    #[cfg(not(feature = "injection"))]
    {
        let _ = meter;
        false
    }
}

/// Flash and RAM used by this image (from the linker symbols of cortex-m-rt).
fn memory_report() {
    unsafe extern "C" {
        static __sidata: u8;
        static __sdata: u8;
        static __edata: u8;
        static __ebss: u8;
    }
    let addr = |s: &u8| s as *const u8 as usize;
    // SAFETY: only the addresses of the linker symbols are taken.
    let (sidata, sdata, edata, ebss) = unsafe {
        (
            addr(&__sidata),
            addr(&__sdata),
            addr(&__edata),
            addr(&__ebss),
        )
    };
    let flash = sidata + (edata - sdata); // FLASH starts at 0 on both machines
    hprintln!(
        "# {CPU} image: flash {} bytes (recording {}), static RAM {} bytes",
        flash,
        replay::recording_len(),
        ebss - sdata
    );
}

fn exit(ok: bool) -> ! {
    debug::exit(if ok {
        debug::EXIT_SUCCESS
    } else {
        debug::EXIT_FAILURE
    });
    // Not reached under QEMU; on a board without a debugger, stop here.
    loop {
        cortex_m::asm::bkpt();
    }
}

#[panic_handler]
fn panic(info: &core::panic::PanicInfo) -> ! {
    hprintln!("# {CPU} panic: {info}");
    exit(false)
}

#[exception]
unsafe fn HardFault(ef: &ExceptionFrame) -> ! {
    hprintln!("# {CPU} hard fault at pc={:#010x}", ef.pc());
    exit(false)
}
