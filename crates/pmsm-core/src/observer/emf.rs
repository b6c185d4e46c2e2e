//! The back-EMF that the measurements imply over each sample interval.
//!
//! From `L di/dt = −R i − e + v` (equations.md §1), integrated exactly over
//! `[t_{k−1}, t_k]`, the mean EMF over the interval is
//!
//! ```text
//! ē_k = v̄_k − R (i_{k−1} + i_k)/2 − (L/T_s) (i_k − i_{k−1})
//! ```
//!
//! `v̄_k` is the mean voltage over the interval (what the inverter applied), the current term is
//! exact, and only `∫ R i` is approximated (trapezoid, error `R T_s² i''/12`). No derivative of
//! a measurement is taken: `L (i_k − i_{k−1})` is the exact volt-seconds stored in the
//! inductance. Every estimator of seed 000 is a filter of this quantity.

use crate::error::ConfigError;
use crate::frames::AlphaBeta;
use crate::num::{Gain, Pu};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// The coefficients of the interval-mean EMF: `R/2` and `L/T_s` in per unit.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct EmfMeterConfig {
    /// `R/Z_b / 2`.
    half_r: Gain,
    /// `L I_b / (V_b T_s)`: per-unit volts per per-unit current change in one sample.
    l_over_ts: Gain,
}

impl EmfMeterConfig {
    /// Coefficients for `motor` with inductance `l_h` (the surface motor's `L`, or `L_q`).
    pub fn new(motor: &MotorParams, base: &PerUnit, l_h: f64) -> Result<Self, ConfigError> {
        let l_h = crate::params::positive("ld_h", l_h)?;
        Ok(Self {
            half_r: super::gain("rs_ohm", 0.5 * motor.rs_ohm / base.impedance_ohm)?,
            l_over_ts: super::gain(
                "ld_h",
                l_h * base.current_a / (base.voltage_v * base.sample_s),
            )?,
        })
    }
}

/// Measured mean EMF over each interval: the state is the previous current sample.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct EmfMeter {
    previous_i: Option<AlphaBeta>,
}

impl EmfMeter {
    /// `ē_k` from the current at `t_k` and the mean voltage over `[t_{k−1}, t_k]`; `None` at
    /// the first sample (no interval yet).
    #[inline(always)]
    pub fn update(&mut self, c: &EmfMeterConfig, i: AlphaBeta, v: AlphaBeta) -> Option<AlphaBeta> {
        let prev = self.previous_i.replace(i)?;
        let component = |v: Pu, i0: Pu, i1: Pu| {
            let drop = c.half_r.apply(i0.saturating_add(i1));
            let stored = c.l_over_ts.apply(i1.saturating_sub(i0));
            v.saturating_sub(drop).saturating_sub(stored)
        };
        Some(AlphaBeta {
            alpha: component(v.alpha, prev.alpha, i.alpha),
            beta: component(v.beta, prev.beta, i.beta),
        })
    }

    /// Forgets the previous current (after a gap in the samples).
    pub fn restart(&mut self) {
        self.previous_i = None;
    }
}
