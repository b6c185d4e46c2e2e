//! The interrupt side's high-frequency injection (docs/injection.md): below its hand-over
//! speed the angle comes from the saliency, and the estimator takes over above it.

use super::{DriveIsr, PERIOD_SHIFT, Setpoint};
use crate::frames::{AlphaBeta, Dq};
use crate::observer::Estimator;

impl DriveIsr {
    /// The closed loop's setpoint from the injection while it runs, `None` while the
    /// estimator does. Hands over with hysteresis: to the injection when the estimated speed
    /// falls below `on_below` (the loop starts at the estimator's angle and speed), back when
    /// the injection's exceeds `off_above` (the estimator restarts at its angle and speed).
    /// Out of line: the drive without the injection pays a test of a flag.
    #[inline(never)]
    pub(super) fn injected(&mut self, i: AlphaBeta) -> Option<Setpoint> {
        let c = self.config.injection.as_ref()?;
        if self.injecting {
            let speed = self.injection.estimate().1.to_bits().saturating_abs();
            if speed > c.off_above.to_bits() {
                self.hand_back();
                return None;
            }
        } else {
            let e = self.estimator.estimate();
            if e.omega.to_bits().saturating_abs() >= c.on_below.to_bits() {
                return None;
            }
            // The estimator is not updated meanwhile (its health figure stands), and restarts
            // at the injection's angle when it takes back.
            self.injection.restart(c, e.theta, e.omega);
            self.injecting = true;
        }
        let (e, frame) = self.injection.update(c, i);
        self.telemetry.estimate = e;
        self.omega_sum = self
            .omega_sum
            .wrapping_add(e.omega.to_bits() >> PERIOD_SHIFT);
        Some(Setpoint {
            theta: e.theta,
            omega: e.omega,
            i_ref: self.i_ref,
            frame: Some(frame),
        })
    }

    /// The estimator takes the angle back, restarted at the injection's.
    #[cold]
    #[inline(never)]
    fn hand_back(&mut self) {
        let (theta, omega) = self.injection.estimate();
        self.estimator.reset(theta, omega);
        self.injecting = false;
    }

    /// The current loops' voltage `v` with the injection added along the frame's d axis while
    /// it runs.
    #[inline(always)]
    pub(super) fn with_injection(&mut self, v: Dq) -> Dq {
        if self.injecting {
            Dq {
                d: v.d.saturating_add(self.injection.voltage()),
                q: v.q,
            }
        } else {
            v
        }
    }
}
