//! Instructions per call of each component, on deterministic inputs generated here.
//!
//! Every benchmark is a state (the component's inputs, its output, and for estimators the
//! estimator itself) built by `init`, a `prepare` step that writes the inputs of call `k` (not
//! measured) and a `call` that runs the component once on them (measured by [`Meter::insn`]). The figure of a
//! call therefore includes loading the inputs from memory and storing the output, as a caller
//! in a control interrupt would.
//!
//! To add a component (SVPWM, the current loops, the MRAS-current estimator, the drive's
//! `step()`), add one `report(...)` to [`run_all`] (names are stable identifiers: `snake_case`,
//! the function, not the paper).

use core::hint::black_box;

use pmsm_core::cordic::{Polar, polar};
use pmsm_core::frames::{clarke, inverse_clarke, inverse_park, park};
use pmsm_core::num::{mul, mul_unit, pu_from_f64};
use pmsm_core::observer::{Ao, Estimate, Estimator, MrasEmf, Nlo, ObserverInput};
use pmsm_core::{Abc, AlphaBeta, Angle, ConfigError, Dq, Pu, SinCos};
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
    Ok(())
}
