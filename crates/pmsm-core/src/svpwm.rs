//! Space-vector PWM by min–max zero-sequence injection (docs/khlaief2012.md §5; Khlaief, Boussak, Gossa (2012) §2, Fig. 1,
//! Fig. 5).
//!
//! ```text
//! (v_a, v_b, v_c) = inverse Clarke of v_αβ            phase voltages to the motor neutral
//! v_0 = −(max + min)/2                                 zero sequence centring the pattern
//! d_x = ½ + (v_x + v_0)/V_DC                           duty of leg x, centre-aligned
//! ```
//!
//! Centre-aligned SVPWM and this carrier comparison with min–max injection give the same
//! switching instants; the injection only recentres the three legs, which the isolated
//! neutral does not see. The legs stay within `[0, 1]` as long as `max − min ≤ V_DC`, i.e. up
//! to the circle `|v| = V_DC/√3` inscribed in the hexagon: `2/√3 = 1.155` times the
//! `V_DC/2` of sine PWM, the 15.5 % of the title of every SVPWM paper.
//!
//! # Limit
//!
//! The legs span `s = max − min` of the three phase voltages; the duties stay within
//! `[(1 − m)/2, (1 + m)/2]` as long as `s ≤ S = m V_DC` (`m ≤ 1` a configurable margin, e.g.
//! for minimum pulse widths): the hexagon, which reaches `m V_DC/√3` toward the middle of its
//! sides and `2 m V_DC/3` toward its vertices. Everything inside it is made exactly. The
//! current loops keep their vector inside the inscribed circle ([`SvpwmConfig::v_max`]); the
//! dead-time compensation added after them may carry it past the circle, and inside the
//! hexagon it still passes whole. Beyond the hexagon the vector is scaled onto it **keeping its
//! angle** and `saturated` is set for the current loops' anti-windup. The vector actually
//! commanded is returned for them and for the estimators.
//!
//! The test is free (the span is formed for the duties anyway) and so is most of the scale:
//! with `e = s/S − 1`, every leg's offset and the vector are shrunk by `1 − c`,
//!
//! ```text
//! c = e − e² + e³ − e⁴ + e⁵ ≥ e/(1 + e) = 1 − S/s      (e < ⅛; Horner, c in Q0.19)
//! ```
//!
//! so `(1 − c) s ≤ S`: never beyond the hexagon, short of it by at most `e⁶` and the
//! roundings, 1e−5 of its length. `e` comes from one product (the excess times `2⁵¹/S`, kept
//! with the configuration), the series from four 16×16-bit products, and each shrink
//! `x − ⌊x c/2¹⁹⌋` from two 32-bit multiplies on a Cortex-M0. A request more than ⅛ beyond
//! the hexagon (a compensation far larger than the dead time ever makes it) or with a
//! component beyond the bus itself is scaled by `S/s` from a reciprocal (one 32-bit division
//! and two Newton steps), out of line.
//!
//! # Overmodulation (optional)
//!
//! `SvpwmConfig::overmodulating` replaces the circle by a continuous path from the linear
//! range to six-step (docs/overmodulation.md). With `u = v/V_DC` the request in fractions of
//! the bus, `s = max − min` of its three phase voltages (`s ≤ 1` is the hexagon) and
//! `λ = clamp((|u|² − 4/9)/(R² − 4/9), 0, 1)`, `R` = [`OVERMOD_SIX_STEP_REQUEST`]:
//!
//! ```text
//! s ≤ 1:  linear, as above (the whole hexagon, not only its inscribed circle)
//! s > 1:  the legs scaled by 1/s (the vector on the hexagon, its angle kept),
//!         then the middle leg moved the fraction λ of the way to the nearest vertex
//!         (its own rail): λ = 0 up to |u| = 2/3 (the vertex), λ = 1 at |u| = R (six-step)
//! ```
//!
//! Then a leg within `δ` of a rail is held at it (`SvpwmConfig::with_min_pulse`, the drive
//! sets `δ` to the dead time over the period): a pulse the dead time would swallow is dropped.
//!
//! The commanded vector is then what the duties make, rebuilt from them (two products), so
//! the estimators see the voltage applied, not the request. [`SvpwmConfig::v_max`] is then
//! the hexagon's vertex `2 V_DC/3`, the longest vector the duties make, and `saturated` is
//! set only for a low bus: the current loops' own limit, `R V_DC`, is the only clamp.
//!
//! A bus at or below `vdc_min` (default 1 % of nominal) gives duties ½ (all legs at the same
//! average: zero voltage), a zero vector and the `bus_low` flag; nothing divides by zero.
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | `v`, `v_dc` | [`Pu`] Q8.24 of `V_b = V_DC,nom/√3` | `v_dc` = √3 at the nominal bus |
//! | duties | [`Unit`] Q2.30 | [0, 1] (clamped; 1 LSB = 9.3e−10 of the period) |
//! | `u`, the legs, their span `s` and `S` | Q2.30 of `V_DC` (`i32`; the span `u32`) | `u` within ±1 (a component beyond the bus goes out of line); `s < 2³²` |
//! | `e` and `c` of the limit | Q0.19 (`u32`) | `[0, ⅛)`: below 2¹⁶, so each product with a 16-bit half fits 32 bits |
//! | the series' `g` | Q0.16 | `(0, 1]` |
//! | overmodulating: `u`, the centred legs, `p`, `q`, `½ − δ` | Q2.30 of `V_DC` (`i32`) | `u` saturated at ±2; legs, `p`, `q` within ±½ |
//! | overmodulating: `|u|²` | Q.60 in `u64`, to Q.30 | < 8 |
//! | overmodulating: `λ` | Q2.30 | [0, 1]; slope `1/(R² − 4/9)` Q24 |
//! | overmodulating: `1/s` | [`Reciprocal`] of the span (`s` in `(2³⁰, 2³¹)` LSB, saturated) | one 32-bit division and two Newton steps per sample beyond the hexagon |
//! | `1/v_dc` | normalised mantissa in `[2³⁰, 2³¹)` and a shift | one 32-bit division and two Newton steps per new bus reading ([`BusReciprocal`]) |
//!
//! Accuracy: the average voltage rebuilt from the duties matches an f64 model within 1 LSB of
//! [`Pu`] in the linear range, the whole hexagon (measured 0.08); beyond it, never longer than
//! the model's and short of it by at most 1.2e−5 of its length (measured 9e−6); tests in
//! `tests/drive_parts_svpwm.rs` and `shrink_is_inside_and_near`.

use crate::error::ConfigError;
use crate::frames::{AlphaBeta, inverse_clarke};
use crate::num::{
    INV_SQRT3_Q31, Pu, Reciprocal, UNIT_FRAC, Unit, mul_q19, pu_from_f64, round_shift_sat, sat_i32,
    wmul,
};
use crate::params::in_range;

mod bus;
mod overmodulation;
#[cfg(test)]
pub(crate) use bus::BUS_TOLERANCE_SHIFT;
pub(crate) use bus::BusReciprocal;
#[cfg(any(test, feature = "overmodulation"))]
use overmodulation::overmodulate;
pub use overmodulation::overmodulate_f64;

/// Default smallest bus voltage the modulator divides by: 1 % of nominal, per unit.
pub const DEFAULT_VDC_MIN_PU: f64 = 0.01 * 1.732_050_807_568_877_2;

/// The request, in fractions of the bus, at which the overmodulation reaches six-step (`R`):
/// the current loops' voltage limit with overmodulation on. Beyond the hexagon's vertex
/// `2/3` by enough that the step from the angle-keeping hexagon to six-step is spread over
/// a range the current loops can regulate in (`λ` grows 8.5 per unit of `|u|²`).
pub const OVERMOD_SIX_STEP_REQUEST: f64 = 0.75;

/// Configuration of the modulator.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct SvpwmConfig {
    /// `m/√3` in Q1.31 (`2/3` with overmodulation: the vertex).
    vmax_per_vdc_q31: i32,
    /// The hexagon's span `S = m`, Q2.30 of `V_DC`, rounded down (`2³⁰` at `m = 1`).
    span_max: u32,
    /// `2⁵¹/S`, rounded up (`2²¹` at `m = 1`): the excess of a span over `S` to Q0.19.
    inv_span_q51: u32,
    /// The largest excess `s − S` the series takes: `e` below ⅛ (2¹⁶ in Q0.19) as the
    /// shrink computes it (`excess_max_for`).
    excess_max: u32,
    /// Overmodulation to six-step instead of the circle.
    #[cfg(any(test, feature = "overmodulation"))]
    overmodulation: bool,
    /// Overmodulating, `½ − δ` in Q2.30: a leg whose centred duty passes it is held at its
    /// rail (`δ` the shortest pulse kept, a fraction of the period).
    #[cfg(any(test, feature = "overmodulation"))]
    rail_q30: i32,
    /// Below this bus, duties ½ and `bus_low`.
    vdc_min: Pu,
}

impl Default for SvpwmConfig {
    /// Full linear range (`m = 1`); the bus is taken as lost below 1 % of nominal
    /// (`0.01 √3` per unit).
    fn default() -> Self {
        Self {
            vmax_per_vdc_q31: INV_SQRT3_Q31,
            span_max: 1 << UNIT_FRAC,
            inv_span_q51: 1 << (51 - UNIT_FRAC),
            excess_max: excess_max_for(1 << UNIT_FRAC, 1 << (51 - UNIT_FRAC)),
            #[cfg(any(test, feature = "overmodulation"))]
            overmodulation: false,
            #[cfg(any(test, feature = "overmodulation"))]
            rail_q30: 1 << (UNIT_FRAC - 1),
            vdc_min: pu_from_f64(DEFAULT_VDC_MIN_PU),
        }
    }
}

impl SvpwmConfig {
    /// Modulator using the fraction `modulation` ∈ [0.5, 1] of the linear range, and treating
    /// a bus below `vdc_min_pu` (per unit of `V_b`, in [1e−4, 1]) as absent.
    pub fn new(modulation: f64, vdc_min_pu: f64) -> Result<Self, ConfigError> {
        let m = in_range("svpwm.modulation", modulation, 0.5, 1.0)?;
        let vmin = in_range("svpwm.vdc_min_pu", vdc_min_pu, 1e-4, 1.0)?;
        let span_max = libm::floor(m * (1u64 << UNIT_FRAC) as f64) as u32;
        let inv_span_q51 = (1u64 << 51).div_ceil(u64::from(span_max)) as u32;
        Ok(Self {
            vmax_per_vdc_q31: libm::round(m / libm::sqrt(3.0) * 2_147_483_648.0) as i32,
            span_max,
            inv_span_q51,
            excess_max: excess_max_for(span_max, inv_span_q51),
            #[cfg(any(test, feature = "overmodulation"))]
            overmodulation: false,
            #[cfg(any(test, feature = "overmodulation"))]
            rail_q30: 1 << (UNIT_FRAC - 1),
            vdc_min: pu_from_f64(vmin),
        })
    }

    #[cfg(any(test, feature = "overmodulation"))]
    /// The default modulator with overmodulation up to six-step (module documentation): no
    /// circle, the vector limited only by the hexagon and moved toward its vertices beyond it.
    pub fn overmodulating() -> Self {
        Self {
            // 2/3 in Q1.31.
            vmax_per_vdc_q31: 1_431_655_765,
            overmodulation: true,
            ..Self::default()
        }
    }

    #[cfg(any(test, feature = "overmodulation"))]
    /// This modulator dropping, when it overmodulates, every pulse shorter than `fraction`
    /// of the period (a leg within `fraction` of a rail is held at the rail): a pulse shorter
    /// than the dead time is swallowed by it, which neither the dead-time compensation nor
    /// the estimator would know; held, the leg does not switch and loses no dead time.
    ///
    /// Errors: `fraction` outside [0, 0.1] (`svpwm.min_pulse`).
    pub fn with_min_pulse(self, fraction: f64) -> Result<Self, ConfigError> {
        let f = in_range("svpwm.min_pulse", fraction, 0.0, 0.1)?;
        Ok(Self {
            rail_q30: (1 << (UNIT_FRAC - 1)) - libm::round(f * (1u64 << UNIT_FRAC) as f64) as i32,
            ..self
        })
    }

    /// Whether the modulator overmodulates (`SvpwmConfig::overmodulating`, feature
    /// `overmodulation`; always false without it).
    #[inline(always)]
    pub fn overmodulation(&self) -> bool {
        #[cfg(any(test, feature = "overmodulation"))]
        return self.overmodulation;
        #[cfg(not(any(test, feature = "overmodulation")))]
        false
    }

    /// Largest vector the modulator makes in every direction for bus `vdc`, the current loops'
    /// limit: the circle `m · v_dc/√3` inscribed in the hexagon, or the vertex `2 v_dc/3` when
    /// overmodulating (0 for a low bus).
    pub fn v_max(&self, vdc: Pu) -> Pu {
        if vdc <= self.vdc_min {
            Pu::ZERO
        } else {
            Pu::from_bits(round_shift_sat(
                wmul(vdc.to_bits(), self.vmax_per_vdc_q31),
                31,
            ))
        }
    }

    /// Duties for the stationary voltage `v` on the bus `vdc` (both per unit of `V_b`).
    /// Integer only; never panics. Takes the bus's reciprocal at every call (the drive keeps
    /// it from one sample to the next while the bus reading stays within 0.2 % of the one it
    /// was taken for).
    pub fn modulate(&self, v: AlphaBeta, vdc: Pu) -> SvpwmOutput {
        // The modulators give the low bus's output at or below `vdc_min` themselves.
        let recip = Reciprocal::of(vdc.to_bits());
        #[cfg(any(test, feature = "overmodulation"))]
        if self.overmodulation {
            return self.overmodulate_on(v, vdc, recip);
        }
        self.modulate_on(v, vdc, recip)
    }

    #[cfg(any(test, feature = "overmodulation"))]
    /// The overmodulating modulator (`SvpwmConfig::overmodulating`) on the bus `vdc` and its
    /// reciprocal (as [`SvpwmConfig::modulate_on`]): out of line, so the linear modulator's
    /// path keeps its registers and the drive pays one test for the choice.
    #[inline(never)]
    pub(crate) fn overmodulate_on(&self, v: AlphaBeta, vdc: Pu, recip: Reciprocal) -> SvpwmOutput {
        if vdc <= self.vdc_min {
            return SvpwmOutput::BUS_LOW;
        }
        overmodulate(v, vdc, recip, self.rail_q30)
    }

    /// The linear modulator on the bus `vdc` and its reciprocal `recip` (the drive's kept
    /// ones, [`BusReciprocal`]). Inlined but on ARMv6-M, where the inlined copy in the drive's
    /// step cost 57 instructions a step in spilled registers (`scripts/pil.sh`).
    #[cfg_attr(
        not(all(target_arch = "arm", not(target_has_atomic = "32"))),
        inline(always)
    )]
    pub(crate) fn modulate_on(&self, v: AlphaBeta, vdc: Pu, recip: Reciprocal) -> SvpwmOutput {
        if vdc <= self.vdc_min {
            return SvpwmOutput::BUS_LOW;
        }
        let (a, b) = (v.alpha.to_bits(), v.beta.to_bits());
        // A component beyond the bus itself is beyond the fractions' exact range (and 1.5
        // times the hexagon's vertex): a request the drive never makes, taken apart.
        if a.unsigned_abs().max(b.unsigned_abs()) > vdc.to_bits() as u32 {
            return self.beyond_the_bus(v, vdc, recip);
        }
        // To fractions of the bus first (two products), then the legs (one more):
        // d_x = ½ + u_x − (max + min)/2 with u = v/v_dc, all in Q2.30.
        let legs = Legs::of(recip.fraction_within(a), recip.fraction_within(b));
        let span = legs.span();
        if span <= self.span_max {
            return SvpwmOutput {
                duties: legs.duties(),
                v,
                saturated: false,
                bus_low: false,
            };
        }
        // Beyond the hexagon: every leg's offset and the vector shrunk by 1 − c, c the
        // series of 1 − S/span (module documentation), or exactly by a division far beyond.
        let Some(c) = self.shrink(span) else {
            return self.beyond_the_bus(v, vdc, recip);
        };
        let shrink = |x: i32| x - mul_q19(x, c);
        SvpwmOutput {
            duties: legs.duties_with(shrink),
            v: AlphaBeta {
                alpha: Pu::from_bits(shrink(a)),
                beta: Pu::from_bits(shrink(b)),
            },
            saturated: true,
            bus_low: false,
        }
    }

    /// For a span `s` beyond the hexagon's `S` by less than an eighth, `c ≥ 1 − S/s` in
    /// Q0.19 (below 2¹⁶): `e = s/S − 1` from one product (rounded up), then
    /// `c = e − e² + e³ − e⁴ + e⁵` by Horner with each rounding taken the way that makes `c`
    /// larger. The series exceeds `e/(1 + e) = 1 − S/s` by `e⁶/(1 + e)`, so `(1 − c) s ≤ S`:
    /// never beyond the hexagon, short of it by at most `e⁶` (4e−6 at `e = ⅛`) and a few
    /// units of 2⁻¹⁹: 1e−5 in all. `None` further out.
    #[inline(always)]
    fn shrink(&self, span: u32) -> Option<u32> {
        let excess = span - self.span_max;
        if excess > self.excess_max {
            return None;
        }
        let e = excess_q19(excess, self.span_max, self.inv_span_q51);
        // g in Q0.16 (≤ 1), e g < 2³²; c = e(1 − e(1 − e(1 − e(1 − e)))).
        let one = 1u32 << 16;
        let g = one - e.div_ceil(8);
        let g = one - ((e * g) >> 19);
        let g = one - (e * g).div_ceil(1 << 19);
        let g = one - ((e * g) >> 19);
        Some((e * g).div_ceil(1 << 16))
    }

    /// The modulator far beyond the hexagon (a component beyond the bus, or a span more than
    /// ⅛ beyond `S`): the request halved until its fractions are exact, then scaled onto the
    /// hexagon by `S/s` from a [`Reciprocal`] (one 32-bit division), toward zero. Out of line:
    /// the drive's compensated request is this far out only with a dead time of some 5 % of
    /// the period.
    #[cold]
    #[inline(never)]
    fn beyond_the_bus(&self, v: AlphaBeta, vdc: Pu, recip: Reciprocal) -> SvpwmOutput {
        let (a, b) = (v.alpha.to_bits(), v.beta.to_bits());
        let bound = vdc.to_bits() as u32;
        let mut n = 0;
        while (a >> n).unsigned_abs().max((b >> n).unsigned_abs()) > bound {
            n += 1;
        }
        let (ua, ub) = (recip.fraction_within(a >> n), recip.fraction_within(b >> n));
        // Halved, a component above half the bus: |u| > ½, span ≥ 1.5 |u| > ¾ S, and
        // k/2 = (S/8)/(s/4) ≤ ⅔ in Q2.30 (the divisor rounded up, the result down: k short).
        let span = Legs::of(ua, ub).span();
        let half_k = Reciprocal::of(((span >> 2) + 1) as i32)
            .fraction((self.span_max >> 3) as i32)
            .saturating_sub(1)
            .max(0);
        // x k / 2^shift, toward zero (the vector from the request itself: its angle to the
        // rounding).
        let scale = |x: i32, shift: u32| {
            let p = wmul(x, half_k);
            let q = sat_i32((p.unsigned_abs() >> (29 + shift)) as i64);
            if p < 0 { -q } else { q }
        };
        SvpwmOutput {
            duties: Legs::of(scale(ua, 0), scale(ub, 0)).duties(),
            v: AlphaBeta {
                alpha: Pu::from_bits(scale(a, n)),
                beta: Pu::from_bits(scale(b, n)),
            },
            saturated: true,
            bus_low: false,
        }
    }
}

/// `e = excess/S` in Q0.19, rounded up, for `excess ≤ S/4`: a shift for the whole hexagon
/// (`S = 2³⁰`, `m = 1`), else the excess (below 2²⁸) times `2⁵¹/S` (at most 2²²), both below
/// 2³¹ so that the signed product, the Cortex-M0's quicker one, is exact; below 2¹⁹.
#[inline(always)]
fn excess_q19(excess: u32, span_max: u32, inv_span_q51: u32) -> u32 {
    if span_max == 1 << UNIT_FRAC {
        excess.div_ceil(1 << (UNIT_FRAC - 19))
    } else {
        ((wmul(excess as i32, inv_span_q51 as i32) + u32::MAX as i64) >> 32) as u32
    }
}

/// The largest excess over `S` whose `e`, as [`SvpwmConfig::shrink`] rounds it, is below
/// 2¹⁶ (⅛ in Q0.19): `e · g` then fits 32 bits. `e` grows with the excess, so the bound is
/// found by bisection at configuration time.
fn excess_max_for(span_max: u32, inv_span_q51: u32) -> u32 {
    // e(lo) < 2¹⁶ ≤ e(hi).
    let (mut lo, mut hi) = (0u32, span_max >> 2);
    while hi - lo > 1 {
        let mid = lo + (hi - lo) / 2;
        if excess_q19(mid, span_max, inv_span_q51) < 1 << 16 {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// The three legs of a request in fractions of the bus (Q2.30), and their extremes.
#[derive(Clone, Copy)]
struct Legs {
    x: [i32; 3],
    hi: i32,
    lo: i32,
}

impl Legs {
    /// The legs of `u = (u_α, u_β)` by the inverse Clarke transform.
    #[inline(always)]
    fn of(ua: i32, ub: i32) -> Self {
        let ph = inverse_clarke(AlphaBeta {
            alpha: Pu::from_bits(ua),
            beta: Pu::from_bits(ub),
        });
        let (a, b, c) = (ph.a.to_bits(), ph.b.to_bits(), ph.c.to_bits());
        Self {
            x: [a, b, c],
            hi: a.max(b).max(c),
            lo: a.min(b).min(c),
        }
    }

    /// `max − min`, the hexagon's measure (`≤ S` inside it).
    #[inline(always)]
    fn span(&self) -> u32 {
        self.hi.wrapping_sub(self.lo) as u32
    }

    /// The duties `½ + (x − (max + min)/2)`, each leg's doubled offset through `f` first.
    #[inline(always)]
    fn duties_with(&self, f: impl Fn(i32) -> i32) -> Duties {
        let duty = |x: i32| -> Unit {
            // (x − max) ≤ 0 ≤ (x − min): the sum cannot overflow; halved, rounded.
            let num = f(x
                .saturating_sub(self.hi)
                .saturating_add(x.saturating_sub(self.lo)));
            let d = (1 << (UNIT_FRAC - 1)) + ((num >> 1) + (num & 1));
            Unit::from_bits(d.clamp(0, 1 << UNIT_FRAC))
        };
        Duties {
            a: duty(self.x[0]),
            b: duty(self.x[1]),
            c: duty(self.x[2]),
        }
    }

    /// The duties of a request inside the hexagon.
    #[inline(always)]
    fn duties(&self) -> Duties {
        self.duties_with(|num| num)
    }
}

/// Duties of the three legs, Q2.30 in [0, 1]: the fraction of the PWM period each high-side
/// switch is on, centred in the period.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Duties {
    /// Leg a.
    pub a: Unit,
    /// Leg b.
    pub b: Unit,
    /// Leg c.
    pub c: Unit,
}

impl Duties {
    /// All legs at ½: zero average voltage.
    pub const HALF: Self = Self {
        a: Unit::from_bits(1 << (UNIT_FRAC - 1)),
        b: Unit::from_bits(1 << (UNIT_FRAC - 1)),
        c: Unit::from_bits(1 << (UNIT_FRAC - 1)),
    };

    /// All low sides on (the zero vector 000): zero voltage without switching, so no
    /// dead-time error.
    pub const LOW: Self = Self {
        a: Unit::ZERO,
        b: Unit::ZERO,
        c: Unit::ZERO,
    };

    /// Compare values of a centre-aligned timer counting to `period` (up-down): `d · period`,
    /// rounded.
    pub fn to_compare(&self, period: u16) -> [u16; 3] {
        let f = |d: Unit| -> u16 {
            // The exact product of two `i32` (`wmul`: the C library calls this every period,
            // and an `i64` product is ARMv6-M's general 64-bit multiply).
            let x = (wmul(d.to_bits().clamp(0, 1 << UNIT_FRAC), i32::from(period))
                + (1 << (UNIT_FRAC - 1)))
                >> UNIT_FRAC;
            x.clamp(0, period as i64) as u16
        };
        [f(self.a), f(self.b), f(self.c)]
    }

    /// As fractions of the period (for host code and tests).
    pub fn to_f64(&self) -> [f64; 3] {
        let f = |d: Unit| d.to_bits() as f64 / (1u64 << UNIT_FRAC) as f64;
        [f(self.a), f(self.b), f(self.c)]
    }
}

/// Output of [`SvpwmConfig::modulate`].
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SvpwmOutput {
    /// Leg duties.
    pub duties: Duties,
    /// The voltage actually commanded after the limit, αβ per unit (what the duties make on
    /// an ideal inverter; zero with `bus_low`).
    pub v: AlphaBeta,
    /// The request was beyond the hexagon and was scaled onto it (or the bus is low).
    pub saturated: bool,
    /// The bus is at or below `vdc_min`: duties ½.
    pub bus_low: bool,
}

impl SvpwmOutput {
    /// The output for a bus at or below `vdc_min`: duties ½, no voltage, both flags.
    const BUS_LOW: Self = Self {
        duties: Duties::HALF,
        v: AlphaBeta {
            alpha: Pu::ZERO,
            beta: Pu::ZERO,
        },
        saturated: true,
        bus_low: true,
    };
}

#[cfg(test)]
mod tests;
