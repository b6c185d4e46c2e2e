//! The inverter's distortion voltage measured at standstill (docs/drive.md, "dead-time
//! calibration").
//!
//! Once the rotor's angle is known (after the initial position detection or the alignment)
//! and before it turns, the drive holds two d-axis currents `I_a = I/2` and `I_b = I` along it
//! through its current loops, each for a settling time and then an averaging time, and
//! records the mean commanded d voltage `y` (the loops' output plus the compensation's vector
//! as sent to the modulator), the mean measured d current `i` and the mean d part `D` of the
//! compensation's vector. At standstill the winding needs `R i`, and the inverter takes its
//! distortion `V_true g` from every command (`g` the d part of the sign pattern, the same for
//! both currents when each phase is beyond the ripple band):
//!
//! ```text
//! y = R i + V_true g    ⇒    V_true g = (y_a i_b − y_b i_a)/(i_b − i_a)
//! ```
//!
//! free of `R`, whatever the motor file says. The compensation was designed for `V_model g =
//! D`, so the drive scales its `V_dead` by `s = V_true g / D` (within [0, 4]) and runs with
//! what its inverter does, not what it was told.
//!
//! Formats: voltages and currents [`Pu`] (Q8.24), summed in units of 2⁻¹⁶ pu (clamped to
//! ±16 pu: ±2²⁰ each, so that [`MAX_AVERAGE`] of them fit an `i32`; the state stays small,
//! which the drive step's registers notice); the scale Q4.28. Integer only; the one division
//! per quantity runs once, at the end.

use crate::num::Pu;

/// The calibration's currents and times, per unit and in samples.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, crate::image::Words)]
pub(crate) struct CalibrationConfig {
    /// `I_a`, `I_b`; zero: no calibration.
    pub levels: [Pu; 2],
    /// Samples to settle at each current, then samples to average.
    pub settle: u32,
    pub average: u32,
}

impl CalibrationConfig {
    /// Whether the drive calibrates.
    pub fn enabled(&self) -> bool {
        self.levels[0] != Pu::ZERO && self.average > 0
    }
}

/// Most samples averaged at each current (the sums' range).
pub(crate) const MAX_AVERAGE: u32 = 1 << 10;

/// One in Q4.28 (the scale's format).
pub(crate) const SCALE_ONE: i32 = 1 << 28;

/// A measured scale within 1/32 (3 %) of one is taken as one: the measurement's own spread
/// (the ADC's steps, the ripple's residue) is about 1 %, and motor B's reversal under a hoist
/// load, which holds with the dead time the drive was told, lost its lock when told 0.2 %
/// less (docs/drive.md, "dead-time calibration").
const SCALE_DEAD_BAND: i32 = SCALE_ONE >> 5;

/// The calibration's progress.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) struct Calibration {
    /// Samples at the present current.
    count: u32,
    /// 0 at `I_a`, 1 at `I_b`.
    level: u8,
    /// Sums of `y`, `i`, `D` over the averaging samples of the present current.
    sums: [i32; 3],
    /// Their means at `I_a`.
    first: [i32; 3],
}

impl Calibration {
    /// The d current to hold at this sample.
    pub fn reference(&self, c: &CalibrationConfig) -> Pu {
        if self.level == 0 {
            c.levels[0]
        } else {
            c.levels[1]
        }
    }

    /// Records the sample's commanded d voltage `y`, measured d current `i` and the
    /// compensation's d voltage `d`; at the end the scale of `V_dead` (Q4.28), `SCALE_ONE`
    /// when the measurement cannot tell (no compensation, currents that did not differ).
    pub fn record(&mut self, c: &CalibrationConfig, y: Pu, i: Pu, d: Pu) -> Option<i32> {
        self.count = self.count.saturating_add(1);
        if self.count > c.settle {
            let clamp = |x: Pu| x.to_bits().clamp(-(1 << 28), 1 << 28) >> 8;
            for (s, x) in self.sums.iter_mut().zip([y, i, d]) {
                *s += clamp(x);
            }
        }
        if self.count < c.settle.saturating_add(c.average) {
            return None;
        }
        let n = c.average.clamp(1, MAX_AVERAGE) as i32;
        // `checked_div`: no panic path (n ≥ 1).
        let means = self.sums.map(|s| s.checked_div(n).unwrap_or(0));
        if self.level == 0 {
            *self = Self {
                level: 1,
                first: means,
                ..Self::default()
            };
            return None;
        }
        Some(scale(self.first, means))
    }
}

/// `s = V_true g / D` from the means `[y, i, D]` at the two currents, Q4.28 within [0, 4];
/// `SCALE_ONE` when `D ≤ 0`, the currents are within 1/64 pu of each other, or `s` is within
/// [`SCALE_DEAD_BAND`] of one.
fn scale(a: [i32; 3], b: [i32; 3]) -> i32 {
    let [ya, ia, da] = a.map(f64::from);
    let [yb, ib, db] = b.map(f64::from);
    let di = ib - ia;
    // Each mean within ±2²⁰ (units of 2⁻¹⁶ pu): the products within ±2⁴⁰, exact in `f64`
    // (once per calibration, in the task: no 64-bit integer division in a firmware).
    let d = (da + db) / 2.0;
    if libm::fabs(di) < 1024.0 || d <= 0.0 {
        return SCALE_ONE;
    }
    // (V_true g / D) · 2²⁸, V_true g within ±2²² (64 pu).
    let v_true_g = ((ya * ib - yb * ia) / di).clamp(-4_194_304.0, 4_194_304.0);
    let s = (v_true_g / d * f64::from(SCALE_ONE)).clamp(0.0, f64::from(4 * SCALE_ONE)) as i32;
    if (s - SCALE_ONE).abs() <= SCALE_DEAD_BAND {
        SCALE_ONE
    } else {
        s
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::num::pu_from_f64;

    /// Against the f64 formula: a winding of resistance `r` (pu) and an inverter of
    /// distortion `v_true g` under a compensation of `d`, with the currents reaching their
    /// references: the scale against `v_true g / d` over resistances, distortions
    /// from none to three times the model, and noisy samples (a deterministic ±2 % ripple):
    /// within 2e−3 (the sums' unit, 2⁻¹⁶ pu, is 1/1300 of this `D` of 0.02 pu).
    #[test]
    fn scale_against_reference() {
        let c = CalibrationConfig {
            levels: [pu_from_f64(1.0), pu_from_f64(0.5)],
            settle: 50,
            average: 400,
        };
        let mut worst: f64 = 0.0;
        for r in [0.005, 0.05, 0.3] {
            for ratio in [0.0, 0.5, 0.9, 1.0, 1.02, 1.7, 3.0] {
                let d = 0.02;
                let v_true_g = ratio * d;
                let mut cal = Calibration::default();
                let mut out = None;
                for k in 0..2 * (c.settle + c.average) {
                    let i_ref = cal.reference(&c).to_num::<f64>();
                    // Ripple with zero mean over the averaging window.
                    let wiggle = 0.02 * if k % 2 == 0 { 1.0 } else { -1.0 };
                    let i = i_ref * (1.0 + wiggle);
                    let y = r * i + v_true_g;
                    out = cal.record(&c, pu_from_f64(y), pu_from_f64(i), pu_from_f64(d));
                    if out.is_some() {
                        break;
                    }
                }
                let s = out.expect("a result") as f64 / SCALE_ONE as f64;
                // Within the dead band: one.
                let want = if (ratio - 1.0f64).abs() <= 1.0 / 32.0 {
                    1.0
                } else {
                    ratio
                };
                worst = worst.max((s - want).abs());
            }
        }
        assert!(worst < 2e-3, "{worst}");
        // Nothing to scale: no compensation, or equal currents.
        assert_eq!(scale([10, 1 << 16, 0], [5, 1 << 15, 0]), SCALE_ONE);
        assert_eq!(scale([10, 1 << 16, 100], [5, 1 << 16, 100]), SCALE_ONE);
        // Within [0, 4].
        assert_eq!(scale([1 << 18, 1 << 16, 1], [0, 1 << 15, 1]), 0);
        assert_eq!(scale([1 << 18, 1 << 16, 1], [1 << 18, 1 << 15, 1]), 4 << 28);
        assert!(!CalibrationConfig::default().enabled() && c.enabled());
    }
}
