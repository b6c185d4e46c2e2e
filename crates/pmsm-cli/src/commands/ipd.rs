//! `pmsm ipd`: the fixed-point initial-position detector of the core against the plant, at one
//! rotor angle or a sweep (Khlaief, Boussak, Gossa (2012) §4).
//!
//! Each run builds the plant at standstill at the true angle (switching-level inverter with
//! dead time, 12-bit current ADC, the motor's saturation), steps the detector once per PWM
//! period until it ends, and writes `theta_true_deg, theta_est_deg, error_deg, polarity_ok,
//! fault` (estimate and error empty when the detector faulted).

use crate::{motor_file, plot};
use anyhow::{Result, anyhow, bail};
use pmsm_core::{AlphaBeta, InverterParams, MotorParams, PerUnit};
use pmsm_core::{Ipd, IpdConfig, IpdDesign, IpdFault};
use pmsm_plant::{AdcParams, InverterKind, InverterModel, Motor, Plant};
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Arguments of `pmsm ipd`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Motor file (TOML).
    #[arg(long, value_name = "M.toml")]
    pub motor: PathBuf,
    /// DC bus voltage, V.
    #[arg(long, value_name = "V", allow_negative_numbers = true)]
    pub vdc: f64,
    /// One true rotor angle, electrical degrees.
    #[arg(
        long,
        value_name = "X",
        conflicts_with = "sweep",
        allow_negative_numbers = true
    )]
    pub theta_deg: Option<f64>,
    /// A sweep of N angles evenly spread over one electrical turn.
    #[arg(long, value_name = "N")]
    pub sweep: Option<u32>,
    /// theta_true_deg, theta_est_deg, error_deg, polarity_ok, fault.
    #[arg(long, value_name = "out.csv")]
    pub output: PathBuf,
    /// PWM (and control) frequency, Hz.
    #[arg(long, value_name = "HZ", default_value_t = 16000.0)]
    pub pwm_hz: f64,
    /// Inverter dead time, s.
    #[arg(long, value_name = "S", default_value_t = 1e-6)]
    pub dead_time_s: f64,
    /// Also draw the error against the true angle to this SVG file.
    #[arg(long, value_name = "out.svg")]
    pub plot: Option<PathBuf>,
}

/// One detection.
#[derive(Clone, Copy, Debug)]
pub struct Detection {
    /// True angle, degrees in [0, 360).
    pub theta_true_deg: f64,
    /// Detected angle, degrees in [0, 360), or the fault.
    pub result: Result<f64, IpdFault>,
}

impl Detection {
    /// Detected minus true, degrees in [−180, 180).
    pub fn error_deg(&self) -> Option<f64> {
        self.result
            .ok()
            .map(|est| (est - self.theta_true_deg + 180.0).rem_euclid(360.0) - 180.0)
    }
}

/// Runs the detector of `config` on the plant at each angle.
pub fn detect(
    motor: &motor_file::Motor,
    inverter: &InverterParams,
    base: &PerUnit,
    config: IpdConfig,
    angles_deg: &[f64],
) -> Result<Vec<Detection>> {
    let mut out = Vec::with_capacity(angles_deg.len());
    for &theta in angles_deg {
        let m = Motor::new(motor.model, theta.to_radians(), 0.0).map_err(|e| anyhow!("{e}"))?;
        let mut plant = Plant::new(
            m,
            InverterModel::new(*inverter, InverterKind::Switching),
            AdcParams::from_inverter(inverter),
        )
        .map_err(|e| anyhow!("{e}"))?;
        let mut ipd = Ipd::new(config);
        let mut i = AlphaBeta::default();
        let vdc = base.voltage_pu(inverter.vdc_v);
        let limit = config.total_samples() as usize + 10;
        let mut result = None;
        for _ in 0..limit {
            let o = ipd.step(i, vdc);
            if let Some(done) = o.done {
                result = Some(done.map(|r| r.theta_deg_0_360()));
                break;
            }
            let s = if o.pwm_on {
                plant.step_pwm(o.duties.to_f64(), 0.0)
            } else {
                plant.step_off(0.0)
            }
            .map_err(|e| anyhow!("the plant failed: {e}"))?;
            let m = s.i_abc_a_measured;
            let ab = pmsm_plant::clarke(m);
            i = AlphaBeta {
                alpha: base.current_pu(ab[0]),
                beta: base.current_pu(ab[1]),
            };
        }
        let result =
            result.ok_or_else(|| anyhow!("the detector did not finish in {limit} samples"))?;
        out.push(Detection {
            theta_true_deg: theta.rem_euclid(360.0),
            result,
        });
    }
    Ok(out)
}

/// Runs `pmsm ipd`.
pub fn run(args: &Args) -> Result<()> {
    let motor = motor_file::read(&args.motor)?;
    let angles = angles_deg(args)?;
    let (inverter, base, config) = build_detector(args, &motor.model.params)?;
    let detections = detect(&motor, &inverter, &base, config, &angles)?;
    write_csv(&args.output, &detections)?;
    let errors: Vec<f64> = detections.iter().filter_map(Detection::error_deg).collect();
    print_summary(args, &motor.name, &config, &detections, &errors);
    crate::outln!("  output     {}", args.output.display());
    if let Some(path) = &args.plot {
        draw(path, &motor.name, &detections, &errors)?;
        crate::outln!("  plot       {}", path.display());
    }
    Ok(())
}

/// The true angles of `--theta-deg` or `--sweep`, degrees.
fn angles_deg(args: &Args) -> Result<Vec<f64>> {
    Ok(match (args.theta_deg, args.sweep) {
        (Some(x), None) if x.is_finite() => vec![x],
        (Some(x), None) => bail!("--theta-deg: must be a finite number, not {x}"),
        (None, Some(n)) if (1..=100_000).contains(&n) => {
            (0..n).map(|k| 360.0 * k as f64 / n as f64).collect()
        }
        (None, Some(n)) => bail!("--sweep: must be between 1 and 100000, not {n}"),
        _ => bail!("give either --theta-deg X or --sweep N"),
    })
}

/// The inverter (ADC range 4 × the current base), the per-unit bases at the PWM rate and the
/// detector's default configuration for the motor.
fn build_detector(args: &Args, m: &MotorParams) -> Result<(InverterParams, PerUnit, IpdConfig)> {
    let mut inverter = InverterParams {
        vdc_v: args.vdc,
        pwm_hz: args.pwm_hz,
        dead_time_s: args.dead_time_s,
        current_full_scale_a: 1.0,
    };
    let base = PerUnit::new(m, &inverter, args.pwm_hz)
        .map_err(|e| anyhow!("{}: {e}", args.motor.display()))?;
    inverter.current_full_scale_a = 4.0 * base.current_a;
    let config = IpdConfig::new(m, &base, IpdDesign::default())
        .map_err(|e| anyhow!("{}: {e}", args.motor.display()))?;
    Ok((inverter, base, config))
}

/// Writes one CSV row per detection (estimate and error empty for a fault).
fn write_csv(path: &Path, detections: &[Detection]) -> Result<()> {
    let file = std::fs::File::create(path)
        .map_err(|e| anyhow!("{}: cannot create: {e}", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let werr = |e: std::io::Error| anyhow!("{}: cannot write: {e}", path.display());
    writeln!(
        w,
        "theta_true_deg,theta_est_deg,error_deg,polarity_ok,fault"
    )
    .map_err(werr)?;
    for d in detections {
        match d.result {
            Ok(est) => {
                let err = (est - d.theta_true_deg + 180.0).rem_euclid(360.0) - 180.0;
                writeln!(
                    w,
                    "{},{est},{err},{},",
                    d.theta_true_deg,
                    u8::from(err.abs() < 90.0)
                )
                .map_err(werr)?
            }
            Err(f) => writeln!(w, "{},,,0,{}", d.theta_true_deg, fault_name(f)).map_err(werr)?,
        }
    }
    w.flush().map_err(werr)
}

/// Prints the set-up, the largest error, the wrong polarities and the faults; `errors` are
/// those of the detections that did not fault.
fn print_summary(
    args: &Args,
    name: &str,
    config: &IpdConfig,
    detections: &[Detection],
    errors: &[f64],
) {
    let faults = detections.len() - errors.len();
    let worst = errors.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    let wrong_polarity = errors.iter().filter(|e| e.abs() >= 90.0).count();
    crate::outln!(
        "pmsm ipd: {} at {} V, {} Hz, {} angle(s): pulses of {} and {} samples, {} off",
        name,
        args.vdc,
        args.pwm_hz,
        detections.len(),
        config.n_short,
        config.n_long,
        config.n_off
    );
    crate::outln!(
        "  error      max {worst:.2}° electrical, polarity wrong {wrong_polarity}, faults {faults}{}",
        detections
            .iter()
            .find_map(|d| d.result.err())
            .map_or(String::new(), |f| format!(" (first: {f:?})"))
    );
}

/// Draws the error against the true angle (faulted detections left out).
fn draw(path: &Path, name: &str, detections: &[Detection], errors: &[f64]) -> Result<()> {
    let t: Vec<f64> = detections
        .iter()
        .filter(|d| d.result.is_ok())
        .map(|d| d.theta_true_deg)
        .collect();
    plot::write_svg(
        path,
        &format!("pmsm ipd: {name} (error against the true angle, x axis in degrees)"),
        &t,
        &[plot::Panel {
            title: "error (° electrical)",
            series: vec![plot::Series {
                label: "detected − true",
                values: errors,
            }],
        }],
    )
}

/// A short name of a detector fault (CSV files).
pub fn fault_name(f: IpdFault) -> &'static str {
    match f {
        IpdFault::OverCurrent(_) => "overcurrent",
        IpdFault::NoCurrent(_) => "no_current",
        IpdFault::LowSaliency { .. } => "low_saliency",
        IpdFault::NoPolarity { .. } => "no_polarity",
        IpdFault::BusLow => "bus_low",
    }
}
