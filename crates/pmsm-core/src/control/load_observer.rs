//! The load observer: the load's torque, as the q current that balances it, estimated from
//! the estimated speed and the measured q current once per task period, and fed forward
//! into the speed loop's output (docs/drive.md, "load observer").
//!
//! The rotor's motion per unit (`ω` of `ω_b`, currents of `I_b`) is
//! `dω/dt = (i_q − i_L)/τ_b`, `τ_b = J ω_b/(p K_T I_b)` (friction, a few per cent of the
//! load at most, is part of `i_L`). Over a task period `T_t` the observer predicts
//! `ω⁻ = ω̂_m + a (i_q − î_L)`, `a = T_t/τ_b`, and corrects both states by the estimated
//! speed's departure from it, `e = ω̄ − ω⁻`:
//!
//! ```text
//! ω̂_m = ω⁻ + l₁ e,    î_L ← î_L − l₂ e,    l₁ = 2 − 2z,    l₂ = (1 − z)²/a,
//! ```
//!
//! the error's two poles at `z = e^{−ω_o T_t}`. The speed loop answers a load step through its
//! integrator, at its own bandwidth; the observer at `ω_o`, half the task rate by default,
//! which a light rotor needs: half its rated torque stops a 600 V servo without its load from
//! half its rated speed in 6–9 ms, three task periods at 8 kHz.
//!
//! In `f32` (the task's arithmetic, as the tracker's): per period three products and a few
//! sums. The estimate is held within `±LOAD_MAX` per unit.

#![cfg_attr(not(feature = "load-observer"), allow(dead_code))]

use crate::error::ConfigError;
use crate::num::{PU_FRAC, Pu};
use crate::params::MotorParams;
use crate::units::PerUnit;

/// The largest load estimate, per unit of `I_b` (beyond every current limit the drive
/// designs).
const LOAD_MAX: f32 = 4.0;

/// One per unit in the bits of [`Pu`].
const PU_ONE: f32 = (1u32 << PU_FRAC) as f32;

/// The default bandwidth over `1/τ_b` ([`default_bandwidth_rad_s`]): the observer answers a
/// load step within a tenth of the time the base torque takes the rotor from rest to base
/// speed.
pub const LOAD_OBSERVER_BANDWIDTH: f64 = 10.0;

/// The largest share `R I_b/(ψ ω_r)` of the resistive drop in the EMF at rated speed with
/// which the default design runs the observer ([`default_bandwidth_rad_s`]).
pub const LOAD_OBSERVER_COPPER: f64 = 0.25;

/// The default bandwidth of the observer, rad/s: `LOAD_OBSERVER_BANDWIDTH/τ_b` within half
/// the task rate, for a back-EMF estimator on a motor whose resistive drop at the base
/// current is below `LOAD_OBSERVER_COPPER` of its EMF at rated speed; `None` otherwise.
///
/// - The current-model MRAS carries a mechanical model and a load estimate of its own.
/// - Where the resistance's drop is a large share of the voltage (gimbal motors: 30–60 % of
///   the power in copper), the estimated speed carries the resistance's and the inverter's
///   errors, and the observer passed them to the current: on the widened family eight of
///   its gimbal motors then ran out of the bars or lost the lock in the reversal.
/// - Scaled by `1/τ_b`, its gain on the speed's noise, `l₂ ≈ (ω_o T_t)² τ_b/T_t`, stays
///   small on a heavy rotor: at half the task rate on every motor, the random family's NLO
///   held 22 of seed 1's 24 surface motors and the MRAS on the EMF 9.
pub(crate) fn default_bandwidth_rad_s(
    motor: &MotorParams,
    base: &PerUnit,
    period_s: f64,
    back_emf: bool,
) -> Option<f64> {
    if !cfg!(feature = "load-observer") {
        return None;
    }
    let rated = crate::drive::rated_e_rad_s(motor, base);
    (back_emf && motor.rs_ohm * base.current_a < LOAD_OBSERVER_COPPER * motor.flux_wb * rated)
        .then(|| (LOAD_OBSERVER_BANDWIDTH / tau_b_s(motor, base)).min(0.5 / period_s))
}

/// The observer's coefficients.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub struct LoadObserverConfig {
    /// `T_t/τ_b`: the speed one per unit of current adds over a task period, per unit.
    a: f32,
    /// The correction's gains.
    l1: f32,
    l2: f32,
}

impl LoadObserverConfig {
    /// The observer of [`crate::DriveDesign::load_observer_rad_s`] (`bandwidth_rad_s`), `None`
    /// for none; a build without the feature `load-observer` refuses one.
    pub(crate) fn of_design(
        motor: &MotorParams,
        base: &PerUnit,
        period_s: f64,
        bandwidth_rad_s: Option<f64>,
    ) -> Result<Option<Self>, ConfigError> {
        match bandwidth_rad_s {
            None => Ok(None),
            Some(_) if !cfg!(feature = "load-observer") => Err(crate::params::ParamError {
                key: "load_observer_rad_s",
                reason: crate::params::ParamReason::Inconsistent(
                    "a build with the load observer (feature load-observer)",
                ),
            }
            .into()),
            Some(w) => Self::new(motor, base, period_s, w).map(Some),
        }
    }

    /// The observer of `motor` at the bases `base`, run every `period_s`, its error's poles
    /// at `bandwidth_rad_s`.
    ///
    /// Errors: `load_observer_rad_s` outside `(0, 1/period_s]` (a pole at `z ≥ e⁻¹`, where the
    /// discrete correction stays well damped), or a motor whose `τ_b` is not positive.
    pub fn new(
        motor: &MotorParams,
        base: &PerUnit,
        period_s: f64,
        bandwidth_rad_s: f64,
    ) -> Result<Self, ConfigError> {
        let w = crate::params::in_range(
            "load_observer_rad_s",
            bandwidth_rad_s,
            1e-9 / period_s,
            1.0 / period_s,
        )?;
        let tau_b = tau_b_s(motor, base);
        let a = period_s / tau_b;
        if !(a.is_finite() && a > 0.0) {
            return Err(crate::params::ParamError {
                key: "j_kg_m2",
                reason: crate::params::ParamReason::Inconsistent(
                    "a positive mechanical time constant J ω_b/(p K_T I_b)",
                ),
            }
            .into());
        }
        let z = exp_neg(w * period_s);
        Ok(Self {
            a: a as f32,
            l1: (2.0 - 2.0 * z) as f32,
            l2: ((1.0 - z) * (1.0 - z) / a) as f32,
        })
    }
}

/// `e^{−x}` for `0 ≤ x ≤ 1` by its Taylor series to the 18th power (the last term below
/// 2⁻⁵²): a few products where `libm::exp`'s reduction tables would cost a firmware's image a
/// kilobyte.
fn exp_neg(x: f64) -> f64 {
    let mut sum = 1.0;
    for k in (1..=18).rev() {
        sum = 1.0 - x * sum / f64::from(k);
    }
    sum
}

/// `τ_b = J ω_b/(p K_T I_b)`, s: the time the base current takes to bring the rotor from
/// rest to the base speed.
pub(crate) fn tau_b_s(motor: &MotorParams, base: &PerUnit) -> f64 {
    motor.j_kg_m2 * base.omega_e_rad_s / (motor.p() * motor.kt_nm_per_a * base.current_a)
}

/// The observer's state: the model's speed and the load estimate, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LoadObserver {
    omega: f32,
    load: f32,
}

impl LoadObserver {
    /// Starts from the speed `omega` without load.
    pub fn reset(&mut self, omega: Pu) {
        self.omega = omega.to_bits() as f32 / PU_ONE;
        self.load = 0.0;
    }

    /// One task period: the estimated speed's mean over it `omega` and the q current `i_q`
    /// that acted in it. Returns how much the load estimate moved (what the speed loop's
    /// output takes as its feed-forward's change), per unit.
    pub fn step(&mut self, c: &LoadObserverConfig, omega: Pu, i_q: Pu) -> Pu {
        let (w, i) = (
            omega.to_bits() as f32 / PU_ONE,
            i_q.to_bits() as f32 / PU_ONE,
        );
        let predicted = self.omega + c.a * (i - self.load);
        let e = w - predicted;
        self.omega = predicted + c.l1 * e;
        let load = (self.load - c.l2 * e).clamp(-LOAD_MAX, LOAD_MAX);
        let delta = load - self.load;
        self.load = load;
        // |delta| ≤ 2 LOAD_MAX: within Pu's range.
        Pu::from_bits((delta * PU_ONE) as i32)
    }

    /// The load estimate, per unit of `I_b`.
    #[cfg(test)]
    pub fn load(&self) -> Pu {
        Pu::from_bits((self.load * PU_ONE) as i32)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The observer in f64, the same equations: the reference.
    struct Reference {
        a: f64,
        l1: f64,
        l2: f64,
        omega: f64,
        load: f64,
    }

    impl Reference {
        fn step(&mut self, w: f64, i: f64) {
            let p = self.omega + self.a * (i - self.load);
            let e = w - p;
            self.omega = p + self.l1 * e;
            self.load -= self.l2 * e;
        }
    }

    fn setup() -> (LoadObserverConfig, f64, f64) {
        let (m, base) = (crate::fixtures::motor_b(), crate::fixtures::base_b());
        let period = 8.0 * base.sample_s;
        let w = 0.5 / period;
        (
            LoadObserverConfig::new(&m, &base, period, w).unwrap(),
            period / tau_b_s(&m, &base),
            libm::exp(-w * period),
        )
    }

    /// A rotor under a step of load, its speed sampled once per period: the estimate reaches
    /// the load within a few of the observer's time constants, and the f32 observer stays
    /// within 1e-5 per unit of the f64 one.
    #[test]
    fn a_load_step_is_found_within_a_few_time_constants_as_the_f64_reference_finds_it() {
        let (c, a, z) = setup();
        let mut obs = LoadObserver::default();
        obs.reset(Pu::from_bits(1 << 23));
        let mut r = Reference {
            a,
            l1: 2.0 - 2.0 * z,
            l2: (1.0 - z) * (1.0 - z) / a,
            omega: 0.5,
            load: 0.0,
        };
        // The plant: ω' = ω + a (i_q − i_L), the drive holding i_q at 0.1 pu, the load 0.4 pu
        // from period 10 on.
        let (mut omega, iq) = (0.5f64, 0.1f64);
        let mut worst = 0.0f64;
        let mut found = None;
        for k in 0..60 {
            let load = if k >= 10 { 0.4 } else { 0.1 };
            omega += a * (iq - load);
            let pu = |x: f64| crate::num::pu_from_f64(x);
            obs.step(&c, pu(omega), pu(iq));
            r.step(omega, iq);
            let got = obs.load().to_bits() as f64 / (1u64 << 24) as f64;
            worst = worst.max((got - r.load).abs());
            if k >= 10 && found.is_none() && (got - 0.4).abs() < 0.02 {
                found = Some(k - 10);
            }
        }
        assert!(worst < 1e-5, "{worst}");
        // Poles at z = e^{-1/2}: within 2 % in about 8 T_o, 16 periods.
        let found = found.expect("the load estimate reaches the load");
        assert!(found <= 16, "{found} periods");
        let end = obs.load().to_bits() as f64 / (1u64 << 24) as f64;
        assert!((end - 0.4).abs() < 1e-3, "{end}");
    }

    #[test]
    fn the_series_is_the_exponential_to_the_last_bits() {
        for k in 0..=100 {
            let x = f64::from(k) / 100.0;
            let (got, want) = (exp_neg(x), libm::exp(-x));
            assert!(
                (got - want).abs() <= 4.0 * f64::EPSILON * want,
                "{x}: {got} {want}"
            );
        }
    }

    #[test]
    fn a_bandwidth_beyond_the_task_rate_is_refused_by_name() {
        let (m, base) = (crate::fixtures::motor_b(), crate::fixtures::base_b());
        let period = 8.0 * base.sample_s;
        let e = LoadObserverConfig::new(&m, &base, period, 2.0 / period).unwrap_err();
        assert!(
            matches!(e, ConfigError::Param(p) if p.key == "load_observer_rad_s"),
            "{e:?}"
        );
    }
}
