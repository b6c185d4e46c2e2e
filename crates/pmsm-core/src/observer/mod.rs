//! Rotor position and speed estimators behind one interface, [`Estimator`].
//!
//! Every estimator is built from a configuration computed once in `f64` (motor parameters,
//! per-unit bases, gains, sample period) and validated, then fed one [`ObserverInput`] per
//! control sample. All signals are per unit (Q8.24) of the bases of
//! [`PerUnit`](crate::units::PerUnit).
//!
//! # Timing convention
//!
//! At sample `k` the input holds the current **sampled at** `t_k` and the voltage **applied
//! over** `[t_{k−1}, t_k)` (the command of the previous sample, after dead-time compensation if
//! any). The estimate returned is for `t_k`.

use crate::angle::Angle;
use crate::frames::AlphaBeta;
use crate::num::Pu;

/// What an estimator sees at one control sample, per unit.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ObserverInput {
    /// Stator current sampled at this instant, αβ, per unit of `I_b`.
    pub i: AlphaBeta,
    /// Stator voltage applied over the period that ended at this instant, αβ, per unit of
    /// `V_b`.
    pub v: AlphaBeta,
}

/// Rotor position and speed, as an estimator sees them.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Estimate {
    /// Electrical angle of the rotor d axis (magnet north).
    pub theta: Angle,
    /// Signed electrical speed, per unit of `ω_b` (positive: θ increasing).
    pub omega: Pu,
    /// Estimated back-EMF vector `ψ ω (−sin θ, cos θ)`, αβ, per unit of `V_b` (zero for
    /// estimators that do not estimate it).
    pub emf: AlphaBeta,
}

/// A rotor position and speed estimator, stepped once per control sample.
///
/// `update` is integer arithmetic only, never panics, never allocates, and saturates instead
/// of wrapping.
pub trait Estimator {
    /// Advances the estimator by one sample and returns the estimate at that sample.
    fn update(&mut self, input: &ObserverInput) -> Estimate;

    /// The estimate of the last [`Estimator::update`] (or of the last reset).
    fn estimate(&self) -> Estimate;

    /// How badly the estimator's model explains the last measurement: zero when it explains
    /// it exactly, growing as the lock is lost. Each estimator states what it measures (all
    /// per unit, `|x| + |y|` norms: no product, no root):
    ///
    /// - [`Nlo`], [`Ao`]: the innovation, measured interval-mean EMF minus the predicted one,
    ///   per unit of `V_b`;
    /// - [`MrasEmf`]: `| |ẽ| − ψ |ω̂| |`, the adjustable model's EMF against the adapted speed,
    ///   per unit of `V_b`;
    /// - [`MrasCurrent`]: the model's current error `|i_d − î_d| + |i_q − î_q|` (eq. 16), per
    ///   unit of `I_b`.
    ///
    /// The drive filters it and trips [`crate::drive::Fault::LossOfLock`] above a limit of the
    /// estimator's kind (`crate::drive::Protection`).
    fn health(&self) -> Pu;

    /// Restarts the estimator from a known rotor angle and speed (after an initial-position
    /// detection or an open-loop start), keeping its configuration.
    fn reset(&mut self, theta: Angle, omega: Pu);

    /// Holds the direction of rotation (`Some(forward)`) or lets the estimator judge it again
    /// (`None`). The drive holds it while its open loop imposes the direction from rest: an estimate whose EMF is still small may turn the wrong way for a few
    /// samples, and the direction tracker, free to flip only at low speed, would then lock on
    /// the mirror solution half a turn off. Estimators without a direction tracker ignore it.
    fn hold_direction(&mut self, _forward: Option<bool>) {}
}

pub(crate) mod ao;
pub(crate) mod direction;
pub(crate) mod emf;
pub(crate) mod injection;
pub(crate) mod mras_current;
pub(crate) mod mras_emf;
pub(crate) mod nlo;

pub use ao::{Ao, AoConfig};
pub(crate) use direction::Direction;
pub(crate) use emf::{EmfMeter, EmfMeterConfig};
pub use injection::InjectionDesign;
#[cfg(feature = "injection")]
pub use injection::InjectionFigures;
#[cfg(feature = "injection")]
pub use injection::polarity::PolarityReport;
#[cfg(feature = "injection")]
pub(crate) use injection::polarity::{PolarityCheck, PolarityConfig};
#[cfg(feature = "injection")]
pub(crate) use injection::{Injection, InjectionConfig};
pub use mras_emf::{MrasEmf, MrasEmfConfig};
pub use nlo::{Nlo, NloConfig};

use crate::error::ConfigError;
use crate::num::Gain;

/// Largest accepted `g T_s` of an observer gain: beyond it the observer keeps less than half a
/// sample of memory and passes the noise of the measured interval-mean EMF almost unfiltered.
pub const MAX_GAIN_TS: f64 = 2.0;

/// The matched pole `κ = 1 − exp(−g T_s)` of the observer gain `g` (key `gain`), which must lie
/// in `(0, MAX_GAIN_TS / T_s]`.
pub(crate) fn observer_pole(
    base: &crate::units::PerUnit,
    gain_rad_s: f64,
) -> Result<Gain, ConfigError> {
    let max = MAX_GAIN_TS / base.sample_s;
    if !(gain_rad_s > 0.0 && gain_rad_s <= max) {
        return Err(ConfigError::Gain {
            key: "gain",
            value: gain_rad_s,
            min: 0.0,
            max,
        });
    }
    gain("gain", 1.0 - libm::exp(-gain_rad_s * base.sample_s))
}

/// A configuration gain as a [`Gain`], or a typed error naming it.
pub(crate) fn gain(key: &'static str, value: f64) -> Result<Gain, ConfigError> {
    Gain::new(value).ok_or(ConfigError::Gain {
        key,
        value,
        min: 1e-9,
        max: 1e9,
    })
}

pub(crate) use mras_current::{MRAS_MODEL_WORDS, MrasDecay, MrasModelScaling};
pub use mras_current::{MrasCurrent, MrasCurrentConfig, MrasCurrentGains, MrasModel};

/// Which estimator a drive runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, crate::image::Words)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum EstimatorKind {
    /// Solsona, Valla, Muravchik (2000) NLO.
    Nlo,
    /// Solsona, Valla, Muravchik (2000) AO.
    Ao,
    /// Solsona, Valla, Muravchik (2000) MRAS on the AO.
    MrasEmf,
    /// Khlaief, Boussak, Gossa (2012) current-model MRAS.
    MrasCurrent,
}

/// The saliency ([`MotorParams::saliency`](crate::MotorParams::saliency)) from which
/// [`EstimatorKind::for_motor`] counts a motor as interior (`L_q/L_d` ≥ 1.083): below every
/// interior motor of the random family (`L_q/L_d` 1.1–2.5, saliency from 0.048), above every
/// surface motor (0).
pub const ESTIMATOR_SALIENCY: f64 = 0.04;

impl EstimatorKind {
    /// Back-EMF estimators see nothing at standstill: they need an open-loop start.
    pub fn needs_open_loop_start(self) -> bool {
        !matches!(self, EstimatorKind::MrasCurrent)
    }

    /// The estimator the defaults choose for `motor` (docs/drive.md, "which estimator"): the
    /// current-model MRAS of Khlaief, Boussak, Gossa (2012) on an interior motor (saliency at
    /// least [`ESTIMATOR_SALIENCY`]), whose model carries both inductances and which starts
    /// from standstill; the NLO of Solsona, Valla, Muravchik (2000) on a surface motor, the
    /// motor it is derived for, which held every surface motor of the random family (612 of
    /// 612 over thirty seeds, against the MRAS's misses on real surface motors: gimbal and
    /// servo motors whose resistance is most of their impedance).
    #[inline]
    pub fn for_motor(motor: &crate::params::MotorParams) -> Self {
        if motor.saliency() >= ESTIMATOR_SALIENCY {
            EstimatorKind::MrasCurrent
        } else {
            EstimatorKind::Nlo
        }
    }
}

/// The configuration of any estimator of the crate: coefficients only (the state is built
/// from it by [`AnyEstimator::new`]).
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
#[allow(clippy::large_enum_variant)]
pub enum EstimatorConfig {
    /// See [`NloConfig`].
    #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
    Nlo(NloConfig),
    /// See [`AoConfig`].
    #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
    Ao(AoConfig),
    /// See [`MrasEmfConfig`].
    #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
    MrasEmf(MrasEmfConfig),
    /// See [`MrasCurrentConfig`].
    #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
    MrasCurrent(MrasCurrentConfig),
}

impl EstimatorConfig {
    /// Which estimator it configures.
    pub fn kind(&self) -> EstimatorKind {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            EstimatorConfig::Nlo(_) => EstimatorKind::Nlo,
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            EstimatorConfig::Ao(_) => EstimatorKind::Ao,
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            EstimatorConfig::MrasEmf(_) => EstimatorKind::MrasEmf,
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            EstimatorConfig::MrasCurrent(_) => EstimatorKind::MrasCurrent,
        }
    }
}

/// Any estimator of the crate, without dynamic dispatch (no allocation, one concrete type
/// for the drive and the C interface). With the feature `select-estimators`, only the
/// variants whose features are on exist (the code of the others is not linked).
#[derive(Clone, Copy, Debug)]
#[allow(clippy::large_enum_variant)]
pub enum AnyEstimator {
    /// See [`Nlo`].
    #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
    Nlo(Nlo),
    /// See [`Ao`].
    #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
    Ao(Ao),
    /// See [`MrasEmf`].
    #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
    MrasEmf(MrasEmf),
    /// See [`MrasCurrent`].
    #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
    MrasCurrent(MrasCurrent),
}

impl AnyEstimator {
    /// The estimator `config` describes, at rest.
    pub fn new(config: &EstimatorConfig) -> Self {
        match *config {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            EstimatorConfig::Nlo(c) => AnyEstimator::Nlo(Nlo::new(c)),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            EstimatorConfig::Ao(c) => AnyEstimator::Ao(Ao::new(c)),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            EstimatorConfig::MrasEmf(c) => AnyEstimator::MrasEmf(MrasEmf::new(c)),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            EstimatorConfig::MrasCurrent(c) => AnyEstimator::MrasCurrent(MrasCurrent::new(c)),
        }
    }

    /// Which one it is.
    pub fn kind(&self) -> EstimatorKind {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(_) => EstimatorKind::Nlo,
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            AnyEstimator::Ao(_) => EstimatorKind::Ao,
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            AnyEstimator::MrasEmf(_) => EstimatorKind::MrasEmf,
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(_) => EstimatorKind::MrasCurrent,
        }
    }
}

/// The rotor frame an estimator already rotated the current into, for the drive to reuse.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Frame {
    /// sin/cos of the last estimate's angle `θ̂`, taken to 2⁻¹⁴ (`angle::sin_cos_frame`).
    pub sc: crate::angle::SinCos,
    /// The measured current of the last update in that frame, bit for bit what `park_frame`
    /// of the same current gives.
    pub i_dq: crate::frames::Dq,
    /// sin/cos of the next update's angle, `θ̂ + ω̂ T_s`, taken to 2⁻¹⁴ likewise.
    pub sc_next: crate::angle::SinCos,
}

impl AnyEstimator {
    /// For the estimators that rotate the measured current into their own estimated frame
    /// (the current-model MRAS): see [`Frame`]. `None` for the others.
    pub(crate) fn frame(&self) -> Option<Frame> {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => {
                let (sc, i_dq) = e.frame();
                Some(Frame {
                    sc,
                    i_dq,
                    sc_next: e.next_frame(),
                })
            }
            #[allow(unreachable_patterns)] // the only variant with `select-estimators`
            _ => None,
        }
    }

    /// The frame at `theta` for the drive's transforms, which take it to 2⁻¹⁴
    /// (`frames::park_frame`): the NLO's own when `theta` is its last estimate's angle (it
    /// computes `sin_cos_frame(θ̂)` for its EMF's direction), else `sin_cos_frame(theta)`. Out of
    /// line, as the sin/cos it stands for: the drive's step keeps its shape (a build without
    /// the NLO calls `sin_cos_frame` itself).
    #[cfg_attr(
        any(not(feature = "select-estimators"), feature = "nlo"),
        inline(never)
    )]
    #[cfg_attr(
        all(feature = "select-estimators", not(feature = "nlo")),
        inline(always)
    )]
    pub(crate) fn sin_cos_of(&self, theta: crate::angle::Angle) -> crate::angle::SinCos {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(e) if e.estimate().theta == theta => e.rotor_sin_cos(),
            _ => crate::angle::sin_cos_frame(theta),
        }
    }

    /// The current-model MRAS takes the gains of its low-speed schedule for its estimated
    /// speed ([`MrasCurrent::schedule`]); the others have none.
    #[inline(always)]
    pub(crate) fn schedule(&mut self) {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.schedule(e.estimate().omega),
            #[allow(unreachable_patterns)] // the only variant with `select-estimators`
            _ => {}
        }
    }

    /// The current-model MRAS holds its adaptation over the next `updates` updates
    /// ([`MrasCurrent::hold`]); the others have nothing to hold.
    #[inline(always)]
    #[cfg_attr(feature = "select-estimators", allow(unused_variables))]
    pub(crate) fn hold(&mut self, updates: u8) {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.hold(updates),
            #[allow(unreachable_patterns)] // the only variant with `select-estimators`
            _ => {}
        }
    }
}

impl Estimator for AnyEstimator {
    fn update(&mut self, input: &ObserverInput) -> Estimate {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(e) => e.update(input),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            AnyEstimator::Ao(e) => e.update(input),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            AnyEstimator::MrasEmf(e) => e.update(input),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.update(input),
        }
    }

    fn estimate(&self) -> Estimate {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(e) => e.estimate(),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            AnyEstimator::Ao(e) => e.estimate(),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            AnyEstimator::MrasEmf(e) => e.estimate(),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.estimate(),
        }
    }

    fn health(&self) -> Pu {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(e) => e.health(),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            AnyEstimator::Ao(e) => e.health(),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            AnyEstimator::MrasEmf(e) => e.health(),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.health(),
        }
    }

    fn reset(&mut self, theta: Angle, omega: Pu) {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(e) => e.reset(theta, omega),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            AnyEstimator::Ao(e) => e.reset(theta, omega),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            AnyEstimator::MrasEmf(e) => e.reset(theta, omega),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.reset(theta, omega),
        }
    }
    fn hold_direction(&mut self, forward: Option<bool>) {
        match self {
            #[cfg(any(not(feature = "select-estimators"), feature = "nlo"))]
            AnyEstimator::Nlo(e) => e.hold_direction(forward),
            #[cfg(any(not(feature = "select-estimators"), feature = "ao"))]
            AnyEstimator::Ao(e) => e.hold_direction(forward),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-emf"))]
            AnyEstimator::MrasEmf(e) => e.hold_direction(forward),
            #[cfg(any(not(feature = "select-estimators"), feature = "mras-current"))]
            AnyEstimator::MrasCurrent(e) => e.hold_direction(forward),
        }
    }
}

/// Default gain `g` of the observers of Solsona, Valla, Muravchik (2000) for `motor`: three times its rated electrical
/// speed (the base speed when it has no rating), within `[100, 0.25/T_s]` rad/s. Motor A
/// (1200 r/min, 3 pole pairs) gets 1131 rad/s; Solsona, Valla, Muravchik (2000) uses 1000.
pub fn default_observer_gain(
    motor: &crate::params::MotorParams,
    base: &crate::units::PerUnit,
) -> f64 {
    let rated_e = crate::drive::rated_e_rad_s(motor, base);
    // max/min, not clamp: clamp has a panic path (min > max) the firmware would link.
    (3.0 * rated_e).max(100.0).min(0.25 / base.sample_s)
}
