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
//! Beyond `m · V_DC/√3` (`m ≤ 1` a configurable margin, e.g. for minimum pulse widths) the
//! vector is scaled onto the circle **keeping its angle** (both components times
//! `V_max/|v|`, from an exact test on the squared length and a Newton reciprocal square root),
//! and `saturated` is set for the current loops' anti-windup. The vector actually commanded is
//! returned for them and for the estimators.
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
//! | `1/v_dc` | normalised mantissa in `[2³⁰, 2³¹)` and a shift | one 32-bit division and two Newton steps per new bus reading ([`BusReciprocal`]) |
//!
//! Accuracy: the average voltage rebuilt from the duties matches an f64 model within 1 LSB of
//! [`Pu`] in the linear range (measured 0.08) and 4 LSB on the circle (measured 1.2), tests in
//! `tests/drive_parts_svpwm.rs`.

use crate::error::ConfigError;
use crate::frames::{AlphaBeta, inverse_clarke};
use crate::num::{
    INV_SQRT3_Q31, Pu, Reciprocal, UNIT_FRAC, Unit, pu_from_f64, round_shift_sat, umul, wmul,
};
use crate::params::in_range;
use crate::sqrt::rsqrt;

/// Default smallest bus voltage the modulator divides by: 1 % of nominal, per unit.
pub const DEFAULT_VDC_MIN_PU: f64 = 0.01 * 1.732_050_807_568_877_2;

/// Configuration of the modulator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SvpwmConfig {
    /// `m/√3` in Q1.31.
    vmax_per_vdc_q31: i32,
    /// Below this bus, duties ½ and `bus_low`.
    vdc_min: Pu,
    /// The margin `m`.
    pub modulation: f64,
}

impl Default for SvpwmConfig {
    /// Full linear range (`m = 1`); the bus is taken as lost below 1 % of nominal
    /// (`0.01 √3` per unit).
    fn default() -> Self {
        Self {
            vmax_per_vdc_q31: INV_SQRT3_Q31,
            vdc_min: pu_from_f64(DEFAULT_VDC_MIN_PU),
            modulation: 1.0,
        }
    }
}

impl SvpwmConfig {
    /// Modulator using the fraction `modulation` ∈ [0.5, 1] of the linear range, and treating
    /// a bus below `vdc_min_pu` (per unit of `V_b`, in [1e−4, 1]) as absent.
    pub fn new(modulation: f64, vdc_min_pu: f64) -> Result<Self, ConfigError> {
        let m = in_range("svpwm.modulation", modulation, 0.5, 1.0)?;
        let vmin = in_range("svpwm.vdc_min_pu", vdc_min_pu, 1e-4, 1.0)?;
        Ok(Self {
            vmax_per_vdc_q31: libm::round(m / libm::sqrt(3.0) * 2_147_483_648.0) as i32,
            vdc_min: pu_from_f64(vmin),
            modulation: m,
        })
    }

    /// Largest vector the modulator makes for bus `vdc`: `m · v_dc/√3` (0 for a low bus).
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
    /// it from one sample to the next while the bus reading does not change).
    pub fn modulate(&self, v: AlphaBeta, vdc: Pu) -> SvpwmOutput {
        self.modulate_cached(v, vdc, &mut BusReciprocal::default())
    }

    /// [`SvpwmConfig::modulate`], bit for bit, with `1/v_dc` and the circle's radius taken
    /// from `cache` when the bus reading is the one they were computed for (a 32-bit division
    /// and four products saved) and recomputed and stored otherwise.
    pub(crate) fn modulate_cached(
        &self,
        v: AlphaBeta,
        vdc: Pu,
        cache: &mut BusReciprocal,
    ) -> SvpwmOutput {
        if vdc <= self.vdc_min {
            return SvpwmOutput {
                duties: Duties::HALF,
                v: AlphaBeta::default(),
                saturated: true,
                bus_low: true,
            };
        }
        let bus = cache.get(vdc, self);
        let (v, saturated) = limit(v, bus.v_max);
        // To fractions of the bus first (two products), then the legs (one more):
        // d_x = ½ + u_x − (max + min)/2 with u = v/v_dc, all in Q2.30. Inside the circle
        // |u_x| ≤ 1/√3 and every difference below is at most 1 (2³⁰) in magnitude.
        let u = AlphaBeta {
            alpha: Pu::from_bits(bus.fraction(v.alpha.to_bits())),
            beta: Pu::from_bits(bus.fraction(v.beta.to_bits())),
        };
        let ph = inverse_clarke(u);
        let (a, b, c) = (ph.a.to_bits(), ph.b.to_bits(), ph.c.to_bits());
        let hi = a.max(b).max(c);
        let lo = a.min(b).min(c);
        let duty = |x: i32| -> Unit {
            // (x − max) ≤ 0 ≤ (x − min): the sum cannot overflow; halved, rounded.
            let num = x.saturating_sub(hi).saturating_add(x.saturating_sub(lo));
            let d = (1 << (UNIT_FRAC - 1)) + ((num >> 1) + (num & 1));
            Unit::from_bits(d.clamp(0, 1 << UNIT_FRAC))
        };
        SvpwmOutput {
            duties: Duties {
                a: duty(a),
                b: duty(b),
                c: duty(c),
            },
            v,
            saturated,
            bus_low: false,
        }
    }
}

/// What the modulator needs of the last bus reading seen: the circle's radius and the
/// reading's [`Reciprocal`], recomputed only when the reading changes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct BusReciprocal {
    /// The bus reading (bits of [`Pu`]) the rest belongs to; 0 when empty (never a valid bus).
    vdc: i32,
    /// `1/v_dc`: `x/v_dc` in Q2.30 for `x` in the bits of [`Pu`].
    recip: Reciprocal,
    /// `m v_dc/√3`.
    v_max: Pu,
}

impl BusReciprocal {
    /// The circle's radius of the last bus reading (0 before the first).
    #[inline(always)]
    pub(crate) fn v_max(&self) -> Pu {
        self.v_max
    }

    /// The bus terms of `vdc > 0` for the modulator `m`: from the cache when `vdc` is the
    /// last reading, else computed and stored (a reading `≤ 0`, which the modulator never
    /// passes, gives 0).
    #[inline]
    fn get(&mut self, vdc: Pu, m: &SvpwmConfig) -> Self {
        let bits = vdc.to_bits();
        // The empty cache's reading, 0, is below any bus the modulator passes here.
        if bits != self.vdc {
            *self = Self {
                vdc: bits,
                recip: Reciprocal::of(bits),
                v_max: m.v_max(vdc),
            };
        }
        *self
    }

    /// `x/v_dc` in Q2.30 for `x` in the bits of [`Pu`], rounded and saturated; exact to the
    /// rounding for every vector inside the circle (`|x| ≤ v_dc/√3`).
    #[inline(always)]
    fn fraction(self, x: i32) -> i32 {
        self.recip.fraction(x)
    }
}

/// `v` limited to the circle of radius `v_max` keeping its angle, and whether it was
/// limited: the test is exact (squares in `u64`), the scale `v_max/|v| < 1` comes from
/// [`rsqrt`] of the normalised squared length, in Q1.31, truncated so the result never
/// leaves the circle by more than the rounding of its components.
fn limit(v: AlphaBeta, v_max: Pu) -> (AlphaBeta, bool) {
    let (a, b) = (v.alpha.to_bits(), v.beta.to_bits());
    let (ua, ub) = (a.unsigned_abs(), b.unsigned_abs());
    let r = v_max.to_bits().max(0) as u32;
    // |v| ≤ max + min/2 of the components' magnitudes: no product for most vectors.
    if (ua.max(ub) as u64 + (ua.min(ub) / 2) as u64) < r as u64 {
        return (v, false);
    }
    // Each square ≤ 2⁶², the sum < 2⁶³.
    let m2 = umul(ua, ua) + umul(ub, ub);
    if m2 <= umul(r, r) {
        return (v, false);
    }
    // m2 = X·2⁶⁴·2^−e with X ∈ [1/4, 1), e even: |v| = √X · 2^(32 − e/2).
    let e = m2.leading_zeros() & !1;
    let x = ((m2 << e) >> 32) as u32;
    let y = rsqrt(x); // 2³⁰/√X
    // k = v_max/|v| = v_max y 2^(e/2 − 62); in Q1.31: (v_max y) >> (31 − e/2), below 2³¹.
    let k = (umul(r, y) >> (31 - e / 2)).min(i32::MAX as u64) as i32;
    (
        AlphaBeta {
            alpha: Pu::from_bits(round_shift_sat(wmul(a, k), 31)),
            beta: Pu::from_bits(round_shift_sat(wmul(b, k), 31)),
        },
        true,
    )
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
            let x = (d.to_bits().clamp(0, 1 << UNIT_FRAC) as i64 * period as i64
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
    /// The request was beyond the circle and was scaled onto it (or the bus is low).
    pub saturated: bool,
    /// The bus is at or below `vdc_min`: duties ½.
    pub bus_low: bool,
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn low_bus_gives_half_duties() {
        let c = SvpwmConfig::default();
        let v = AlphaBeta {
            alpha: Pu::from_num(1),
            beta: Pu::ZERO,
        };
        for vdc in [Pu::ZERO, Pu::MIN, Pu::from_bits(1), pu_from_f64(0.01)] {
            let o = c.modulate(v, vdc);
            assert_eq!(o.duties, Duties::HALF);
            assert!(o.bus_low && o.saturated);
            assert_eq!(o.v, AlphaBeta::default());
        }
        assert!(SvpwmConfig::new(1.1, 0.01).is_err());
        assert_eq!(Duties::HALF.to_compare(1000), [500; 3]);
    }

    proptest! {
        /// Any input: duties in [0, 1] and the commanded vector inside the circle (within 2 LSB
        /// and the 1e−8 relative error of the CORDIC magnitude).
        #[test]
        fn duties_always_valid(al in any::<i32>(), be in any::<i32>(), vdc in any::<i32>()) {
            let c = SvpwmConfig::default();
            let v = AlphaBeta { alpha: Pu::from_bits(al), beta: Pu::from_bits(be) };
            let vdc = Pu::from_bits(vdc);
            let o = c.modulate(v, vdc);
            for d in [o.duties.a, o.duties.b, o.duties.c] {
                prop_assert!(d >= Unit::ZERO && d <= Unit::from_num(1));
            }
            let (x, y) = (o.v.alpha.to_bits() as f64, o.v.beta.to_bits() as f64);
            let vmax = c.v_max(vdc).to_bits() as f64;
            prop_assert!((x * x + y * y).sqrt() <= vmax * (1.0 + 1e-8) + 2.0);
        }
    }
}
