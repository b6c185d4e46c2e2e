//! The current-model MRAS held through a phase current's zero crossing at low speed and light
//! load (docs/drive.md, "Zero crossings at low speed").
//!
//! Where a phase current crosses zero its leg's dead-time error flips from `−V_dead` to
//! `+V_dead`, and how it flips (the current clamped near zero, the ripple crossing back and
//! forth at each switching edge) is the inverter's, not the compensation's band. For a few
//! milliseconds the estimator's voltage is then wrong by up to `(4/3) V_dead`. At speed the EMF
//! dwarfs that; at 30 r/min on motor B (540 V, 2 µs, 14 kHz: 15 V of distortion against 3 V of
//! EMF) the current-model MRAS read each crossing as a position error, its angle jumped by
//! 0.03 rad, and the speed loop turned the jumps into dips of 9.4 r/min.
//!
//! So the drive holds the estimator's adaptation ([`crate::MrasCurrent::hold`]: the model
//! follows the measured current, the speed the mechanical model alone) while
//!
//! - the estimated speed is below the one whose EMF equals the compensation's `V_dead` at the
//!   bus measured (`|ω̂| ψ < V_dead`: 160 r/min on motor B), where the distortion's error is as
//!   large as the signal the MRAS reads the rotor from; with the compensation off it never
//!   holds;
//! - the load is light and has been for a while: `|i_q*|` through its 16 ms filter (the
//!   light-load current's) below 1.5 compensation bands `i_band` (the ripple amplitude,
//!   0.19 A on motor B), at every check for four of that filter's time constants (64 ms). A
//!   loaded reversal through zero needs the adaptation, and there the load changes sign under
//!   a rotor near zero speed and `i_q*` crosses zero with it: gated on `|i_q*|` itself (below
//!   three bands) one motor of the random family lost its lock there, and gated on the filter
//!   alone the reversal of `tests/drive_robustness.rs` strayed 0.86 rad instead of 0.48;
//! - a phase current lies within `1.5 i_band` of zero (the ripple's reach and the clamp's
//!   bounce), while the low-speed d current (docs/drive.md, "low-speed current") exceeds
//!   `4 i_band`, so that each crossing is brief (without it every phase sits near zero at
//!   light load and the MRAS would never adapt).
//!
//! The drive's task checks once per task period (eight samples), from the phase currents of
//! the window's last sample, and the interrupt side holds the eight updates after it takes
//! the task's command: at 160 r/min on motor B a crossing lasts some 50 samples.
//!
//! Formats: all thresholds [`Pu`] magnitudes in bits (Q8.24 of `ω_b`, `V_b` and `I_b`).

use crate::frames::Abc;
use crate::num::Pu;
#[cfg(test)]
use crate::num::pu_from_f64;

/// The band multiple within which a phase current is at its zero crossing.
pub const NEAR_BANDS: f64 = 1.5;
/// The band multiple the low-speed d current must exceed.
pub const FAR_BANDS: f64 = 4.0;
/// The band multiple below which the filtered `|i_q*|` is light load.
pub const LIGHT_BANDS: f64 = 1.5;

// `ZeroCrossing::holds` computes them as `band + band/2` and `band << 2`.
const _: () = assert!(NEAR_BANDS == 1.5 && LIGHT_BANDS == 1.5 && FAR_BANDS == 4.0);

/// The hold's state: how many checks in a row the load has been light.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct ZeroCrossing {
    light_for: u16,
}

impl ZeroCrossing {
    /// One check (every eighth sample): whether to hold at the estimated speed `omega`, the
    /// filtered `|i_q*|` `iq_level` and the low-speed d current `id_low`, with the phase
    /// currents `i`, the compensation's band `band` and its distortion voltage `v_dead` at the
    /// bus measured ([`Pu`] bits; `v_dead` zero: never), once the load has been light for
    /// `settle` checks in a row.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn holds(
        &mut self,
        omega: Pu,
        iq_level: Pu,
        id_low: Pu,
        i: &Abc,
        band: u32,
        v_dead: u32,
        settle: u32,
    ) -> bool {
        let mag = |x: Pu| x.to_bits().unsigned_abs();
        // NEAR_BANDS and LIGHT_BANDS, 1.5, in a shift and an add; FAR_BANDS, 4, a shift.
        let near = band + (band >> 1);
        self.light_for = if mag(iq_level) < near {
            self.light_for.saturating_add(1)
        } else {
            0
        };
        u32::from(self.light_for) >= settle
            && mag(omega) < v_dead
            && mag(id_low) > band << 2
            && mag(i.a).min(mag(i.b)).min(mag(i.c)) < near
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The fixed-point decision against its f64 definition over a grid of speeds, filtered q
    /// references, low-speed currents and current vectors at every angle, with motor B's band
    /// (0.193 A of 3.58 A) and distortion (15.1 V of 311.8 V, 0.0485 pu); identical away from
    /// a threshold's own LSB, once the load has been light for the checks asked; never
    /// without a distortion voltage.
    #[test]
    fn holds_as_its_f64_definition() {
        const SETTLE: u32 = 5;
        let base = crate::fixtures::base_b();
        let (band, v_dead) = (0.1928 / base.current_a, 15.12 / 311.8);
        let bits = |x: f64| pu_from_f64(x).to_bits().unsigned_abs();
        let (b, v) = (bits(band), bits(v_dead));
        let mut held = 0;
        let mut total = 0;
        for w in [-0.1, -0.04, 0.0, 0.01, 0.047, 0.049, 0.2] {
            for level in [0.0, 0.03, 0.08, 0.082, 0.5] {
                for id in [0.0, 0.2, 0.22, 0.9] {
                    for amp in [0.05, 0.7] {
                        for k in 0..360 {
                            let th = (k as f64).to_radians();
                            let ph = [0.0, -2.0, 2.0]
                                .map(|s: f64| amp * (th + s * core::f64::consts::FRAC_PI_3).cos());
                            let want = f64::abs(w) < v_dead
                                && level < LIGHT_BANDS * band
                                && id > FAR_BANDS * band
                                && ph.iter().any(|x| x.abs() < NEAR_BANDS * band);
                            let i = Abc {
                                a: pu_from_f64(ph[0]),
                                b: pu_from_f64(ph[1]),
                                c: pu_from_f64(ph[2]),
                            };
                            let (w, level, id) =
                                (pu_from_f64(w), pu_from_f64(level), pu_from_f64(id));
                            // Not before the load has been light for `SETTLE` checks.
                            let mut z = ZeroCrossing::default();
                            for _ in 1..SETTLE {
                                assert!(!z.holds(w, level, id, &i, b, v, SETTLE));
                            }
                            let got = z.holds(w, level, id, &i, b, v, SETTLE);
                            assert_eq!(got, want, "{th} {amp}");
                            assert!(!z.holds(w, level, id, &i, b, 0, SETTLE));
                            held += usize::from(want);
                            total += 1;
                        }
                    }
                }
            }
        }
        // The grid reaches both answers.
        assert!(held > 1000 && held < total / 4, "{held} of {total}");
    }
}
