//! Overmodulation up to six-step (`SvpwmConfig::overmodulating`; the module documentation of
//! `svpwm` derives it): the fixed-point modulator and its f64 reference.

use super::OVERMOD_SIX_STEP_REQUEST;
#[cfg(any(test, feature = "overmodulation"))]
use super::{Duties, SvpwmOutput};
#[cfg(any(test, feature = "overmodulation"))]
use crate::frames::{Abc, AlphaBeta, clarke, inverse_clarke};
#[cfg(any(test, feature = "overmodulation"))]
use crate::num::{Pu, Reciprocal, UNIT_FRAC, Unit, round_shift_sat, umul, wmul};
#[cfg(any(test, feature = "overmodulation"))]
/// `4/9`, the squared vertex length in fractions of the bus, Q2.30.
const VERTEX_SQ_Q30: i64 = 477_218_588;
#[cfg(any(test, feature = "overmodulation"))]
/// `1/(R² − 4/9)`, Q24, the slope of `λ` in `|u|²` (`|u|²` below 8 by the saturation of `u`: the product stays below 2⁶¹).
const LAMBDA_SLOPE_Q24: i64 = ((1u64 << 24) as f64 / (0.5625 - 4.0 / 9.0) + 0.5) as i64;

#[cfg(any(test, feature = "overmodulation"))]
/// The overmodulating modulator (module documentation) for a bus above `vdc_min`.
#[inline(always)]
pub(super) fn overmodulate(v: AlphaBeta, vdc: Pu, recip: Reciprocal, rail: i32) -> SvpwmOutput {
    let (ua, ub) = (
        recip.fraction(v.alpha.to_bits()),
        recip.fraction(v.beta.to_bits()),
    );
    let ph = inverse_clarke(AlphaBeta {
        alpha: Pu::from_bits(ua),
        beta: Pu::from_bits(ub),
    });
    let (a, b, c) = (ph.a.to_bits(), ph.b.to_bits(), ph.c.to_bits());
    let hi = a.max(b).max(c);
    let lo = a.min(b).min(c);
    let (hi64, lo64) = (i64::from(hi), i64::from(lo));
    let half = 1i32 << (UNIT_FRAC - 1);
    let span = hi64 - lo64;
    // Each leg's offset from the centre of the legs, rounded: (2x − max − min)/2.
    let centred = |x: i32| -> i32 {
        let num = i64::from(x) * 2 - hi64 - lo64;
        ((num >> 1) + (num & 1)) as i32
    };
    let (ea, eb, ec) = if span <= 1 << UNIT_FRAC {
        // Inside the hexagon: the min–max injection alone (|offset| ≤ ½).
        (centred(a), centred(b), centred(c))
    } else {
        // The middle leg's offset, |w| ≤ span/2 ≤ 2³¹ − 1 after the saturation below.
        let mid = i64::from(a) + i64::from(b) + i64::from(c) - hi64 - lo64;
        let w =
            ((2 * mid - hi64 - lo64) / 2).clamp(-i64::from(i32::MAX), i64::from(i32::MAX)) as i32;
        // On the hexagon, angle kept: w/span in [−½, ½], Q2.30.
        let p = Reciprocal::of(span.min(i64::from(i32::MAX)) as i32).fraction(w);
        // λ from |u|² (Q.60 to Q.30; the sum of two squares of i32 fits u64).
        let u2 = ((umul(ua.unsigned_abs(), ua.unsigned_abs())
            + umul(ub.unsigned_abs(), ub.unsigned_abs()))
            >> 30) as i64;
        let lambda = (((u2 - VERTEX_SQ_Q30) * LAMBDA_SLOPE_Q24) >> 24).clamp(0, 1 << UNIT_FRAC);
        let vertex = if w >= 0 { half } else { -half };
        let q = p + ((i64::from(vertex - p) * lambda) >> UNIT_FRAC) as i32;
        // The highest leg at +½, the lowest at −½, the middle one at q.
        let leg = |x: i32| -> i32 {
            if x == hi {
                half
            } else if x == lo {
                -half
            } else {
                q
            }
        };
        (leg(a), leg(b), leg(c))
    };
    // Pulses shorter than the minimum dropped: the leg held at its rail.
    let snap = |e: i32| -> i32 {
        if e > rail {
            half
        } else if e < -rail {
            -half
        } else {
            e
        }
    };
    let (ea, eb, ec) = (snap(ea), snap(eb), snap(ec));
    // The vector the duties make: Clarke of the centred legs (the zero sequence drops out),
    // from fractions of the bus (Q2.30) to per unit.
    let f = clarke(Abc {
        a: Pu::from_bits(ea),
        b: Pu::from_bits(eb),
        c: Pu::from_bits(ec),
    });
    let to_pu = |x: Pu| Pu::from_bits(round_shift_sat(wmul(x.to_bits(), vdc.to_bits()), UNIT_FRAC));
    let duty = |e: i32| Unit::from_bits(half + e);
    SvpwmOutput {
        duties: Duties {
            a: duty(ea),
            b: duty(eb),
            c: duty(ec),
        },
        v: AlphaBeta {
            alpha: to_pu(f.alpha),
            beta: to_pu(f.beta),
        },
        saturated: false,
        bus_low: false,
    }
}

/// The overmodulating modulator in f64, the reference of `SvpwmConfig::overmodulating`
/// with `SvpwmConfig::with_min_pulse``(min_pulse)`: for the request `u = (u_α, u_β)` in
/// fractions of the bus, the three duties and the average vector they make, in fractions of
/// the bus.
pub fn overmodulate_f64(u_alpha: f64, u_beta: f64, min_pulse: f64) -> ([f64; 3], [f64; 2]) {
    let s3 = libm::sqrt(3.0);
    let ph = [
        u_alpha,
        -0.5 * u_alpha + 0.5 * s3 * u_beta,
        -0.5 * u_alpha - 0.5 * s3 * u_beta,
    ];
    let hi = ph[0].max(ph[1]).max(ph[2]);
    let lo = ph[0].min(ph[1]).min(ph[2]);
    let span = hi - lo;
    let centre = 0.5 * (hi + lo);
    let [a, b, c] = ph;
    let mut e = ph.map(|x| x - centre);
    if span > 1.0 {
        let lambda = ((u_alpha * u_alpha + u_beta * u_beta - 4.0 / 9.0)
            / (OVERMOD_SIX_STEP_REQUEST * OVERMOD_SIX_STEP_REQUEST - 4.0 / 9.0))
            .clamp(0.0, 1.0);
        // The highest and lowest legs (distinct, as span > 0) and the middle one's offset.
        let ihi = if a >= b && a >= c {
            0
        } else if b >= c {
            1
        } else {
            2
        };
        let ilo = if c <= a && c <= b && ihi != 2 {
            2
        } else if b <= a && ihi != 1 {
            1
        } else {
            0
        };
        let p = (a + b + c - hi - lo - centre) / span;
        let q = p + lambda * ((0.5f64).copysign(p) - p);
        e = core::array::from_fn(|k| {
            if k == ihi {
                0.5
            } else if k == ilo {
                -0.5
            } else {
                q
            }
        });
    }
    // Pulses shorter than the minimum dropped.
    let rail = 0.5 - min_pulse;
    let [ea, eb, ec] = e.map(|x| {
        if x > rail {
            0.5
        } else if x < -rail {
            -0.5
        } else {
            x
        }
    });
    (
        [0.5 + ea, 0.5 + eb, 0.5 + ec],
        [(2.0 * ea - eb - ec) / 3.0, (eb - ec) / s3],
    )
}
