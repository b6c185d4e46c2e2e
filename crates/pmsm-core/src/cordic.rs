//! atan2 and vector magnitude without floating point or division: a short CORDIC in
//! vectoring mode, and the small angle it leaves taken from its tangent.
//!
//! The input vector is normalised so that its larger component lies in [2²⁸, 2²⁹) (a shift,
//! no precision is lost for small vectors), turned into the right half-plane, and rotated
//! toward the x axis by ±atan 2⁻ⁱ for i = 0..[`ITERATIONS`]. That leaves it within
//! atan 2⁻⁷ of the axis, where the rest of the angle is `φ = atan(y/x) = u − u³/3 + …`
//! with `u = y/x` below 2⁻⁷ (the next term, `u⁵/5`, is below 2⁻³⁷ rad): `1/x` from a
//! 64-entry table and two Newton steps, `u` from one product. The accumulated rotation plus
//! `φ` is the angle; `x √(1 + u²)` (`x + y u/2`: the next term, `x u⁴/8`, is below 0.6 LSB
//! of the normalised scale) times the gain compensation `K = Π 1/√(1 + 2⁻²ⁱ)` is the
//! magnitude. Headroom: |x| ≤ √2 · 2²⁹ / K < 2³¹, so the iterations never overflow `i32`.
//!
//! The eight rotations and the tail replace the twenty further rotations a CORDIC needs for
//! the same precision: a rotation is about ten instructions on a Cortex-M4 or M0, the tail
//! four 32 × 32 → 64 products (docs/numerics.md §4). Error bounds are in the tests and
//! `docs/PERFORMANCE.md`.

use crate::angle::Angle;
use crate::num::{Pu, reciprocal_step, round_shift_var, wmul};

/// CORDIC rotations before the tail. The residual angle is at most atan 2⁻⁽ᴺ⁻¹⁾ plus rounding.
pub const ITERATIONS: usize = 8;

/// `atan(2^-i)` in turns · 2³², computed at compile time.
static ATAN_TURNS: [u32; ITERATIONS] = atan_table();

// Evaluated at compile time: a bad index would fail the build, it cannot panic at run time.
#[allow(clippy::indexing_slicing)]
const fn atan_table() -> [u32; ITERATIONS] {
    let mut t = [0u32; ITERATIONS];
    let mut i = 0;
    while i < ITERATIONS {
        let x = 1.0 / (1u64 << i) as f64;
        let turns = const_atan(x) / core::f64::consts::TAU;
        t[i] = (turns * 4_294_967_296.0 + 0.5) as u32;
        i += 1;
    }
    t
}

/// atan for 0 < x ≤ 1 at f64 accuracy (compile time only): atan 1 = π/4 exactly, otherwise
/// the alternating series, which converges for x ≤ 1/2 in under 60 terms.
const fn const_atan(x: f64) -> f64 {
    if x >= 1.0 {
        return core::f64::consts::FRAC_PI_4;
    }
    let x2 = x * x;
    let mut power = x;
    let mut sum = 0.0;
    let mut n = 0;
    while n < 60 {
        let term = power / (2 * n + 1) as f64;
        sum = if n % 2 == 0 { sum + term } else { sum - term };
        power *= x2;
        n += 1;
    }
    sum
}

/// CORDIC gain compensation K = Π_{i<N} 1/√(1 + 2⁻²ⁱ) in Q1.31 (unsigned, K ≈ 0.6073).
const K_Q31: i32 = cordic_gain_q31();

const fn cordic_gain_q31() -> i32 {
    // Product of cos(atan 2^-i) = 1/sqrt(1 + 4^-i); sqrt by Newton in f64 at compile time.
    let mut k = 1.0f64;
    let mut i = 0;
    while i < ITERATIONS {
        let v = 1.0 + 1.0 / ((1u64 << (2 * i)) as f64);
        let mut r = 1.0;
        let mut n = 0;
        while n < 60 {
            r = 0.5 * (r + v / r);
            n += 1;
        }
        k /= r;
        i += 1;
    }
    (k * 2_147_483_648.0 + 0.5) as i32
}

/// Entries of the reciprocal's table: `x_n ∈ [2³⁰, 2³¹)` in 64 slices of 2²⁴.
const RECIP_SLICES: usize = 64;

/// `2⁶¹/m` at the middle `m = (64 + j + ½) 2²⁴` of slice `j`: within 2⁻⁷ of `2⁶¹/x_n` over the
/// slice, below 2³¹.
static RECIP: [u32; RECIP_SLICES] = recip_table();

#[allow(clippy::indexing_slicing)]
const fn recip_table() -> [u32; RECIP_SLICES] {
    let mut t = [0u32; RECIP_SLICES];
    let mut j = 0;
    while j < RECIP_SLICES {
        let m = (RECIP_SLICES as f64 + j as f64 + 0.5) * 16_777_216.0;
        t[j] = (2_305_843_009_213_693_952.0 / m + 0.5) as u32;
        j += 1;
    }
    t
}

/// `2³²/(4π)`: turns · 2³² per unit of `u` in Q33, rounded.
const TURNS_PER_U33: i32 = 341_782_638;

/// Magnitude and angle of a vector, from one CORDIC run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Polar {
    /// `√(x² + y²)` in the input's format, saturated.
    pub magnitude: Pu,
    /// `atan2(y, x)`; zero for the zero vector.
    pub angle: Angle,
}

/// Magnitude and angle of `(x, y)`, both in [`Pu`].
pub fn polar(x: Pu, y: Pu) -> Polar {
    let (x, y) = (x.to_bits(), y.to_bits());
    let big = x.unsigned_abs().max(y.unsigned_abs());
    if big == 0 {
        return Polar {
            magnitude: Pu::ZERO,
            angle: Angle::ZERO,
        };
    }
    // Bring the larger component into [2^28, 2^29): shift left (exact) or right (≤ 3 bits).
    let lz = big.leading_zeros(); // 0..=31
    let (mut x, mut y, left, right) = if lz >= 3 {
        let s = lz - 3;
        (x << s, y << s, s, 0)
    } else {
        let s = 3 - lz;
        (x >> s, y >> s, 0, s)
    };
    // Right half-plane: a half-turn rotation is exact.
    let mut z: u32 = 0;
    if x < 0 {
        x = -x;
        y = -y;
        z = 1 << 31;
    }
    let mut i = 0;
    while i < ITERATIONS {
        let (dx, dy) = (y >> i, x >> i);
        let a = match ATAN_TURNS.get(i) {
            Some(a) => *a,
            None => 0,
        };
        if y > 0 {
            x += dx;
            y -= dy;
            z = z.wrapping_add(a);
        } else {
            x -= dx;
            y += dy;
            z = z.wrapping_sub(a);
        }
        i += 1;
    }
    let (x, phi) = tail(x, y);
    // x ≥ 0 here; scale by K, then undo the normalisation (left and right are exclusive).
    // x < 2³¹ and K < 2³¹: the product is below 2⁶², the shift in 28..=62.
    let magnitude = round_shift_var(wmul(x, K_Q31), 31 + left - right);
    Polar {
        magnitude: Pu::from_bits(magnitude),
        angle: Angle(z.wrapping_add(phi as u32) as i32),
    }
}

/// The vector `(x, y)` the rotations left, `x` in [2²⁸·⁷, 2³⁰·³) and `|y/x|` within
/// `tan atan 2⁻⁷` (plus their truncations): its length `x √(1 + u²)` and its angle
/// `u − u³/3` in turns · 2³² (`u = y/x`, module docs). All bounds below follow from these.
#[inline(always)]
fn tail(x: i32, y: i32) -> (i32, i32) {
    // x_n = x 2^sh in [2³⁰, 2³¹) (sh ≤ 2); r ≈ 2⁶¹/x_n from the table, two Newton steps
    // r ← r + r (2⁶¹ − x_n r)/2⁶¹: 2⁻⁷ → 2⁻¹³ → 2⁻²⁶ (and the 2⁻³¹ of the arithmetic). The
    // first needs only 16-bit factors: x_n/2¹⁵ times r/2¹⁶ is near 2³⁰, the residual below
    // 2²³·¹, r/2¹⁶ times its top 15 bits below 2³⁰; its truncations cost 2⁻¹⁴. The second is
    // `Reciprocal::of`'s, in wide products.
    let sh = if x >= 1 << 30 {
        0
    } else if x >= 1 << 29 {
        1
    } else {
        2
    };
    let xn = x << sh;
    let slice = ((xn >> 24) as usize).wrapping_sub(RECIP_SLICES);
    let r = RECIP.get(slice).map_or(i32::MAX, |&r| r as i32);
    let rs = r >> 16;
    let e = (1 << 30) - (xn >> 15) * rs;
    let r = r + ((rs * (e >> 8)) >> 6);
    let r = reciprocal_step(xn, r);
    // u 2³³ = y 2^sh r / 2²⁸: |y 2^sh| < 2²⁴·³ and r < 2³¹, the product below 2⁵⁶; |u| < 2⁻⁷
    // (plus parts in 10⁴), so |u 2³³| < 2²⁶·¹.
    let u33 = (wmul(y << sh, r) >> 28) as i32;
    // The angle's first term u 2³²/(2π) = u33/(4π), rounded: below 2²²·⁴.
    let turns = ((wmul(u33, TURNS_PER_U33) + (1 << 31)) >> 32) as i32;
    // −u³/3 as turns · u²/3, from 16-bit factors (it is below 2⁶·⁸ LSB: a few parts in 10⁴
    // suffice): u² in Q44 from u in Q22 (below 2¹⁵·¹, the square below 2³⁰·²), to Q30 times
    // ⅓ in Q16 (below 2³⁰·⁶), to u²/3 in Q30 (below 2¹⁴·⁵); turns/2⁸ (below 2¹⁴·⁴) times it
    // is below 2²⁹.
    let u22 = u33 >> 11;
    let u2 = (u22 * u22) as u32;
    let third = ((u2 >> 14) * 21_845) >> 16;
    let cubic = ((turns >> 8) * third as i32) >> 22;
    // x √(1 + u²) = x + y u/2 to half an LSB: y/2⁸ (below 2¹⁵·⁴) times u33/2¹¹ (below 2¹⁵·¹),
    // of the same sign, is y u 2¹⁴, below 2³⁰·⁵; halved and to x's LSB, below 2¹⁵·⁵.
    let stretch = ((y >> 8) * (u33 >> 11)) >> 15;
    (x + stretch, turns - cubic)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::units::to_f64;
    use proptest::prelude::*;

    /// Angle error in LSB (2π/2³²) and magnitude error in LSB of Q8.24 against f64.
    fn errors(x: i32, y: i32) -> (f64, f64) {
        let (xf, yf) = (to_f64(Pu::from_bits(x)), to_f64(Pu::from_bits(y)));
        let p = polar(Pu::from_bits(x), Pu::from_bits(y));
        let exact_angle = Angle::from_rad(libm::atan2(yf, xf));
        let angle_err = (p.angle - exact_angle).0.unsigned_abs() as f64;
        let exact_mag = libm::hypot(xf, yf).min(to_f64(Pu::MAX));
        let mag_err = (to_f64(p.magnitude) - exact_mag).abs() * (1u64 << 24) as f64;
        (angle_err, mag_err)
    }

    /// Bound on the angle error in LSB (2π/2³²): 12 LSB = 1.8e-8 rad, for any non-zero
    /// vector, because the normalisation shift is exact for small inputs. The eight rotations
    /// truncate their shifted terms by under one LSB of the normalised scale 2²⁸ each, about
    /// 8·2⁻²⁸·⁷ rad ≈ 6 LSB at worst; the tail's rounding adds under one (4·10⁶ random
    /// vectors: 7 LSB).
    fn angle_bound(_x: i32, _y: i32) -> f64 {
        12.0
    }

    /// Bound on the magnitude error in LSB: 2 LSB plus 2e-8 relative. Each of the 8
    /// rotations truncates its shifted term by under one LSB of the normalised scale 2²⁸
    /// (2⁻²⁸ relative), and the gain K ≈ 0.607 carries their sum to the output:
    /// 8 · 2⁻²⁸ · 0.607 = 1.8e−8 at worst, with the tail's stretch within an LSB (4·10⁶
    /// random vectors: 9.1e−9 beyond the 2 LSB).
    fn mag_bound(x: i32, y: i32) -> f64 {
        2.0 + 2e-8 * libm::hypot(x as f64, y as f64)
    }

    #[test]
    fn axes_and_diagonals() {
        let one = Pu::from_num(1);
        let cases = [
            (one, Pu::ZERO, 0.0),
            (Pu::ZERO, one, 90.0),
            (-one, Pu::ZERO, -180.0),
            (Pu::ZERO, -one, -90.0),
            (one, one, 45.0),
            (-one, -one, -135.0),
        ];
        for (x, y, deg) in cases {
            let p = polar(x, y);
            assert!(
                (p.angle - Angle::from_deg(deg)).0.unsigned_abs() < 16,
                "{deg}"
            );
        }
        assert_eq!(
            polar(Pu::ZERO, Pu::ZERO),
            Polar {
                magnitude: Pu::ZERO,
                angle: Angle::ZERO
            }
        );
        let m = to_f64(polar(one, one).magnitude);
        assert!((m - core::f64::consts::SQRT_2).abs() < 2e-7);
    }

    #[test]
    fn extremes_saturate() {
        let p = polar(Pu::MIN, Pu::MIN);
        // At the rail within the 15 LSB a saturating shift by 28 lets pass.
        assert!(Pu::MAX.to_bits() - p.magnitude.to_bits() < 16);
        assert!((p.angle - Angle::from_deg(-135.0)).0.unsigned_abs() < 16);
        assert!(polar(Pu::MAX, Pu::ZERO).magnitude.to_bits() >= i32::MAX - 15);
        assert_eq!(polar(Pu::from_bits(1), Pu::ZERO).magnitude.to_bits(), 1);
    }

    proptest! {
        #[test]
        fn full_range_against_f64(x in any::<i32>(), y in any::<i32>()) {
            let (ea, em) = errors(x, y);
            prop_assert!(ea <= angle_bound(x, y), "angle error {} LSB", ea);
            prop_assert!(em <= mag_bound(x, y), "magnitude error {} LSB", em);
        }

        #[test]
        fn small_vectors_against_f64(x in -4096i32..4096, y in -4096i32..4096) {
            let (ea, em) = errors(x, y);
            prop_assert!(ea <= angle_bound(x, y), "angle error {} LSB", ea);
            prop_assert!(em <= 2.0, "magnitude error {} LSB", em);
        }
    }
}
