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
        let slower = c
            .speed_injecting
            .filter(|&(_, band)| w.injecting && omega_ref.saturating_abs() < band);
        #[cfg(not(feature = "injection"))]
        let slower: Option<(crate::control::speed::SpeedGains, Pu)> = {
            let _ = (w, omega_ref);
            None
        };
        let speed = self.speed_filtered.saturating_abs();
        let stiff = c.speed_stiff.filter(|&(_, above)| {
            let from = if self.speed_stiff {
                above.saturating_sub(Pu::from_bits(above.to_bits() >> 2))
            } else {
                above
            };
            slower.is_none() && speed >= from
        });
        #[cfg(feature = "injection")]
        let held = self.injection_hold;
        #[cfg(not(feature = "injection"))]
        let held = false;
        if (slower.is_some(), stiff.is_some()) == (held, self.speed_stiff) {
            return;
        }
        #[cfg(feature = "injection")]
        {
            self.injection_hold = slower.is_some();
        }
        self.speed_stiff = stiff.is_some();
        let gains = slower.or(stiff).map_or(c.speed_own, |(g, _)| g);
        self.speed.retune_gains(gains, self.speed_filtered);
    }
}
