//! Unit tests of `num`.

use super::gain::shr_low_word_by_words;
use super::wide::{dot_q14, dot_q14_halves, umul_halves, wmul_halves};
use super::*;
use proptest::prelude::*;

fn to_f64(x: Pu) -> f64 {
    x.to_bits() as f64 / (1u64 << PU_FRAC) as f64
}

#[test]
fn rounding_is_to_nearest() {
    // 1.5 LSB rounds up to 2, -1.5 LSB to -1 (ties toward +inf), 1.49 down.
    assert_eq!(round_shift_sat(3, 1), 2);
    assert_eq!(round_shift_sat(-3, 1), -1);
    assert_eq!(round_shift_sat(0b1011, 2), 3);
    assert_eq!(round_shift_sat(0b1001, 2), 2);
}

/// `x` at the rail `rail` within the low bits a saturation by `shift` lets pass
/// ([`round_shift_sat`]: `2^(32−shift) − 1` LSB for shifts 16..=31).
fn at_rail(x: Pu, rail: Pu, shift: u32) -> bool {
    (x.to_bits() as i64 - rail.to_bits() as i64).abs() < 1 << (32 - shift)
}

#[test]
fn products_saturate_instead_of_wrapping() {
    let big = Pu::from_num(100);
    assert!(at_rail(mul(big, big), Pu::MAX, PU_FRAC));
    assert!(at_rail(mul(big, -big), Pu::MIN, PU_FRAC));
    assert!(at_rail(
        mul_unit(Pu::MIN, Unit::from_bits(i32::MIN)),
        Pu::MAX,
        UNIT_FRAC
    ));
    assert_eq!(pu_from_f64(1e9), Pu::MAX);
    assert_eq!(pu_from_f64(-1e9), Pu::MIN);
    assert_eq!(pu_from_f64(f64::NAN), Pu::ZERO);
}

/// At the extremes of both factors and every shift, a gain's product is the rounding of the
/// exact one ([`round_shift_sat`]).
#[test]
fn gain_products_at_the_extremes() {
    let edges = [
        i32::MIN,
        i32::MIN + 1,
        -(1 << 30),
        -3,
        -1,
        0,
        1,
        3,
        1 << 30,
        i32::MAX,
    ];
    for shift in 1..=62 {
        for m in edges {
            for x in edges {
                let want = round_shift_sat(x as i64 * m as i64, shift);
                assert_eq!(
                    Gain::from_raw(m, shift).apply_bits(x),
                    want,
                    "{m} {x} {shift}"
                );
            }
        }
    }
}

/// The low word of a 64-bit shift by 1 to 32, from the two words (ARMv6-M's form), is the
/// shift's, for words at the extremes and every shift.
#[test]
fn the_low_word_of_a_shift_from_the_two_words() {
    let words = [i32::MIN, -(1 << 30) - 7, -1, 0, 1, 0x1234_5678, i32::MAX];
    for s in 1..=32 {
        for hi in words {
            for lo in words {
                let q = ((hi as i64) << 32) | lo as u32 as i64;
                assert_eq!(
                    shr_low_word_by_words(q, hi, s),
                    (q >> s) as i32,
                    "{hi:#x} {lo:#x} {s}"
                );
            }
        }
    }
}

#[test]
fn gains_keep_thirty_bits_across_decades() {
    for v in [
        1e-9, -3.7e-6, 0.001234, 0.5, -1.0, 3.0, 268.4, 16384.0, -1e9,
    ] {
        let g = Gain::new(v).unwrap();
        assert!(((g.to_f64() - v) / v).abs() < 1e-9, "{v}");
    }
    assert_eq!(Gain::new(0.0), Some(Gain::ZERO));
    assert_eq!(Gain::new(f64::NAN), None);
    assert_eq!(Gain::new(1e10), None);
    assert_eq!(Gain::new(1e-10), None);
    assert!(at_rail(
        Gain::new(1e6).unwrap().apply(Pu::from_num(1)),
        Pu::MAX,
        16
    ));
}

fn round_shift_reference(x: i64, shift: u32) -> i32 {
    let r = (x as i128 + (1i128 << (shift - 1))) >> shift;
    r.clamp(i32::MIN as i128, i32::MAX as i128) as i32
}

/// [`round_shift_sat`] against the exact rounding: equal inside the `i32` range; beyond it, at
/// the rail passed, exactly for shifts below 16 or above 31, else within `2^(32−shift) − 1`.
fn check_round_shift(x: i64, shift: u32) -> Result<(), (i32, i32, i64)> {
    let got = round_shift_sat(x, shift);
    let want = round_shift_reference(x, shift);
    let exact = (x as i128 + (1i128 << (shift - 1))) >> shift;
    let inside = (i32::MIN as i128..=i32::MAX as i128).contains(&exact);
    let slack = if inside || !(16..=31).contains(&shift) {
        0
    } else {
        (1i64 << (32 - shift)) - 1
    };
    if (got as i64 - want as i64).abs() <= slack {
        Ok(())
    } else {
        Err((got, want, slack))
    }
}

#[test]
fn round_shift_at_the_corners() {
    let lim = i64::MAX - (1i64 << 32) + 1;
    for shift in [1, 2, 15, 16, 17, 23, 24, 30, 31, 32, 33, 48, 62] {
        for x in [
            0,
            1,
            -1,
            lim,
            -lim,
            1 << 62,
            -(1 << 62),
            i32::MAX as i64,
            i32::MIN as i64,
        ] {
            assert_eq!(check_round_shift(x, shift), Ok(()), "{x} >> {shift}");
        }
        let edge = (i32::MAX as i64) << shift;
        for x in [edge - 1, edge, edge + 1, -edge - 1, -edge, -edge + 1] {
            assert_eq!(check_round_shift(x, shift), Ok(()), "{x} >> {shift}");
        }
    }
}

#[test]
fn coefs_reject_what_they_cannot_hold() {
    assert_eq!(
        Coef::<30>::new(1.999_999_999).map(|c| c.bits()),
        Some(i32::MAX)
    );
    assert_eq!(Coef::<30>::new(2.0), None);
    assert_eq!(Coef::<30>::new(-2.0).map(|c| c.bits()), Some(i32::MIN));
    assert_eq!(Coef::<24>::new(f64::NAN), None);
    assert!(at_rail(
        Coef::<24>::new(100.0).unwrap().apply(Pu::from_num(2)),
        Pu::MAX,
        24
    ));
    assert!((Coef::<30>::limit() - 2.0).abs() < 1e-12);
}

/// The product proptest found just inside Pu's range (−127.90000004): rounded, not saturated.
#[test]
fn mul_just_inside_the_range_is_rounded() {
    let (a, b) = (Pu::from_bits(22_919_686), Pu::from_bits(-1_570_730_486));
    let exact = to_f64(a) * to_f64(b);
    assert!((to_f64(mul(a, b)) - exact).abs() <= 0.5 / (1u64 << PU_FRAC) as f64);
}

/// The Cortex-M0's wide products at the edges of the halves: every pair of operands at and
/// around zero, ±2¹⁵, ±2¹⁶, ±2³¹ ∓ 2¹⁵ and the ends of the range (a balanced high half of
/// 2¹⁵ where the low half is negative, near `i32::MAX`).
#[test]
fn wide_multiply_from_halves_is_exact_at_the_edges() {
    extern crate std;
    let mut edges = std::vec::Vec::new();
    for c in [0i64, 1 << 15, 1 << 16, (1 << 31) - (1 << 15), 1 << 31] {
        for d in -2i64..=2 {
            for x in [c + d, -(c + d)] {
                if let Ok(x) = i32::try_from(x) {
                    edges.push(x);
                }
            }
        }
    }
    for &a in &edges {
        for &b in &edges {
            let exact = a as i64 * b as i64;
            assert_eq!(wmul_halves(a, b), exact, "{a} {b}");
            for (u, v) in [
                (1 << 14, 0),
                (-(1 << 14), 1),
                (23_170, -23_170),
                (-32_767, 32_767),
                (32_767, 0),
                (-32_768, 32_767),
            ] {
                let exact = round_shift_sat((a as i64 * u as i64 + b as i64 * v as i64) << 16, 30);
                assert_eq!(
                    dot_q14_halves(a, u << 16 | 0xffff, b, v << 16),
                    exact,
                    "{a} {b} {u} {v}"
                );
            }
            assert_eq!(
                umul_halves(a as u32, b as u32),
                a as u32 as u64 * b as u32 as u64
            );
        }
    }
}

proptest! {
    #[test]
    fn reciprocal_within_half_lsb_and_two_ulp(d in 1i32..=i32::MAX, x in any::<i32>()) {
        // The contract: |x| ≤ d.
        let x = (x as i64 % (d as i64 + 1)) as i32;
        let exact = x as f64 * (1u64 << 30) as f64 / d as f64;
        for r in [Reciprocal::of(d), Reciprocal::from_f64(d as f64).unwrap()] {
            let got = r.fraction(x) as f64;
            // 2⁻³⁰ relative from the mantissa, half an LSB from the rounding.
            prop_assert!((got - exact).abs() <= 0.5 + exact.abs() * 2e-9, "{} {}", got, exact);
        }
    }

    #[test]
    fn reciprocal_of_fractional_divisors(d in 1.0f64..1e9, x in -1.0f64..1.0) {
        let r = Reciprocal::from_f64(d).unwrap();
        let xi = libm::round(x * d) as i32;
        let exact = xi as f64 * (1u64 << 30) as f64 / d;
        let got = r.fraction(xi) as f64;
        prop_assert!((got - exact).abs() <= 0.5 + exact.abs() * 2e-9, "{} {}", got, exact);
        // Q4.28: within one LSB.
        let got = r.fraction_q28(xi) as f64;
        prop_assert!((got - exact / 4.0).abs() <= 1.0, "{} {}", got, exact / 4.0);
    }

    #[test]
    fn round_shift_matches_exact_rounding(
        x in -(i64::MAX - (1i64 << 32) + 1)..=(i64::MAX - (1i64 << 32) + 1),
        shift in 1u32..=62,
    ) {
        prop_assert!(check_round_shift(x, shift).is_ok(), "{:?}", check_round_shift(x, shift));
    }

    /// The Cortex-M0's path (a test of the high word, `p >> shift` when it is all sign) and
    /// the clamp give the same bits whenever the result fits.
    #[test]
    fn clamp_join_is_the_shift_when_it_fits(x in any::<i64>(), shift in 16u32..=31) {
        let hi = (x >> 32) as i32;
        if (hi >> (shift - 1)) == (hi >> 31) {
            prop_assert_eq!(join_clamped(x, shift), (x >> shift) as i32);
        }
    }

    #[test]
    fn coef_within_half_lsb(v in -100.0f64..100.0, x in any::<i32>()) {
        let c = Coef::<24>::new(v).unwrap();
        prop_assert!((c.to_f64() - v).abs() <= 0.5 / (1u64 << 24) as f64);
        let exact = x as f64 * c.to_f64();
        let got = c.apply_bits(x) as f64;
        if exact.abs() < 2.147e9 {
            prop_assert!((got - exact).abs() <= 0.5);
        } else if exact.abs() > 2.1475e9 {
            let rail = if exact > 0.0 { Pu::MAX } else { Pu::MIN };
            prop_assert!(at_rail(Pu::from_bits(c.apply_bits(x)), rail, 24));
        }
    }

    #[test]
    fn wide_multiply_from_halves_is_exact(a in any::<i32>(), b in any::<i32>()) {
        prop_assert_eq!(wmul_halves(a, b), a as i64 * b as i64);
        prop_assert_eq!(wmul(a, b), a as i64 * b as i64);
        prop_assert_eq!(wmul_inline(a, b), a as i64 * b as i64);
        let (ua, ub) = (a as u32, b as u32);
        prop_assert_eq!(umul_halves(ua, ub), ua as u64 * ub as u64);
        prop_assert_eq!(umul(ua, ub), ua as u64 * ub as u64);
    }

    /// The Cortex-M0's dot product of 32×16 products is the exact one of `u`, `v` taken down
    /// to 2⁻¹⁴, rounded and saturated, for every `a`, `b` and every `u`, `v` of the contract
    /// (`|u| + |v| < 2` once so taken).
    #[test]
    fn dot_q14_from_halves_is_exact(
        a in any::<i32>(),
        b in any::<i32>(),
        u in any::<i32>(),
        f in 0.0f64..1.0,
        low in any::<u16>(),
    ) {
        let uh = (u >> 16).max(-(1 << 15) + 1);
        let room = (1i32 << 16) - 1 - uh.abs();
        let vh = ((room as f64 * (2.0 * f - 1.0)) as i32).clamp(-(1 << 15), (1 << 15) - 1);
        let (u, v) = (uh << 16 | (u & 0xffff), vh << 16 | i32::from(low));
        let exact = round_shift_sat((a as i64 * uh as i64 + b as i64 * vh as i64) << 16, 30);
        prop_assert_eq!(dot_q14_halves(a, u, b, v), exact);
        let (u, v) = (uh << 16, vh << 16);
        prop_assert_eq!(dot_q14(a, u, b, v), exact);
        prop_assert_eq!(dot_q14_halves(a, u, b, v), exact);
    }

    #[test]
    fn coarse_fraction_is_never_short(d in 1i32..=i32::MAX, f in 0.0f64..=1.0) {
        let x = (d as f64 * f) as i32;
        let exact = x as f64 / d as f64 * 65536.0;
        let got = Reciprocal::of(d).fraction_q16_up(x) as f64;
        // The reciprocal's own rounding (2 ulp of its 31 bits) is far below a unit here.
        prop_assert!(got >= exact - 1e-6 && got <= exact + 6.0, "{} {}", got, exact);
    }

    #[test]
    fn small_factor_product_from_halves_is_exact(x in any::<i32>(), c in 0u32..(1 << 16)) {
        let exact = ((x as i64 * c as i64) >> 16) as i32;
        prop_assert_eq!(mul_u16_halves(x, c), exact);
        prop_assert_eq!(mul_u16(x, c), exact);
        prop_assert_eq!(mul_q19(x, c), ((x as i64 * c as i64) >> 19) as i32);
    }

    #[test]
    fn gain_products_are_the_rounding_of_the_exact_product(
        m in any::<i32>(),
        shift in 1u32..=62,
        x in any::<i32>(),
    ) {
        let g = Gain::from_raw(m, shift);
        prop_assert_eq!(g.apply_bits(x), round_shift_sat(x as i64 * m as i64, shift));
    }

    #[test]
    fn gain_within_half_lsb_plus_relative(v in -1e4f64..1e4, x in any::<i32>()) {
        let g = Gain::new(v).unwrap();
        let exact = x as f64 * g.to_f64();
        let got = g.apply_bits(x) as f64;
        if exact.abs() < 2.1e9 {
            prop_assert!((got - exact).abs() <= 0.5 + 1e-9);
        }
    }

    #[test]
    fn mul_within_half_lsb_of_exact(a in any::<i32>(), b in any::<i32>()) {
        let (a, b) = (Pu::from_bits(a), Pu::from_bits(b));
        let exact = to_f64(a) * to_f64(b);
        let got = mul(a, b);
        // Within Pu's range (to MAX = 128 − 2⁻²⁴, MIN = −128) the product is rounded, beyond
        // it saturated: a product of −127.90000004 is representable, not saturated.
        if to_f64(Pu::MIN) <= exact && exact <= to_f64(Pu::MAX) {
            prop_assert!((to_f64(got) - exact).abs() <= 0.5 / (1u64 << PU_FRAC) as f64);
        } else {
            let rail = if exact > 0.0 { Pu::MAX } else { Pu::MIN };
            prop_assert!(at_rail(got, rail, PU_FRAC));
        }
    }
}

/// The logarithms from the bits agree with the library's `round(log2 x)` and
/// `ceil(log2 x)` (the f64 reference) over fifty decades, powers of two and their
/// neighbours included.
#[test]
fn log2_from_the_bits_matches_the_library() {
    let mut x = 1e-20;
    let mut n = 0;
    while x < 1e30 {
        for y in [x, libm::ldexp(1.0, libm::ilogb(x)), libm::nextafter(x, 0.0)] {
            assert_eq!(
                super::log2_round(y),
                libm::round(libm::log2(y)) as i32,
                "{y}"
            );
            assert_eq!(super::log2_ceil(y), libm::ceil(libm::log2(y)) as i32, "{y}");
            n += 1;
        }
        x *= 1.37;
    }
    assert!(n > 300, "{n}");
}

#[test]
fn small_factor_product_at_the_extremes() {
    for x in [
        i32::MIN,
        i32::MIN + 1,
        -1,
        0,
        1,
        i32::MAX - 1,
        i32::MAX,
        0x7fff_0000,
        -0x8000,
    ] {
        for c in [0u32, 1, 0x7fff, 0x8000, 0xfffe, 0xffff] {
            let exact = ((x as i64 * c as i64) >> 16) as i32;
            assert_eq!(mul_u16_halves(x, c), exact, "{x} {c}");
        }
    }
}
