//! Direction of rotation from the sense in which an EMF vector turns.
//!
//! `|ê|` gives only the magnitude of the speed (Solsona, Valla, Muravchik (2000) eq. 12, 19); its sign is the sense in
//! which `ê` turns. The angle step `Δφ` of a (filtered) EMF vector between samples is averaged
//! by a first-order filter of time constant [`TIME_CONSTANT_S`]; the direction flips when the
//! mean step exceeds a threshold of the other sign (hysteresis), so noise at standstill does
//! not toggle it. Through a reversal the EMF shrinks to zero and reappears turned by half a
//! turn: a step larger than a quarter turn is that flip, not a rotation, and is ignored. The
//! angle of a vector too small to have one (at start-up, at standstill) is not used at all.
//! And since a real reversal passes through zero speed, the direction may flip on that
//! threshold only while the EMF is small, below [`FLIP_SPEED_PU`] of the base speed: a burst
//! of angle noise at speed cannot turn the estimate half a turn.
//!
//! At speed it flips only when the EMF has kept turning the other way, its mean step at more
//! than half the speed its magnitude gives (and faster than [`FLIP_SPEED_PU`]), for
//! [`AT_SPEED_HOLD_S`]: that is no noise nor a transient (after an open-loop start the NLO's
//! EMF swings back and forth at a tenth of rated speed for a few milliseconds) but the mirror
//! solution, the estimate half a turn off and turning the wrong way (`(θ + π, −ω)` has the same EMF as `(θ, ω)` at
//! any instant, but the EMF keeps turning with the rotor). A back-EMF estimator driven
//! through zero speed by an overhauling load came out of it there, the rotor running one way
//! at speed and the estimate the other, with no fault for seconds (`cargo xtask family`,
//! seed 4); flipped, the estimate shows the rotor turning against the reference, which the
//! drive names ([`crate::drive::Fault::DrivenBackwards`]).

use crate::angle::Angle;

/// Time constant of the mean angle step, s.
pub const TIME_CONSTANT_S: f64 = 2e-3;
/// Speed, as a fraction of the base speed, that the mean step must exceed to flip.
pub const THRESHOLD_PU: f64 = 0.002;
/// Largest speed (fraction of the base speed, judged from the EMF) at which the direction may
/// flip.
pub const FLIP_SPEED_PU: f64 = 0.02;

/// How long the EMF must keep turning against the direction at speed before it flips, s.
pub const AT_SPEED_HOLD_S: f64 = 0.02;

/// The least flip threshold at speed, as a multiple of the threshold at low speed: the mean
/// step of [`FLIP_SPEED_PU`].
const AT_SPEED_FACTOR: i64 = (FLIP_SPEED_PU / THRESHOLD_PU) as i64;

/// Fractional bits of the filtered step (kept in `i64` to average sub-LSB steps).
const FRAC: u32 = 16;

/// The coefficients of the direction tracker: the filter's shift and the flip threshold.
#[derive(Clone, Copy, Debug, PartialEq, Eq, crate::image::Words)]
pub(crate) struct DirectionConfig {
    threshold: i64,
    /// Half the angle step of one sample at 1 pu of speed, angle LSB (the flip threshold at
    /// speed, per unit of the speed the EMF's magnitude gives): below 2³¹ for any accepted
    /// sample period (`ω_b T_s` below a turn).
    half_step_per_pu: i32,
    /// [`AT_SPEED_HOLD_S`] in samples.
    at_speed_samples: u16,
    /// The filter's shift (1..=16). (Small fields: the configuration is in every back-EMF
    /// estimator, and the Cortex-M0 holds several drives on its 16 KiB stack.)
    shift: u16,
}

impl DirectionConfig {
    /// Tracker for sample period `sample_s` and base electrical speed `omega_b_rad_s`.
    pub fn new(sample_s: f64, omega_b_rad_s: f64) -> Self {
        let samples = TIME_CONSTANT_S / sample_s;
        let shift = crate::num::log2_round(samples).clamp(1, 16) as u16;
        let step = THRESHOLD_PU * omega_b_rad_s * sample_s / Angle::RAD_PER_LSB;
        Self {
            shift,
            threshold: (step * (1u64 << FRAC) as f64) as i64,
            half_step_per_pu: libm::round(0.5 * omega_b_rad_s * sample_s / Angle::RAD_PER_LSB)
                .min(i32::MAX as f64) as i32,
            at_speed_samples: libm::ceil(AT_SPEED_HOLD_S / sample_s).clamp(1.0, 65535.0) as u16,
        }
    }
}

/// Tracks the direction of rotation of an EMF vector (the state; see [`DirectionConfig`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Direction {
    forward: bool,
    previous: Option<Angle>,
    /// Mean angle step per sample, in angle LSB · 2^FRAC.
    mean_step: i64,
    /// The direction is held (the drive's open loop imposes it).
    held: bool,
    /// Consecutive samples the EMF has turned against the direction at speed.
    against: u16,
}

impl Default for Direction {
    /// Forwards, no history.
    fn default() -> Self {
        Self {
            forward: true,
            previous: None,
            mean_step: 0,
            held: false,
            against: 0,
        }
    }
}

impl Direction {
    /// Feeds the angle of the EMF vector at this sample, whether the vector is large enough
    /// for its angle to mean anything, whether it is small enough for the rotor to be
    /// reversing ([`FLIP_SPEED_PU`]), and the speed its magnitude gives (per unit, `≥ 0`);
    /// returns `true` when turning forwards.
    pub fn update(
        &mut self,
        c: &DirectionConfig,
        phi: Angle,
        valid: bool,
        slow: bool,
        speed: crate::num::Pu,
    ) -> bool {
        if !valid {
            self.previous = None;
            return self.forward;
        }
        if let Some(prev) = self.previous.replace(phi) {
            let step = (phi - prev).0;
            if step.unsigned_abs() < 1 << 30 {
                let target = (step as i64) << FRAC;
                self.mean_step += (target - self.mean_step) >> c.shift;
            }
        }
        if self.held {
            self.against = 0;
            return self.forward;
        }
        let threshold = if slow {
            c.threshold
        } else {
            // |speed| < 2³¹ bits, the step per unit below 2³¹ LSB: the product fits.
            let half_step =
                (i64::from(speed.to_bits()).abs() * i64::from(c.half_step_per_pu)) >> (24 - FRAC);
            half_step.max(AT_SPEED_FACTOR * c.threshold)
        };
        let against = if self.forward {
            self.mean_step < -threshold
        } else {
            self.mean_step > threshold
        };
        self.against = if against && !slow {
            self.against.saturating_add(1)
        } else {
            0
        };
        if against && (slow || self.against >= c.at_speed_samples) {
            self.forward = !self.forward;
            self.against = 0;
        }
        self.forward
    }

    /// Holds the direction `Some(forward)` (no flip) or lets it flip again (`None`).
    /// The drive holds the direction (its open loop runs).
    pub fn is_held(&self) -> bool {
        self.held
    }

    pub fn hold(&mut self, forward: Option<bool>) {
        if let Some(f) = forward {
            self.forward = f;
        }
        self.held = forward.is_some();
    }

    /// Restarts with a known direction.
    pub fn reset(&mut self, forward: bool) {
        self.forward = forward;
        self.previous = None;
        self.mean_step = 0;
        self.against = 0;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An EMF turning backwards at low speed flips the direction, unless it is held; released,
    /// the same evidence flips it.
    #[test]
    fn a_held_direction_does_not_flip() {
        let c = DirectionConfig::new(5e-5, 1000.0);
        // 0.01 of the base speed backwards: far beyond the threshold (0.002).
        let step = -((0.01 * 1000.0 * 5e-5 / Angle::RAD_PER_LSB) as i32);
        let run = |d: &mut Direction| {
            let mut phi = Angle::ZERO;
            for _ in 0..2000 {
                phi = phi + Angle(step);
                d.update(&c, phi, true, true, crate::num::Pu::ZERO);
            }
            d.forward
        };
        let mut d = Direction::default();
        d.hold(Some(true));
        assert!(run(&mut d), "held");
        d.hold(None);
        assert!(!run(&mut d), "released");
    }

    /// At speed (an EMF whose magnitude gives 0.1 pu): an EMF turning the other way at that
    /// speed (the mirror solution) flips the direction within the hold time and five time
    /// constants of the filter, not before the hold time; turning the other way at 0.04 pu (less than half the speed its magnitude gives:
    /// a transient) it does not, nor does angle noise of ±0.2 pu per sample around a forward
    /// rotation at 0.1 pu.
    #[test]
    fn at_speed_only_a_steady_reverse_turning_flips() {
        let ts = 5e-5;
        let c = DirectionConfig::new(ts, 1000.0);
        let per_sample = |pu: f64| (pu * 1000.0 * ts / Angle::RAD_PER_LSB) as i32;
        let speed = crate::num::pu_from_f64(0.1);
        let flipped_after = |steps: &dyn Fn(u32) -> i32| {
            let mut d = Direction::default();
            let mut phi = Angle::ZERO;
            for k in 0..4000 {
                phi = phi + Angle(steps(k));
                if !d.update(&c, phi, true, false, speed) {
                    return Some(k);
                }
            }
            None
        };
        let tau = (TIME_CONSTANT_S / ts) as u32;
        let hold = (AT_SPEED_HOLD_S / ts) as u32;
        let k = flipped_after(&|_| -per_sample(0.1)).expect("the mirror flips");
        assert!((hold..hold + 5 * tau).contains(&k), "{k} samples");
        assert_eq!(flipped_after(&|_| -per_sample(0.04)), None);
        let noisy = |k: u32| {
            let n = if k.is_multiple_of(2) { 0.2 } else { -0.2 };
            per_sample(0.1 + n)
        };
        assert_eq!(flipped_after(&noisy), None);
    }
}
