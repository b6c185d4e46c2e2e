//! `[faults]`: faults injected into the plant at given times.

use pmsm_core::validate::{in_range, non_negative, positive};
use pmsm_core::{ParamError, ParamReason};
use serde::Deserialize;

/// `[faults]` of a scenario: faults injected into the plant at given times.
///
/// ```toml
/// [faults]
/// phase_open = "a"          # a broken phase (a, b or c) ...
/// phase_open_at_s = 1.2     # ... from this time
/// locked_rotor_at_s = 1.5   # the rotor jams
/// adc_stuck_phase = "b"     # a current channel freezes at its value ...
/// adc_stuck_at_s = 1.0      # ... from this time
/// vdc_sag_at_s = 1.3        # the bus drops ...
/// vdc_sag_to_v = 200.0      # ... to this voltage
/// short_phases = "ab"       # a short between two terminals ...
/// short_at_s = 1.1          # ... from this time ...
/// short_ohm = 0.5           # ... of this resistance (default 0.1 Ω)
/// ```
#[derive(Clone, Copy, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Faults {
    /// Phase to open.
    pub phase_open: Option<Phase>,
    /// When, s.
    pub phase_open_at_s: Option<f64>,
    /// When the rotor locks, s.
    pub locked_rotor_at_s: Option<f64>,
    /// Current channel to freeze.
    pub adc_stuck_phase: Option<Phase>,
    /// When, s.
    pub adc_stuck_at_s: Option<f64>,
    /// When the bus sags, s.
    pub vdc_sag_at_s: Option<f64>,
    /// To what, V.
    pub vdc_sag_to_v: Option<f64>,
    /// Terminals shorted together.
    pub short_phases: Option<PhasePair>,
    /// When, s.
    pub short_at_s: Option<f64>,
    /// Resistance of the short, Ω.
    pub short_ohm: Option<f64>,
}

impl Faults {
    /// Times not negative, each fault with its companion key, a bus sag within range and a
    /// short of positive resistance.
    pub(super) fn check(&self) -> Result<(), ParamError> {
        for (key, t) in [
            ("faults.phase_open_at_s", self.phase_open_at_s),
            ("faults.locked_rotor_at_s", self.locked_rotor_at_s),
            ("faults.adc_stuck_at_s", self.adc_stuck_at_s),
            ("faults.vdc_sag_at_s", self.vdc_sag_at_s),
            ("faults.short_at_s", self.short_at_s),
        ] {
            if let Some(t) = t {
                non_negative(key, t)?;
            }
        }
        both_or_neither(
            "faults.phase_open",
            self.phase_open.is_some(),
            self.phase_open_at_s.is_some(),
        )?;
        both_or_neither(
            "faults.adc_stuck_phase",
            self.adc_stuck_phase.is_some(),
            self.adc_stuck_at_s.is_some(),
        )?;
        both_or_neither(
            "faults.vdc_sag_to_v",
            self.vdc_sag_to_v.is_some(),
            self.vdc_sag_at_s.is_some(),
        )?;
        both_or_neither(
            "faults.short_phases",
            self.short_phases.is_some(),
            self.short_at_s.is_some(),
        )?;
        if let Some(v) = self.vdc_sag_to_v {
            in_range("faults.vdc_sag_to_v", v, 0.0, 2000.0)?;
        }
        if let Some(r) = self.short_ohm {
            positive("faults.short_ohm", r)?;
        }
        Ok(())
    }
}

/// A fault and its time come together: `key` names the first.
fn both_or_neither(key: &'static str, what: bool, when: bool) -> Result<(), ParamError> {
    if what != when {
        Err(ParamError {
            key,
            reason: ParamReason::Inconsistent("its companion key (both or neither)"),
        })
    } else {
        Ok(())
    }
}

/// A phase of the motor.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Phase {
    /// Phase a.
    A,
    /// Phase b.
    B,
    /// Phase c.
    C,
}

impl Phase {
    /// 0, 1 or 2.
    pub fn index(self) -> usize {
        match self {
            Phase::A => 0,
            Phase::B => 1,
            Phase::C => 2,
        }
    }
}

/// Two terminals: `"ab"`, `"bc"` or `"ca"`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum PhasePair {
    /// a and b.
    Ab,
    /// b and c.
    Bc,
    /// c and a.
    Ca,
}

impl PhasePair {
    /// The first terminal's index (the second is the next one).
    pub fn first(self) -> usize {
        match self {
            PhasePair::Ab => 0,
            PhasePair::Bc => 1,
            PhasePair::Ca => 2,
        }
    }
}
