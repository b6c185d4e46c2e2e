//! The control loops of the drive of Khlaief, Boussak, Gossa (2012) (docs/khlaief2012.md §6–7): a fixed-point PI with
//! anti-windup ([`pi`]), the dq current controllers ([`current`]) and the IP speed controller
//! ([`speed`]).
//!
//! All of them follow the crate's split: a `Config::new` that designs and checks every
//! coefficient in `f64` once, and an integer-only `step` that saturates instead of wrapping
//! and reports it. Signals are per unit ([`Pu`], Q8.24) of [`PerUnit`](crate::units::PerUnit).
//!
//! The current and speed loops run on compile-time binary points ([`Coef`](crate::num::Coef)
//! gains, integrators whose LSB is the exact product's: [`pi::Pi`], [`speed`]) and exact
//! square roots in a fixed number of steps ([`isqrt_fast`], [`circle_room`]), a few tens of
//! instructions each on a Cortex-M4.

pub(crate) mod current;
pub(crate) mod flux;
pub(crate) mod light_load;
pub(crate) mod low_speed;
pub(crate) mod pi;
pub(crate) mod speed;

pub use current::{CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput};
pub use flux::{
    FluxConfig, FluxController, FluxDesign, SPEED_CAP_PER_BASE, max_speed_f64, mtpa_id_f64,
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
use crate::num::{Pu, sat_i32, wmul};
use crate::sqrt::isqrt_fast;

/// `√(r² − x²)` for `|x| ≤ r`, both [`Pu`] ≥ 0 in magnitude; 0 when `|x| ≥ r` (the room left on
/// the q axis of a voltage circle of radius `r` once d takes `x`). Exact: `⌊·⌋` to the LSB.
pub(crate) fn circle_room(r: Pu, x: Pu) -> Pu {
    let r = r.to_bits().unsigned_abs();
    let x = x.to_bits().unsigned_abs();
    if x >= r {
        return Pu::ZERO;
    }
    // (r − x)(r + x): the root of a Q.48 value is Q.24. Below 2^62 when r < 2^30 (64 pu):
    // a product of two i32; beyond, in u64 (the bit-by-bit root then).
    let sq = if r < 1 << 30 {
        wmul((r - x) as i32, (r + x) as i32) as u64
    } else {
        crate::num::umul(r - x, r + x)
    };
    Pu::from_bits(sat_i32(isqrt_fast(sq) as i64))
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
    fn circle_room_examples() {
        let one = Pu::from_num(1);
        assert_eq!(circle_room(one, Pu::ZERO), one);
        assert_eq!(circle_room(one, one), Pu::ZERO);
        assert_eq!(circle_room(one, Pu::from_num(2)), Pu::ZERO);
        let r = circle_room(Pu::from_num(5), Pu::from_num(-3));
        assert_eq!(r, Pu::from_num(4));
    }

    proptest! {
        #[test]
        fn circle_room_within_one_lsb(r in 0i32..1 << 30, x in any::<i32>()) {
            let got = circle_room(Pu::from_bits(r), Pu::from_bits(x)).to_bits() as f64;
            let (rf, xf) = (r as f64, (x as f64).abs());
            let exact = if xf >= rf { 0.0 } else { (rf * rf - xf * xf).sqrt() };
            prop_assert!((got - exact).abs() <= 1.0);
        }
    }
}
