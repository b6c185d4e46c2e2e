//! The speed loop's gains by operating point: its own; slower while the injection holds the
//! rotor at low speed (docs/injection.md); stiffer above twice the open loop's handover speed,
//! where a back-EMF estimate is clean enough for a light rotor's stiff loop
//! (docs/khlaief2012.md, "stiffer above the handover"). Each change is bumpless
//! ([`crate::SpeedController::retune`]).

use super::DriveTask;
use crate::drive::messages::Window;
use crate::num::Pu;

impl DriveTask {
    /// The gains for this task period. Held at low speed on the injection's angle, the loop
    /// runs slower (`observer::injection::SPEED_SHARE` of the injection's tracking loop): the
    /// angle it reads steps with the ADC's, and a loop as fast as the tracking passes every
    /// step on to the rotor; a reference beyond the injection's band (a ramp through it)
    /// keeps the loop's own gains, so that it does not build the slower loop's lag and
    /// release it at the hand-over. The stiff gains apply from the filtered speed's passing
    /// twice the handover speed until it falls below one and a half times it.
    pub(super) fn speed_schedule(&mut self, w: &Window, omega_ref: Pu) {
        let c = &self.config;
        #[cfg(feature = "injection")]
        let hold = c
            .speed_injecting
            .is_some_and(|(_, _, band)| w.injecting && omega_ref.saturating_abs() < band);
        #[cfg(not(feature = "injection"))]
        let hold = {
            let _ = (w, omega_ref);
            false
        };
        let stiff = !hold
            && c.speed_stiff.is_some_and(|(_, _, above)| {
                let speed = self.speed_filtered.saturating_abs();
                if self.speed_stiff {
                    speed >= above.saturating_sub(Pu::from_bits(above.to_bits() >> 2))
                } else {
                    speed >= above
                }
            });
        #[cfg(feature = "injection")]
        let changed = hold != self.injection_hold || stiff != self.speed_stiff;
        #[cfg(not(feature = "injection"))]
        let changed = stiff != self.speed_stiff;
        if !changed {
            return;
        }
        #[cfg(feature = "injection")]
        let slower = c.speed_injecting.filter(|_| hold).map(|(_, s, _)| s);
        #[cfg(not(feature = "injection"))]
        let slower = None;
        let gains = slower
            .or(c.speed_stiff.filter(|_| stiff).map(|(_, s, _)| s))
            .or(c.speed_stiff.map(|(own, _, _)| own));
        #[cfg(feature = "injection")]
        let gains = gains.or(c.speed_injecting.map(|(own, _, _)| own));
        #[cfg(feature = "injection")]
        {
            self.injection_hold = hold;
        }
        self.speed_stiff = stiff;
        if let Some(g) = gains {
            self.speed.retune_gains(g, self.speed_filtered);
        }
    }
}
