//! Motor B at light load (docs/drive.md, "light load"): the no-load run of
//! `examples/b-800rpm-load.toml` with the light-load d current off and on, the same with an
//! inverter the drive does not know exactly, and no load at 30 r/min (with the current-model
//! MRAS's hold through zero crossings off and on) and 3000 r/min. A table for
//! docs/PERFORMANCE.md and the before/after figures docs/figures/no-load-motor-b.svg and
//! docs/figures/low-speed-motor-b.svg.

use crate::progress;
use anyhow::{Result, bail};
use pmsm_cli::commands::simulate::stats::{self, rms_angle, std_dev, window};
use pmsm_cli::commands::simulate::{Row, run_scenario};
use pmsm_cli::{plot, scenario_file};
use rayon::prelude::*;
use std::path::Path;

/// One run: the inverter the plant has, what the drive is told, the light-load current.
struct Case {
    label: &'static str,
    /// `[inverter]` lines beyond the bus and the PWM.
    inverter: &'static str,
    /// The light-load current, A (`None`: the default).
    light_load_a: Option<f64>,
    /// Further `[control]` lines.
    control: &'static str,
    /// Final speed reference, r/min, reached at `ramp_end_s`.
    rpm: f64,
    ramp_end_s: f64,
    /// Rated load (4 N·m) from `load_s` on, if any.
    load_s: Option<f64>,
    duration_s: f64,
    /// The no-load window and the loaded one (if any), s.
    no_load: (f64, f64),
    loaded: Option<(f64, f64)>,
}

const SWITCHING_2US: &str = "dead_time_s = 2e-6\nmodel = \"switching\"";

/// Motor B to 800 r/min, rated load from 1.0 s, on the inverter `inverter`.
const fn at_800(label: &'static str, inverter: &'static str, light_load_a: Option<f64>) -> Case {
    Case {
        label,
        inverter,
        light_load_a,
        control: "",
        rpm: 800.0,
        ramp_end_s: 0.6,
        load_s: Some(1.0),
        duration_s: 1.6,
        no_load: (0.7, 1.0),
        loaded: Some((1.2, 1.6)),
    }
}

/// Motor B to `rpm` (reached at `ramp_end_s`), no load, measured over `no_load`.
const fn unloaded(
    label: &'static str,
    light_load_a: Option<f64>,
    control: &'static str,
    rpm: f64,
    ramp_end_s: f64,
    duration_s: f64,
    no_load: (f64, f64),
) -> Case {
    Case {
        label,
        inverter: SWITCHING_2US,
        light_load_a,
        control,
        rpm,
        ramp_end_s,
        load_s: None,
        duration_s,
        no_load,
        loaded: None,
    }
}

const CASES: [Case; 10] = [
    at_800(
        "800 r/min, switching 2 µs, light-load current off (before)",
        SWITCHING_2US,
        Some(0.0),
    ),
    at_800("800 r/min, switching 2 µs (default)", SWITCHING_2US, None),
    at_800(
        "800 r/min, averaged, sign_band_a = 0",
        "dead_time_s = 2e-6\nmodel = \"averaged\"\nsign_band_a = 0.0",
        None,
    ),
    at_800(
        "800 r/min, switching 1 µs, drive told 2 µs",
        "dead_time_s = 1e-6\nmodel = \"switching\"",
        None,
    ),
    at_800(
        "800 r/min, switching 3 µs, drive told 2 µs",
        "dead_time_s = 3e-6\nmodel = \"switching\"",
        None,
    ),
    unloaded(
        "30 r/min, switching 2 µs, without the injection, zero-crossing hold off (before)",
        None,
        "injection = false\nzero_crossing_hold = false\n",
        30.0,
        0.6,
        1.5,
        (0.8, 1.5),
    ),
    unloaded(
        "30 r/min, switching 2 µs, without the injection",
        None,
        "injection = false\n",
        30.0,
        0.6,
        1.5,
        (0.8, 1.5),
    ),
    unloaded(
        "30 r/min, switching 2 µs (default)",
        None,
        "",
        30.0,
        0.6,
        1.5,
        (0.8, 1.5),
    ),
    unloaded(
        "3000 r/min, switching 2 µs, light-load current off",
        Some(0.0),
        "",
        3000.0,
        1.0,
        1.6,
        (1.2, 1.6),
    ),
    unloaded(
        "3000 r/min, switching 2 µs (default)",
        None,
        "",
        3000.0,
        1.0,
        1.6,
        (1.2, 1.6),
    ),
];

/// The scenario file of `case`: motor B from standstill after initial position detection,
/// the drive told 2 µs of dead time, compensated, current-model MRAS.
fn scenario_text(case: &Case, motor: &Path) -> String {
    let mut s = format!(
        "duration_s = {}\nmotor = {:?}\n\n[inverter]\nvdc_v = 540.0\npwm_hz = 14000.0\n{}\n\n\
         [control]\nobserver = \"mras-current\"\nstartup = \"ipd\"\n\
         deadtime_compensation = true\ndead_time_s = 2e-6\n",
        case.duration_s,
        motor.display().to_string(),
        case.inverter
    );
    if let Some(i) = case.light_load_a {
        s.push_str(&format!("light_load_id_a = {i}\n"));
    }
    s.push_str(case.control);
    s.push_str(&format!(
        "\n[initial]\ntheta_e_deg = 137.0\n\n[speed_ref]\nt_s = [0.0, 0.1, {}]\nrpm = [0.0, 0.0, {}]\n",
        case.ramp_end_s, case.rpm
    ));
    if let Some(t) = case.load_s {
        s.push_str(&format!(
            "\n[load]\nt_s = [0.0, {t}, {}]\nnm = [0.0, 0.0, 4.0]\n",
            t + 0.01
        ));
    }
    s
}

/// Runs case `k` in a directory of its own (the cases run at the same time).
fn run_case(k: usize, case: &Case) -> Result<(Vec<Row>, f64)> {
    let dir = std::env::temp_dir().join(format!("pmsm-light-load-{}-{k}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let motor = super::root().join("examples/motor-b.toml");
    let path = dir.join("case.toml");
    std::fs::write(&path, scenario_text(case, &motor.canonicalize()?))?;
    let sc = scenario_file::read(&path)?;
    let run = run_scenario(&sc)?;
    std::fs::remove_dir_all(&dir).ok();
    Ok((run.rows, run.deadtime_scale))
}

/// Estimated-speed σ, true-speed σ (r/min), `i_q*` σ (A), angle rms (rad), largest distance
/// of the rotor's speed from the reference (r/min) over `rows`.
fn figures(rows: &[&Row]) -> [f64; 5] {
    [
        std_dev(rows, |r| r.speed_est_rpm),
        std_dev(rows, |r| r.speed_rpm),
        std_dev(rows, |r| r.i_q_ref_a),
        rms_angle(rows),
        rows.iter()
            .map(|r| (r.speed_rpm - r.speed_ref_rpm).abs())
            .fold(0.0, f64::max),
    ]
}

fn first_fault(rows: &[Row]) -> Option<(f64, &'static str)> {
    stats::first_fault(rows).map(|r| (r.t_s, r.fault()))
}

/// The markdown section; `figure`: also the before/after figure into that directory.
pub fn section(figure: Option<&Path>) -> Result<String> {
    let mut s = String::from(
        "### Light load (motor B)\n\n\
         Motor B from standstill (initial position detection) to the speed, no load, then at \
         800 r/min its rated 4 N·m; current-model MRAS, the drive told 2 µs of dead time, \
         compensated, calibrated at standstill (docs/drive.md §2; \"V_dead learned\": the scale \
         it found, kept at one within 3 %). σ: standard deviation over the window (no load: 0.7–1.0 s at 800 r/min, \
         0.8–1.5 s at 30 r/min, 1.2–1.6 s at 3000 r/min; rated load: 1.2–1.6 s). The light-load \
         d current is the drive's default (docs/drive.md, \"light load\": 0.57 A on motor B) \
         unless the row says off; so is the current-model MRAS's hold through the phase \
         currents' zero crossings at low speed (docs/drive.md, \"zero crossings at low speed\"). \
         \"Largest |n − n*|\": the rotor's largest distance from the speed reference in the \
         no-load window. Generated by `cargo xtask perf` (or `cargo xtask light-load`).\n\n\
         | run | V_dead learned | no load: est. speed σ | true speed σ | largest \\|n − n*\\| | i_q* σ | angle rms | rated load: angle rms | fault |\n\
         |---|---|---|---|---|---|---|---|---|\n",
    );
    let bar = progress::bar(CASES.len(), "light load");
    let runs = CASES
        .par_iter()
        .enumerate()
        .map(|(k, case)| {
            progress::eprintln(format_args!("  light load: {}", case.label));
            let run = run_case(k, case);
            bar.inc(1);
            run
        })
        .collect::<Result<Vec<_>>>()?;
    drop(bar);
    let mut before_after: Vec<Vec<Row>> = Vec::new();
    for (k, (case, (rows, scale))) in CASES.iter().zip(runs).enumerate() {
        let f = figures(&window(&rows, case.no_load.0, case.no_load.1));
        let loaded = case
            .loaded
            .map(|(a, b)| format!("{:.4} rad", rms_angle(&window(&rows, a, b))))
            .unwrap_or_else(|| "-".into());
        let fault = first_fault(&rows)
            .map(|(t, name)| format!("`{name}` at {t:.3} s"))
            .unwrap_or_else(|| "none".into());
        s.push_str(&format!(
            "| {} | ×{scale:.3} | {:.2} r/min | {:.2} r/min | {:.2} r/min | {:.3} A | {:.4} rad | {} | {} |\n",
            case.label, f[0], f[1], f[4], f[2], f[3], loaded, fault
        ));
        // The figure's pairs: the light-load current off and on at 800 r/min, the
        // zero-crossing hold off and on at 30 r/min (without the injection, which holds the
        // angle there by default and leaves the estimator's crossings out).
        if k < 2 || (case.rpm < 100.0 && case.control.contains("injection = false")) {
            before_after.push(rows);
        }
    }
    s.push_str(
        "\nBars (docs/drive.md): no load at 800 r/min, estimated-speed σ ≤ 5 r/min, i_q* σ ≤ \
         0.15 A, true-speed σ ≤ 1.5 r/min; 30 r/min held within 3 r/min and 0.1 rad rms; an \
         inverter off by ±1 µs: no fault, no load ≤ 0.05 rad rms and σ ≤ 10 r/min, rated load \
         ≤ 0.02 rad rms.\n\n",
    );
    if let Some(dir) = figure {
        let [before, after, slow_before, slow_after] = &before_after[..] else {
            bail!("light load: the before/after runs are missing");
        };
        draw(&dir.join("no-load-motor-b.svg"), before, after)?;
        draw_low_speed(&dir.join("low-speed-motor-b.svg"), slow_before, slow_after)?;
        s.push_str(
            "![no load, before and after](figures/no-load-motor-b.svg)\n\n\
             ![30 r/min, the hold off and on](figures/low-speed-motor-b.svg)\n\n",
        );
    }
    Ok(s)
}

/// A panel of a before/after figure: its title and the column it draws.
type Column = (&'static str, fn(&Row) -> f64);

/// A before/after figure: each of `panels` for the two `runs` over `span` (s), labelled
/// `labels`.
fn draw_pair(
    path: &Path,
    title: &str,
    span: (f64, f64),
    labels: [&str; 2],
    runs: [&[Row]; 2],
    panels: &[Column],
) -> Result<()> {
    let pick = |rows: &[Row], f: fn(&Row) -> f64| -> Vec<f64> {
        window(rows, span.0, span.1).into_iter().map(f).collect()
    };
    let t = pick(runs[0], |r| r.t_s);
    // The two runs may differ by a sample in the window: both cut to the first's length.
    let columns: Vec<[Vec<f64>; 2]> = panels
        .iter()
        .map(|&(_, f)| {
            runs.map(|rows| {
                let mut v = pick(rows, f);
                v.truncate(t.len());
                v
            })
        })
        .collect();
    let panels: Vec<plot::Panel> = panels
        .iter()
        .zip(&columns)
        .map(|(&(title, _), [a, b])| plot::Panel {
            title,
            series: vec![
                plot::Series {
                    label: labels[0],
                    values: a,
                },
                plot::Series {
                    label: labels[1],
                    values: b,
                },
            ],
        })
        .collect();
    plot::write_svg(path, title, &t, &panels)
}

/// Estimated speed, `i_q*` and `i_d` from 0.6 to 1.0 s (no load at 800 r/min), the light-load
/// current off and on.
fn draw(path: &Path, before: &[Row], after: &[Row]) -> Result<()> {
    draw_pair(
        path,
        "Motor B at 800 r/min, no load, switching inverter with 2 µs dead time: light-load d current off and on",
        (0.6, 1.0),
        ["off", "on"],
        [before, after],
        &[
            ("estimated speed (r/min)", |r| r.speed_est_rpm),
            ("i_q* (A)", |r| r.i_q_ref_a),
            ("i_d (A)", |r| r.i_dq_a[0]),
        ],
    )
}

/// The rotor's speed, the estimated speed and the angle error from 0.6 to 1.5 s (no load at
/// 30 r/min), the zero-crossing hold off and on.
fn draw_low_speed(path: &Path, before: &[Row], after: &[Row]) -> Result<()> {
    draw_pair(
        path,
        "Motor B at 30 r/min, no load, switching inverter with 2 µs dead time: the current-model MRAS's hold through zero crossings off and on",
        (0.6, 1.5),
        ["hold off", "hold on"],
        [before, after],
        &[
            ("rotor speed (r/min)", |r| r.speed_rpm),
            ("estimated speed (r/min)", |r| r.speed_est_rpm),
            ("angle error (rad)", Row::angle_error_rad),
        ],
    )
}
