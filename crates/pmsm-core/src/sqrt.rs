//! The reciprocal square root `1/√X` of the modulator's circle limit ([`rsqrt`]), within a
//! few LSB of Q2.30 over one octave: a step seed from a small table and three Newton steps.
//! (The current loops' circle needs no root: [`crate::control`]'s arc is interpolated.)

use crate::num::umul;

/// `1/√X` in Q2.30 at the centres of 24 intervals of `X ∈ [1/4, 1)` (seed of [`rsqrt`]).
const RSQRT_SEED: [u32; 24] = [
    2083365155, 1970666148, 1874477404, 1791125178, 1717986918, 1653133683, 1595110809, 1542797797,
    1495315679, 1451963954, 1412176548, 1375490368, 1341522400, 1309952745, 1280511845, 1252970736,
    1227133513, 1202831433, 1179918260, 1158266544, 1137764631, 1118314230, 1099828424, 1082230034,
];

/// `2³⁰/√X` for `x = X·2³²`, `x ∈ [2³⁰, 2³²)`: a table seed within 3 %, then three Newton
/// steps `y ← y (3 − X y²)/2`, each squaring the relative error (3 % → 1.4e−3 → 2.7e−6 →
/// the 2⁻³⁰ of the arithmetic). Newton from either side ends below `1/√X`, so the result
/// never exceeds it by more than the seed's rounding.
#[inline]
pub(crate) fn rsqrt(x: u32) -> u32 {
    let k = ((x >> 27) as usize).saturating_sub(8);
    let mut y = RSQRT_SEED.get(k).copied().unwrap_or(1 << 30);
    for _ in 0..3 {
        // X y² in Q2.30 (y² in Q3.29 first: y ≤ 2.02 · 2³⁰).
        let y2 = (umul(y, y) >> 31) as u32;
        let xy2 = (umul(x, y2) >> 31) as u32;
        let f = (3u32 << 30).saturating_sub(xy2);
        y = (umul(y, f) >> 31) as u32;
    }
    y
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn rsqrt_within_four_lsb(x in (1u32 << 30)..=u32::MAX) {
            let exact = (1u64 << 30) as f64 / (x as f64 / 4_294_967_296.0).sqrt();
            let got = rsqrt(x) as f64;
            prop_assert!((got - exact).abs() <= 4.0, "{} {}", got, exact);
        }
    }
}
