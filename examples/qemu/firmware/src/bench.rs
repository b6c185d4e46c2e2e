//! Instructions per call of each component, on deterministic inputs generated here.
//!
//! Every benchmark is a state (the component's inputs, its output, and for estimators the
//! estimator itself) built by `init`, a `prepare` step that writes the inputs of call `k` (not
//! measured) and a `call` that runs the component once on them (measured by [`Meter::insn`]). The figure of a
//! call therefore includes loading the inputs from memory and storing the output, as a caller
//! in a control interrupt would.
//!
//! To add a component, add one `report(...)` to [`run_all`] (names are stable identifiers:
//! `snake_case`, the function, not the paper). The drive's parts run on motor B (Khlaief, Boussak, Gossa (2012));
//! `ipd_step` and `drive_step` on the recorded closed loop of the `drive` replay case.

use core::hint::black_box;

use pmsm_core::{Abc, AlphaBeta, Angle, ConfigError, Dq, Pu, SinCos};
use pmsm_core::{
    Ao, Estimate, Estimator, MrasCurrent, MrasCurrentConfig, MrasCurrentGains, MrasEmf, Nlo,
    ObserverInput,
};
use pmsm_core::{
    CurrentConfig, CurrentController, CurrentDesign, CurrentInput, CurrentOutput, SpeedConfig,
    SpeedController, SpeedDesign, SpeedOutput,
};
use pmsm_core::{DeadTimeConfig, DeadTimeDesign};
use pmsm_core::{DriveInput, DriveOutput};
use pmsm_core::{Ipd, IpdConfig, IpdDesign, IpdOutput};
use pmsm_core::{Polar, polar};
use pmsm_core::{SvpwmConfig, SvpwmOutput};
use pmsm_core::{clarke, inverse_clarke, inverse_park, park};
use pmsm_core::{mul, mul_unit, pu_from_f64};
use pmsm_pil::cases::{self, Case, DRIVE_STATE_WORD, DriveCase, STATE_RUN};
use pmsm_pil::format::{CaseData, Recording};
use pmsm_pil::setup::Setup;

use crate::meter::Meter;

/// Instruction counts of one benchmark.
#[derive(Clone, Copy, Debug, Default)]
pub struct Stats {
    /// Calls measured.
    pub calls: u32,
    /// Sum over the calls.
    pub sum: u64,
    /// Largest.
    pub max: u32,
}

impl Stats {
    /// Mean per call, rounded to nearest.
    pub fn mean(&self) -> u64 {
        if self.calls == 0 {
            0
        } else {
            (self.sum + u64::from(self.calls) / 2) / u64::from(self.calls)
        }
    }
}

/// Measures `calls` calls of `call` on the state `init()`, each after `prepare(state, k)`.
///
/// Never inlined, and the state is built here: every benchmark has a stack frame of its own,
/// used one after the other (the micro:bit has 16 KiB of RAM).
#[inline(never)]
pub fn bench<S>(
    meter: &Meter,
    calls: u32,
    init: impl FnOnce() -> S,
    mut prepare: impl FnMut(&mut S, u32),
    mut call: impl FnMut(&mut S),
) -> Stats {
    let mut state = init();
    let mut stats = Stats::default();
    for k in 0..calls {
        prepare(&mut state, k);
        let n = meter.insn(&mut || call(&mut state));
        stats.calls += 1;
        stats.sum += u64::from(n);
        stats.max = stats.max.max(n);
    }
    // Keep the outputs alive: nothing computed may be optimised away.
    black_box(&mut state);
    stats
}

/// Calls per transform benchmark.
const TRANSFORM_CALLS: u32 = 1000;
/// Calls per estimator benchmark: 0.1 s at 20 kHz from a cold start.
const ESTIMATOR_CALLS: u32 = 2000;

/// Angle of call `k`: the golden-ratio sequence, uniform over the turn and all quadrants.
fn golden(k: u32) -> Angle {
    Angle(k.wrapping_mul(0x9E37_79B9) as i32)
}

/// `r (cos θ, sin θ)`.
fn phasor(r: Pu, theta: Angle) -> AlphaBeta {
    let sc = theta.sin_cos();
    AlphaBeta {
        alpha: mul_unit(r, sc.cos),
        beta: mul_unit(r, sc.sin),
    }
}

/// Magnitude of call `k` for atan2: 3·2⁻¹⁰ to 6 per unit, cycling over 12 octaves.
fn magnitude(k: u32) -> Pu {
    Pu::from_bits(3 << (14 + k % 12))
}

/// Steady state of motor A at 120 rad/s mechanical (360 rad/s electrical) with half the
/// rated current on the q axis, plus small deterministic noise on the currents (ADC-like):
/// `i = i_q (−sin θ, cos θ)`, `v = r i + x J i + ψ ω (−sin θ, cos θ)`, per unit.
struct Motion {
    step: Angle,
    iq: Pu,
    r: Pu,
    x: Pu,
    emf: Pu,
    noise: u32,
}

impl Motion {
    fn new(setup: &Setup) -> Self {
        let b = &setup.base;
        let m = &setup.motor;
        let omega_e = 3.0 * 120.0;
        let omega_pu = omega_e / b.omega_e_rad_s;
        Self {
            step: Angle::from_rad(omega_e * b.sample_s),
            iq: pu_from_f64(0.5),
            r: pu_from_f64(m.rs_ohm / b.impedance_ohm),
            x: pu_from_f64(omega_pu * m.ld_h / b.inductance_h),
            emf: pu_from_f64(omega_pu * m.flux_wb / b.flux_wb),
            noise: 0x1234_5678,
        }
    }

    /// Input of sample `k`.
    fn input(&mut self, k: u32) -> ObserverInput {
        let theta = Angle(0x2000_0000) + Angle(self.step.0.wrapping_mul(k as i32));
        let sc = theta.sin_cos();
        // Unit vector of the q axis (and of the EMF): (−sin θ, cos θ).
        let q = (sc.sin.saturating_neg(), sc.cos);
        // xorshift32, ±2^13 LSB (±5e−4 per unit).
        let mut noise = || {
            self.noise ^= self.noise << 13;
            self.noise ^= self.noise >> 17;
            self.noise ^= self.noise << 5;
            Pu::from_bits((self.noise >> 18) as i32 - (1 << 13))
        };
        let i = AlphaBeta {
            alpha: mul_unit(self.iq, q.0).saturating_add(noise()),
            beta: mul_unit(self.iq, q.1).saturating_add(noise()),
        };
        let v = AlphaBeta {
            alpha: mul(self.r, i.alpha)
                .saturating_sub(mul(self.x, i.beta))
                .saturating_add(mul_unit(self.emf, q.0)),
            beta: mul(self.r, i.beta)
                .saturating_add(mul(self.x, i.alpha))
                .saturating_add(mul_unit(self.emf, q.1)),
        };
        ObserverInput { i, v }
    }
}

/// An estimator with its input and output slots.
struct EstimatorBench<E> {
    est: E,
    motion: Motion,
    input: ObserverInput,
    out: Estimate,
}

fn bench_estimator<E: Estimator>(meter: &Meter, setup: &Setup, make: impl FnOnce() -> E) -> Stats {
    bench(
        meter,
        ESTIMATOR_CALLS,
        || EstimatorBench {
            est: make(),
            motion: Motion::new(setup),
            input: ObserverInput::default(),
            out: Estimate::default(),
        },
        |s, k| s.input = s.motion.input(k),
        |s| s.out = s.est.update(&s.input),
    )
}

/// xorshift32 noise of ±2^(bits−1) LSB.
fn noise(state: &mut u32, bits: u32) -> Pu {
    *state ^= *state << 13;
    *state ^= *state >> 17;
    *state ^= *state << 5;
    Pu::from_bits((*state >> (32 - bits)) as i32 - (1 << (bits - 1)))
}

/// The drive case of the embedded recording (`None` if it was not recorded).
fn drive_recording() -> Option<CaseData<'static>> {
    Recording::parse(crate::replay::RECORDING)
        .ok()?
        .cases()
        .find(|c| c.name == <DriveCase as Case>::NAME)
}

/// First recorded step that starts in `Run` (the state after the step before it).
fn first_run_step(rec: &CaseData) -> usize {
    (1..rec.steps)
        .find(|&k| rec.output(k - 1, DRIVE_STATE_WORD) == STATE_RUN)
        .unwrap_or(rec.steps)
}

/// Recorded drive input of `step` (and its speed reference).
fn recorded_drive_input(rec: &CaseData, step: usize) -> (DriveInput, Pu) {
    let mut w = [0i32; 5];
    rec.inputs_of(step, &mut w);
    cases::drive_input(&w)
}

/// `Drive::step` in `Run` on the recorded closed loop of the `drive` replay case (motor B,
/// current-model MRAS): the drive is fed the recorded inputs, unmeasured, through its initial
/// position detection, then every step in `Run` is measured.
#[inline(never)]
fn bench_drive_step(meter: &Meter, rec: &CaseData<'static>) -> Option<Stats> {
    let k0 = first_run_step(rec);
    let calls = rec.steps.checked_sub(k0).filter(|&n| n > 0)? as u32;
    let st = bench(
        meter,
        calls,
        || {
            let mut d = DriveCase::drive().ok();
            if let Some(d) = d.as_mut() {
                for k in 0..k0 {
                    let (x, w) = recorded_drive_input(rec, k);
                    d.set_speed_ref(w);
                    black_box(d.step(&x));
                }
            }
            (DriveInput::default(), None::<DriveOutput>, d)
        },
        |s, k| {
            let (x, w) = recorded_drive_input(rec, k0 + k as usize);
            s.0 = x;
            if let Some(d) = s.2.as_mut() {
                d.set_speed_ref(w);
            }
        },
        |s| {
            if let Some(d) = s.2.as_mut() {
                s.1 = Some(d.step(&s.0));
            }
        },
    );
    Some(st)
}

/// `Ipd::step` over the recorded detection (the steps of the drive case before `Run`).
#[inline(never)]
fn bench_ipd(meter: &Meter, rec: &CaseData<'static>, cfg: IpdConfig) -> Stats {
    let n = first_run_step(rec).saturating_sub(1).max(1) as u32;
    bench(
        meter,
        n,
        || {
            let mut ipd = Ipd::new(cfg);
            ipd.restart();
            (AlphaBeta::default(), Pu::ZERO, None::<IpdOutput>, ipd)
        },
        |s, k| {
            let (x, _) = recorded_drive_input(rec, k as usize);
            s.0 = clarke(x.i_abc);
            s.1 = x.vdc;
        },
        |s| s.2 = Some(s.3.step(s.0, s.1)),
    )
}

/// Runs every benchmark and passes each figure to `report(name, stats)`. Configurations are
/// built here, states in each [`bench`] (in its own frame: build a drive in `init`).
#[inline(never)]
pub fn run_all(
    meter: &Meter,
    setup: &Setup,
    report: &mut dyn FnMut(&str, &Stats),
) -> Result<(), ConfigError> {
    // Trigonometry.
    let st = bench(
        meter,
        TRANSFORM_CALLS,
        || (Angle::ZERO, SinCos::default()),
        |s, k| s.0 = golden(k),
        |s| s.1 = s.0.sin_cos(),
    );
    report("sin_cos", &st);

    let st = bench(
        meter,
        TRANSFORM_CALLS,
        || {
            let zero = Polar {
                magnitude: Pu::ZERO,
                angle: Angle::ZERO,
            };
            (AlphaBeta::default(), zero)
        },
        |s, k| s.0 = phasor(magnitude(k), golden(k)),
        |s| s.1 = polar(s.0.alpha, s.0.beta),
    );
    report("atan2", &st);

    // Frames: a balanced three-phase set of 1 per unit and its transforms.
    let st = bench(
        meter,
        TRANSFORM_CALLS,
        <(Abc, AlphaBeta)>::default,
        |s, k| {
            let one = Pu::from_num(1);
            let third = Angle(0x5555_5555);
            let t = golden(k);
            s.0 = Abc {
                a: phasor(one, t).alpha,
                b: phasor(one, t - third).alpha,
                c: phasor(one, t + third).alpha,
            }
        },
        |s| s.1 = clarke(s.0),
    );
    report("clarke", &st);

    let st = bench(
        meter,
        TRANSFORM_CALLS,
        <(AlphaBeta, Abc)>::default,
        |s, k| s.0 = phasor(Pu::from_num(1), golden(k)),
        |s| s.1 = inverse_clarke(s.0),
    );
    report("inverse_clarke", &st);

    let st = bench(
        meter,
        TRANSFORM_CALLS,
        <(AlphaBeta, SinCos, Dq)>::default,
        |s, k| {
            s.0 = phasor(Pu::from_num(1), golden(k));
            s.1 = golden(k.wrapping_add(7)).sin_cos();
        },
        |s| s.2 = park(s.0, s.1),
    );
    report("park", &st);

    let st = bench(
        meter,
        TRANSFORM_CALLS,
        <(Dq, SinCos, AlphaBeta)>::default,
        |s, k| {
            let v = phasor(Pu::from_num(1), golden(k));
            s.0 = Dq {
                d: v.alpha,
                q: v.beta,
            };
            s.1 = golden(k.wrapping_add(7)).sin_cos();
        },
        |s| s.2 = inverse_park(s.0, s.1),
    );
    report("inverse_park", &st);

    // Estimators (configurations built on the target, in f64).
    let c = setup.nlo()?;
    report("nlo_update", &bench_estimator(meter, setup, || Nlo::new(c)));
    let c = setup.ao()?;
    report("ao_update", &bench_estimator(meter, setup, || Ao::new(c)));
    let c = setup.mras_emf()?;
    report(
        "mras_emf_update",
        &bench_estimator(meter, setup, || MrasEmf::new(c)),
    );

    // The drive's parts, on motor B (Khlaief, Boussak, Gossa (2012)) at 14 kHz on 540 V.
    let b = Setup::motor_b()?;
    let vdc = b.base.voltage_pu(b.inverter.vdc_v);
    let c = MrasCurrentConfig::new(
        &b.motor,
        &b.base,
        MrasCurrentGains::default_for(&b.motor, &b.base),
    )?;
    report(
        "mras_current_update",
        &bench_estimator(meter, &b, || {
            let mut e = MrasCurrent::new(c);
            e.reset(Angle(0x2000_0000), Pu::ZERO);
            e
        }),
    );

    // SVPWM: vectors at every angle, 0.1 to 1.3 times the largest the bus makes (a third of
    // them saturate), on the nominal bus.
    let m = SvpwmConfig::default();
    let v_max = m.v_max(vdc);
    let st = bench(
        meter,
        TRANSFORM_CALLS,
        || (AlphaBeta::default(), None::<SvpwmOutput>),
        |s, k| {
            let r = mul(v_max, Pu::from_bits((k % 13 + 1) as i32 * (1 << 24) / 10));
            s.0 = phasor(r, golden(k));
        },
        |s| s.1 = Some(m.modulate(s.0, vdc)),
    );
    report("svpwm", &st);

    // Current loops: half the rated current on q, noisy measurement, at 800 r/min.
    let cc = CurrentConfig::new(&b.motor, &b.base, CurrentDesign::default_for(&b.base))?;
    let omega = b.base.speed_pu(800.0 * core::f64::consts::TAU / 60.0 * 3.0);
    let st = bench(
        meter,
        ESTIMATOR_CALLS,
        || {
            (
                CurrentInput::default(),
                CurrentOutput::default(),
                CurrentController::new(cc),
                0x1234_5678u32,
            )
        },
        |s, _| {
            let i_ref = Dq {
                d: Pu::ZERO,
                q: pu_from_f64(0.5),
            };
            s.0 = CurrentInput {
                i_ref,
                i: Dq {
                    d: noise(&mut s.3, 20),
                    q: i_ref.q.saturating_add(noise(&mut s.3, 20)),
                },
                omega,
                vdc,
                hold: false,
            };
        },
        |s| s.1 = s.2.step(&s.0),
    );
    report("current_loops", &st);

    // Speed loop: 800 r/min reference, a noisy estimate around it.
    let sc = SpeedConfig::new(&b.motor, &b.base, SpeedDesign::default_for(&b.base))?;
    let st = bench(
        meter,
        ESTIMATOR_CALLS,
        || {
            (
                (Pu::ZERO, Pu::ZERO),
                SpeedOutput::default(),
                SpeedController::new(sc),
                0x8765_4321u32,
            )
        },
        |s, _| s.0 = (omega, omega.saturating_add(noise(&mut s.3, 18))),
        |s| s.1 = s.2.step(s.0.0, s.0.1),
    );
    report("speed_loop", &st);

    // Dead-time error vector: a rotating current of 0.3 pu (through every zero crossing).
    let dt = DeadTimeConfig::new(
        &b.inverter,
        &b.base,
        DeadTimeDesign::default_for(&b.motor, &b.inverter),
    )?;
    let st = bench(
        meter,
        TRANSFORM_CALLS,
        <(AlphaBeta, AlphaBeta)>::default,
        |s, k| s.0 = phasor(pu_from_f64(0.3), golden(k)),
        |s| s.1 = dt.error_vector(s.0, vdc),
    );
    report("deadtime", &st);

    // The drive's initial position detection and the drive step, on the recorded run.
    let ipd = IpdConfig::new(&b.motor, &b.base, IpdDesign::default())?;
    if let Some(rec) = drive_recording() {
        report("ipd_step", &bench_ipd(meter, &rec, ipd));
        if let Some(st) = bench_drive_step(meter, &rec) {
            report("drive_step", &st);
        }
    }
    Ok(())
}
