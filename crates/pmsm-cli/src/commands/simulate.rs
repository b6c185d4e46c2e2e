//! `pmsm simulate`: the fixed-point drive of the core against the floating-point plant.
//!
//! Output, one row per control sample: `t_s, speed_ref_rpm, speed_rpm, speed_est_rpm,
//! theta_e_rad, theta_e_est_rad, i_d_a, i_q_a, i_q_ref_a, v_alpha_v, v_beta_v, duty_a, duty_b,
//! duty_c, pwm_on, fault, health`. Angles in [−π, π); `i_d`, `i_q` in the true rotor frame;
//! `i_q_ref` and the voltage are the controller's; `health` is the estimator's health figure as
//! the drive's loss-of-lock check filters it (per unit; see `Estimator::health`).

use crate::plot;
use crate::scenario_file::{self, CompensationMode, InverterKind, ObserverKind, Scenario, Startup};
use anyhow::{Context, Result, anyhow, bail};
use pmsm_core::deadtime::DeadTimeMode;
use pmsm_core::drive::{Drive, DriveConfig, DriveDesign, DriveInput, DriveState, StartupMode};
use pmsm_core::observer::EstimatorKind;
use pmsm_core::{Abc, Angle, InverterParams, PerUnit};
use pmsm_plant::{AdcParams, Motor, Plant};
use std::f64::consts::{PI, TAU};
use std::io::Write as _;
use std::path::PathBuf;

/// Arguments of `pmsm simulate`.
#[derive(clap::Args, Debug)]
pub struct Args {
    /// Scenario file (TOML).
    #[arg(value_name = "SCENARIO.toml")]
    pub scenario: PathBuf,
    /// One row per control sample (see the module docs for the columns).
    #[arg(long, value_name = "out.csv")]
    pub output: PathBuf,
    /// Also draw speed, angle error and currents to this SVG file.
    #[arg(long, value_name = "out.svg")]
    pub plot: Option<PathBuf>,
}

/// The output columns, in order.
pub const OUTPUT_COLUMNS: [&str; 17] = [
    "t_s",
    "speed_ref_rpm",
    "speed_rpm",
    "speed_est_rpm",
    "theta_e_rad",
    "theta_e_est_rad",
    "i_d_a",
    "i_q_a",
    "i_q_ref_a",
    "v_alpha_v",
    "v_beta_v",
    "duty_a",
    "duty_b",
    "duty_c",
    "pwm_on",
    "fault",
    "health",
];

/// One control sample of a run, in SI units.
#[derive(Clone, Debug)]
pub struct Row {
    /// Time, s.
    pub t_s: f64,
    /// Speed reference, r/min.
    pub speed_ref_rpm: f64,
    /// True speed, r/min.
    pub speed_rpm: f64,
    /// Estimated speed, r/min.
    pub speed_est_rpm: f64,
    /// True electrical angle, rad, [−π, π).
    pub theta_e_rad: f64,
    /// Estimated electrical angle, rad, [−π, π).
    pub theta_e_est_rad: f64,
    /// True rotor-frame currents, A.
    pub i_dq_a: [f64; 2],
    /// q-current reference, A.
    pub i_q_ref_a: f64,
    /// Commanded voltage, V.
    pub v_ab_v: [f64; 2],
    /// Leg duties.
    pub duties: [f64; 3],
    /// Inverter switching.
    pub pwm_on: bool,
    /// The drive's state.
    pub state: DriveState,
    /// Largest phase current at this sample, A.
    pub i_peak_a: f64,
    /// The estimator's health figure as the drive filters it, per unit (of `V_b` for the EMF
    /// estimators, of `I_b` for the current-model MRAS; 0 outside the closed loop).
    pub health: f64,
}

impl Row {
    /// Estimated minus true angle, wrapped, rad.
    pub fn angle_error_rad(&self) -> f64 {
        wrap(self.theta_e_est_rad - self.theta_e_rad)
    }

    /// The fault's name, or "".
    pub fn fault(&self) -> &'static str {
        match self.state {
            DriveState::Fault(f) => f.name(),
            _ => "",
        }
    }
}

/// Wraps to [−π, π).
pub fn wrap(x: f64) -> f64 {
    (x + PI).rem_euclid(TAU) - PI
}

/// The result of a run.
#[derive(Debug)]
pub struct Run {
    /// Every control sample.
    pub rows: Vec<Row>,
    /// Detected initial angle and true one, degrees, when the start-up was `ipd`.
    pub ipd: Option<(f64, f64)>,
}

/// Builds the drive and the plant of `sc` and runs them.
pub fn run_scenario(sc: &Scenario) -> Result<Run> {
    let shown = sc.path.display();
    // The drive's model of the motor; the plant keeps the true one.
    let mut model = sc.model_motor.as_ref().unwrap_or(&sc.motor).model.params;
    model.rs_ohm *= sc.control.model_rs_factor.unwrap_or(1.0);
    model.ld_h *= sc.control.model_l_factor.unwrap_or(1.0);
    model.lq_h *= sc.control.model_l_factor.unwrap_or(1.0);
    model.flux_wb *= sc.control.model_flux_factor.unwrap_or(1.0);
    model.kt_nm_per_a *= sc.control.model_flux_factor.unwrap_or(1.0);
    let m = &model;
    let pwm_hz = sc.inverter.pwm_hz;
    let sample_hz = sc.control.sample_hz.unwrap_or(pwm_hz);
    let ratio = pwm_hz / sample_hz;
    if (ratio - ratio.round()).abs() > 1e-9 {
        bail!(
            "{shown}: `control.sample_hz` ({sample_hz}) must divide `inverter.pwm_hz` ({pwm_hz})"
        );
    }
    let ratio = ratio.round() as usize;
    let mut inverter = InverterParams {
        vdc_v: sc.inverter.vdc_v,
        pwm_hz,
        dead_time_s: sc.inverter.dead_time_s,
        current_full_scale_a: 1.0,
    };
    let base = PerUnit::new(m, &inverter, sample_hz).map_err(|e| anyhow!("{shown}: {e}"))?;
    inverter.current_full_scale_a = sc
        .inverter
        .current_full_scale_a
        .unwrap_or(4.0 * base.current_a);

    let estimator = match sc.control.observer {
        ObserverKind::Nlo => EstimatorKind::Nlo,
        ObserverKind::Ao => EstimatorKind::Ao,
        ObserverKind::MrasEmf => EstimatorKind::MrasEmf,
        ObserverKind::MrasCurrent => EstimatorKind::MrasCurrent,
    };
    let mut design = DriveDesign::default_for(m, &inverter, &base, estimator);
    design.startup = match sc.control.startup {
        Startup::Ipd => StartupMode::Ipd,
        Startup::Align => StartupMode::Align,
        Startup::Known => StartupMode::Known(Angle::from_rad(sc.theta0_rad)),
    };
    design.deadtime.mode = match sc.control.deadtime_compensation.mode() {
        CompensationMode::Off => DeadTimeMode::Off,
        CompensationMode::Command => DeadTimeMode::Command,
        CompensationMode::Estimator => DeadTimeMode::Estimator,
        CompensationMode::Both => DeadTimeMode::Both,
    };
    design.protection.health_limit_pu = sc.control.health_limit_pu;
    design.deadtime.device.v_sat_v = sc.inverter.v_sat_v;
    design.deadtime.device.v_f_v = sc.inverter.v_f_v;
    let c = &sc.control;
    if let Some(g) = c.observer_gain {
        design.observer_gain_rad_s = g;
    }
    if let Some(hz) = c.current_bandwidth_hz {
        design.current.bandwidth_rad_s = TAU * hz;
    }
    if let Some(hz) = c.speed_bandwidth_hz {
        design.speed.bandwidth_rad_s = TAU * hz;
    }
    if let Some(hz) = c.mras_bandwidth_hz {
        design.mras_current = pmsm_core::observer::MrasCurrentGains::design(m, TAU * hz);
    }
    if let Some(a) = c.current_limit_a {
        design.speed.current_limit_a = a;
        design.open_loop.current_a = design.open_loop.current_a.min(a);
    }
    let config =
        DriveConfig::new(m, &inverter, sample_hz, design).map_err(|e| anyhow!("{shown}: {e}"))?;
    let mut drive = Drive::new(config);

    let motor = Motor::new(sc.motor.model, sc.theta0_rad, sc.omega_m0_rad_s)
        .map_err(|e| anyhow!("{shown}: {e}"))?;
    let mut plant_inverter = pmsm_plant::InverterModel::new(
        inverter,
        match sc.inverter.model {
            InverterKind::Averaged => pmsm_plant::InverterKind::Averaged,
            InverterKind::Switching => pmsm_plant::InverterKind::Switching,
        },
    );
    plant_inverter.v_sat_v = sc.inverter.v_sat_v;
    plant_inverter.v_f_v = sc.inverter.v_f_v;
    let mut adc = AdcParams::from_inverter(&inverter);
    adc.bits = sc.sensing.adc_bits.unwrap_or(12);
    adc.noise_rms_a = sc.sensing.noise_rms_a;
    adc.offset_a = sc.sensing.offset_a;
    adc.gain_error = sc.sensing.gain_error;
    let mut plant = Plant::new(motor, plant_inverter, adc).map_err(|e| anyhow!("{shown}: {e}"))?;

    let p = m.p();
    let rpm_to_pu = |rpm: f64| base.speed_pu(rpm * TAU / 60.0 * p);
    let n = (sc.duration_s * sample_hz).round() as usize;
    let mut rows = Vec::with_capacity(n);
    let (mut i_meas, mut vdc) = ([0.0; 3], sc.inverter.vdc_v);
    let mut ipd = None;
    let mut last_codes = [0u16; 3];
    let mut injector = Injector::new(&sc.faults);
    drive.start();
    for k in 0..n {
        let t = k as f64 / sample_hz;
        let speed_ref_rpm = sc.speed_ref.at(t);
        drive.set_speed_ref(rpm_to_pu(speed_ref_rpm));
        let input = DriveInput {
            i_abc: Abc {
                a: base.current_pu(i_meas[0]),
                b: base.current_pu(i_meas[1]),
                c: base.current_pu(i_meas[2]),
            },
            vdc: base.voltage_pu(vdc),
        };
        let out = drive.step(&input);
        if ipd.is_none()
            && let Some(r) = drive.ipd_result()
        {
            let true_deg = plant
                .motor()
                .state()
                .theta_e_rad
                .to_degrees()
                .rem_euclid(360.0);
            ipd = Some((r.theta_deg_0_360(), true_deg));
        }
        let tel = drive.telemetry();
        let s = plant.motor().state();
        let i_dq = plant.motor().i_dq();
        let i_true = plant.motor().i_abc();
        rows.push(Row {
            t_s: t,
            speed_ref_rpm,
            speed_rpm: s.omega_m_rad_s * 60.0 / TAU,
            speed_est_rpm: base.speed_rad_s(tel.estimate.omega) / p * 60.0 / TAU,
            theta_e_rad: wrap(s.theta_e_rad),
            theta_e_est_rad: tel.estimate.theta.to_rad(),
            i_dq_a: i_dq,
            i_q_ref_a: base.current_a(tel.i_ref.q),
            v_ab_v: [base.voltage_v(tel.v.alpha), base.voltage_v(tel.v.beta)],
            duties: if out.pwm_on {
                out.duties.to_f64()
            } else {
                [0.0; 3]
            },
            pwm_on: out.pwm_on,
            state: drive.state(),
            i_peak_a: i_true.iter().fold(0.0f64, |a, x| a.max(x.abs())),
            health: pmsm_core::units::to_f64(drive.health()),
        });
        injector
            .apply(t, &mut plant, last_codes)
            .map_err(|e| anyhow!("{shown}: t = {t:.6} s: {e}"))?;
        let load = sc.load.at(t);
        if let Some(th) = &sc.thermal {
            th.apply(&mut plant)
                .map_err(|e| anyhow!("{shown}: thermal: {e}"))?;
        }
        for _ in 0..ratio {
            let sample = if out.pwm_on {
                plant.step_pwm(out.duties.to_f64(), load)
            } else {
                plant.step_off(load)
            }
            .map_err(|e| anyhow!("{shown}: the plant failed at t = {t:.6} s: {e}"))?;
            i_meas = sample.i_abc_a_measured;
            last_codes = sample.adc_codes;
            vdc = sample.vdc_v;
        }
    }
    Ok(Run { rows, ipd })
}

/// Applies the `[faults]` of a scenario to the plant when their time comes, once each.
struct Injector {
    faults: scenario_file::Faults,
    done: [bool; 5],
}

impl Injector {
    fn new(faults: &scenario_file::Faults) -> Self {
        Self {
            faults: *faults,
            done: [false; 5],
        }
    }

    fn due(&mut self, k: usize, at: Option<f64>, t: f64) -> bool {
        match (at, self.done.get(k).copied()) {
            (Some(at), Some(false)) if t >= at => {
                self.done[k] = true;
                true
            }
            _ => false,
        }
    }

    fn apply(
        &mut self,
        t: f64,
        plant: &mut Plant,
        codes: [u16; 3],
    ) -> Result<(), pmsm_plant::PlantError> {
        let f = self.faults;
        let mut inj = plant.injected();
        if self.due(0, f.phase_open_at_s, t) {
            inj.open_phase = f.phase_open.map(scenario_file::Phase::index);
        }
        if self.due(1, f.adc_stuck_at_s, t)
            && let Some(k) = f.adc_stuck_phase.map(scenario_file::Phase::index)
        {
            inj.stuck_adc = codes.get(k).map(|c| (k, *c));
        }
        if self.due(2, f.short_at_s, t) {
            inj.short = f
                .short_phases
                .map(|p| (p.first(), f.short_ohm.unwrap_or(0.1)));
        }
        plant.inject(inj);
        if self.due(3, f.locked_rotor_at_s, t) {
            plant.set_mechanics(pmsm_plant::Mechanics::Locked)?;
        }
        if self.due(4, f.vdc_sag_at_s, t)
            && let Some(v) = f.vdc_sag_to_v
        {
            plant.set_vdc_v(v)?;
        }
        Ok(())
    }
}

/// Statistics of a stretch of a run, for tests and reports.
pub mod stats {
    use super::Row;

    /// The rows with `t0 ≤ t < t1`.
    pub fn window(rows: &[Row], t0: f64, t1: f64) -> Vec<&Row> {
        rows.iter().filter(|r| r.t_s >= t0 && r.t_s < t1).collect()
    }

    /// Largest |angle error|, rad.
    pub fn max_angle(rows: &[&Row]) -> f64 {
        rows.iter()
            .map(|r| r.angle_error_rad().abs())
            .fold(0.0, f64::max)
    }

    /// RMS angle error, rad (0 for no rows).
    pub fn rms_angle(rows: &[&Row]) -> f64 {
        (rows
            .iter()
            .map(|r| r.angle_error_rad().powi(2))
            .sum::<f64>()
            / rows.len().max(1) as f64)
            .sqrt()
    }

    /// Mean |speed − reference| / |reference| (0 for no rows).
    pub fn speed_err(rows: &[&Row]) -> f64 {
        rows.iter()
            .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs() / r.speed_ref_rpm.abs())
            .sum::<f64>()
            / rows.len().max(1) as f64
    }
}

/// Statistics of one phase of a run (between two breakpoints of the references).
#[derive(Clone, Debug)]
pub struct Phase {
    /// Start and end, s.
    pub span_s: (f64, f64),
    /// Mean |speed − reference| over the last half of the phase, r/min.
    pub speed_err_rpm: f64,
    /// The same relative to the reference, when it is not zero.
    pub speed_err_rel: Option<f64>,
    /// RMS and max |angle error| while running closed loop, rad.
    pub angle_err_rms_rad: f64,
    /// See `angle_err_rms_rad`.
    pub angle_err_max_rad: f64,
    /// Largest phase current, A.
    pub i_peak_a: f64,
    /// Faults that occurred.
    pub faults: Vec<&'static str>,
}

/// Splits a run at the breakpoints of its references and summarises each phase.
pub fn phases(sc: &Scenario, rows: &[Row]) -> Vec<Phase> {
    let mut cuts: Vec<f64> = sc
        .speed_ref
        .times()
        .iter()
        .chain(sc.load.times())
        .copied()
        .filter(|t| *t > 0.0 && *t < sc.duration_s)
        .collect();
    cuts.push(0.0);
    cuts.push(sc.duration_s);
    cuts.sort_by(f64::total_cmp);
    cuts.dedup_by(|a, b| (*a - *b).abs() < 0.02);
    cuts.windows(2)
        .filter_map(|w| {
            let span: Vec<&Row> = rows
                .iter()
                .filter(|r| r.t_s >= w[0] && r.t_s < w[1])
                .collect();
            if span.is_empty() {
                return None;
            }
            let tail = &span[span.len() / 2..];
            let speed_err_rpm = tail
                .iter()
                .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs())
                .sum::<f64>()
                / tail.len() as f64;
            let reference =
                tail.iter().map(|r| r.speed_ref_rpm.abs()).sum::<f64>() / tail.len() as f64;
            let running: Vec<f64> = span
                .iter()
                .filter(|r| r.state == DriveState::Run)
                .map(|r| r.angle_error_rad())
                .collect();
            let rms = if running.is_empty() {
                0.0
            } else {
                (running.iter().map(|x| x * x).sum::<f64>() / running.len() as f64).sqrt()
            };
            let mut faults: Vec<&'static str> = span
                .iter()
                .map(|r| r.fault())
                .filter(|f| !f.is_empty())
                .collect();
            faults.dedup();
            Some(Phase {
                span_s: (w[0], w[1]),
                speed_err_rpm,
                speed_err_rel: (reference > 1.0).then(|| speed_err_rpm / reference),
                angle_err_rms_rad: rms,
                angle_err_max_rad: running.iter().fold(0.0, |a, x| a.max(x.abs())),
                i_peak_a: span.iter().fold(0.0, |a, r| a.max(r.i_peak_a)),
                faults,
            })
        })
        .collect()
}

/// Runs `pmsm simulate`.
pub fn run(args: &Args) -> Result<()> {
    let sc = scenario_file::read(&args.scenario)?;
    let result = run_scenario(&sc)?;
    write_csv(&args.output, &result.rows)?;
    println!(
        "pmsm simulate: {} on {}, {:?} estimator, start-up {:?}, {:.3} s at {:.0} Hz",
        sc.path.display(),
        sc.motor.name,
        sc.control.observer,
        sc.control.startup,
        sc.duration_s,
        sc.control.sample_hz.unwrap_or(sc.inverter.pwm_hz)
    );
    if let Some((est, truth)) = result.ipd {
        let err = wrap((est - truth).to_radians()).to_degrees();
        println!(
            "  initial position: detected {est:.1}°, true {truth:.1}° (error {err:+.1}° electrical)"
        );
    }
    println!(
        "  {:>15} {:>14} {:>9} {:>16} {:>10}  faults",
        "phase (s)", "speed err", "(%)", "angle err rms/max", "I peak (A)"
    );
    for ph in phases(&sc, &result.rows) {
        println!(
            "  {:>6.3} – {:>6.3} {:>10.2} rpm {:>9} {:>7.4}/{:<7.4} rad {:>8.2}   {}",
            ph.span_s.0,
            ph.span_s.1,
            ph.speed_err_rpm,
            ph.speed_err_rel
                .map_or("-".to_owned(), |x| format!("{:.2}", 100.0 * x)),
            ph.angle_err_rms_rad,
            ph.angle_err_max_rad,
            ph.i_peak_a,
            if ph.faults.is_empty() {
                "none".to_owned()
            } else {
                ph.faults.join(", ")
            }
        );
    }
    if let Some(r) = result
        .rows
        .iter()
        .find(|r| matches!(r.state, DriveState::Fault(_)))
    {
        println!("  first fault at t = {:.4} s: {:?}", r.t_s, r.state);
    }
    println!("  output     {}", args.output.display());
    if let Some(path) = &args.plot {
        draw(path, &sc, &result.rows)?;
        println!("  plot       {}", path.display());
    }
    Ok(())
}

fn write_csv(path: &std::path::Path, rows: &[Row]) -> Result<()> {
    let file = std::fs::File::create(path)
        .with_context(|| format!("{}: cannot create", path.display()))?;
    let mut w = std::io::BufWriter::new(file);
    let err = |e: std::io::Error| anyhow!("{}: cannot write: {e}", path.display());
    writeln!(w, "{}", OUTPUT_COLUMNS.join(",")).map_err(err)?;
    for r in rows {
        let nums = [
            r.t_s,
            r.speed_ref_rpm,
            r.speed_rpm,
            r.speed_est_rpm,
            r.theta_e_rad,
            r.theta_e_est_rad,
            r.i_dq_a[0],
            r.i_dq_a[1],
            r.i_q_ref_a,
            r.v_ab_v[0],
            r.v_ab_v[1],
            r.duties[0],
            r.duties[1],
            r.duties[2],
        ];
        if nums.iter().any(|x| !x.is_finite()) {
            bail!(
                "{}: t = {} s: refusing to write a non-finite value",
                path.display(),
                r.t_s
            );
        }
        let line: Vec<String> = nums.iter().map(|x| format!("{x}")).collect();
        writeln!(
            w,
            "{},{},{},{}",
            line.join(","),
            u8::from(r.pwm_on),
            r.fault(),
            r.health
        )
        .map_err(err)?;
    }
    w.flush().map_err(err)
}

/// Draws speed, angle error and dq currents of a run to an SVG file.
pub fn draw(path: &std::path::Path, sc: &Scenario, rows: &[Row]) -> Result<()> {
    let t: Vec<f64> = rows.iter().map(|r| r.t_s).collect();
    let col = |f: &dyn Fn(&Row) -> f64| rows.iter().map(f).collect::<Vec<f64>>();
    let (sref, s, sest) = (
        col(&|r| r.speed_ref_rpm),
        col(&|r| r.speed_rpm),
        col(&|r| r.speed_est_rpm),
    );
    let err = col(&|r| r.angle_error_rad());
    let (id, iq, iqr) = (
        col(&|r| r.i_dq_a[0]),
        col(&|r| r.i_dq_a[1]),
        col(&|r| r.i_q_ref_a),
    );
    let ser = |label, values| plot::Series { label, values };
    plot::write_svg(
        path,
        &format!(
            "pmsm simulate: {} ({:?}, {:?})",
            sc.motor.name, sc.control.observer, sc.control.startup
        ),
        &t,
        &[
            plot::Panel {
                title: "speed (r/min)",
                series: vec![
                    ser("reference", &sref),
                    ser("true", &s),
                    ser("estimated", &sest),
                ],
            },
            plot::Panel {
                title: "angle error (rad)",
                series: vec![ser("θ̂ − θ", &err)],
            },
            plot::Panel {
                title: "current (A)",
                series: vec![ser("i_d", &id), ser("i_q", &iq), ser("i_q*", &iqr)],
            },
        ],
    )
}
