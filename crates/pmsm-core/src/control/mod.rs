//! The control loops of the drive of Khlaief, Boussak, Gossa (2012) (docs/khlaief2012.md §6–7): a fixed-point PI with
//! anti-windup ([`pi`]), the dq current controllers ([`current`]) and the IP speed controller
//! ([`speed`]) with the load observer that feeds it forward ([`load_observer`]).
//!
//! All of them follow the crate's split: a `Config::new` that designs and checks every
//! coefficient in `f64` once, and an integer-only `step` that saturates instead of wrapping
//! and reports it. Signals are per unit ([`Pu`], Q8.24) of [`PerUnit`](crate::units::PerUnit).
//!
//! The current and speed loops run on compile-time binary points ([`Coef`](crate::num::Coef)
//! gains, integrators whose LSB is the exact product's: [`pi::Pi`], [`speed`]) and a voltage
//! circle interpolated from inside ([`arc_room`]), a few tens of instructions each on a
//! Cortex-M4.

pub(crate) mod current;
pub(crate) mod flux;
pub(crate) mod light_load;
pub(crate) mod load_observer;
pub(crate) mod low_speed;
pub(crate) mod pi;
pub(crate) mod speed;

pub use current::{CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput};
pub use flux::{
    FluxConfig, FluxController, FluxDesign, SPEED_CAP_PER_BASE, max_speed_f64, mtpa_id_f64,
    weakening_current_f64,
};
pub use light_load::{
    LIGHT_LOAD_BANDS, LIGHT_LOAD_FILTER_S, LIGHT_LOAD_MAX_PER_LIMIT, LIGHT_LOAD_RAISED_PER_LIMIT,
    LightLoad, LightLoadConfig,
};
pub use low_speed::{LOW_SPEED_FADE_PER_RATED, LowSpeedConfig};
pub use pi::{Pi, PiConfig, PiOutput};
pub use speed::{
    IP_FORM, PI_FORM, SPEED_LOOP_DECIMATION, SpeedConfig, SpeedController, SpeedDesign, SpeedOutput,
};

use crate::error::ConfigError;
use crate::num::{Pu, mul_u16};

/// `√(1 − t²)` at `t = k/64`, `k = 0..=64`, in Q0.16 rounded down (1 held at 65535): the
/// arc of [`arc_room`] (130 bytes).
const ARC: [u16; 65] = [
    65535, 65527, 65503, 65463, 65407, 65335, 65247, 65142, 65021, 64884, 64731, 64560, 64373,
    64169, 63948, 63710, 63454, 63181, 62890, 62581, 62253, 61907, 61542, 61157, 60753, 60329,
    59884, 59418, 58931, 58421, 57889, 57334, 56755, 56152, 55523, 54867, 54184, 53473, 52733,
    51962, 51159, 50322, 49449, 48540, 47591, 46600, 45565, 44482, 43347, 42158, 40908, 39593,
    38204, 36735, 35175, 33511, 31727, 29801, 27704, 25394, 22805, 19829, 16255, 11539, 0,
];

/// `r √(1 − t²)` for `r ≥ 0` ([`Pu`]) and `t ∈ [0, 1]` in Q2.30 (zero from `t = 1` on): the
/// room left on the q axis of a voltage circle of radius `r` once d takes `t r`.
///
/// Never above the exact value, so the vector stays inside the circle: the arc is concave, so
/// the chords between the points of [`ARC`] (rounded down) lie below it, the chord is rounded
/// down, and one unit of Q0.16 more covers the 8 bits of `t` dropped (the chords' slopes are
/// below 12). Below it by at most `10⁻⁴ r` for `t ≤ ½`, `5·10⁻⁴ r` for `t ≤ 0.9`, `4·10⁻³ r`
/// up to `t = 63/64` and `0.05 r` in the last interval, where d takes nearly all of the
/// circle; two products and a table read (an exact root took ~130 instructions on a
/// Cortex-M4, several hundred on a Cortex-M0).
#[inline(always)]
pub(crate) fn arc_room(r: Pu, t: i32) -> Pu {
    if t >= 1 << 30 {
        return Pu::ZERO;
    }
    let t = t.max(0) as u32;
    let k = (t >> 24) as usize; // 0..=63
    let frac = (t >> 8) & 0xffff;
    let (g0, g1) = match (ARC.get(k), ARC.get(k + 1)) {
        (Some(&a), Some(&b)) => (u32::from(a), u32::from(b)),
        _ => (0, 0),
    };
    // g0 ≥ g1 (the arc falls): the chord, its fall rounded up, less one unit
    // ((g0 − g1) frac < 2³²).
    let g = (g0 - ((g0 - g1) * frac).div_ceil(0x1_0000)).saturating_sub(1);
    // r g rounded down (r < 2³¹, g < 2¹⁶: two 32-bit products on a Cortex-M0).
    Pu::from_bits(mul_u16(r.to_bits().max(0), g))
}

/// `c · x` rounded to nearest for a coefficient `|c| < 1` ([`Coef<31>`](crate::num::Coef)):
/// `|c x| < |x|`, so the result always fits an `i32` and needs no saturation test.
#[inline(always)]
pub(crate) fn frac_mul(c: crate::num::Coef<31>, x: i32) -> i32 {
    ((crate::num::wmul_inline(x, c.bits()) + (1 << 30)) >> 31) as i32
}

/// Checks `min ≤ value ≤ max` (finite) for a gain named `key`.
pub(crate) fn gain_in(
    key: &'static str,
    value: f64,
    min: f64,
    max: f64,
) -> Result<f64, ConfigError> {
    if value.is_finite() && value >= min && value <= max {
        Ok(value)
    } else {
        Err(ConfigError::Gain {
            key,
            value,
            min,
            max,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn the_arc_is_the_circle_rounded_down() {
        for (k, &g) in ARC.iter().enumerate() {
            let t = k as f64 / 64.0;
            let want = (libm::floor(65536.0 * libm::sqrt(1.0 - t * t)) as u32).min(65535);
            assert_eq!(u32::from(g), want, "k = {k}");
        }
    }

    #[test]
    fn arc_room_examples() {
        let one = Pu::from_num(1);
        let exact = |t: f64| libm::sqrt(1.0 - t * t);
        for (t, bound) in [
            (0.0, 1e-4),
            (0.5, 1e-4),
            (0.6, 5e-4),
            (0.9, 5e-4),
            (0.99, 0.05),
        ] {
            let got: f64 = arc_room(one, (t * (1u64 << 30) as f64) as i32).to_num();
            assert!(got <= exact(t) && got >= exact(t) - bound, "{t}: {got}");
        }
        assert_eq!(arc_room(one, 1 << 30), Pu::ZERO);
        assert_eq!(arc_room(one, i32::MAX), Pu::ZERO);
        assert_eq!(arc_room(Pu::ZERO, 0), Pu::ZERO);
    }

    proptest! {
        /// Never outside the circle, and within the documented distance inside it, for every
        /// radius of the format's positive half and every `t`.
        #[test]
        fn arc_room_is_inside_and_near(r in 0i32..=i32::MAX, t in 0i32..=1 << 30) {
            let got = arc_room(Pu::from_bits(r), t).to_bits() as f64;
            let tf = t as f64 / (1u64 << 30) as f64;
            let exact = r as f64 * libm::sqrt((1.0 - tf * tf).max(0.0));
            let slack = match tf {
                _ if tf <= 0.5 => 1e-4,
                _ if tf <= 0.9 => 5e-4,
                _ if tf <= 63.0 / 64.0 => 4e-3,
                _ => 0.05,
            };
            prop_assert!(got <= exact, "{got} > {exact}");
            prop_assert!(got >= exact - slack * r as f64 - 1.0, "{got} < {exact}");
        }
    }
}
