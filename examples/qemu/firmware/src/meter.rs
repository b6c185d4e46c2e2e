//! Instruction counting with SysTick under `qemu-system-arm -icount shift=N`.
//!
//! With `-icount shift=N` QEMU advances its virtual clock by exactly 2^N ns per guest
//! instruction (every Thumb instruction counts one, whatever its cycle count on silicon), and
//! SysTick, clocked from the CPU clock of the board model (`CLKSOURCE = 1`), follows the
//! virtual clock: 25 MHz (40 ns per tick) on `mps2-an386`, 16 MHz (62.5 ns) on `microbit`.
//! Measured with `shift=0`, one tick is 40 instructions on `mps2-an386` and 62.5 on `microbit`
//! (2·10⁶ instructions read 50 000 resp. 32 000 ticks): too coarse for a per-call figure. The
//! runners use `shift=8`: 6.4 resp. 4.096 ticks per instruction.
//!
//! An interval of `n` instructions reads `T` ticks with `|T − k n| < 1` (`k` ticks per
//! instruction; tick boundaries fall anywhere), so `T / k` is within `1/k` of `n`, and with
//! `k > 2` rounding `T / k` gives `n` exactly.
//!
//! [`Meter::calibrate`] does not assume the clocks: it measures `k` from two busy loops of known
//! length (`subs; bne`: 2 instructions per iteration) that differ by 10⁶ instructions; it
//! measures the overhead of a measurement (an empty closure: the second SysTick read, the
//! indirect call, the closure's return), which must be the same 200 times out of 200; and it
//! checks that blocks of 1 to 1000 `nop`s measure exactly 1 to 1000 instructions, 50 times
//! each at varying phases of the tick, and across the wrap of the counter. Any failure stops
//! the run (`PIL <cpu> calibration exact=false`, exit status 1).
//!
//! The counter is the 24-bit SysTick with reload `2^24 − 1`, read before and after the call;
//! the difference modulo 2^24 handles a wrap. An interval must stay under 2^24 ticks: 2.6
//! million instructions at 6.4 ticks per instruction.

use core::arch::asm;
use core::hint::black_box;

use cortex_m::peripheral::SYST;
use cortex_m::peripheral::syst::SystClkSource;

/// SysTick current value register.
const SYST_CVR: u32 = 0xE000_E018;
/// SysTick counts modulo 2^24.
const MASK: u32 = 0x00FF_FFFF;

/// Starts SysTick free-running from the processor clock, reload 2^24 − 1, no interrupt.
pub fn start(mut syst: SYST) {
    syst.disable_interrupt();
    syst.set_clock_source(SystClkSource::Core);
    syst.set_reload(MASK);
    syst.clear_current();
    syst.enable_counter();
}

/// Reads SysTick's current value. An `asm!` block without `nomem`/`pure`: the compiler may not
/// move memory accesses or calls across it.
#[inline(always)]
fn now() -> u32 {
    let v: u32;
    // SAFETY: a 32-bit read of the SysTick CVR register, always present on ARMv6-M/ARMv7-M.
    unsafe {
        asm!("ldr {v}, [{a}]", v = out(reg) v, a = in(reg) SYST_CVR, options(nostack, preserves_flags))
    };
    v
}

/// Ticks elapsed over `f()`, including the measurement's own instructions. Never inlined,
/// called through `black_box`, so every measurement runs this same machine code.
#[inline(never)]
fn ticks(f: &mut dyn FnMut()) -> u32 {
    let t0 = now();
    f();
    let t1 = now();
    // SysTick counts down.
    t0.wrapping_sub(t1) & MASK
}

/// `n` iterations of a two-instruction loop (`subs; bne`): `2 n` instructions, plus the
/// set-up that is the same for every `n`.
#[inline(always)]
fn spin(n: u32) {
    // SAFETY: register-only loop; r0 is declared clobbered.
    unsafe { asm!("1:", "subs r0, r0, #1", "bne 1b", inout("r0") n => _, options(nomem, nostack)) };
}

/// `N` `nop` instructions.
#[inline(always)]
fn nops<const N: usize>() {
    // SAFETY: no-ops.
    unsafe {
        asm!(".rept {n}", "nop", ".endr", n = const N, options(nomem, nostack, preserves_flags))
    };
}

/// Why the calibration failed.
#[derive(Clone, Copy, Debug)]
pub enum CalibrationError {
    /// Fewer than 2 ticks per instruction: counts are not exact (raise `-icount shift`).
    Coarse {
        /// Ticks over the reference interval.
        ticks: u64,
        /// Instructions of the reference interval.
        insn: u64,
    },
    /// Repeated empty measurements disagree.
    Overhead {
        /// Smallest overhead seen, instructions.
        min: u32,
        /// Largest.
        max: u32,
    },
    /// A block of 1000 nops across the wrap of SysTick measured `got` instructions.
    Wrap {
        /// Instructions measured.
        got: u32,
    },
    /// A block of `expected` nops measured `got` instructions.
    Nops {
        /// Instructions in the block.
        expected: u32,
        /// Instructions measured.
        got: u32,
    },
}

impl core::fmt::Display for CalibrationError {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        match *self {
            Self::Coarse { ticks, insn } => write!(
                f,
                "{ticks} ticks over {insn} instructions: under 2 ticks per instruction, raise -icount shift"
            ),
            Self::Overhead { min, max } => {
                write!(
                    f,
                    "measurement overhead varies from {min} to {max} instructions"
                )
            }
            Self::Wrap { got } => {
                write!(
                    f,
                    "1000 nops across the SysTick wrap measured {got} instructions"
                )
            }
            Self::Nops { expected, got } => {
                write!(f, "a block of {expected} nops measured {got} instructions")
            }
        }
    }
}

/// Converts tick counts into instruction counts, net of the measurement overhead.
#[derive(Clone, Copy, Debug)]
pub struct Meter {
    /// Ticks over the reference interval ([`Meter::ref_insn`] instructions).
    pub ref_ticks: u64,
    /// Instructions of the reference interval.
    pub ref_insn: u64,
    /// Instructions of an empty measurement, subtracted from every figure.
    pub overhead: u32,
}

/// Iterations difference of the two reference loops: 10⁶ instructions.
const REF_ITERATIONS: u32 = 500_000;

impl Meter {
    /// Measures ticks per instruction and the overhead, and checks exactness (module docs).
    pub fn calibrate() -> Result<Self, CalibrationError> {
        let short = black_box(1_000u32);
        let long = black_box(1_000u32 + REF_ITERATIONS);
        let t_short = ticks(black_box(&mut || spin(short)));
        let t_long = ticks(black_box(&mut || spin(long)));
        let mut meter = Self {
            ref_ticks: u64::from(t_long.wrapping_sub(t_short) & MASK),
            ref_insn: 2 * u64::from(REF_ITERATIONS),
            overhead: 0,
        };
        if meter.ref_ticks < 2 * meter.ref_insn {
            return Err(CalibrationError::Coarse {
                ticks: meter.ref_ticks,
                insn: meter.ref_insn,
            });
        }
        let (mut min, mut max) = (u32::MAX, 0);
        for _ in 0..200 {
            let n = meter.raw(&mut || {});
            min = min.min(n);
            max = max.max(n);
        }
        if min != max {
            return Err(CalibrationError::Overhead { min, max });
        }
        meter.overhead = min;
        meter.check::<1>()?;
        meter.check::<2>()?;
        meter.check::<3>()?;
        meter.check::<5>()?;
        meter.check::<8>()?;
        meter.check::<13>()?;
        meter.check::<100>()?;
        meter.check::<1000>()?;
        // Across the wrap of the counter: start just before it reaches 0.
        for _ in 0..3 {
            while !(2_000..4_000).contains(&now()) {}
            let got = meter.insn(&mut || nops::<1000>());
            if got != 1000 {
                return Err(CalibrationError::Wrap { got });
            }
        }
        Ok(meter)
    }

    /// Measures `N` nops 50 times (at varying phases of the tick): each must give `N`.
    fn check<const N: usize>(&self) -> Result<(), CalibrationError> {
        for _ in 0..50 {
            let got = self.insn(&mut || nops::<N>());
            if got != N as u32 {
                return Err(CalibrationError::Nops {
                    expected: N as u32,
                    got,
                });
            }
        }
        Ok(())
    }

    /// Ticks per instruction × 10⁶ (for the report).
    pub fn ticks_per_insn_e6(&self) -> u64 {
        (self.ref_ticks * 1_000_000 + self.ref_insn / 2) / self.ref_insn
    }

    /// Instructions of `f()` including the measurement overhead.
    fn raw(&self, f: &mut dyn FnMut()) -> u32 {
        let t = u64::from(ticks(black_box(f)));
        // round(t · insn / ticks)
        ((2 * t * self.ref_insn + self.ref_ticks) / (2 * self.ref_ticks)) as u32
    }

    /// Instructions executed by `f()` net of an empty closure: what the closure does beyond
    /// an empty function's frame-pointer `push`/`mov`/`pop` (loading what it reads, the calls
    /// it makes, storing what it writes, saving the registers it uses). The overhead
    /// subtracted is the empty closure's, the indirect call and the second SysTick read.
    pub fn insn(&self, f: &mut dyn FnMut()) -> u32 {
        self.raw(f).saturating_sub(self.overhead)
    }
}
