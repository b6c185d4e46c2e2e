//! Temperature drift of the motor as piecewise-linear factors on its true resistance and
//! magnet flux over time (a scenario's `[thermal]` table).
//!
//! Copper's resistance rises about 0.39 %/K and a NdFeB magnet's remanence falls about
//! 0.1 %/K, so a winding heated by 100 K has `rs_factor` ≈ 1.4 and `flux_factor` ≈ 0.9. The
//! profile holds the first factor before its first time and the last after its last; in
//! between it interpolates linearly. [`Thermal::apply`] sets the factors on a plant
//! ([`crate::Plant::set_thermal_factors`]): the motor's resistance, magnet flux and torque
//! constant are scaled from the next period on, its state (currents, angle, speed) kept.

use pmsm_core::validate::in_range;
use pmsm_core::{ParamError, ParamReason};

use crate::{Plant, PlantError};

/// Largest number of breakpoints (no allocation in the plant).
pub const MAX_POINTS: usize = 32;

/// Piecewise-linear resistance and flux factors against time.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Thermal {
    t_s: [f64; MAX_POINTS],
    rs_factor: [f64; MAX_POINTS],
    flux_factor: [f64; MAX_POINTS],
    len: usize,
}

impl Thermal {
    /// A profile from breakpoints: times strictly increasing, factors in `[0.2, 5]`, all three
    /// of the same length (1 to [`MAX_POINTS`]). Errors name `thermal.<key>`.
    pub fn new(t_s: &[f64], rs_factor: &[f64], flux_factor: &[f64]) -> Result<Self, ParamError> {
        let len = t_s.len();
        if len == 0 || len > MAX_POINTS {
            return Err(ParamError {
                key: "thermal.t_s",
                reason: ParamReason::OutOfRange {
                    min: 1.0,
                    max: MAX_POINTS as f64,
                },
            });
        }
        for (key, v) in [
            ("thermal.rs_factor", rs_factor),
            ("thermal.flux_factor", flux_factor),
        ] {
            if v.len() != len {
                return Err(ParamError {
                    key,
                    reason: ParamReason::Inconsistent("thermal.t_s (as many values as times)"),
                });
            }
        }
        let mut out = Self {
            t_s: [0.0; MAX_POINTS],
            rs_factor: [1.0; MAX_POINTS],
            flux_factor: [1.0; MAX_POINTS],
            len,
        };
        let mut last = f64::NEG_INFINITY;
        for (k, ((t, r), f)) in t_s.iter().zip(rs_factor).zip(flux_factor).enumerate() {
            in_range("thermal.t_s", *t, 0.0, 1e6)?;
            if *t <= last {
                return Err(ParamError {
                    key: "thermal.t_s",
                    reason: ParamReason::Inconsistent("the previous time (strictly increasing)"),
                });
            }
            last = *t;
            if let (Some(a), Some(b), Some(c)) = (
                out.t_s.get_mut(k),
                out.rs_factor.get_mut(k),
                out.flux_factor.get_mut(k),
            ) {
                *a = *t;
                *b = in_range("thermal.rs_factor", *r, 0.2, 5.0)?;
                *c = in_range("thermal.flux_factor", *f, 0.2, 5.0)?;
            }
        }
        Ok(out)
    }

    /// `(rs_factor, flux_factor)` at time `t_s`.
    pub fn factors_at(&self, t_s: f64) -> (f64, f64) {
        let t = self.t_s.get(..self.len).unwrap_or(&[]);
        let r = self.rs_factor.get(..self.len).unwrap_or(&[]);
        let f = self.flux_factor.get(..self.len).unwrap_or(&[]);
        let first = (
            r.first().copied().unwrap_or(1.0),
            f.first().copied().unwrap_or(1.0),
        );
        if t.first().is_none_or(|&t0| t_s <= t0) {
            return first;
        }
        for k in 1..t.len() {
            if let (Some(&t0), Some(&t1)) = (t.get(k - 1), t.get(k))
                && t_s <= t1
            {
                let x = (t_s - t0) / (t1 - t0);
                let lerp = |v: &[f64]| {
                    let a = v.get(k - 1).copied().unwrap_or(1.0);
                    let b = v.get(k).copied().unwrap_or(1.0);
                    a + x * (b - a)
                };
                return (lerp(r), lerp(f));
            }
        }
        (
            r.last().copied().unwrap_or(1.0),
            f.last().copied().unwrap_or(1.0),
        )
    }

    /// Sets the factors at the plant's present time on `plant`.
    pub fn apply(&self, plant: &mut Plant) -> Result<(), PlantError> {
        let (r, f) = self.factors_at(plant.time_s());
        plant.set_thermal_factors(r, f)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn interpolates_and_holds() {
        let th = Thermal::new(&[1.0, 3.0], &[1.0, 1.4], &[1.0, 0.9]).unwrap();
        assert_eq!(th.factors_at(0.0), (1.0, 1.0));
        let (r, f) = th.factors_at(2.0);
        assert!((r - 1.2).abs() < 1e-12 && (f - 0.95).abs() < 1e-12);
        assert_eq!(th.factors_at(9.0), (1.4, 0.9));
        assert_eq!(
            Thermal::new(&[1.0, 1.0], &[1.0, 1.0], &[1.0, 1.0]).map_err(|e| e.key),
            Err("thermal.t_s")
        );
        assert_eq!(
            Thermal::new(&[0.0], &[9.0], &[1.0]).map_err(|e| e.key),
            Err("thermal.rs_factor")
        );
        assert_eq!(
            Thermal::new(&[0.0, 1.0], &[1.0], &[1.0, 1.0]).map_err(|e| e.key),
            Err("thermal.rs_factor")
        );
    }
}
