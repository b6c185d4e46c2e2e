//! The magnet's polarity, checked again when the drive comes back to zero speed on the
//! injection (docs/injection.md, "Polarity").
//!
//! The injection's angle error `sin 2(θ − θ̂)` has a zero on the d axis and one on its
//! opposite: the loop holds either. The angle it starts from (the detection's, the
//! estimator's) carries the polarity; the check tells, from the iron's saturation as the
//! initial position detection does (Khlaief, Boussak, Gossa (2012) §4), whether the axis it
//! holds is the magnet's north:
//!
//! ```text
//! bias     i_d* += +I_c for S + M task periods, then −I_c for S + M
//! measure  r_k = d̂(i_n) − d̂((i_n + i_{n−1})/2) = d̂(i_n − i_{n−1})/2     (the last sample
//!          of each of the M periods: half the injection's current step along d̂,
//!          V_h T_s / (2 L_inc), its sign the injection's at that sample, which the even
//!          task period keeps)
//!          S± = Σ r_k over the M periods of each bias
//! decide   c = (|S+| − |S−|)/|S−|:  c > 0 the bias along d̂ saturated the iron more
//!          (d̂ is north);  c < −margin: d̂ is south, the angle is turned by π
//! ```
//!
//! Current along the magnet's flux saturates the iron and lowers the incremental inductance
//! `L_inc`, so the injection's step grows; current against it relieves the iron. The
//! contrast `c` is the drive's evidence; a check between `−margin` and `margin` changes
//! nothing (a motor whose iron barely saturates at `I_c`).
//!
//! A turn is verified: the check runs again from the turned angle. A second `c < −margin`
//! contradicts the first (the evidence is not to be trusted on this motor, at this operating
//! point): the angle is turned back, and no more checks run until the estimator has given the
//! angle again. So a check misled by noise costs a transient, not a rotor held the wrong way.
//!
//! # Formats
//!
//! | signal | format | range |
//! |---|---|---|
//! | `I_c`, `r_k` | [`Pu`] Q8.24 of `I_b` | `I_c` within the speed loop's current limit |
//! | `S±` | `i64`, `Pu` bits | at most 255 terms of ±128 pu |
//! | `c`, margin | [`Pu`] | `c` saturated to ±127 |

use crate::num::{PU_FRAC, Pu, pu_from_f64};

/// Task periods of each bias before its measurement (the current loops settle).
pub const SETTLE_PERIODS: u8 = 6;
/// Task periods each bias is measured over.
pub const MEASURE_PERIODS: u8 = 16;
/// Least contrast, either way, the check acts on.
pub const MARGIN: f64 = 0.03;

/// The check's configuration.
#[derive(Clone, Copy, Debug, PartialEq, crate::image::Words)]
pub(crate) struct PolarityConfig {
    /// `I_c`, per unit.
    pub bias: Pu,
    pub settle: u8,
    pub measure: u8,
    pub margin: Pu,
}

impl PolarityConfig {
    /// The check with a bias of `bias_pu` of `I_b`.
    pub fn new(bias_pu: f64) -> Self {
        Self {
            bias: pu_from_f64(bias_pu),
            settle: SETTLE_PERIODS,
            measure: MEASURE_PERIODS,
            margin: pu_from_f64(MARGIN),
        }
    }
}

/// What the checks found since the drive was built.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct PolarityReport {
    /// Checks that ran to their end (verifications among them).
    pub checks: u32,
    /// Half turns of the angle: checks that found it a half turn off, and verifications that
    /// contradicted them.
    pub turns: u32,
    /// Verifications that contradicted the turn before them (and turned back).
    pub contradicted: u32,
    /// The last check's contrast `c` (module docs), per unit: positive when the angle held
    /// was the magnet's north.
    pub contrast: Pu,
}

/// What a check that ended asks of the drive.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Verdict {
    /// Keep the angle.
    Keep,
    /// Turn the angle by a half, and verify: run the check again.
    Turn,
    /// The verification contradicted the turn: turn back, and check no more.
    TurnBack,
}

/// The check's state.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct PolarityCheck {
    /// Task periods into the check; 0: not running.
    period: u16,
    sums: [i64; 2],
    /// The check verifies a turn.
    verify: bool,
    report: PolarityReport,
}

impl PolarityCheck {
    /// Starts a check (afresh if one runs).
    pub fn start(&mut self) {
        self.period = 1;
        self.sums = [0; 2];
    }

    /// Leaves a running check without a decision.
    pub fn abort(&mut self) {
        self.period = 0;
    }

    /// Forgets a turn to verify (the estimator gives the angle again).
    pub fn settled(&mut self) {
        self.verify = false;
    }

    /// Whether a check runs.
    pub fn running(&self) -> bool {
        self.period != 0
    }

    /// What the checks found.
    pub fn report(&self) -> PolarityReport {
        self.report
    }

    /// The bias to add to the d-axis reference this task period.
    pub fn bias(&self, c: &PolarityConfig) -> Pu {
        let half = u16::from(c.settle) + u16::from(c.measure);
        match self.period {
            0 => Pu::ZERO,
            p if p <= half => c.bias,
            _ => c.bias.saturating_neg(),
        }
    }

    /// One task period of a running check, `ripple` its `r_k` (module docs): the verdict
    /// when the check ends, `None` while it runs (or none runs).
    pub fn record(&mut self, c: &PolarityConfig, ripple: Pu) -> Option<Verdict> {
        if self.period == 0 {
            return None;
        }
        let (settle, measure) = (u16::from(c.settle), u16::from(c.measure));
        let half = settle + measure;
        let p = self.period;
        let k = usize::from(p > half);
        let into = if p > half { p - half } else { p };
        if into > settle
            && let Some(s) = self.sums.get_mut(k)
        {
            *s += i64::from(ripple.to_bits());
        }
        if p < 2 * half {
            self.period = p + 1;
            return None;
        }
        self.period = 0;
        let contrast = contrast(self.sums[0], self.sums[1]);
        let south = contrast < c.margin.saturating_neg();
        let r = &mut self.report;
        r.checks = r.checks.wrapping_add(1);
        r.turns = r.turns.wrapping_add(u32::from(south));
        r.contrast = contrast;
        let verdict = match (south, self.verify) {
            (false, _) => Verdict::Keep,
            (true, false) => Verdict::Turn,
            (true, true) => {
                r.contradicted = r.contradicted.wrapping_add(1);
                Verdict::TurnBack
            }
        };
        self.verify = verdict == Verdict::Turn;
        Some(verdict)
    }
}

/// `(|plus| − |minus|)/|minus|` per unit, saturated to ±127; zero when the sums have opposite
/// signs or `minus` is zero (no evidence).
fn contrast(plus: i64, minus: i64) -> Pu {
    if minus == 0 || (plus ^ minus) < 0 {
        return Pu::ZERO;
    }
    let (a, b) = (
        i128::from(plus.unsigned_abs()),
        i128::from(minus.unsigned_abs()),
    );
    let c = ((a - b) << PU_FRAC) / b;
    Pu::from_bits(c.clamp(-(127 << PU_FRAC), 127 << PU_FRAC) as i32)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The contrast in `f64` from the two sums: the reference.
    fn contrast_f64(a: f64, b: f64) -> f64 {
        (a.abs() - b.abs()) / b.abs()
    }

    /// Runs a check on ripples `r(sign, k)`: its verdict, its contrast and the reference's.
    fn check(r: impl Fn(f64, u32) -> f64) -> (Option<Verdict>, Pu, f64) {
        check_from(&mut PolarityCheck::default(), r)
    }

    /// [`check`] from the state `p`.
    fn check_from(
        p: &mut PolarityCheck,
        r: impl Fn(f64, u32) -> f64,
    ) -> (Option<Verdict>, Pu, f64) {
        let c = PolarityConfig::new(1.0);
        p.start();
        let (mut plus, mut minus) = (0.0, 0.0);
        let mut decision = None;
        for k in 0..2 * u32::from(SETTLE_PERIODS + MEASURE_PERIODS) {
            let sign = p.bias(&c).to_num::<f64>();
            let x = r(sign, k);
            let q = pu_from_f64(x);
            let half = u32::from(SETTLE_PERIODS + MEASURE_PERIODS);
            if k % half >= u32::from(SETTLE_PERIODS) {
                if k < half {
                    plus += q.to_num::<f64>()
                } else {
                    minus += q.to_num::<f64>()
                }
            }
            assert!(decision.is_none(), "decided before its end");
            decision = p.record(&c, q);
        }
        assert!(!p.running());
        (decision, p.report().contrast, contrast_f64(plus, minus))
    }

    #[test]
    fn the_contrast_matches_its_reference_and_decides() {
        // A step of 0.04 pu along d̂, 10 % larger under the bias along north, with a
        // deterministic noise of 0.003 pu; the injection's sign at the window's end is −.
        let noise = |k: u32| 0.003 * ((k as f64) * 1.7).sin();
        use Verdict::*;
        for (north_gain, verdict) in [(1.1, Keep), (1.0 / 1.1, Turn), (1.01, Keep)] {
            let (d, c, reference) =
                check(|sign, k| -0.04 * if sign > 0.0 { north_gain } else { 1.0 } + noise(k));
            assert_eq!(d, Some(verdict), "{north_gain}: {c:?} ({reference})");
            let err = (c.to_num::<f64>() - reference).abs();
            assert!(err < 1e-6, "{north_gain}: {c:?} against {reference}");
        }
    }

    #[test]
    fn a_turn_is_verified_and_a_contradicted_one_turned_back() {
        let south = |sign: f64, _| -0.04 * if sign > 0.0 { 0.9 } else { 1.0 };
        let north = |sign: f64, _| -0.04 * if sign > 0.0 { 1.1 } else { 1.0 };
        // Turned, then verified.
        let mut p = PolarityCheck::default();
        assert_eq!(check_from(&mut p, south).0, Some(Verdict::Turn));
        assert_eq!(check_from(&mut p, north).0, Some(Verdict::Keep));
        assert_eq!(check_from(&mut p, south).0, Some(Verdict::Turn));
        // Turned, then contradicted.
        assert_eq!(check_from(&mut p, south).0, Some(Verdict::TurnBack));
        let r = p.report();
        assert_eq!((r.checks, r.turns, r.contradicted), (4, 3, 1));
        // A turn the estimator settled is not verified.
        assert_eq!(check_from(&mut p, south).0, Some(Verdict::Turn));
        p.settled();
        assert_eq!(check_from(&mut p, south).0, Some(Verdict::Turn));
    }

    #[test]
    fn no_evidence_changes_nothing() {
        // Sums of opposite signs, or no ripple at all.
        assert_eq!(check(|sign, _| 0.04 * sign).0, Some(Verdict::Keep));
        assert_eq!(check(|_, _| 0.0).0, Some(Verdict::Keep));
        assert_eq!(contrast(5, 0), Pu::ZERO);
        assert_eq!(contrast(i64::MAX, 1), Pu::from_bits(127 << PU_FRAC));
    }

    #[test]
    fn the_bias_is_plus_then_minus_then_none() {
        let c = PolarityConfig::new(0.5);
        let mut p = PolarityCheck::default();
        assert_eq!(p.bias(&c), Pu::ZERO);
        p.start();
        assert_eq!(p.bias(&c), c.bias);
        let half = SETTLE_PERIODS + MEASURE_PERIODS;
        for _ in 0..half {
            p.record(&c, Pu::ZERO);
        }
        assert_eq!(p.bias(&c), c.bias.saturating_neg());
        p.abort();
        assert_eq!(p.bias(&c), Pu::ZERO);
        assert_eq!(p.record(&c, Pu::ZERO), None);
        assert_eq!(p.report().checks, 0);
    }
}
