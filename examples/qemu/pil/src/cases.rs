//! The functions the replay checks bit for bit, each seen as a step from a list of `i32`
//! input words to a list of `i32` output words (the bits of the fixed-point values).
//!
//! The host recorder feeds a scenario through [`run_named`] and writes every step's words
//! ([`crate::format`]); the firmware feeds the recorded inputs through the same
//! [`run_named`] and compares the outputs. A new case (the drive's `step()`) is a type that
//! implements [`Case`] plus its name in the [`cases!`] list at the bottom of this file; the
//! host then records it on a scenario of its own (an open-loop trajectory, or the plant in a
//! closed loop through [`Io::output`]).

use pmsm_core::{Abc, AlphaBeta, Angle, ConfigError, Pu};
use pmsm_core::{Ao, Estimate, Estimator, EstimatorKind, Nlo, ObserverInput};
use pmsm_core::{Drive, DriveInput, DriveState, StartupMode};

use crate::setup::Setup;
use core::mem::MaybeUninit;

/// Largest number of input or output words of a case.
pub const MAX_WORDS: usize = 32;

/// A function under test, stepped with input words into output words.
pub trait Case: Sized {
    /// Name in recordings and reports (at most 16 ASCII bytes).
    const NAME: &'static str;
    /// Input words per step (at most [`MAX_WORDS`]).
    const INPUTS: usize;
    /// Output words per step (at most [`MAX_WORDS`]).
    const OUTPUTS: usize;
    /// The function's state at step 0, configured from `setup`.
    fn new(setup: &Setup) -> Result<Self, ConfigError>;
    /// One step: `input` has [`Case::INPUTS`] words, `output` [`Case::OUTPUTS`] (zeroed).
    fn step(&mut self, input: &[i32], output: &mut [i32]);

    /// [`Case::new`] written into `slot` (never dropped: a case holds no resource). A case
    /// whose state is kilobytes builds it there: returned through `Result`s, the drive's case
    /// stood three times on the micro:bit's 16 KiB stack, 10 KiB of `run`'s frame.
    fn init<'a>(
        setup: &Setup,
        slot: &'a mut MaybeUninit<Self>,
    ) -> Result<&'a mut Self, ConfigError> {
        Ok(slot.write(Self::new(setup)?))
    }
}

/// Where the inputs of a run come from and its outputs go.
pub trait Io {
    /// Fills the inputs of `step`; false when there are no more steps.
    fn input(&mut self, step: usize, input: &mut [i32]) -> bool;
    /// Takes the outputs of `step`; false stops the run (after a mismatch, say). A closed
    /// loop feeds them back into the next inputs.
    fn output(&mut self, step: usize, output: &[i32]) -> bool;
}

/// Name and shape of a case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shape {
    /// [`Case::NAME`].
    pub name: &'static str,
    /// [`Case::INPUTS`].
    pub inputs: usize,
    /// [`Case::OUTPUTS`].
    pub outputs: usize,
}

/// The shape of case `C`.
pub const fn shape<C: Case>() -> Shape {
    Shape {
        name: C::NAME,
        inputs: C::INPUTS,
        outputs: C::OUTPUTS,
    }
}

/// Runs case `C` from step 0 until `io` stops it; returns the number of steps run.
///
/// Never inlined: each case has a stack frame of its own, used one after the other (a drive's
/// state is kilobytes; the micro:bit has 16 KiB of RAM).
#[inline(never)]
pub fn run<C: Case>(setup: &Setup, io: &mut dyn Io) -> Result<usize, ConfigError> {
    let mut slot = MaybeUninit::uninit();
    let case = C::init(setup, &mut slot)?;
    let mut input = [0i32; MAX_WORDS];
    let mut output = [0i32; MAX_WORDS];
    let input = &mut input[..C::INPUTS.min(MAX_WORDS)];
    let output = &mut output[..C::OUTPUTS.min(MAX_WORDS)];
    let mut step = 0;
    while io.input(step, input) {
        output.fill(0);
        case.step(input, output);
        step += 1;
        if !io.output(step - 1, output) {
            break;
        }
    }
    Ok(step)
}

/// Word `j` of `w`, or 0.
#[inline(always)]
pub fn word(w: &[i32], j: usize) -> i32 {
    w.get(j).copied().unwrap_or(0)
}

/// Stores `value` as word `j` of `w` (ignored if out of range).
#[inline(always)]
pub fn set_word(w: &mut [i32], j: usize, value: i32) {
    if let Some(x) = w.get_mut(j) {
        *x = value;
    }
}

/// Estimator input from 4 words: `i_α, i_β, v_α, v_β` (Q8.24 bits).
pub fn observer_input(w: &[i32]) -> ObserverInput {
    let pu = |j| Pu::from_bits(word(w, j));
    ObserverInput {
        i: AlphaBeta {
            alpha: pu(0),
            beta: pu(1),
        },
        v: AlphaBeta {
            alpha: pu(2),
            beta: pu(3),
        },
    }
}

/// The 4 words of an [`ObserverInput`] (inverse of [`observer_input`]).
pub fn observer_input_words(x: &ObserverInput, w: &mut [i32]) {
    set_word(w, 0, x.i.alpha.to_bits());
    set_word(w, 1, x.i.beta.to_bits());
    set_word(w, 2, x.v.alpha.to_bits());
    set_word(w, 3, x.v.beta.to_bits());
}

/// Estimate as 4 words: `θ` (turn bits), `ω`, `ê_α`, `ê_β` (Q8.24 bits).
pub fn estimate_words(e: &Estimate, w: &mut [i32]) {
    set_word(w, 0, e.theta.0);
    set_word(w, 1, e.omega.to_bits());
    set_word(w, 2, e.emf.alpha.to_bits());
    set_word(w, 3, e.emf.beta.to_bits());
}

/// Inverse of [`estimate_words`].
pub fn estimate_of(w: &[i32]) -> Estimate {
    Estimate {
        theta: Angle(word(w, 0)),
        omega: Pu::from_bits(word(w, 1)),
        emf: AlphaBeta {
            alpha: Pu::from_bits(word(w, 2)),
            beta: Pu::from_bits(word(w, 3)),
        },
    }
}

/// The NLO (`Estimator::update`), from zero state.
pub struct NloCase(pub Nlo);

impl Case for NloCase {
    const NAME: &'static str = "nlo";
    const INPUTS: usize = 4;
    const OUTPUTS: usize = 4;
    fn new(setup: &Setup) -> Result<Self, ConfigError> {
        Ok(Self(Nlo::new(setup.nlo()?)))
    }
    fn step(&mut self, input: &[i32], output: &mut [i32]) {
        estimate_words(&self.0.update(&observer_input(input)), output);
    }
}

/// The AO (`Estimator::update`), from zero state.
pub struct AoCase(pub Ao);

impl Case for AoCase {
    const NAME: &'static str = "ao";
    const INPUTS: usize = 4;
    const OUTPUTS: usize = 4;
    fn new(setup: &Setup) -> Result<Self, ConfigError> {
        Ok(Self(Ao::new(setup.ao()?)))
    }
    fn step(&mut self, input: &[i32], output: &mut [i32]) {
        estimate_words(&self.0.update(&observer_input(input)), output);
    }
}

/// Drive input from 5 words: `i_a, i_b, i_c, v_dc, ω*` (Q8.24 bits); returns the input and
/// the speed reference.
pub fn drive_input(w: &[i32]) -> (DriveInput, Pu) {
    let pu = |j| Pu::from_bits(word(w, j));
    (
        DriveInput {
            i_abc: Abc {
                a: pu(0),
                b: pu(1),
                c: pu(2),
            },
            vdc: pu(3),
        },
        pu(4),
    )
}

/// The 5 words of a drive input and speed reference (inverse of [`drive_input`]).
pub fn drive_input_words(x: &DriveInput, speed_ref: Pu, w: &mut [i32]) {
    set_word(w, 0, x.i_abc.a.to_bits());
    set_word(w, 1, x.i_abc.b.to_bits());
    set_word(w, 2, x.i_abc.c.to_bits());
    set_word(w, 3, x.vdc.to_bits());
    set_word(w, 4, speed_ref.to_bits());
}

/// [`DriveState::code`] of [`DriveState::Run`] (the recording stores the drive's own state
/// codes).
pub const STATE_RUN: i32 = DriveState::Run.code() as i32;

/// Output word of the drive case holding the state after the step.
pub const DRIVE_STATE_WORD: usize = 6;

/// The Khlaief, Boussak, Gossa (2012) sensorless drive (`Drive::step`) on motor B at 14 kHz with the current-model
/// MRAS, started by initial position detection ([`Setup::drive`]).
///
/// Inputs (5 words): `i_a, i_b, i_c, v_dc, ω*` (Q8.24). Outputs (7 words): duties `a, b, c`
/// (Q2.30), `pwm_on` (0/1), `θ̂` (turn), `ω̂` (Q8.24), the state after the step
/// ([`DriveState::code`]).
pub struct DriveCase(pub Drive);

impl DriveCase {
    /// The configuration of the case's drive (out of line: its design's frame is gone before
    /// the drive is built).
    #[inline(never)]
    pub fn config() -> Result<pmsm_core::DriveConfig, ConfigError> {
        Setup::motor_b()?.drive(EstimatorKind::MrasCurrent, StartupMode::Ipd)
    }
}

/// A drive built from `config` and started. Out of line, apart from the configuration's
/// design: the micro:bit's 16 KiB of stack hold one or the other at a time.
#[inline(never)]
pub fn started(config: pmsm_core::DriveConfig) -> Drive {
    let mut d = Drive::new(config);
    d.start();
    d
}

impl Case for DriveCase {
    const NAME: &'static str = "drive";
    const INPUTS: usize = 5;
    const OUTPUTS: usize = 7;
    /// The case's drive, started (in `Ipd`); [`Case::init`] builds it in place.
    fn new(_setup: &Setup) -> Result<Self, ConfigError> {
        Ok(Self(started(Self::config()?)))
    }
    fn init<'a>(
        _setup: &Setup,
        slot: &'a mut MaybeUninit<Self>,
    ) -> Result<&'a mut Self, ConfigError> {
        let config = Self::config()?;
        let case = slot.write(Self(Drive::new(config)));
        case.0.start();
        Ok(case)
    }
    fn step(&mut self, input: &[i32], o: &mut [i32]) {
        let (x, speed_ref) = drive_input(input);
        self.0.set_speed_ref(speed_ref);
        let out = self.0.step(&x);
        set_word(o, 0, out.duties.a.to_bits());
        set_word(o, 1, out.duties.b.to_bits());
        set_word(o, 2, out.duties.c.to_bits());
        set_word(o, 3, i32::from(out.pwm_on));
        let e = self.0.telemetry().estimate;
        set_word(o, 4, e.theta.0);
        set_word(o, 5, e.omega.to_bits());
        set_word(o, DRIVE_STATE_WORD, i32::from(self.0.state().code()));
    }
}

/// Drive steps per recorded step of [`ClosedLoopCase`].
pub const CLOSED_LOOP_CHUNK: usize = 25;

/// Processor-in-the-loop proper: the drive and `pmsm-plant` both run on the
/// target, in a closed loop, and what they compute is compared with the host's run of the
/// same code. Motor B at rest at θ = 137°, the angle known (no detection), averaged inverter
/// at 540 V and 14 kHz, 12-bit ADC, the current-model MRAS; the speed reference ramps at
/// 4000 r/min/s. One recorded step is [`CLOSED_LOOP_CHUNK`] drive steps; no inputs.
///
/// Outputs (8 words) after each chunk: the drive state ([`DriveState::code`]), `θ̂` (turn), `ω̂`
/// (Q8.24), the duty of leg a (Q2.30), and the plant's mechanical speed and electrical angle
/// as the two halves of their `f64` bits: the float model must agree to the bit too (`libm`
/// on both sides, IEEE basic operations, no fused multiply–adds).
///
/// Only on cores with a 32-bit multiply–accumulate and room for the soft-float model
/// (Cortex-M3/M4); the micro:bit's flash holds the recording and the core, not the plant.
#[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
pub struct ClosedLoopCase {
    drive: Drive,
    plant: pmsm_plant::Plant,
    base: pmsm_core::PerUnit,
    sample: Option<pmsm_plant::Sample>,
    /// Speed reference increment per drive step, per unit.
    ramp: Pu,
    /// The speed reference's final value, per unit.
    top: Pu,
    /// The speed reference of the last step, per unit.
    speed_ref: Pu,
    failed: bool,
}

/// Electrical angle at which the closed loop's rotor rests, degrees.
pub const CLOSED_LOOP_THETA0_DEG: f64 = 137.0;

#[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
impl Case for ClosedLoopCase {
    const NAME: &'static str = "closed_loop";
    const INPUTS: usize = 0;
    const OUTPUTS: usize = 8;
    fn new(_setup: &Setup) -> Result<Self, ConfigError> {
        let b = Setup::motor_b()?;
        let theta0 = CLOSED_LOOP_THETA0_DEG.to_radians();
        fn plant_error<E>(_: E) -> ConfigError {
            ConfigError::Param(pmsm_core::ParamError {
                key: "plant",
                reason: pmsm_core::ParamReason::Inconsistent("the plant rejected motor B"),
            })
        }
        let motor = pmsm_plant::Motor::new(pmsm_plant::MotorModel::new(b.motor), theta0, 0.0)
            .map_err(plant_error)?;
        let inverter =
            pmsm_plant::InverterModel::new(b.inverter, pmsm_plant::InverterKind::Averaged);
        let adc = pmsm_plant::AdcParams::from_inverter(&b.inverter);
        let plant = pmsm_plant::Plant::new(motor, inverter, adc).map_err(plant_error)?;
        let mut drive = Drive::new(b.drive(
            EstimatorKind::MrasCurrent,
            StartupMode::Known(Angle::from_rad(theta0)),
        )?);
        drive.start();
        let rpm_to_pu = |rpm: f64| {
            b.base
                .speed_pu(rpm * core::f64::consts::TAU / 60.0 * b.motor.p())
        };
        Ok(Self {
            drive,
            plant,
            ramp: rpm_to_pu(4000.0 / crate::setup::DRIVE_SAMPLE_HZ),
            top: rpm_to_pu(800.0),
            base: b.base,
            sample: None,
            speed_ref: Pu::ZERO,
            failed: false,
        })
    }
    fn step(&mut self, _input: &[i32], o: &mut [i32]) {
        for _ in 0..CLOSED_LOOP_CHUNK {
            if self.failed {
                break;
            }
            let (i, vdc) = match &self.sample {
                Some(s) => (s.i_abc_a_measured, s.vdc_v),
                None => ([0.0; 3], self.plant.vdc_v()),
            };
            let x = DriveInput {
                i_abc: Abc {
                    a: self.base.current_pu(i[0]),
                    b: self.base.current_pu(i[1]),
                    c: self.base.current_pu(i[2]),
                },
                vdc: self.base.voltage_pu(vdc),
            };
            self.speed_ref = self.speed_ref.saturating_add(self.ramp).min(self.top);
            self.drive.set_speed_ref(self.speed_ref);
            let out = self.drive.step(&x);
            let duty = |d: pmsm_core::Unit| d.to_bits() as f64 / (1u64 << 30) as f64;
            let next = if out.pwm_on {
                self.plant.step_pwm(
                    [duty(out.duties.a), duty(out.duties.b), duty(out.duties.c)],
                    0.0,
                )
            } else {
                self.plant.step_off(0.0)
            };
            match next {
                Ok(s) => self.sample = Some(s),
                Err(_) => self.failed = true,
            }
            set_word(o, 3, out.duties.a.to_bits());
        }
        let e = self.drive.telemetry().estimate;
        set_word(
            o,
            0,
            if self.failed {
                -1
            } else {
                i32::from(self.drive.state().code())
            },
        );
        set_word(o, 1, e.theta.0);
        set_word(o, 2, e.omega.to_bits());
        let st = self.plant.motor().state();
        let halves = |x: f64| {
            let b = x.to_bits();
            ((b >> 32) as u32 as i32, b as u32 as i32)
        };
        let (w_hi, w_lo) = halves(st.omega_m_rad_s);
        let (t_hi, t_lo) = halves(st.theta_e_rad);
        set_word(o, 4, w_hi);
        set_word(o, 5, w_lo);
        set_word(o, 6, t_hi);
        set_word(o, 7, t_lo);
    }
}

/// Declares the list of cases: [`CASES`] and [`run_named`].
macro_rules! cases {
    ($($case:ty),* $(,)?) => {
        /// Every case, in recording order.
        pub const CASES: &[Shape] = &[$(shape::<$case>()),*];

        /// Runs the case called `name` (`None`: no such case).
        pub fn run_named(
            name: &str,
            setup: &Setup,
            io: &mut dyn Io,
        ) -> Option<Result<usize, ConfigError>> {
            $(
                if name == <$case as Case>::NAME {
                    return Some(run::<$case>(setup, io));
                }
            )*
            None
        }
    };
}

#[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
cases!(NloCase, AoCase, DriveCase, ClosedLoopCase);
#[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
cases!(NloCase, AoCase, DriveCase);

/// Cases of the recording this build does not run (the plant on the micro:bit), by name.
#[cfg(all(target_arch = "arm", not(target_has_atomic = "32")))]
pub const SKIPPED: &[&str] = &["closed_loop"];
/// Cases of the recording this build does not run, by name: none.
#[cfg(not(all(target_arch = "arm", not(target_has_atomic = "32"))))]
pub const SKIPPED: &[&str] = &[];

#[cfg(test)]
mod tests {
    extern crate std;
    use super::*;
    use std::vec::Vec;

    /// Constant inputs (the pattern repeated over the case's input words) for `n` steps;
    /// keeps the outputs.
    struct Const {
        input: [i32; 4],
        n: usize,
        outputs: Vec<i32>,
    }

    impl Io for Const {
        fn input(&mut self, step: usize, input: &mut [i32]) -> bool {
            for (j, w) in input.iter_mut().enumerate() {
                *w = self.input[j % self.input.len()];
            }
            step < self.n
        }
        fn output(&mut self, _step: usize, output: &[i32]) -> bool {
            self.outputs.extend_from_slice(output);
            true
        }
    }

    #[test]
    fn every_case_runs_by_name_and_fits() {
        let setup = Setup::motor_a().unwrap();
        for shape in CASES {
            assert!(shape.name.len() <= crate::format::NAME_LEN);
            assert!(shape.inputs <= MAX_WORDS && shape.outputs <= MAX_WORDS);
            let mut io = Const {
                input: [1 << 22, -(1 << 22), 1 << 24, 0],
                n: 10,
                outputs: Vec::new(),
            };
            let steps = run_named(shape.name, &setup, &mut io).unwrap().unwrap();
            assert_eq!(steps, 10, "{}", shape.name);
            assert_eq!(io.outputs.len(), 10 * shape.outputs, "{}", shape.name);
        }
        assert!(
            run_named(
                "no-such-case",
                &setup,
                &mut Const {
                    input: [0; 4],
                    n: 1,
                    outputs: Vec::new()
                }
            )
            .is_none()
        );
    }

    #[test]
    fn words_round_trip() {
        let x = ObserverInput {
            i: AlphaBeta {
                alpha: Pu::from_bits(-5),
                beta: Pu::from_bits(i32::MAX),
            },
            v: AlphaBeta {
                alpha: Pu::from_bits(i32::MIN),
                beta: Pu::from_bits(7),
            },
        };
        let mut w = [0; 4];
        observer_input_words(&x, &mut w);
        assert_eq!(observer_input(&w), x);
        let e = Estimate {
            theta: Angle(-123),
            omega: Pu::from_bits(456),
            emf: AlphaBeta {
                alpha: Pu::from_bits(-1),
                beta: Pu::from_bits(1),
            },
        };
        estimate_words(&e, &mut w);
        assert_eq!(estimate_of(&w), e);
    }
}
