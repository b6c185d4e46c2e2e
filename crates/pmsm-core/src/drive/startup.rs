//! Start-up of the drive without the estimator: the alignment, and the open-loop current-vector
//! ("I–f") start that the back-EMF estimators of seed 000 need, since they see nothing at
//! standstill.
//!
//! # Open-loop start
//!
//! The current loops regulate `(0, ±I)` in an imposed frame `θ_ol` that accelerates from the
//! detected rotor angle at a constant rate. The current vector leads the imposed d axis by 90°,
//! so the rotor settles where the torque `K_T I cos(θ_ol − θ)` equals what the acceleration and
//! the load need: its d axis between the imposed frame (full torque) and the current vector
//! (no torque), `δ = θ − θ_ol ∈ [0, 90°]` turning forwards (mirrored backwards).
//!
//! # Handover
//!
//! At the handover speed the estimator has seen the EMF for a while. It takes over when its
//! angle lies where the rotor can be, `δ̂ ∈ [−HANDOVER_MARGIN, 90° + HANDOVER_MARGIN]`, and
//! its speed within [`HANDOVER_SPEED_TOLERANCE`] of the imposed one; otherwise the drive trips
//! with a named fault rather than closing the loop on a wrong angle. The speed loop starts
//! from the torque current the rotor was getting, `I cos δ̂`, so the handover is bumpless.

use super::Fault;
use super::config::DriveConfig;
use crate::angle::Angle;
use crate::frames::Dq;
use crate::num::{Pu, mul_unit};
use crate::observer::Estimate;

/// Tolerance of the handover angle check beyond the physical range [0, 90°].
pub const HANDOVER_MARGIN: Angle = Angle(1 << 28); // 22.5°
/// Largest relative speed difference accepted at the handover.
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

    /// The alignment's frame (θ = 0) and current reference `(I, 0)`; counts the sample.
    pub fn align_frame(&mut self, c: &DriveConfig) -> (Angle, Dq) {
        self.count = self.count.saturating_add(1);
        (
            Angle::ZERO,
            Dq {
                d: c.open_loop.current,
                q: Pu::ZERO,
            },
        )
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

    /// Advances the imposed frame by one sample: its angle, speed and current reference.
    pub fn advance(&mut self, c: &DriveConfig) -> (Angle, Pu, Dq) {
        let ol = &c.open_loop;
        let step = if self.reverse {
            ol.accel.saturating_neg()
        } else {
            ol.accel
        };
        self.omega = self.omega.saturating_add(step);
        self.theta = self.theta + Angle(ol.turn_per_speed.apply_bits(self.omega.to_bits()));
        let iq = if self.reverse {
            ol.current.saturating_neg()
        } else {
            ol.current
        };
        (self.theta, self.omega, Dq { d: Pu::ZERO, q: iq })
    }

    /// The imposed frame has reached the handover speed.
    pub fn at_handover(&self, c: &DriveConfig) -> bool {
        self.omega.saturating_abs() >= c.open_loop.handover_speed
    }

    /// Checks the estimate against the imposed frame; on success the torque current the rotor
    /// gets in the estimated frame, per unit.
    pub fn handover(&self, est: &Estimate, c: &DriveConfig) -> Result<Pu, Fault> {
        // δ̂ measured in the sense of rotation.
        let delta = if self.reverse {
            self.theta - est.theta
        } else {
            est.theta - self.theta
        };
        let angle_ok =
            delta.0 >= -HANDOVER_MARGIN.0 && delta.0 <= (Angle::HALF_PI.0 + HANDOVER_MARGIN.0);
        let speed_err = est.omega.saturating_sub(self.omega).saturating_abs();
        let tolerance = crate::num::pu_from_f64(HANDOVER_SPEED_TOLERANCE);
        let speed_ok = speed_err <= crate::num::mul(tolerance, self.omega.saturating_abs());
        if !(angle_ok && speed_ok) {
            return Err(Fault::Handover(delta, est.omega));
        }
        let iq = if self.reverse {
            c.open_loop.current.saturating_neg()
        } else {
            c.open_loop.current
        };
        Ok(mul_unit(iq, delta.sin_cos().cos))
    }
}
