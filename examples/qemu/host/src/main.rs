//! `pil-record [--output PATH] [--steps N]`: runs every replay case of `pmsm_pil::cases` on the
//! host on its scenario and writes the input and output words of each step to PATH (default
//! `examples/qemu/target/pil/recording.bin`), which the firmware embeds (`PIL_RECORDING`).
//!
//! Scenario of the estimator cases: motor A (Solsona, Valla, Muravchik (2000)) turning at 120 rad/s mechanical, then
//! slowing to 115 rad/s with a raised-cosine profile (a torque-consistent prescribed trajectory,
//! `i_d = 0`, as `tests/support/trajectory.rs`), sampled at 20 kHz with ADC-like noise on the
//! currents and voltages; the estimators start from zero state, so the recording covers their
//! convergence and tracking.

use std::f64::consts::PI;
use std::path::Path;
use std::process::ExitCode;

use pmsm_core::DriveInput;
use pmsm_core::ObserverInput;
use pmsm_core::{Abc, AlphaBeta, Angle, PerUnit, Pu};
use pmsm_pil::cases::Case;
use pmsm_pil::cases::{self, CASES, Io, Shape};
use pmsm_pil::format;
use pmsm_pil::loops;
use pmsm_pil::setup::{DRIVE_SAMPLE_HZ, SAMPLE_HZ, Setup};

/// Default number of steps of the estimator cases (5 ms at 20 kHz, from the first sample of
/// the trajectory). The micro:bit's 256 KiB of flash holds the firmware, the drive case and
/// little more.
const DEFAULT_STEPS: usize = 100;

/// Default number of steps of the drive case (79 ms at 14 kHz: the initial position
/// detection, the start of the ramp to 800 r/min).
const DEFAULT_DRIVE_STEPS: usize = 1100;

fn main() -> ExitCode {
    match run() {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("pil-record: {e}");
            ExitCode::FAILURE
        }
    }
}

fn run() -> Result<(), String> {
    // examples/qemu/target/pil/recording.bin, where the firmware's build.rs looks by default.
    let workspace = Path::new(env!("CARGO_MANIFEST_DIR"))
        .parent()
        .unwrap_or(Path::new(".."));
    let mut output = workspace.join("target/pil/recording.bin");
    let mut steps = DEFAULT_STEPS;
    let mut drive_steps = DEFAULT_DRIVE_STEPS;
    let mut args = std::env::args().skip(1);
    while let Some(arg) = args.next() {
        match arg.as_str() {
            "--output" => output = args.next().ok_or("--output needs a path")?.into(),
            "--steps" => {
                steps = args
                    .next()
                    .and_then(|s| s.parse().ok())
                    .filter(|&n| n > 0)
                    .ok_or("--steps needs a positive integer")?
            }
            "--drive-steps" => {
                drive_steps = args
                    .next()
                    .and_then(|s| s.parse().ok())
                    .filter(|&n| n > 0)
                    .ok_or("--drive-steps needs a positive integer")?
            }
            _ => {
                return Err(format!(
                    "unknown argument {arg:?} (usage: pil-record [--output PATH] [--steps N] [--drive-steps N])"
                ));
            }
        }
    }
    let setup = Setup::motor_a().map_err(|e| format!("motor A set-up: {e}"))?;
    let mut bytes = format::file_header(CASES.len() as u32).to_vec();
    for shape in CASES {
        let steps = match shape.name {
            "drive" => drive_steps,
            "closed_loop" => CLOSED_LOOP_STEPS,
            _ => steps,
        };
        let mut io = scenario(shape, &setup, steps)?;
        let ran = cases::run_named(shape.name, &setup, &mut *io)
            .ok_or_else(|| format!("case {} is in CASES but not in run_named", shape.name))?
            .map_err(|e| format!("case {}: {e}", shape.name))?;
        if ran != steps || io.words().len() != steps * (shape.inputs + shape.outputs) {
            return Err(format!("case {}: ran {ran} of {steps} steps", shape.name));
        }
        let header = format::case_header(shape.name, shape.inputs, shape.outputs, steps)
            .map_err(|e| format!("case {}: {e}", shape.name))?;
        bytes.extend_from_slice(&header);
        bytes.extend(io.words().iter().flat_map(|w| w.to_le_bytes()));
        eprintln!(
            "pil-record: {:<10} {steps} steps, {}",
            shape.name,
            io.summary(&setup)
        );
    }
    // The firmware's parser must accept what we write.
    format::Recording::parse(&bytes).map_err(|e| format!("own recording: {e}"))?;
    write_unchanged(&output, &bytes, &format!("{} cases", CASES.len()))?;
    write_unchanged(
        &output.with_file_name("loops.bin"),
        &closed_loops()?,
        &format!("{} closed loops", loops::LOOP_MOTORS.len()),
    )?;
    // The `drive` case's configuration designed here, as its image (docs/image.md): the
    // Cortex-M4 reads it and compares it with its own design.
    let config = cases::DriveCase::config().map_err(|e| format!("drive image: {e}"))?;
    let mut words = [0u32; pmsm_core::DriveConfig::IMAGE_WORDS];
    config.write_image(&mut words);
    let image: Vec<u8> = words.iter().flat_map(|w| w.to_le_bytes()).collect();
    write_unchanged(
        &output.with_file_name("drive_image.bin"),
        &image,
        &format!("the drive's image, {} words", words.len()),
    )
}

/// Writes `bytes` to `path`, unless it holds them already: an unchanged file keeps its time
/// stamp, so the firmware is not rebuilt.
fn write_unchanged(path: &Path, bytes: &[u8], what: &str) -> Result<(), String> {
    if std::fs::read(path).is_ok_and(|old| old == bytes) {
        eprintln!("pil-record: {} unchanged ({what})", path.display());
        return Ok(());
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(path, bytes).map_err(|e| format!("{}: {e}", path.display()))?;
    eprintln!(
        "pil-record: wrote {} ({} bytes, {what})",
        path.display(),
        bytes.len()
    );
    Ok(())
}

/// Runs the closed loops of `pmsm_pil::loops` on the host: their digests, for the firmware to
/// compare its own with. Each loop must hold its rotor.
fn closed_loops() -> Result<Vec<u8>, String> {
    let mut digests = Vec::new();
    for published in &loops::LOOP_MOTORS {
        let m = published.make();
        let end = loops::run(&m, &mut |d, x| d.step(x))
            .map_err(|e| format!("closed loop {}: {e}", m.name))?;
        let angle = end.error.to_rad();
        eprintln!(
            "pil-record: loop {:<7} {} steps, {:?}, state {}, angle off by {angle:+.4} rad, \
             rotor at {:.1} rad/s, digest {:#010x}",
            m.name,
            loops::LOOP_SAMPLES,
            pmsm_core::EstimatorKind::for_motor(&m.motor),
            end.state,
            end.omega_e_rad_s,
            end.digest
        );
        if !m.held(&end) {
            return Err(format!("closed loop {} does not hold its rotor", m.name));
        }
        digests.push(end.digest);
    }
    Ok(loops::digest_file(&digests).to_vec())
}

/// The scenario of a case: where its inputs come from.
fn scenario(shape: &Shape, setup: &Setup, steps: usize) -> Result<Box<dyn Recording>, String> {
    match shape.name {
        "nlo" | "ao" => Ok(Box::new(Recorder::open_loop(
            shape,
            estimator_inputs(setup, steps),
        ))),
        "drive" => Ok(Box::new(DriveLoop::new(steps)?)),
        "closed_loop" => Ok(Box::new(Silent {
            steps,
            outputs: shape.outputs,
            words: Vec::new(),
        })),
        other => Err(format!(
            "no scenario for case {other}: add one in host/src/main.rs"
        )),
    }
}

/// Recorded steps of the closed-loop case (each `CLOSED_LOOP_CHUNK` drive steps: 1400 steps,
/// 0.1 s at 14 kHz; the plant's soft-float model is most of the target's time).
const CLOSED_LOOP_STEPS: usize = 56;

/// A case without inputs (the closed loop, whose plant runs inside it): `steps` steps, every
/// output kept.
struct Silent {
    steps: usize,
    outputs: usize,
    words: Vec<i32>,
}

impl Io for Silent {
    fn input(&mut self, step: usize, _input: &mut [i32]) -> bool {
        step < self.steps
    }
    fn output(&mut self, _step: usize, output: &[i32]) -> bool {
        self.words.extend_from_slice(output);
        true
    }
}

impl Recording for Silent {
    fn words(&self) -> &[i32] {
        &self.words
    }
    fn summary(&self, _setup: &Setup) -> String {
        let Some(last) = self.words.rchunks(self.outputs).next() else {
            return String::new();
        };
        let word = |j: usize| last.get(j).copied().unwrap_or(0);
        let f = |hi: usize| {
            f64::from_bits(((word(hi) as u32 as u64) << 32) | word(hi + 1) as u32 as u64)
        };
        format!(
            "last step: state {}, plant {:.1} r/min, estimate off by {:+.2}°",
            word(0),
            f(4) * 60.0 / (2.0 * PI),
            (Angle(word(1)).to_rad() - f(6) + PI)
                .rem_euclid(2.0 * PI)
                .to_degrees()
                - 180.0
        )
    }
}

/// A scenario's [`Io`] that keeps every step's words.
trait Recording: Io {
    /// Input and output words of every step so far, in order.
    fn words(&self) -> &[i32];
    /// One line on the run (errors at the last step).
    fn summary(&self, setup: &Setup) -> String;
}

impl Recording for Recorder {
    fn words(&self) -> &[i32] {
        &self.words
    }
    fn summary(&self, setup: &Setup) -> String {
        Recorder::summary(self, setup)
    }
}

/// The drive case in a closed loop with `pmsm-plant`: motor B from standstill at θ = 137°
/// (as `examples/b-800rpm-load.toml`), switching-level inverter with 2 µs dead time, 12-bit
/// ADC, the default d-axis saturation. The drive detects the initial position (about 0.1 s),
/// then the speed reference ramps toward 800 r/min at 4000 r/min/s and a 2 N·m load steps on
/// at 0.15 s. `Io::input` samples the plant, `Io::output` applies the duties for a period.
struct DriveLoop {
    plant: pmsm_plant::Plant,
    base: PerUnit,
    sample: Option<pmsm_plant::Sample>,
    /// First step in `Run` (when the ramp starts).
    run_from: Option<usize>,
    steps: usize,
    inputs: usize,
    words: Vec<i32>,
    last_theta_e: f64,
}

/// Electrical angle at which the drive case's rotor rests, rad.
const DRIVE_THETA0_RAD: f64 = 137.0 * PI / 180.0;

impl DriveLoop {
    fn new(steps: usize) -> Result<Self, String> {
        let b = Setup::motor_b().map_err(|e| format!("motor B set-up: {e}"))?;
        let model = pmsm_plant::MotorModel::new(b.motor);
        let motor = pmsm_plant::Motor::new(model, DRIVE_THETA0_RAD, 0.0)
            .map_err(|e| format!("motor B: {e}"))?;
        let inverter =
            pmsm_plant::InverterModel::new(b.inverter, pmsm_plant::InverterKind::Switching);
        let adc = pmsm_plant::AdcParams::from_inverter(&b.inverter);
        let plant =
            pmsm_plant::Plant::new(motor, inverter, adc).map_err(|e| format!("plant: {e}"))?;
        Ok(Self {
            plant,
            base: b.base,
            sample: None,
            run_from: None,
            steps,
            inputs: shape_of("drive")?.inputs,
            words: Vec::new(),
            last_theta_e: DRIVE_THETA0_RAD,
        })
    }

    /// Speed reference at `step`, electrical rad/s.
    fn speed_ref_rad_s(&self, step: usize) -> f64 {
        let Some(k0) = self.run_from else {
            return 0.0;
        };
        let t = (step.saturating_sub(k0)) as f64 / DRIVE_SAMPLE_HZ;
        let rpm = (4000.0 * t).min(800.0);
        rpm * 2.0 * PI / 60.0 * self.plant.motor().model().params.p()
    }

    /// Load torque at `step`, N·m.
    fn load_nm(step: usize) -> f64 {
        if step as f64 / DRIVE_SAMPLE_HZ >= 0.15 {
            2.0
        } else {
            0.0
        }
    }
}

/// The shape of the case called `name`.
fn shape_of(name: &str) -> Result<&'static Shape, String> {
    CASES
        .iter()
        .find(|s| s.name == name)
        .ok_or_else(|| format!("no case {name}"))
}

impl Io for DriveLoop {
    fn input(&mut self, step: usize, input: &mut [i32]) -> bool {
        if step >= self.steps {
            return false;
        }
        let (i, vdc) = match &self.sample {
            Some(s) => (s.i_abc_a_measured, s.vdc_v),
            None => ([0.0; 3], self.plant.vdc_v()),
        };
        let b = &self.base;
        let x = DriveInput {
            i_abc: Abc {
                a: b.current_pu(i[0]),
                b: b.current_pu(i[1]),
                c: b.current_pu(i[2]),
            },
            vdc: b.voltage_pu(vdc),
        };
        let speed_ref = b.speed_pu(self.speed_ref_rad_s(step));
        cases::drive_input_words(&x, speed_ref, input);
        self.words.extend_from_slice(input);
        true
    }

    fn output(&mut self, step: usize, output: &[i32]) -> bool {
        self.words.extend_from_slice(output);
        if self.run_from.is_none() && output[cases::DRIVE_STATE_WORD] == cases::STATE_RUN {
            self.run_from = Some(step + 1);
        }
        self.last_theta_e = self.plant.motor().state().theta_e_rad;
        let duty = |j: usize| output[j] as f64 / (1u64 << 30) as f64;
        let load = Self::load_nm(step);
        let sample = if output[3] != 0 {
            self.plant.step_pwm([duty(0), duty(1), duty(2)], load)
        } else {
            self.plant.step_off(load)
        };
        match sample {
            Ok(s) => {
                self.sample = Some(s);
                true
            }
            Err(e) => {
                eprintln!("pil-record: drive: the plant failed at step {step}: {e}");
                false
            }
        }
    }
}

impl Recording for DriveLoop {
    fn words(&self) -> &[i32] {
        &self.words
    }
    fn summary(&self, _setup: &Setup) -> String {
        let n = self.inputs + cases::DriveCase::OUTPUTS;
        let Some(last) = self.words.rchunks(n).next() else {
            return String::new();
        };
        let o = &last[self.inputs..];
        let theta_est = Angle(o[4]).to_rad();
        let d = theta_est - self.last_theta_e;
        let d = (d + PI).rem_euclid(2.0 * PI) - PI;
        let s = self.plant.motor().state();
        format!(
            "run from step {}, last step: state {}, speed {:.1} r/min (estimate {:.1}), angle error {:+.3}°",
            self.run_from.map_or(-1, |k| k as i64),
            o[cases::DRIVE_STATE_WORD],
            s.omega_m_rad_s * 60.0 / (2.0 * PI),
            self.base.speed_rad_s(Pu::from_bits(o[5])) * 60.0
                / (2.0 * PI)
                / self.plant.motor().model().params.p(),
            d.to_degrees()
        )
    }
}

/// Records every step's words; inputs from a precomputed list (open loop).
struct Recorder {
    inputs: Vec<Vec<i32>>,
    words: Vec<i32>,
    /// Truth per step for the summary: electrical angle (rad), speed (rad/s).
    truth: Vec<(f64, f64)>,
    outputs: usize,
}

impl Recorder {
    fn open_loop(shape: &Shape, inputs: Vec<(ObserverInput, (f64, f64))>) -> Self {
        let (inputs, truth) = inputs
            .into_iter()
            .map(|(x, t)| {
                let mut w = vec![0; shape.inputs];
                cases::observer_input_words(&x, &mut w);
                (w, t)
            })
            .unzip();
        Self {
            inputs,
            words: Vec::new(),
            truth,
            outputs: shape.outputs,
        }
    }

    /// Angle and speed error of the last estimate (estimator cases).
    fn summary(&self, setup: &Setup) -> String {
        let n = self.inputs.first().map_or(0, Vec::len) + self.outputs;
        let (Some(last), Some(&(theta, omega))) = (self.words.rchunks(n).next(), self.truth.last())
        else {
            return String::new();
        };
        let e = cases::estimate_of(&last[n - self.outputs..]);
        let d = e.theta.to_rad() - theta;
        let d = (d + PI).rem_euclid(2.0 * PI) - PI;
        format!(
            "last step: angle error {:+.3}°, speed error {:+.3} rad/s electrical",
            d.to_degrees(),
            setup.base.speed_rad_s(e.omega) - omega
        )
    }
}

impl Io for Recorder {
    fn input(&mut self, step: usize, input: &mut [i32]) -> bool {
        match self.inputs.get(step) {
            Some(w) => {
                input.copy_from_slice(w);
                self.words.extend_from_slice(w);
                true
            }
            None => false,
        }
    }

    fn output(&mut self, _step: usize, output: &[i32]) -> bool {
        self.words.extend_from_slice(output);
        true
    }
}

/// Mechanical speed profile: 120 rad/s, then a raised-cosine ramp to 115 rad/s over
/// [40 ms, 100 ms] (peak torque about 5 N·m, under rated). Returns `(ω_m, ω̇_m, ω̈_m)`.
fn profile(t: f64) -> (f64, f64, f64) {
    const W0: f64 = 120.0;
    const W1: f64 = 115.0;
    const T0: f64 = 0.04;
    const T1: f64 = 0.1;
    if t <= T0 {
        (W0, 0.0, 0.0)
    } else if t >= T1 {
        (W1, 0.0, 0.0)
    } else {
        let d = T1 - T0;
        let x = PI * (t - T0) / d;
        let a = 0.5 * (W1 - W0);
        (
            W0 + a * (1.0 - x.cos()),
            a * x.sin() * PI / d,
            a * x.cos() * (PI / d).powi(2),
        )
    }
}

/// `∫₀ᵗ ω_m dt` of [`profile`] (exact).
fn angle_m(t: f64) -> f64 {
    const W0: f64 = 120.0;
    const W1: f64 = 115.0;
    const T0: f64 = 0.04;
    const T1: f64 = 0.1;
    let d = T1 - T0;
    let a = 0.5 * (W1 - W0);
    let tau = (t.min(T1) - T0).max(0.0);
    W0 * t.min(T0) + W0 * tau + a * (tau - d / PI * (PI * tau / d).sin()) + W1 * (t - T1).max(0.0)
}

/// SplitMix64: deterministic noise.
struct SplitMix(u64);

impl SplitMix {
    fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^= z >> 31;
        lo + (hi - lo) * (z >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Per-unit estimator inputs of the trajectory with the truth `(θ_e, ω_e)` of each sample.
/// The voltage of sample k is the mean over `[t_{k−1}, t_k]` (trapezoid), as `pmsm observe`
/// and the tests of Solsona, Valla, Muravchik (2000) feed it.
fn estimator_inputs(setup: &Setup, steps: usize) -> Vec<(ObserverInput, (f64, f64))> {
    let m = &setup.motor;
    let base: &PerUnit = &setup.base;
    let p = m.p();
    let theta0 = 0.3;
    let sample = |t: f64| {
        let (w, dw, ddw) = profile(t);
        let th = theta0 + p * angle_m(t);
        let we = p * w;
        let iq = (m.j_kg_m2 * dw + m.b_nm_s * w) / m.kt_nm_per_a;
        let diq = (m.j_kg_m2 * ddw + m.b_nm_s * dw) / m.kt_nm_per_a;
        let (s, c) = th.sin_cos();
        let i = [-iq * s, iq * c];
        let di = [-diq * s - iq * we * c, diq * c - iq * we * s];
        let e = [-m.flux_wb * we * s, m.flux_wb * we * c];
        let v = [
            m.rs_ohm * i[0] + m.ld_h * di[0] + e[0],
            m.rs_ohm * i[1] + m.ld_h * di[1] + e[1],
        ];
        (i, v, th, we)
    };
    let ts = 1.0 / SAMPLE_HZ;
    let mut noise = SplitMix(0x5eed_0005);
    let mut prev_v = None;
    (0..steps)
        .map(|k| {
            let (i, v, th, we) = sample(k as f64 * ts);
            let mean_v = match prev_v.replace(v) {
                Some(pv) => [0.5 * (pv[0] + v[0]), 0.5 * (pv[1] + v[1])],
                None => v,
            };
            // ±1 LSB of a 12-bit ADC over ±20 A; ±0.3 V on the voltages.
            let mut ni = || noise.uniform(-0.01, 0.01);
            let (ia, ib) = (i[0] + ni(), i[1] + ni());
            let mut nv = || noise.uniform(-0.3, 0.3);
            let (va, vb) = (mean_v[0] + nv(), mean_v[1] + nv());
            let input = ObserverInput {
                i: AlphaBeta {
                    alpha: base.current_pu(ia),
                    beta: base.current_pu(ib),
                },
                v: AlphaBeta {
                    alpha: base.voltage_pu(va),
                    beta: base.voltage_pu(vb),
                },
            };
            (input, (th, we))
        })
        .collect()
}
