//! Exact 32×32→64 products, as cheap as each core makes them.

/// `a · b` as the exact 64-bit product of two `i32`.
///
/// On cores with a 32×32→64 multiply (Cortex-M3/M4, x86) this is `a as i64 * b as i64`, one
/// `SMULL`. ARMv6-M (Cortex-M0/M0+) has only the 32×32→32 `MULS`, and the compiler turns an
/// `i64` product into a call to the general 64×64 `__aeabi_lmul`; there the product is built
/// from four 16×16 partial products, about half the instructions. Both give the same
/// bits (exact integer arithmetic; checked against the `i64` product in the tests). ARMv6-M
/// is recognised as the ARM architecture without 32-bit compare-and-swap atomics (Rust sets
/// no `target_feature` that tells the Thumb-1-only cores apart).
#[inline(always)]
pub(crate) fn wmul(a: i32, b: i32) -> i64 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        wmul_v6m(a, b)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        a as i64 * b as i64
    }
}

/// [`wmul_halves`] out of line: the micro:bit's flash is nearly full, and a call costs a few
/// instructions against the 20-odd of the product.
#[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
#[inline(never)]
fn wmul_v6m(a: i32, b: i32) -> i64 {
    wmul_halves(a, b)
}

/// `a · b` from 16-bit halves taken balanced: `a = a_h 2¹⁶ + a_l` with `a_l` the low half
/// sign-extended (`[−2¹⁵, 2¹⁵)`) and `a_h = (a − a_l)/2¹⁶` (`[−2¹⁵, 2¹⁵]`), formed as
/// `⌊a/2¹⁶⌋ − ⌊a_l/2¹⁶⌋` (plus one where `a_l` is negative: `a − a_l` itself leaves the `i32`
/// range for `a ≥ 2³¹ − 2¹⁵`, where `a_h = 2¹⁵`). Every partial
/// product is within ±2³⁰, and so is the middle sum within the `i32` range: `a_h b_l` reaches
/// 2³⁰ only at `a_h = b_l = −2¹⁵`, where `a_l ≥ 0` keeps `a_l b_h` below 2³⁰ − 2¹⁵ (the
/// negative side likewise). So the middle term needs no 64-bit sum of its own: a Cortex-M0
/// forms the product in 20-odd instructions without spilling.
#[inline(always)]
#[allow(dead_code)] // used on ARMv6-M only, and by the tests
pub(super) const fn wmul_halves(a: i32, b: i32) -> i64 {
    let (al, bl) = (a as i16 as i32, b as i16 as i32);
    let (ah, bh) = ((a >> 16) - (al >> 16), (b >> 16) - (bl >> 16));
    let mid = ah.wrapping_mul(bl).wrapping_add(al.wrapping_mul(bh));
    let ll = al.wrapping_mul(bl);
    // (a_h b_h 2³² + mid 2¹⁶) + a_l b_l by words: the high word of mid 2¹⁶ is mid >> 16.
    let (lo, carry) = ((mid as u32) << 16).overflowing_add(ll as u32);
    let hi = ah
        .wrapping_mul(bh)
        .wrapping_add(mid >> 16)
        .wrapping_add(ll >> 31)
        .wrapping_add(carry as i32);
    ((hi as i64) << 32) | lo as i64
}

/// [`wmul`], inlined on every core (the halves on ARMv6-M): for the few kernels called most
/// often per sample (sin/cos, Park), where the call is worth saving; elsewhere [`wmul`] keeps
/// the micro:bit's nearly full flash in budget.
#[inline(always)]
pub(crate) fn wmul_inline(a: i32, b: i32) -> i64 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        wmul_halves(a, b)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        a as i64 * b as i64
    }
}

/// `a · b` as the exact 64-bit product of two `u32` (`UMULL` on Cortex-M3/M4; four 16×16
/// partial products on ARMv6-M instead of the general `__aeabi_lmul`).
#[cfg(any(test, feature = "overmodulation"))]
#[inline(always)]
pub(crate) fn umul(a: u32, b: u32) -> u64 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        umul_v6m(a, b)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        a as u64 * b as u64
    }
}

#[cfg(all(
    target_arch = "arm",
    not(target_has_atomic = "32"),
    any(test, feature = "overmodulation")
))]
#[inline(never)]
fn umul_v6m(a: u32, b: u32) -> u64 {
    umul_halves(a, b)
}

/// `a · b` from unsigned 16-bit halves; the middle sum may carry into bit 32, so it is kept
/// in `u64`.
#[inline(always)]
#[allow(dead_code)] // used on ARMv6-M only, and by the tests
pub(super) const fn umul_halves(a: u32, b: u32) -> u64 {
    let (al, ah) = (a & 0xffff, a >> 16);
    let (bl, bh) = (b & 0xffff, b >> 16);
    let mid = (ah * bl) as u64 + (al * bh) as u64;
    (((ah * bh) as u64) << 32) + (mid << 16) + (al * bl) as u64
}

/// `a·u + b·v` rounded by 2³⁰ and saturated as [`super::round_shift_sat`] does, for `u`, `v`
/// on the 2⁻¹⁴ grid (Q2.30 bits whose low 16 are zero) with `|u| + |v| < 2` (a unit vector's
/// components, or those of any vector shorter than √2): the dot product of the transforms in
/// the current-model MRAS's frames ([`super::dot_frame`]).
///
/// A Cortex-M3/M4 forms it with `SMULL` and `SMLAL`. On ARMv6-M each product is two 16×16
/// ones ([`dot_q14_halves`]) instead of the four of [`wmul_halves`], with no 64-bit sum on
/// the common path. The same bits on every core (tests).
#[inline(always)]
pub(crate) fn dot_q14(a: i32, u: i32, b: i32, v: i32) -> i32 {
    #[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
    {
        dot_q14_halves(a, u, b, v)
    }
    #[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
    {
        super::round_shift_sat(a as i64 * u as i64 + b as i64 * v as i64, 30)
    }
}

/// [`dot_q14`] from 16-bit halves: `x = x_h 2¹⁶ + x_l` for `a` and `b`, balanced as in
/// [`wmul_halves`] (both halves within ±2¹⁵), and `u_h = u >> 16`, `v_h = v >> 16` with
/// `|u_h| + |v_h| < 2¹⁶`. The two sums of partial products, `hi` of the high halves and `lo`
/// of the low ones, are each below 2³¹ in magnitude, and the exact sum is
/// `hi 2³² + lo 2¹⁶`, so its rounding by 2³⁰ is `4 hi + ((lo + 2¹³) >> 14)`: 32-bit
/// arithmetic while `|hi| < 2²⁸` (results within ±2³⁰), the exact 64-bit rounding beyond.
#[inline(always)]
#[allow(dead_code)] // used on ARMv6-M only, and by the tests
pub(super) fn dot_q14_halves(a: i32, u: i32, b: i32, v: i32) -> i32 {
    let (u, v) = (u >> 16, v >> 16);
    let (al, bl) = (a as i16 as i32, b as i16 as i32);
    let (ah, bh) = ((a >> 16) - (al >> 16), (b >> 16) - (bl >> 16));
    let hi = ah.wrapping_mul(u).wrapping_add(bh.wrapping_mul(v));
    let lo = al.wrapping_mul(u).wrapping_add(bl.wrapping_mul(v));
    if hi.unsigned_abs() < 1 << 28 {
        (hi << 2) + (lo.wrapping_add(1 << 13) >> 14)
    } else {
        wide_dot_q14(hi, lo)
    }
}

/// [`dot_q14_halves`] beyond ±2³⁰: the exact sum rounded and saturated. Rare, so out of line.
#[cold]
#[inline(never)]
#[allow(dead_code)] // used on ARMv6-M only, and by the tests
fn wide_dot_q14(hi: i32, lo: i32) -> i32 {
    super::round_shift_sat(((hi as i64) << 32) + ((lo as i64) << 16), 30)
}
