//! Peak stack use. cortex-m-rt's `paint-stack` feature fills the stack area (from the end of
//! the static data to the top of RAM) with [`PAINT`] before `main`; [`peak`] finds the lowest
//! word that is no longer paint. The stack grows down from the top of RAM with nothing below
//! it but the static data: an overflow faults (on the micro:bit, with 16 KiB of RAM, QEMU then
//! stops with "Lockup").

use cortex_m_rt::heap_start;

/// The value the stack is painted with (cortex-m-rt's `STACK_PAINT_VALUE`).
const PAINT: u32 = cortex_m_rt::STACK_PAINT_VALUE;

/// `(peak, size)`: the deepest stack use so far and the size of the stack area, bytes.
pub fn peak() -> (usize, usize) {
    unsafe extern "C" {
        static _stack_start: u32;
    }
    // SAFETY: only the address of the linker symbol is taken.
    let top = &raw const _stack_start as usize;
    let bottom = heap_start() as usize;
    let mut p = bottom;
    // SAFETY: [bottom, top) is RAM (the stack area), word-aligned (cortex-m-rt's link.x).
    while p < top && unsafe { core::ptr::read_volatile(p as *const u32) } == PAINT {
        p += 4;
    }
    (top - p, top - bottom)
}
