//! Space-vector PWM by min–max zero-sequence injection (equations.md §4.3; seed 001 §2, Fig. 1,
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
//! vector is scaled onto the circle **keeping its angle** (CORDIC magnitude and angle, then
//! `V_max (cos φ, sin φ)`), and `saturated` is set for the current loops' anti-windup. The
//! vector actually commanded is returned for them and for the estimators.
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
//! | `1/v_dc` | Q.30 in `i64` | one `i64` division per new bus reading ([`BusReciprocal`]) |
//!
//! Accuracy: the average voltage rebuilt from the duties matches an f64 model within 1 LSB of
//! [`Pu`] in the linear range (measured 0.65) and 4 LSB on the circle (measured 1.7), tests in
//! `tests/drive_parts_svpwm.rs`.

use crate::cordic::polar;
use crate::error::ConfigError;
use crate::frames::{AlphaBeta, inverse_clarke};
use crate::num::{PU_FRAC, Pu, UNIT_FRAC, Unit, mul_unit, pu_from_f64, round_shift_sat};
use crate::params::in_range;

/// `1/√3` in Q1.31 (rounded).
const INV_SQRT3_Q31: i64 = 1_239_850_262;

/// Default smallest bus voltage the modulator divides by: 1 % of nominal, per unit.
pub const DEFAULT_VDC_MIN_PU: f64 = 0.01 * 1.732_050_807_568_877_2;

/// Configuration of the modulator.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SvpwmConfig {
    /// `m/√3` in Q1.31.
    vmax_per_vdc_q31: i64,
    /// Below this bus, duties ½ and `bus_low`.
    vdc_min: Pu,
    /// The margin `m`.
    pub modulation: f64,
}

impl Default for SvpwmConfig {
    /// Full linear range (`m = 1`), [`DEFAULT_VDC_MIN_PU`].
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
            vmax_per_vdc_q31: libm::round(m / libm::sqrt(3.0) * 2_147_483_648.0) as i64,
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
                vdc.to_bits() as i64 * self.vmax_per_vdc_q31,
                31,
            ))
        }
    }

    /// Duties for the stationary voltage `v` on the bus `vdc` (both per unit of `V_b`).
    /// Integer only; never panics. Divides by the bus at every call; a caller that modulates
    /// every sample keeps a [`BusReciprocal`] and calls [`SvpwmConfig::modulate_cached`].
    pub fn modulate(&self, v: AlphaBeta, vdc: Pu) -> SvpwmOutput {
        self.modulate_cached(v, vdc, &mut BusReciprocal::default())
    }

    /// [`SvpwmConfig::modulate`], bit for bit, with `1/v_dc` taken from `cache` when the bus
    /// reading is the one it was computed for (the `i64` division is most of the cost of a
    /// call) and recomputed and stored otherwise.
    pub fn modulate_cached(&self, v: AlphaBeta, vdc: Pu, cache: &mut BusReciprocal) -> SvpwmOutput {
        if vdc <= self.vdc_min {
            return SvpwmOutput {
                duties: Duties::HALF,
                v: AlphaBeta::default(),
                saturated: true,
                bus_low: true,
            };
        }
        let inv = cache.get(vdc);
        let v_max = self.v_max(vdc);
        let (v, saturated) = if clearly_inside(v, v_max) {
            // Far inside the circle: the CORDIC test of `limit` would find the same, so the
            // result is bit for bit the same without the 28 CORDIC iterations.
            (v, false)
        } else {
            limit(v, v_max)
        };
        let ph = inverse_clarke(v);
        let (a, b, c) = (
            ph.a.to_bits() as i64,
            ph.b.to_bits() as i64,
            ph.c.to_bits() as i64,
        );
        let hi = a.max(b).max(c);
        let lo = a.min(b).min(c);
        // 2 (v_x + v_0) = 2 v_x − (max + min): exact in Q8.25.
        let off = hi + lo;
        // d = ½ + (2 v_x − off)/2 · inv: Q8.25 · Q.30 = Q.55 → Q2.30 (shift 25).
        let duty = |x: i64| -> Unit {
            let num = (2 * x - off) * inv; // |2x − off| ≤ 2^33, inv ≤ 2^38: below 2^63 after the
            // bus check (v_dc ≥ 2^-9 pu gives inv ≤ 2^39 and |v| ≤ v_dc/√3 after the limit).
            let d = round_shift_sat(num, PU_FRAC + 1).saturating_add(1 << (UNIT_FRAC - 1));
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

/// `1/v_dc` in Q.30 (`⌊2⁵⁴/v_dc⌋` of the bits) for the last bus reading seen: one `i64`
/// division per change of the reading instead of one per call (the result is the same bits).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct BusReciprocal {
    /// The bus reading (bits of [`Pu`]) `inv` belongs to; 0 when empty (never a valid bus).
    vdc: i32,
    inv: i64,
}

impl BusReciprocal {
    /// `⌊2⁵⁴/v_dc⌋` for a bus `vdc > 0`: from the cache when `vdc` is the last reading, else
    /// divided and stored (0 for `vdc ≤ 0`, which the modulator never passes).
    #[inline]
    pub fn get(&mut self, vdc: Pu) -> i64 {
        let bits = vdc.to_bits();
        if bits != self.vdc || bits == 0 {
            self.inv = (1i64 << (PU_FRAC + UNIT_FRAC))
                .checked_div(bits as i64)
                .unwrap_or(0);
            self.vdc = bits;
        }
        self.inv
    }
}

/// `|v| < v_max (1 − 2⁻¹²)`, exactly (squares in `u64`: each component's magnitude is at
/// most 2³¹, so each square is at most 2⁶² and their sum fits). The margin, 2.4e−4 of
/// `v_max`, is far beyond the CORDIC magnitude's error (3e−7 relative, `docs/PERFORMANCE.md`),
/// so a vector accepted here is one that [`limit`] leaves unchanged.
#[inline]
fn clearly_inside(v: AlphaBeta, v_max: Pu) -> bool {
    let a = v.alpha.to_bits().unsigned_abs() as u64;
    let b = v.beta.to_bits().unsigned_abs() as u64;
    let r = v_max.to_bits().max(0) as u64;
    let r = r - (r >> 12);
    a * a + b * b < r * r
}

/// `v` limited to the circle of radius `v_max` keeping its angle (CORDIC magnitude and
/// angle), and whether it was limited.
fn limit(v: AlphaBeta, v_max: Pu) -> (AlphaBeta, bool) {
    let p = polar(v.alpha, v.beta);
    if p.magnitude > v_max {
        // Onto the circle, same angle.
        let sc = p.angle.sin_cos();
        (
            AlphaBeta {
                alpha: mul_unit(v_max, sc.cos),
                beta: mul_unit(v_max, sc.sin),
            },
            true,
        )
    } else {
        (v, false)
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
