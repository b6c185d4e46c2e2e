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
use pmsm_core::{
    Drive, DriveConfig, DriveDesign, DriveInput, DriveOutput, DriveState, EstimatorKind,
    FluxConfig, FluxController, FluxDesign, PerUnit, StartupMode,
};
use pmsm_core::{Identify, IdentifyConfig, IdentifyDesign, IdentifyOutput};
use pmsm_core::{Ipd, IpdConfig, IpdDesign, IpdOutput};
use pmsm_core::{Polar, polar};
use pmsm_core::{SvpwmConfig, SvpwmOutput};
use pmsm_core::{clarke, inverse_clarke, inverse_park, park};
use pmsm_core::{mul, mul_unit, pu_from_f64};
use pmsm_pil::cases::{self, Case, DRIVE_STATE_WORD, DriveCase, STATE_RUN};
use pmsm_pil::format::{CaseData, Recording};
use pmsm_pil::loops::{Constants, DqPlant};
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

/// The two sides of a drive measured apart: the interrupt step of every sample in `Run`, the
/// task step of every task period in `Run`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Sides {
    /// [`pmsm_core::DriveIsr::step`].
    pub isr: Stats,
    /// [`pmsm_core::DriveTask::step`].
    pub task: Stats,
}

impl Sides {
    /// One sample of `drive` on `x` (the task too when due), counted when `measure`.
    #[inline(always)]
    fn step(
        &mut self,
        meter: &Meter,
        drive: &mut Drive,
        x: &DriveInput,
        measure: bool,
    ) -> DriveOutput {
        let (isr, task, handoff) = drive.parts();
        let mut out = None::<DriveOutput>;
        let n = meter.insn(&mut || out = Some(isr.step(handoff, x)));
        let out = black_box(out).unwrap_or(DriveOutput {
            duties: pmsm_core::Duties::HALF,
            pwm_on: false,
        });
        if measure {
            add(&mut self.isr, n);
        }
        if isr.task_due() {
            let n = meter.insn(&mut || task.step(handoff));
            if measure {
                add(&mut self.task, n);
            }
        }
        out
    }

    /// The closed loop's step: one sample of `drive` on `x`, counted while it runs.
    pub fn measured<'a>(
        &'a mut self,
        meter: &'a Meter,
    ) -> impl FnMut(&mut Drive, &DriveInput) -> DriveOutput + 'a {
        move |d, x| {
            let running = d.state() == DriveState::Run;
            self.step(meter, d, x, running)
        }
    }
}

/// One call of `n` instructions into `st`.
fn add(st: &mut Stats, n: u32) {
    st.calls += 1;
    st.sum += u64::from(n);
    st.max = st.max.max(n);
}

/// How a benchmark reads the bus: the recorded reading (constant) in eighths of itself, and
/// whether it moves at every sample by up to three steps of 1/2048 of itself, as a 12-bit
/// converter's reading does (the drive then takes new bus terms at every sample).
#[derive(Clone, Copy)]
struct BusReading {
    eighths: i32,
    noise: bool,
}

/// The recorded bus reading as it is.
const RECORDED_BUS: BusReading = BusReading {
    eighths: 8,
    noise: false,
};

/// The interrupt and task steps of `drive` in `Run` on the recorded closed loop of the
/// `drive` replay case (motor B, current-model MRAS), with the bus read as `bus` says: the
/// drive is fed the recorded inputs through its initial position detection,
/// then every step in `Run` is measured. The drive is designed here (`drive`), before the
/// benchmark's frame is on the stack, and no caller's frame holds one.
#[inline(never)]
fn bench_drive_sides(
    meter: &Meter,
    rec: &CaseData<'static>,
    config: fn() -> Option<DriveConfig>,
    bus: BusReading,
) -> Option<Sides> {
    let mut d = cases::started(config()?);
    let input = |k: usize| {
        let (mut x, w) = recorded_drive_input(rec, k);
        let v = x.vdc.to_bits() / 8 * bus.eighths;
        // 0, 3, 2, 1, 0, … steps of 1/2048 of the reading: a new value at every sample.
        let noise = if bus.noise {
            ((k as i32 * 7) & 3) * (v >> 11)
        } else {
            0
        };
        x.vdc = Pu::from_bits(v + noise);
        (x, w)
    };
    let mut sides = Sides::default();
    for k in 0..rec.steps {
        let (x, w) = input(k);
        d.set_speed_ref(w);
        let running = d.state() == DriveState::Run;
        sides.step(meter, &mut d, &x, running);
    }
    black_box(&mut d);
    Some(sides)
}

/// The drive of the `drive` case with MTPA and field weakening on (their updates in the
/// task: docs/field-weakening.md, "Cost"), started. Both are the drive's defaults, so this is
/// the `drive` case's own drive, written out so that `isr_flux` keeps measuring them whatever
/// the defaults become.
#[inline(never)]
fn drive_with_flux() -> Option<DriveConfig> {
    edited_config(|design, _| design.flux = FluxDesign::ON)
}

/// The configuration of the `drive` case's drive (motor B, current-model MRAS, detection)
/// with `edit` applied to its design.
fn edited_config(edit: fn(&mut DriveDesign, &Setup)) -> Option<DriveConfig> {
    let b = Setup::motor_b().ok()?;
    let mut design = b
        .drive(EstimatorKind::MrasCurrent, StartupMode::Ipd)
        .ok()?
        .design;
    edit(&mut design, &b);
    b.config(design).ok()
}

/// The drive of the `drive` case with the high-frequency injection on (docs/injection.md):
/// below its hand-over speed the injection's loop replaces the estimator's update. On the
/// Cortex-M4 only (the one with atomics here), whose build has the feature `injection`.
#[cfg(target_has_atomic = "32")]
#[inline(never)]
fn drive_with_injection() -> Option<DriveConfig> {
    edited_config(|design, _| design.injection = Some(pmsm_core::InjectionDesign::default()))
}

/// The default drive with its undervoltage trip at a fifth of the nominal bus, for the
/// `drive` case's inputs with the bus read at a quarter of the recorded value
/// ([`LOW_BUS_EIGHTHS`]): the ramp's voltage is then beyond the circle, and the current
/// loops' circle and the modulator's limit act in 75 of the 388 steps in `Run` (on the host;
/// none at the recorded bus): the cost of a saturated step, which the recorded run never
/// reaches.
#[inline(never)]
fn drive_on_low_bus() -> Option<DriveConfig> {
    edited_config(|design, b| design.protection.vdc_min_v = 0.2 * b.inverter.vdc_v)
}

/// The bus reading of [`drive_on_low_bus`]'s benchmark, eighths of the recorded one.
const LOW_BUS_EIGHTHS: i32 = 2;

/// The d-axis reference's configuration on motor B, MTPA and field weakening on, 3.6 A.
#[inline(never)]
fn flux_config() -> Option<FluxConfig> {
    let b = Setup::motor_b().ok()?;
    FluxConfig::new(&b.motor, &b.base, 3.6, FluxDesign::ON, 1.0, 2.0).ok()
}

/// The d-axis reference's three updates (MTPA and field weakening on), each alone: a q
/// current swinging over ±1 pu, a vector turning near the circle on a bus that moves.
#[inline(never)]
fn bench_flux(meter: &Meter, report: &mut dyn FnMut(&str, &Stats)) {
    if let Some(fc) = flux_config() {
        let mut fx = FluxController::default();
        fx.reset(&fc);
        let st = bench(
            meter,
            TRANSFORM_CALLS,
            || (fx, Pu::ZERO),
            |s, k| s.1 = Pu::from_bits(((k % 64) as i32 - 32) << 19),
            |s| s.0.update_mtpa(&fc, s.1),
        );
        report("flux_mtpa", &st);
        let st = bench(
            meter,
            TRANSFORM_CALLS,
            || (fx, AlphaBeta::default(), Pu::ZERO),
            |s, k| {
                s.1 = phasor(pu_from_f64(0.98), golden(k));
                s.2 = pu_from_f64(1.0).saturating_add(Pu::from_bits((k as i32 & 7) << 10));
            },
            |s| s.0.update_fw(&fc, &s.1, s.2),
        );
        report("flux_fw", &st);
        let st = bench(
            meter,
            TRANSFORM_CALLS,
            || fx,
            |_, _| {},
            |s| {
                black_box(s.update_circle(&fc));
            },
        );
        report("flux_circle", &st);
    }
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

/// Motor B's constants for [`DqPlant`].
const MOTOR_B: Constants = (7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011, 3.0);

/// How a benchmarked identification ended.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum IdentifyEnd {
    /// It identified the plant: the relative errors of `R, L_d, L_q, ψ, J` in per mille
    /// (information only: the accuracy is the host tests' business).
    Identified([i32; 5]),
    /// It stopped with an error (the benchmark still covers the stages it ran).
    Failed,
    /// It did not finish within the sample limit.
    Unfinished,
}

/// `Identify::step` (per sample) and `Identify::poll` (the background work; its maximum is
/// the final fits) over a whole identification of motor B on 540 V at 14 kHz, current limit
/// √2 × 2.53 A, against [`DqPlant`] (its rotor starting 40° electrical off the α axis).
/// Returns the step's and the poll's figures, how it ended, and the samples it took.
#[inline(never)]
fn bench_identify(meter: &Meter, cfg: IdentifyConfig) -> (Stats, Stats, IdentifyEnd, u32) {
    let t_s = cfg.sample_s as f32;
    let mut plant = DqPlant::at_rest(
        MOTOR_B,
        Angle(0x1C71_C71C),
        cfg.voltage_base_v as f32,
        cfg.current_base_a as f32,
    );
    // The bus per unit of V_b = V_DC/√3.
    let vdc = Pu::from_bits((1.732_050_8f32 * (1u32 << 24) as f32) as i32);
    let mut id = Identify::new(cfg);
    let (mut step, mut poll) = (Stats::default(), Stats::default());
    let mut i = AlphaBeta::default();
    // 20 s of samples: far beyond the sequence's few seconds.
    let limit = (20.0 / t_s) as u32;
    for k in 0..limit {
        let mut out = None::<IdentifyOutput>;
        let n = meter.insn(&mut || out = Some(id.step(black_box(i), black_box(vdc))));
        step.calls += 1;
        step.sum += u64::from(n);
        step.max = step.max.max(n);
        let mut res = None;
        let n = meter.insn(&mut || res = id.poll());
        poll.calls += 1;
        poll.sum += u64::from(n);
        poll.max = poll.max.max(n);
        if let Some(r) = res {
            let end = match r {
                Ok(f) => {
                    let m = f.motor;
                    let (r, ld, lq, psi, j, _, _) = MOTOR_B;
                    let e = |got: f64, truth: f32| ((got / truth as f64 - 1.0) * 1000.0) as i32;
                    IdentifyEnd::Identified([
                        e(m.rs_ohm, r),
                        e(m.ld_h, ld),
                        e(m.lq_h, lq),
                        e(m.flux_wb, psi),
                        e(m.j_kg_m2, j),
                    ])
                }
                Err(_) => IdentifyEnd::Failed,
            };
            return (step, poll, end, k + 1);
        }
        if let Some(o) = out {
            i = plant.step(o.v, o.pwm_on, t_s);
        }
    }
    (step, poll, IdentifyEnd::Unfinished, limit)
}

/// Runs every benchmark and passes each figure to `report(name, stats)`. Configurations are
/// built here, states in each [`bench`] (in its own frame: build a drive in `init`).
#[inline(never)]
pub fn run_all(
    meter: &Meter,
    setup: &Setup,
    report: &mut dyn FnMut(&str, &Stats),
) -> Result<(), ConfigError> {
    run_components(meter, setup, report)?;
    run_drive(meter, report)
}

/// The components' benchmarks. Their configurations fill this frame, which is gone before
/// [`run_drive`] designs drives on top of the stack (the micro:bit's 16 KiB: the flux drive's
/// design was the image's deepest point).
#[inline(never)]
fn run_components(
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

    bench_flux(meter, report);
    bench_tracker(meter, report);
    Ok(())
}

/// The tracker of `R` and `ψ` (docs/tracking.md) learning on motor B's steady states at
/// 0.5 pu of speed and 0.8 pu of q current, the plant's `R` 1.3 times the model's (the
/// voltages computed outside the count): [`pmsm_core::Tracker::task_step`], the tracker's
/// share of a task step (a stage of its cycle: a half update, or half the new coefficients),
/// with the task period's sample on every call as the drive gives it.
#[inline(never)]
fn bench_tracker(meter: &Meter, report: &mut dyn FnMut(&str, &Stats)) {
    let Ok(b) = Setup::motor_b() else { return };
    let base = b.base;
    let mut design = pmsm_core::TrackerDesign::default_for(&base);
    design.settle_s = 0.0;
    let Ok(t0) = pmsm_core::Tracker::new(&b.motor, &base, design) else {
        return;
    };
    let (r, lq, psi) = (
        1.3 * b.motor.rs_ohm / base.impedance_ohm,
        b.motor.lq_h / base.inductance_h,
        b.motor.flux_wb / base.flux_wb,
    );
    let (omega, iq) = (0.5, 0.8);
    let step = f64::from(design.interval_samples) * base.omega_e_rad_s * base.sample_s * omega;
    let input = move |k: u32| {
        let theta = step * k as f64;
        let (vd, vq) = (-omega * lq * iq, r * iq + omega * psi);
        let mid = theta + 0.5 * base.omega_e_rad_s * base.sample_s * omega;
        let sc = Angle::from_rad(mid).sin_cos();
        let q30 = 1.0 / (1u64 << 30) as f64;
        let (s, c) = (sc.sin.to_bits() as f64 * q30, sc.cos.to_bits() as f64 * q30);
        pmsm_core::TrackerInput {
            running: true,
            theta: Angle::from_rad(theta),
            omega: pu_from_f64(omega),
            i_dq: Dq {
                d: Pu::ZERO,
                q: pu_from_f64(iq),
            },
            i_ref: Dq {
                d: Pu::ZERO,
                q: pu_from_f64(iq),
            },
            v: AlphaBeta {
                alpha: pu_from_f64(vd * c - vq * s),
                beta: pu_from_f64(vd * s + vq * c),
            },
            saturated: false,
        }
    };
    let mut t = t0;
    let mut writes = 0u32;
    let st = bench(
        meter,
        TRANSFORM_CALLS,
        pmsm_core::TrackerInput::default,
        |s, k| *s = input(k / pmsm_core::TRACKER_STAGES),
        |s| writes += u32::from(t.task_step(s).is_some()),
    );
    report("task_tracker", &st);
    black_box(writes);
}

/// The drive's initial position detection and the drive step, on the recorded run.
#[inline(never)]
fn run_drive(meter: &Meter, report: &mut dyn FnMut(&str, &Stats)) -> Result<(), ConfigError> {
    let b = Setup::motor_b()?;
    let ipd = IpdConfig::new(&b.motor, &b.base, IpdDesign::default())?;
    if let Some(rec) = drive_recording() {
        report("ipd_step", &bench_ipd(meter, &rec, ipd));
        profile_begin();
        let sides = bench_drive_sides(meter, &rec, || DriveCase::config().ok(), RECORDED_BUS);
        profile_end();
        if let Some(st) = sides {
            report("isr_mras_current", &st.isr);
            report("task", &st.task);
        }
        if let Some(st) = bench_drive_sides(meter, &rec, drive_with_flux, RECORDED_BUS) {
            report("isr_flux", &st.isr);
            report("task_flux", &st.task);
        }
        let low_bus = BusReading {
            eighths: LOW_BUS_EIGHTHS,
            noise: false,
        };
        if let Some(st) = bench_drive_sides(meter, &rec, drive_on_low_bus, low_bus) {
            report("isr_saturated", &st.isr);
            report("task_saturated", &st.task);
        }
        let noisy_bus = BusReading {
            noise: true,
            ..RECORDED_BUS
        };
        let config = || DriveCase::config().ok();
        if let Some(st) = bench_drive_sides(meter, &rec, config, noisy_bus) {
            report("isr_bus_noise", &st.isr);
        }
        #[cfg(target_has_atomic = "32")]
        if let Some(st) = bench_drive_sides(meter, &rec, drive_with_injection, RECORDED_BUS) {
            report("isr_injection", &st.isr);
        }
    }
    Ok(())
}

/// Marks the start of the `isr_mras_current` benchmark (or, in the image of feature
/// `identify` built with `PIL_PROFILE`, of that back-EMF estimator's) for `cargo xtask
/// isr-profile`, which attributes the instructions QEMU's execution log shows between this
/// call and [`profile_end`]'s to the parts of the interrupt step. The figures are not
/// affected: they count the measured calls only.
#[inline(never)]
fn profile_begin() {
    black_box(1u32);
}

/// Marks the end of that benchmark ([`profile_begin`]).
#[inline(never)]
fn profile_end() {
    black_box(2u32);
}

/// Motor A of Solsona, Valla, Muravchik (2000) with a rotor a tenth as heavy (the
/// estimators' closed loops reach their speed within the run): `(R Ω, L_d H, L_q H, ψ Wb,
/// J kg m², B N m s, p)`, [`pmsm_pil::setup::motor_a`]'s but `J`, `B`.
const MOTOR_A_LIGHT: Constants = (1.6, 0.0134, 0.0134, 0.288, 0.004256, 0.0004256, 3.0);

/// Samples of an estimator's closed loop (0.4 s at 20 kHz).
const CLOSED_LOOP_SAMPLES: u32 = 8000;

/// The interrupt and task steps of the drive with `estimator` on [`MOTOR_A_LIGHT`] at 20 kHz
/// (300 V, 1 µs dead time, the PWM update delay of one period), started at the rotor's
/// angle, the speed reference at half the rated speed, in a closed loop with [`DqPlant`]
/// (the voltage the drive's estimator is given applied as is): every step in `Run` measured.
#[inline(never)]
fn bench_estimator_drive(meter: &Meter, estimator: EstimatorKind) -> Option<Sides> {
    let setup = Setup::motor_a().ok()?;
    let mut m = setup.motor;
    m.j_kg_m2 = f64::from(MOTOR_A_LIGHT.4);
    m.b_nm_s = f64::from(MOTOR_A_LIGHT.5);
    let base = PerUnit::new(&m, &setup.inverter, pmsm_pil::setup::SAMPLE_HZ).ok()?;
    let mut design = DriveDesign::default_for(&m, &setup.inverter, &base, estimator);
    design.startup = StartupMode::Known(Angle::ZERO);
    design.pwm_delay_samples = 1;
    design.deadtime_calibration = false;
    let config = DriveConfig::new(&m, &setup.inverter, pmsm_pil::setup::SAMPLE_HZ, design).ok()?;
    let mut d = Drive::new(config);
    d.set_speed_ref(base.speed_pu(0.5 * 1200.0 * core::f64::consts::TAU / 60.0 * 3.0));
    d.start();
    let vdc = base.voltage_pu(setup.inverter.vdc_v);
    Some(closed_loop(
        meter,
        &mut d,
        MOTOR_A_LIGHT,
        &base,
        vdc,
        |_| None,
    ))
}

/// [`CLOSED_LOOP_SAMPLES`] steps of the started drive `d` against [`DqPlant`] with `motor`'s
/// constants at the bases `base` and the bus `vdc`, the rotor at rest at angle 0; `speed_ref(k)`
/// sets the reference before step `k` when it gives one. Every step in `Run` measured.
fn closed_loop(
    meter: &Meter,
    d: &mut Drive,
    motor: Constants,
    base: &PerUnit,
    vdc: Pu,
    speed_ref: impl Fn(u32) -> Option<Pu>,
) -> Sides {
    let mut plant = DqPlant::at_rest(
        motor,
        Angle::ZERO,
        base.voltage_v as f32,
        base.current_a as f32,
    );
    let mut sides = Sides::default();
    pmsm_pil::loops::closed_loop(
        d,
        &mut plant,
        vdc,
        base.sample_s as f32,
        CLOSED_LOOP_SAMPLES,
        &speed_ref,
        &mut sides.measured(meter),
    );
    black_box(d);
    sides
}

/// The drive's two steps on the motors of [`pmsm_pil::loops::LOOP_MOTORS`] (a low-inductance
/// and a high-pole-count motor, each with its own defaults) in a closed loop with [`DqPlant`]
/// (the image of feature `identify`): passes `isr_<name>` and `task_<name>` to `report`, then
/// the loop's end and whether its digest is the host's (`host`: the digest file) to `ended`.
#[inline(never)]
pub fn run_motors(
    meter: &Meter,
    host: &[u8],
    report: &mut dyn FnMut(&str, &str, &Stats),
    ended: &mut dyn FnMut(&pmsm_pil::loops::LoopMotor, &pmsm_pil::loops::LoopEnd, bool),
) -> Result<(), ConfigError> {
    for (k, published) in pmsm_pil::loops::LOOP_MOTORS.iter().enumerate() {
        let m = published.make();
        let mut sides = Sides::default();
        let end = pmsm_pil::loops::run(&m, &mut sides.measured(meter))?;
        report("isr", m.name, &sides.isr);
        report("task", m.name, &sides.task);
        ended(
            &m,
            &end,
            pmsm_pil::loops::digest_at(host, k) == Some(end.digest),
        );
    }
    Ok(())
}

/// The interrupt and task steps of motor B's default drive with the high-frequency injection
/// (docs/injection.md) in a closed loop with [`DqPlant`] (the image of feature `injection`, which
/// builds the core with the injection on both machines: the recording's image has no room for
/// its state on the micro:bit): started at the rotor's angle, held at 0 r/min for a third of
/// the run and then at 2 % of rated speed (60 r/min), the injection giving the angle throughout;
/// every step in `Run` measured.
#[cfg(feature = "injection")]
#[inline(never)]
fn bench_injection_drive(meter: &Meter) -> Option<Sides> {
    let b = Setup::motor_b().ok()?;
    let mut design = b
        .drive(EstimatorKind::MrasCurrent, StartupMode::Known(Angle::ZERO))
        .ok()?
        .design;
    design.injection = Some(pmsm_core::InjectionDesign::default());
    let config = b.config(design).ok()?;
    config.injection()?;
    let mut d = Drive::new(config);
    d.start();
    let vdc = b.base.voltage_pu(b.inverter.vdc_v);
    let creep = b
        .base
        .speed_pu(0.02 * 3000.0 * core::f64::consts::TAU / 60.0 * 3.0);
    Some(closed_loop(meter, &mut d, MOTOR_B, &b.base, vdc, |k| {
        Some(if k < CLOSED_LOOP_SAMPLES / 3 {
            Pu::ZERO
        } else {
            creep
        })
    }))
}

/// [`bench_injection_drive`]'s figures: `isr_injection_loop` and `task_injection_loop`.
#[cfg(feature = "injection")]
#[inline(never)]
pub fn run_injection(meter: &Meter, report: &mut dyn FnMut(&str, &Stats)) {
    if let Some(st) = bench_injection_drive(meter) {
        report("isr_injection_loop", &st.isr);
        report("task_injection_loop", &st.task);
    }
}

/// The interrupt and task steps of each back-EMF estimator's drive in a closed loop
/// ([`bench_estimator_drive`]): `isr_nlo`, `isr_ao`, `isr_mras_emf` and their tasks (the
/// image of feature `identify`: the plant fits beside the core where the recording does not).
#[inline(never)]
pub fn run_estimators(meter: &Meter, report: &mut dyn FnMut(&str, &Stats)) {
    for (kind, isr, task) in [
        (EstimatorKind::Nlo, "isr_nlo", "task_nlo"),
        (EstimatorKind::Ao, "isr_ao", "task_ao"),
        (EstimatorKind::MrasEmf, "isr_mras_emf", "task_mras_emf"),
    ] {
        // `cargo xtask isr-profile --bench <isr>` builds this image with `PIL_PROFILE=<isr>`:
        // that benchmark between the profile's marks.
        let profiled = option_env!("PIL_PROFILE") == Some(isr);
        if profiled {
            profile_begin();
        }
        let sides = bench_estimator_drive(meter, kind);
        if profiled {
            profile_end();
        }
        if let Some(st) = sides {
            report(isr, &st.isr);
            report(task, &st.task);
        }
    }
}

/// The identification's benchmarks (the image of feature `identify`, which embeds no
/// recording: the micro:bit's flash holds the recording or the identification, not both):
/// self-commissioning of motor B from its pole pairs, the inverter and the rated peak
/// current. Passes `identify_step` and `identify_poll` to `report`, then how it ended and the
/// samples it took to `identified`.
#[inline(never)]
pub fn run_identify(
    meter: &Meter,
    report: &mut dyn FnMut(&str, &Stats),
    identified: &mut dyn FnMut(IdentifyEnd, u32),
) -> Result<(), ConfigError> {
    let b = Setup::motor_b()?;
    let limit_a = core::f64::consts::SQRT_2 * 2.53;
    let cfg = IdentifyConfig::new(3, &b.inverter, limit_a, IdentifyDesign::default())?;
    let (step, poll, end, samples) = bench_identify(meter, cfg);
    report("identify_step", &step);
    report("identify_poll", &poll);
    identified(end, samples);
    Ok(())
}
