//! Direction of rotation from the sense in which an EMF vector turns.
//!
//! `|ê|` gives only the magnitude of the speed (Solsona, Valla, Muravchik (2000) eq. 12, 19); its sign is the sense in
//! which `ê` turns. The angle step `Δφ` of a (filtered) EMF vector between samples is averaged
//! by a first-order filter of time constant [`TIME_CONSTANT_S`]; the direction flips when the
//! mean step exceeds a threshold of the other sign (hysteresis), so noise at standstill does
//! not toggle it. Through a reversal the EMF shrinks to zero and reappears turned by half a
//! turn: a step larger than a quarter turn is that flip, not a rotation, and is ignored. The
//! angle of a vector too small to have one (at start-up, at standstill) is not used at all.
//! And since a real reversal passes through zero speed, the direction may only flip while the
//! EMF is small, below [`FLIP_SPEED_PU`] of the base speed: a burst of angle noise at speed
//! cannot turn the estimate half a turn.

use crate::angle::Angle;

/// Time constant of the mean angle step, s.
pub const TIME_CONSTANT_S: f64 = 2e-3;
/// Speed, as a fraction of the base speed, that the mean step must exceed to flip.
pub const THRESHOLD_PU: f64 = 0.002;
/// Largest speed (fraction of the base speed, judged from the EMF) at which the direction may
/// flip.
pub const FLIP_SPEED_PU: f64 = 0.02;

/// Fractional bits of the filtered step (kept in `i64` to average sub-LSB steps).
const FRAC: u32 = 16;

/// The coefficients of the direction tracker: the filter's shift and the flip threshold.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct DirectionConfig {
    shift: u32,
    threshold: i64,
}

impl DirectionConfig {
    /// Tracker for sample period `sample_s` and base electrical speed `omega_b_rad_s`.
    pub fn new(sample_s: f64, omega_b_rad_s: f64) -> Self {
        let samples = TIME_CONSTANT_S / sample_s;
        let shift = libm::round(libm::log2(samples)).clamp(1.0, 16.0) as u32;
        let step = THRESHOLD_PU * omega_b_rad_s * sample_s / Angle::RAD_PER_LSB;
        Self {
            shift,
            threshold: (step * (1u64 << FRAC) as f64) as i64,
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
}

impl Default for Direction {
    /// Forwards, no history.
    fn default() -> Self {
        Self {
            forward: true,
            previous: None,
            mean_step: 0,
            held: false,
        }
    }
}

impl Direction {
    /// Feeds the angle of the EMF vector at this sample, whether the vector is large enough
    /// for its angle to mean anything, and whether it is small enough for the rotor to be
    /// reversing ([`FLIP_SPEED_PU`]); returns `true` when turning forwards.
    pub fn update(&mut self, c: &DirectionConfig, phi: Angle, valid: bool, slow: bool) -> bool {
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
        let slow = slow && !self.held;
        if slow && self.forward && self.mean_step < -c.threshold {
            self.forward = false;
        } else if slow && !self.forward && self.mean_step > c.threshold {
            self.forward = true;
        }
        self.forward
    }

    /// Holds the direction `Some(forward)` (no flip) or lets it flip again (`None`).
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
                d.update(&c, phi, true, true);
            }
            d.forward
        };
        let mut d = Direction::default();
        d.hold(Some(true));
        assert!(run(&mut d), "held");
        d.hold(None);
        assert!(!run(&mut d), "released");
    }
}
