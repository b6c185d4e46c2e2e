//! Bit-exact replay: the host's recording (`pil-record`) is embedded in flash; every case is
//! run through the same `pmsm_pil::cases::run_named` as on the host, fed the recorded inputs,
//! and every output word is compared with the host's.

use pmsm_pil::cases::{self, CASES, Io};
use pmsm_pil::format::{CaseData, FormatError, Recording};
use pmsm_pil::setup::Setup;

/// The host's recording (see `build.rs`).
pub static RECORDING: &[u8] = include_bytes!(env!("PIL_RECORDING_PATH"));

/// Bytes of the embedded recording.
pub fn recording_len() -> usize {
    RECORDING.len()
}

/// The first difference between target and host.
#[derive(Clone, Copy, Debug)]
pub struct Mismatch<'a> {
    /// Case name.
    pub case: &'a str,
    /// Step (from 0).
    pub step: usize,
    /// Output word.
    pub output: usize,
    /// What the target computed.
    pub target: i32,
    /// What the host recorded.
    pub host: i32,
}

/// Result of the replay.
#[derive(Clone, Copy, Debug)]
pub enum Outcome<'a> {
    /// Every output of every case matches.
    Exact {
        /// Steps compared, over all cases.
        steps: usize,
        /// Cases replayed.
        cases: usize,
    },
    /// An output differs.
    Mismatch {
        /// Steps compared before and including the mismatch.
        steps: usize,
        /// The difference.
        at: Mismatch<'a>,
    },
    /// The recording cannot be replayed.
    Invalid {
        /// Steps compared before.
        steps: usize,
        /// Why.
        reason: Invalid<'a>,
    },
}

/// Why a recording cannot be replayed.
#[derive(Clone, Copy, Debug)]
pub enum Invalid<'a> {
    /// Not a valid recording.
    Format(FormatError),
    /// No cases.
    Empty,
    /// A case this firmware does not know.
    UnknownCase(&'a str),
    /// A case whose input/output word counts differ from this firmware's.
    Shape(&'a str),
    /// A configuration failed on the target.
    Config(&'a str),
    /// A case ran fewer steps than recorded.
    Short(&'a str),
}

/// Feeds recorded inputs, compares outputs, stops at the first difference.
struct Checker<'a> {
    case: CaseData<'a>,
    mismatch: Option<Mismatch<'a>>,
    compared: usize,
}

impl Io for Checker<'_> {
    fn input(&mut self, step: usize, input: &mut [i32]) -> bool {
        if step >= self.case.steps {
            return false;
        }
        self.case.inputs_of(step, input);
        true
    }

    fn output(&mut self, step: usize, output: &[i32]) -> bool {
        self.compared += 1;
        for (j, &got) in output.iter().enumerate() {
            let want = self.case.output(step, j);
            if got != want {
                self.mismatch = Some(Mismatch {
                    case: self.case.name,
                    step,
                    output: j,
                    target: got,
                    host: want,
                });
                return false;
            }
        }
        true
    }
}

/// Replays every recorded case; `each(name, steps)` is told of each case that matched.
/// Never inlined, so that its frame and the benchmarks' are not both on the stack.
#[inline(never)]
pub fn run(setup: &Setup, each: &mut dyn FnMut(&str, usize)) -> Outcome<'static> {
    let rec = match Recording::parse(RECORDING) {
        Ok(r) => r,
        Err(e) => {
            return Outcome::Invalid {
                steps: 0,
                reason: Invalid::Format(e),
            };
        }
    };
    if rec.is_empty() {
        return Outcome::Invalid {
            steps: 0,
            reason: Invalid::Empty,
        };
    }
    let mut steps = 0;
    for case in rec.cases() {
        if cases::SKIPPED.contains(&case.name) {
            each(case.name, 0);
            continue;
        }
        let invalid = |reason| Outcome::Invalid { steps, reason };
        let Some(shape) = CASES.iter().find(|s| s.name == case.name) else {
            return invalid(Invalid::UnknownCase(case.name));
        };
        if shape.inputs != case.inputs || shape.outputs != case.outputs {
            return invalid(Invalid::Shape(case.name));
        }
        let mut checker = Checker {
            case,
            mismatch: None,
            compared: 0,
        };
        let ran = cases::run_named(case.name, setup, &mut checker);
        steps += checker.compared;
        if let Some(at) = checker.mismatch {
            return Outcome::Mismatch { steps, at };
        }
        match ran {
            Some(Ok(n)) if n == case.steps => each(case.name, n),
            Some(Ok(_)) => {
                return Outcome::Invalid {
                    steps,
                    reason: Invalid::Short(case.name),
                };
            }
            Some(Err(_)) => {
                return Outcome::Invalid {
                    steps,
                    reason: Invalid::Config(case.name),
                };
            }
            None => {
                return Outcome::Invalid {
                    steps,
                    reason: Invalid::UnknownCase(case.name),
                };
            }
        }
    }
    Outcome::Exact {
        steps,
        cases: rec.len(),
    }
}
