//! `pmsm identify`: the core's self-commissioning routine against the plant built from a
//! "true" motor file; writes the identified motor file and prints it against the truth.
//!
//! The routine sees only what a board would: the phase currents through the plant's ADC
//! model (12 bits, full scale 2.5 × the current limit) and the bus voltage. The plant is the
//! switching-level inverter with dead time unless `--averaged` is given.

use crate::{motor_file, plot};
use anyhow::{Result, anyhow, bail};
use pmsm_core::{AlphaBeta, InverterParams, MotorParams};
use pmsm_core::{Identified, Identify, IdentifyConfig, IdentifyDesign};
use pmsm_plant::{AdcParams, InverterKind, InverterModel, Motor, MotorModel, Plant};
use std::fmt::Write as _;
use std::path::PathBuf;

/// Arguments of `pmsm identify`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// The true motor (TOML): the plant is built from it; the routine is not told.
    #[arg(long, value_name = "TRUTH.toml")]
    pub motor: PathBuf,
    /// DC bus voltage, V.
    #[arg(long, value_name = "V", allow_negative_numbers = true)]
    pub vdc: f64,
    /// PWM (and control) frequency, Hz.
    #[arg(long, value_name = "HZ", default_value_t = 16000.0)]
    pub pwm_hz: f64,
    /// Inverter dead time, s.
    #[arg(long, value_name = "S", default_value_t = 1e-6)]
    pub dead_time_s: f64,
    /// Current limit, A peak (default √2 × the truth's rated_current_a).
    #[arg(long, value_name = "A")]
    pub current_limit_a: Option<f64>,
    /// Initial electrical rotor angle of the plant, degrees.
    #[arg(
        long,
        value_name = "DEG",
        default_value_t = 40.0,
        allow_negative_numbers = true
    )]
    pub theta_deg: f64,
    /// Mechanical acceleration of the spin's ramps, rad/s² (lower it for a heavy rotor: the
    /// field must not outrun it).
    #[arg(long, value_name = "RAD_S2", default_value_t = 200.0)]
    pub accel_rad_s2: f64,
    /// White noise on each phase-current reading, A RMS.
    #[arg(long, value_name = "A", default_value_t = 0.0)]
    pub adc_noise_a: f64,
    /// Use the averaged inverter model (faster) instead of the switching one.
    #[arg(long)]
    pub averaged: bool,
    /// The identified motor file to write.
    #[arg(long, value_name = "identified.toml")]
    pub output: PathBuf,
    /// Also draw the routine's currents and speed to this SVG file.
    #[arg(long, value_name = "out.svg")]
    pub plot: Option<PathBuf>,
}

/// Decimated record of a run, for the plot.
#[derive(Clone, Debug, Default)]
pub struct Trace {
    /// Time, s.
    pub t_s: Vec<f64>,
    /// Measured α current, A.
    pub i_alpha_a: Vec<f64>,
    /// Measured β current, A.
    pub i_beta_a: Vec<f64>,
    /// Commanded mechanical speed, r/min.
    pub speed_cmd_rpm: Vec<f64>,
    /// True mechanical speed, r/min.
    pub speed_rpm: Vec<f64>,
}

/// One identification against the plant.
#[derive(Clone, Debug)]
pub struct Run {
    /// What the routine found.
    pub identified: Identified,
    /// Simulated duration, s.
    pub duration_s: f64,
    /// The record.
    pub trace: Trace,
}

/// Runs the routine on a plant of `truth` on `inverter` (whose `current_full_scale_a` is the
/// ADC's), limited to `current_limit_a`, rotor starting at `theta_deg`.
pub fn identify(
    truth: &MotorModel,
    inverter: &InverterParams,
    kind: InverterKind,
    current_limit_a: f64,
    theta_deg: f64,
) -> Result<Run> {
    identify_with(
        truth,
        inverter,
        kind,
        AdcParams::from_inverter(inverter),
        current_limit_a,
        theta_deg,
        IdentifyDesign::default(),
    )
}

/// [`identify`] with an ADC (noise, offsets) and a design of one's own.
pub fn identify_with(
    truth: &MotorModel,
    inverter: &InverterParams,
    kind: InverterKind,
    adc: AdcParams,
    current_limit_a: f64,
    theta_deg: f64,
    design: IdentifyDesign,
) -> Result<Run> {
    let config = IdentifyConfig::new(truth.params.pole_pairs, inverter, current_limit_a, design)
        .map_err(|e| anyhow!("identification: {e}"))?;
    let motor = Motor::new(*truth, theta_deg.to_radians(), 0.0).map_err(|e| anyhow!("{e}"))?;
    let mut plant =
        Plant::new(motor, InverterModel::new(*inverter, kind), adc).map_err(|e| anyhow!("{e}"))?;
    let mut id = Identify::new(config);
    let i_b = config.current_base_a;
    let v_b = config.voltage_base_v;
    let p = truth.params.p();
    let rpm = 60.0 / std::f64::consts::TAU;
    let mut i = AlphaBeta::default();
    let mut trace = Trace::default();
    // Enough for the slowest sequence the design allows (the spin is at most a few s).
    let limit = (120.0 / config.sample_s) as u64;
    for n in 0..limit {
        let vdc = pmsm_core::pu_from_f64(plant.vdc_v() / v_b);
        let o = id.step(i, vdc);

        if let Some(r) = id.poll() {
            let identified = r.map_err(|e| anyhow!("identification failed: {e}"))?;
            return Ok(Run {
                identified,
                duration_s: plant.time_s(),
                trace,
            });
        }
        let s = if o.pwm_on {
            plant.step_pwm(o.duties.to_f64(), 0.0)
        } else {
            plant.step_off(0.0)
        }
        .map_err(|e| anyhow!("the plant failed: {e}"))?;
        let ab = pmsm_plant::clarke(s.i_abc_a_measured);
        i = AlphaBeta {
            alpha: pmsm_core::pu_from_f64(ab[0] / i_b),
            beta: pmsm_core::pu_from_f64(ab[1] / i_b),
        };
        if n % 16 == 0 {
            trace.t_s.push(s.t_s);
            trace.i_alpha_a.push(ab[0]);
            trace.i_beta_a.push(ab[1]);
            trace
                .speed_cmd_rpm
                .push(id.speed_rad_s(o.speed_q16) / p * rpm);
            trace
                .speed_rpm
                .push(plant.motor().state().omega_m_rad_s * rpm);
        }
    }
    bail!("the identification did not finish in {limit} samples")
}

/// Relative error of `got` against `truth`.
pub fn rel(got: f64, truth: f64) -> f64 {
    (got - truth) / truth
}

/// The bars the identification is held to on motors it was not tuned for
/// (docs/identification.md): R, L_d, L_q, ψ, J, relative.
pub const BARS: [f64; 5] = [0.03, 0.05, 0.05, 0.03, 0.15];

/// Identified against true: R, L_d, L_q, ψ, J, B (relative; the first five against [`BARS`]).
pub fn errors(got: &MotorParams, truth: &MotorParams) -> [f64; 6] {
    [
        rel(got.rs_ohm, truth.rs_ohm),
        rel(got.ld_h, truth.ld_h),
        rel(got.lq_h, truth.lq_h),
        rel(got.flux_wb, truth.flux_wb),
        rel(got.j_kg_m2, truth.j_kg_m2),
        rel(got.b_nm_s, truth.b_nm_s),
    ]
}

/// The motor file text (same keys and format as the examples).
pub fn motor_toml(name: &str, m: &MotorParams) -> String {
    let mut s = String::new();
    let _ = writeln!(s, "# Identified by `pmsm identify`.");
    let _ = writeln!(s, "name = \"{name}\"");
    let _ = writeln!(s, "pole_pairs = {}", m.pole_pairs);
    let _ = writeln!(s, "rs_ohm = {:.6e}", m.rs_ohm);
    let _ = writeln!(s, "ld_h = {:.6e}", m.ld_h);
    let _ = writeln!(s, "lq_h = {:.6e}", m.lq_h);
    let _ = writeln!(s, "flux_wb = {:.6e}", m.flux_wb);
    let _ = writeln!(s, "j_kg_m2 = {:.6e}", m.j_kg_m2);
    let _ = writeln!(s, "b_nm_s = {:.6e}", m.b_nm_s);
    if let Some(i) = m.rated_current_a {
        let _ = writeln!(s, "rated_current_a = {i}");
    }
    if let Some(n) = m.rated_speed_rpm {
        let _ = writeln!(s, "rated_speed_rpm = {n}");
    }
    // Identified at small signal: linear magnetics.
    let _ = writeln!(s, "\n[saturation]\nmodel = \"none\"");
    s
}

/// What an identification is run with, as `pmsm identify`'s options give it.
#[derive(Clone, Copy, Debug)]
pub struct Request {
    /// DC bus voltage, V.
    pub vdc_v: f64,
    /// PWM (and control) frequency, Hz.
    pub pwm_hz: f64,
    /// Inverter dead time, s.
    pub dead_time_s: f64,
    /// Current limit, A peak (`None`: √2 × the truth's rated current).
    pub current_limit_a: Option<f64>,
    /// Initial electrical rotor angle of the plant, degrees.
    pub theta_deg: f64,
    /// Mechanical acceleration of the spin's ramps, rad/s².
    pub accel_rad_s2: f64,
    /// White noise on each phase-current reading, A RMS.
    pub adc_noise_a: f64,
    /// The averaged inverter model instead of the switching one.
    pub averaged: bool,
}

/// An identification done: the identified motor (with the truth's ratings) and the report.
#[derive(Clone, Debug)]
pub struct Commissioned {
    /// The identified motor.
    pub motor: MotorParams,
    /// Its motor file ([`motor_toml`]).
    pub toml: String,
    /// Identified against true, one line each (what `pmsm identify` prints).
    pub report: String,
    /// The run.
    pub run: Run,
}

/// Identifies `truth` (named `shown` in messages) as `request` says.
pub fn commission(
    truth: &motor_file::Motor,
    request: &Request,
    shown: &str,
) -> Result<Commissioned> {
    let t = truth.model.params;
    let limit = match (request.current_limit_a, t.rated_current_a) {
        (Some(a), _) => a,
        (None, Some(rms)) => std::f64::consts::SQRT_2 * rms,
        (None, None) => bail!("{shown}: no rated_current_a; give --current-limit-a"),
    };
    if !(limit.is_finite() && limit > 0.0) {
        bail!("--current-limit-a: must be a positive number, not {limit}");
    }
    let inverter = InverterParams {
        vdc_v: request.vdc_v,
        pwm_hz: request.pwm_hz,
        dead_time_s: request.dead_time_s,
        current_full_scale_a: 2.5 * limit,
    };
    inverter.validate().map_err(|e| anyhow!("{e}"))?;
    let kind = if request.averaged {
        InverterKind::Averaged
    } else {
        InverterKind::Switching
    };
    let design = IdentifyDesign {
        accel_m_rad_s2: request.accel_rad_s2,
        ..IdentifyDesign::default()
    };
    let mut adc = AdcParams::from_inverter(&inverter);
    adc.noise_rms_a = request.adc_noise_a;
    adc.validate().map_err(|e| anyhow!("--adc-noise-a: {e}"))?;
    let run = identify_with(
        &truth.model,
        &inverter,
        kind,
        adc,
        limit,
        request.theta_deg,
        design,
    )
    .map_err(|e| {
        if format!("{e}").contains("flux step: the rotor moved") {
            e.context("the rotor did not follow the spin: try a lower --accel-rad-s2")
        } else {
            e
        }
    })?;
    let mut m = run.identified.motor;
    m.rated_current_a = t.rated_current_a;
    m.rated_speed_rpm = t.rated_speed_rpm;
    let name = format!("{} (identified)", truth.name);
    let mut report = String::new();
    let _ = writeln!(
        report,
        "pmsm identify: {} at {} V, {} Hz, dead time {} s, limit {limit:.3} A: {:.2} s",
        truth.name, request.vdc_v, request.pwm_hz, request.dead_time_s, run.duration_s
    );
    let _ = writeln!(
        report,
        "  {:<10} {:>13} {:>13} {:>9}",
        "", "identified", "plant", "error"
    );
    for (key, got, want) in [
        ("rs_ohm", m.rs_ohm, t.rs_ohm),
        ("ld_h", m.ld_h, t.ld_h),
        ("lq_h", m.lq_h, t.lq_h),
        ("flux_wb", m.flux_wb, t.flux_wb),
        ("j_kg_m2", m.j_kg_m2, t.j_kg_m2),
        ("b_nm_s", m.b_nm_s, t.b_nm_s),
    ] {
        let err = if want != 0.0 {
            format!("{:+.2} %", 100.0 * rel(got, want))
        } else {
            "-".to_owned()
        };
        let _ = writeln!(report, "  {key:<10} {got:>13.5e} {want:>13.5e} {err:>9}");
    }
    let _ = writeln!(
        report,
        "  distortion voltage {:.3} V, spin at {:.0} and {:.0} rad/s electrical",
        run.identified.distortion_v,
        run.identified.spin_speeds_rad_s[0],
        run.identified.spin_speeds_rad_s[1]
    );
    Ok(Commissioned {
        motor: m,
        toml: motor_toml(&name, &m),
        report,
        run,
    })
}

/// Runs `pmsm identify`.
pub fn run(args: &Args) -> Result<()> {
    let truth = motor_file::read(&args.motor)?;
    let request = Request {
        vdc_v: args.vdc,
        pwm_hz: args.pwm_hz,
        dead_time_s: args.dead_time_s,
        current_limit_a: args.current_limit_a,
        theta_deg: args.theta_deg,
        accel_rad_s2: args.accel_rad_s2,
        adc_noise_a: args.adc_noise_a,
        averaged: args.averaged,
    };
    let done = commission(&truth, &request, &args.motor.display().to_string())?;
    std::fs::write(&args.output, &done.toml)
        .map_err(|e| anyhow!("{}: cannot write: {e}", args.output.display()))?;
    crate::out::emit(format_args!("{}", done.report));
    let run = done.run;
    crate::outln!("  output     {}", args.output.display());
    if let Some(path) = &args.plot {
        let tr = &run.trace;
        plot::write_svg(
            path,
            &format!("pmsm identify: {}", truth.name),
            &tr.t_s,
            &[
                plot::Panel {
                    title: "current (A)",
                    series: vec![
                        plot::Series {
                            label: "i_alpha measured",
                            values: &tr.i_alpha_a,
                        },
                        plot::Series {
                            label: "i_beta measured",
                            values: &tr.i_beta_a,
                        },
                    ],
                },
                plot::Panel {
                    title: "speed (r/min)",
                    series: vec![
                        plot::Series {
                            label: "commanded",
                            values: &tr.speed_cmd_rpm,
                        },
                        plot::Series {
                            label: "plant",
                            values: &tr.speed_rpm,
                        },
                    ],
                },
            ],
        )?;
        crate::outln!("  plot       {}", path.display());
    }
    Ok(())
}
