//! The task's side of the high-frequency injection (docs/injection.md): the polarity check when
//! the drive comes back to zero speed (the speed loop's gains while the injection holds the
//! rotor: `speed_schedule`; the low-speed d current is off then: `DriveTask::run`).

use super::DriveTask;
use crate::angle::Angle;
use crate::drive::interface::DriveState;
use crate::drive::messages::{Mode, Window};
use crate::frames::{clarke, park};
use crate::num::Pu;
use crate::observer::PolarityReport;
use crate::observer::injection::polarity::Verdict;

impl DriveTask {
    /// The polarity check (`observer::injection::polarity`) in the closed loop: armed while
    /// the speed reference is beyond the injection's band (the drive runs), run once the
    /// injection holds the rotor at a steady reference within the band (the drive came back to
    /// zero speed). A reference that moves, or a rotor that leaves the band, ends it
    /// undecided: a load that pushes the rotor about at standstill is not a return to zero
    /// speed. A check that finds the angle a half turn off turns it and arms the
    /// verification; one that contradicts the turn turns back. Whether it turned (`true`).
    pub(super) fn check_polarity(&mut self, w: &Window, omega_ref: Pu) -> bool {
        let (Some(c), Some((_, band))) = (self.config.polarity, self.config.speed_injecting) else {
            return false;
        };
        let steady = self.injection_hold
            && omega_ref == self.polarity_ref
            && self.speed_filtered.saturating_abs() < band;
        self.polarity_ref = omega_ref;
        if omega_ref.saturating_abs() >= band {
            self.polarity_armed = true;
        }
        if !w.injecting {
            // The estimator has the angle, and its polarity.
            self.polarity.abort();
            self.polarity.settled();
        } else if self.polarity.running() {
            if !steady {
                self.polarity.abort();
            } else if let Some(v) = self.polarity.record(&c, ripple_d(w)) {
                if v == Verdict::Keep {
                    return false;
                }
                self.polarity_armed = v == Verdict::Turn;
                self.turn_half(w);
                return true;
            }
        } else if self.polarity_armed && steady {
            self.polarity_armed = false;
            self.polarity_from = self.i_ref.d;
            self.polarity.start();
        }
        false
    }

    /// The d-axis reference `d` with a running polarity check's bias: on the reference the
    /// check started from, held through it (MTPA and the light-load current follow the speed
    /// loop every period, and their steps would move the current the check measures).
    pub(super) fn polarity_d(&self, d: Pu) -> Pu {
        match self.config.polarity {
            Some(c) if self.polarity.running() => {
                Pu::from_bits(self.polarity_from.to_bits() + self.polarity.bias(&c).to_bits())
            }
            _ => d,
        }
    }

    /// What the polarity checks found since the drive was built (none without the
    /// injection).
    pub fn polarity(&self) -> PolarityReport {
        self.polarity.report()
    }

    /// The angle held is the magnet's south: the closed loop restarts a half turn from it, as
    /// from a detection (the injection restarts there with the estimator), the speed loop
    /// from the speed and no torque current.
    fn turn_half(&mut self, w: &Window) {
        let theta = w.theta_est + Angle(i32::MIN);
        self.iq_ref = Pu::ZERO;
        self.speed.reset(self.speed_filtered, Pu::ZERO);
        self.i_ref = self.d_reference();
        self.command(DriveState::Run, Mode::Run { from: Some(theta) });
    }
}

/// Half the injection's current step along the frame's d axis at the window's last sample:
/// that sample's current less the mean the current loops saw (the window's `i_dq`), both in
/// the frame of that sample.
fn ripple_d(w: &Window) -> Pu {
    let i = park(clarke(w.i_abc), w.theta.sin_cos());
    i.d.saturating_sub(w.i_dq.d)
}
