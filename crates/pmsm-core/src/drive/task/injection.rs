//! The task's side of the high-frequency injection (docs/injection.md): the speed loop's gains
//! while it holds the rotor at low speed (the low-speed d current is off then: `DriveTask::run`).

use super::DriveTask;
use crate::drive::messages::Window;
use crate::num::Pu;

impl DriveTask {
    /// Held at low speed on the injection's angle, the speed loop runs slower
    /// (`observer::injection::SPEED_SHARE` of the injection's tracking loop): the angle it
    /// reads steps with the ADC's, and a loop as fast as the tracking passes every step on to
    /// the rotor. A reference beyond the injection's band (a ramp through it) keeps the loop's
    /// own gains, so that it does not build the slower loop's lag and release it at the
    /// hand-over. Bumpless: [`crate::SpeedController::retune`].
    pub(super) fn speed_gains(&mut self, w: &Window, omega_ref: Pu) {
        let Some((own, slower, band)) = self.config.speed_injecting else {
            return;
        };
        let slow = w.injecting && omega_ref.saturating_abs() < band;
        if slow != self.injection_hold {
            self.injection_hold = slow;
            let gains = if slow { slower } else { own };
            self.speed.retune(gains, self.speed_filtered);
        }
    }
}
