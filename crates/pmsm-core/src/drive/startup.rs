//! Start-up of the drive without the estimator: the alignment, and the open-loop current-vector
//! ("I–f") start that the back-EMF estimators of Solsona, Valla, Muravchik (2000) need, since they see nothing at
//! standstill.
//!
//! # Open-loop start
//!
//! The current loops regulate `(I, 0)` in an imposed frame `θ_ol` that starts at the detected
//! rotor angle (the current along the rotor's d axis: no torque, no jerk) and accelerates at a
//! constant rate. The rotor lags the current vector by the angle where the torque
//! `K_T I sin(θ_ol − θ)` equals what the acceleration and the load need:
//! `δ = θ − θ_ol ∈ [−90°, 0]` turning forwards (mirrored backwards). Nothing but friction damps
//! the rotor's swing about that angle; the closed loop does, once it has taken over.
//!
//! # Handover
//!
//! At the handover speed the estimator has seen the EMF for a while. The rotor swings about its
//! lag angle, so the check is what physics allows whatever the swing: the estimated angle
//! within a quarter turn (plus [`HANDOVER_MARGIN`]) of the current vector, which rules out the
//! dangerous false lock half a turn away, and the estimated speed in the commanded direction
//! and at least [`HANDOVER_SPEED_TOLERANCE`] of the imposed one. Otherwise the drive trips
//! with a named fault rather than closing the loop on a wrong angle. The speed loop starts
//! from the torque current the rotor was getting, `I sin(−δ̂)`, so the handover is bumpless.
//!
//! # Alignment
//!
//! The d current along `θ = 0` ramps up over the first half of the alignment time and holds
//! over the second. Nothing in a current loop damps the rotor's swing about `θ = 0` (a heavy
//! rotor released at 120° still swings by ±90° after 0.5 s, and the estimator then starts on a
//! rotor that is neither there nor at rest), so the q axis is not regulated: its reference is
//! the measured `i_β`, the q error is zero, its PI (reset, without speed feed-forward at
//! `ω = 0`) puts out zero volts, and the β winding is shorted through the inverter. The swing's
//! EMF `ω ψ cos θ` then drives `i_β = −ω ψ cos θ / R`, whose torque brakes the rotor with the
//! electrical damping `1.5 p² ψ²/R` (docs/identification.md, the same held-voltage argument).

use super::Fault;
use super::config::DriveConfig;
use crate::angle::Angle;
use crate::frames::Dq;
use crate::num::{Pu, mul_unit};
use crate::observer::Estimate;

/// Tolerance of the handover angle check beyond the physical range [0, 90°].
pub const HANDOVER_MARGIN: Angle = Angle(1 << 28); // 22.5°
/// Smallest estimated speed at the handover, as a fraction of the imposed one.
pub const HANDOVER_SPEED_TOLERANCE: f64 = 0.25;

/// State of the alignment and of the open-loop start.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct OpenLoop {
    theta: Angle,
    omega: Pu,
    reverse: bool,
    count: u32,
}

impl OpenLoop {
    /// Alignment from its first sample.
    pub fn align() -> Self {
        Self::default()
    }

    /// The alignment's frame (θ = 0) and current reference `(I, i_β)`, `I` ramped over the
    /// first half of the alignment, `i_β` the measured current (zero q voltage: the module
    /// docs); counts the sample.
    pub fn align_frame(&mut self, c: &DriveConfig, i_beta: Pu) -> (Angle, Dq) {
        self.count = self.count.saturating_add(1);
        let half = (c.open_loop.align_samples / 2).max(1);
        let i = if self.count >= half {
            c.open_loop.current
        } else {
            // I · count/half in i64: the ramp is exact to an LSB and cannot overflow.
            let bits = (c.open_loop.current.to_bits() as i64 * self.count as i64)
                .checked_div(half as i64)
                .unwrap_or(0);
            Pu::from_bits(bits as i32)
        };
        (Angle::ZERO, Dq { d: i, q: i_beta })
    }

    /// The alignment has lasted its time.
    pub fn align_done(&self, c: &DriveConfig) -> bool {
        self.count >= c.open_loop.align_samples
    }

    /// Open-loop start from the rotor angle `theta`, backwards if `reverse`.
    pub fn start(theta: Angle, reverse: bool) -> Self {
        Self {
            theta,
            omega: Pu::ZERO,
            reverse,
            count: 0,
        }
    }

    /// Advances the imposed frame by one sample: its angle, speed and current reference
    /// `(I, 0)` (the current vector is the imposed d axis).
    pub fn advance(&mut self, c: &DriveConfig) -> (Angle, Pu, Dq) {
        let ol = &c.open_loop;
        let step = if self.reverse {
            ol.accel.saturating_neg()
        } else {
            ol.accel
        };
        self.omega = self.omega.saturating_add(step);
        self.theta = self.theta + Angle(ol.turn_per_speed.apply_bits(self.omega.to_bits()));
        (
            self.theta,
            self.omega,
            Dq {
                d: ol.current,
                q: Pu::ZERO,
            },
        )
    }

    /// The imposed frame has reached the handover speed.
    pub fn at_handover(&self, c: &DriveConfig) -> bool {
        self.omega.saturating_abs() >= c.open_loop.handover_speed
    }

    /// Checks the estimate against the imposed frame; on success the torque current the rotor
    /// gets in the estimated frame, per unit.
    pub fn handover(&self, est: &Estimate, c: &DriveConfig) -> Result<Pu, Fault> {
        // δ̂ = θ̂ − θ_ol, measured in the sense of rotation.
        let delta = if self.reverse {
            self.theta - est.theta
        } else {
            est.theta - self.theta
        };
        let angle_ok = delta.0.unsigned_abs() <= (Angle::HALF_PI.0 + HANDOVER_MARGIN.0) as u32;
        let tolerance = crate::num::pu_from_f64(HANDOVER_SPEED_TOLERANCE);
        let forward_speed = if self.reverse {
            est.omega.saturating_neg()
        } else {
            est.omega
        };
        let speed_ok = forward_speed >= crate::num::mul(tolerance, self.omega.saturating_abs());
        if !(angle_ok && speed_ok) {
            return Err(Fault::Handover(delta, est.omega));
        }
        // The current (I, 0) at θ_ol seen from the rotor at θ_ol + δ: q component I sin(−δ),
        // signed with the direction.
        let iq = mul_unit(c.open_loop.current, (-delta).sin_cos().sin);
        Ok(if self.reverse {
            iq.saturating_neg()
        } else {
            iq
        })
    }
}
