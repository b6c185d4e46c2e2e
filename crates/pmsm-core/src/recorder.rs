//! The fault recorder: the last `N` control samples before a fault, for the post-mortem.

use heapless::HistoryBuf;

use crate::drive::{DriveInput, DriveIsr, DriveState, Fault};
use crate::frames::{Abc, AlphaBeta};
use crate::num::Pu;
use crate::observer::Estimate;

/// One recorded control sample (per unit, see the table of [`FaultRecorder`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FaultSample {
    /// Phase currents given to the step.
    pub i_abc: Abc,
    /// Bus voltage given to the step.
    pub vdc: Pu,
    /// Voltage commanded by the step, αβ (zero while the outputs are off).
    pub v: AlphaBeta,
    /// The estimate after the step.
    pub estimate: Estimate,
    /// [`DriveState::code`] after the step.
    pub state: u8,
}

/// The last `N` samples before a fault.
///
/// It is not part of [`DriveIsr`](crate::DriveIsr) (the interrupt step's budget stays what
/// it is): the caller feeds it after each step, `recorder.record(&isr, &input)`, at a priority and a
/// cost of its choosing (a copy of eleven words into a ring buffer). It keeps the newest `N`
/// samples in a [`heapless::HistoryBuf`] and freezes when the drive enters `Fault`, so the
/// samples that led to the fault stay, ending with the one at which the drive tripped.
/// [`FaultRecorder::rearm`] empties it and records again (after `Drive::clear_fault`).
///
/// Every field is the drive's own per-unit word, so a dump replays bit for bit through the
/// fixed-point code (`pmsm observe`, or the estimators in a test):
///
/// | field | unit, format | meaning |
/// |---|---|---|
/// | `i_abc` | `I_b`, Q8.24 | phase currents the step was given |
/// | `vdc` | `V_b`, Q8.24 | bus voltage the step was given |
/// | `v` | `V_b`, Q8.24, αβ | voltage the step commanded (held over the next period) |
/// | `estimate` | turn (2³²), `ω_b` and `V_b` in Q8.24 | the estimator's output after the step |
/// | `state` | [`DriveState::code`] | the state after the step |
#[derive(Clone, Debug)]
pub struct FaultRecorder<const N: usize> {
    samples: HistoryBuf<FaultSample, N>,
    fault: Option<Fault>,
    /// The interrupt side's trip count at the first sample since (re)arming: a trip still
    /// latched then (cleared by the task, the outputs not yet back) is not a new fault.
    old_trips: Option<u32>,
}

impl<const N: usize> Default for FaultRecorder<N> {
    fn default() -> Self {
        Self::new()
    }
}

impl<const N: usize> FaultRecorder<N> {
    /// An empty, recording recorder (`N` > 0, checked at compile time).
    pub const fn new() -> Self {
        Self {
            samples: HistoryBuf::new(),
            fault: None,
            old_trips: None,
        }
    }

    /// Records the sample that the drive's interrupt side `isr` has just stepped on `input`,
    /// unless frozen. Returns true at the sample that freezes it (the interrupt side's first
    /// sample in `Fault`: its own trip, or the task's fault when it took it).
    pub fn record(&mut self, isr: &DriveIsr, input: &DriveInput) -> bool {
        if self.fault.is_some() || !self.position_in_range() {
            return false;
        }
        let state = isr.state();
        let old = *self.old_trips.get_or_insert(isr.trips());
        let t = isr.telemetry();
        self.samples.write(FaultSample {
            i_abc: input.i_abc,
            vdc: input.vdc,
            v: t.v,
            estimate: t.estimate,
            state: state.code(),
        });
        if let DriveState::Fault(f) = state
            && isr.trips() != old
        {
            self.fault = Some(f);
            return true;
        }
        false
    }

    /// The fault that froze the recorder, if it is frozen.
    pub fn fault(&self) -> Option<Fault> {
        self.fault
    }

    /// True once a fault froze the recorder.
    pub fn is_frozen(&self) -> bool {
        self.fault.is_some()
    }

    /// Number of samples held (at most `N`).
    pub fn len(&self) -> usize {
        self.samples.len()
    }

    /// True before the first sample.
    pub fn is_empty(&self) -> bool {
        self.samples.is_empty()
    }

    /// The samples, oldest first (the last one is the drive's first sample in `Fault` once
    /// frozen).
    pub fn samples(&self) -> impl Iterator<Item = &FaultSample> + '_ {
        // The guard never fails; it lets the compiler see that the slicing inside cannot.
        self.position_in_range()
            .then(|| self.samples.oldest_ordered())
            .into_iter()
            .flatten()
    }

    /// Sample `n`, oldest first.
    pub fn sample(&self, n: usize) -> Option<FaultSample> {
        self.samples().nth(n).copied()
    }

    /// The buffer's write position is below `N`. Always true; `HistoryBuf` indexes and slices
    /// its storage at that position, and testing it here (through its public accessors, which
    /// both return it) lets the compiler drop those bounds checks, so a firmware image keeps
    /// no panic path.
    fn position_in_range(&self) -> bool {
        let at = if self.samples.is_full() {
            self.samples.oldest_index()
        } else {
            Some(self.samples.len())
        };
        matches!(at, Some(k) if k < N)
    }

    /// Empties the recorder and records again.
    pub fn rearm(&mut self) {
        self.samples.clear();
        self.fault = None;
        self.old_trips = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::drive::{Drive, DriveConfig, DriveDesign, StartupMode};
    use crate::observer::EstimatorKind;
    use crate::params::{InverterParams, MotorParams};
    use crate::units::PerUnit;

    fn drive() -> Drive {
        let m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
        let inv = InverterParams {
            vdc_v: 300.0,
            pwm_hz: 10e3,
            dead_time_s: 1e-6,
            current_full_scale_a: 20.0,
        };
        let base = PerUnit::new(&m, &inv, 10_000.0).unwrap();
        let mut design = DriveDesign::default_for(&m, &inv, &base, EstimatorKind::Nlo);
        design.startup = StartupMode::Known(crate::angle::Angle::ZERO);
        Drive::new(DriveConfig::new(&m, &inv, 10_000.0, design).unwrap())
    }

    fn input(k: i32, vdc: f64) -> DriveInput {
        // Distinct, balanced currents per sample (a sum ≠ 0 would be a sensor fault).
        let a = Pu::from_bits(k * 1000);
        let b = Pu::from_bits(-k * 400);
        DriveInput {
            i_abc: Abc { a, b, c: -a - b },
            vdc: Pu::from_num(vdc),
        }
    }

    #[test]
    fn keeps_the_last_n_samples_oldest_first_and_freezes_at_the_fault() {
        let mut d = drive();
        d.start();
        let mut rec = FaultRecorder::<8>::new();
        let mut froze_at = None;
        for k in 0..40 {
            // The bus collapses from sample 30 on: under-voltage trip.
            let x = input(k, if k < 30 { 1.732 } else { 0.05 });
            d.step(&x);
            if rec.record(d.isr(), &x) {
                assert!(froze_at.is_none(), "froze twice");
                froze_at = Some(k);
            }
        }
        let k_fault = froze_at.expect("the bus collapse must trip the drive");
        assert!((30..40).contains(&k_fault), "tripped at {k_fault}");
        assert!(matches!(rec.fault(), Some(Fault::BusUnderVoltage(_))));
        assert_eq!(rec.len(), 8);
        // Oldest first: samples k_fault−7 … k_fault, each with its own input words.
        for (n, s) in rec.samples().enumerate() {
            let k = k_fault - 7 + n as i32;
            assert_eq!(s.i_abc, input(k, 0.0).i_abc, "sample {n}");
            assert_eq!(
                s.vdc,
                if k < 30 {
                    Pu::from_num(1.732)
                } else {
                    Pu::from_num(0.05)
                }
            );
        }
        let last = rec.samples().last().unwrap();
        assert_eq!(last.state, 5);
        assert!(rec.samples().take(7).all(|s| s.state != 5));
        // Frozen: later samples do not displace the ones before the fault.
        let first = *rec.samples().next().unwrap();
        for k in 40..60 {
            let x = input(k, 1.732);
            d.step(&x);
            assert!(!rec.record(d.isr(), &x));
        }
        assert_eq!(*rec.samples().next().unwrap(), first);
        assert_eq!(rec.len(), 8);

        rec.rearm();
        assert!(rec.is_empty() && !rec.is_frozen());
    }

    #[test]
    fn records_the_commanded_voltage_and_estimate_words() {
        let mut d = drive();
        d.start();
        let mut rec = FaultRecorder::<4>::new();
        for k in 0..3 {
            let x = input(k, 1.732);
            d.step(&x);
            rec.record(d.isr(), &x);
            let s = rec.samples().last().unwrap();
            let t = d.telemetry();
            assert_eq!((s.v, s.estimate), (t.v, t.estimate));
            assert_eq!(s.state, d.isr().state().code());
        }
        assert_eq!(rec.len(), 3);
        assert!(!rec.is_frozen());
    }
}
