//! The workbench's binding: `pmsm simulate` and `pmsm identify` behind a small
//! request/response interface that a page calls from a Web Worker (docs/workbench.md).
//!
//! Everything goes through [`Workbench`]: a request is a JSON object, the answer a JSON
//! object (and, after a run, its rows as `f32` columns). A scenario travels as the JSON image
//! of its TOML file with the motor inline, so that the page edits any key (those of its form
//! and those it does not show, which it keeps) and the drive is given exactly the numbers
//! typed: the scenario is written back to TOML and read by the very parser of `pmsm
//! simulate`, and run by its loop. The same scenario therefore gives the same bits in the
//! browser and on the host (the plant uses `libm`, the drive integers).
//!
//! [`exports`] (the WebAssembly functions) is the only unsafe-attributed code: the page
//! writes a request into the buffer that [`exports::wb_request`] hands out, calls an
//! operation and reads the answer from the buffer [`exports::wb_answer`] points to.

pub mod exports;
mod series;

pub use series::{SERIES, series};

use anyhow::{Context, Result, anyhow, bail};
use pmsm_cli::commands::identify::{Request as IdentifyRequest, commission};
use pmsm_cli::commands::simulate::{Simulation, build_drive, build_plant, summary};
use pmsm_cli::motor_file::{self, Motor};
use pmsm_cli::scenario_file::{self, Scenario};
use serde::Deserialize;
use serde_json::{Value, json};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// A scenario as the page sends it: its name (shown in the summary as `pmsm simulate`
/// shows the file) and its content.
#[derive(Debug, Deserialize)]
pub struct ScenarioRequest {
    /// The name, e.g. `examples/b-800rpm-load.toml`.
    pub name: String,
    /// The scenario's TOML as JSON, the motor inline ([`Workbench::load`]).
    pub scenario: Value,
}

/// What [`Workbench::load`] reads: a scenario file and the files it names.
#[derive(Debug, Deserialize)]
pub struct LoadRequest {
    /// The scenario's name (its path in the repository for a shipped one).
    pub name: String,
    /// Its text.
    pub text: String,
    /// Motor files by path, relative to the scenario's directory as the scenario names them.
    #[serde(default)]
    pub files: BTreeMap<String, String>,
}

/// What [`Workbench::identify`] is asked.
#[derive(Debug, Deserialize)]
pub struct IdentifyAsk {
    /// The true motor (a motor file's keys as JSON).
    pub motor: Value,
    /// DC bus, V.
    pub vdc_v: f64,
    /// PWM frequency, Hz.
    pub pwm_hz: f64,
    /// Dead time, s.
    pub dead_time_s: f64,
}

/// The workbench's state between calls: the run in progress, if any.
#[derive(Default)]
pub struct Workbench {
    run: Option<(Scenario, Simulation)>,
}

/// A failed request as the page shows it: the message, and the key it names (the first
/// one in backquotes, e.g. `ld_h` or `inverter.vdc_v`) for the field to show it by.
pub fn error_answer(e: &anyhow::Error) -> Value {
    let message = format!("{e:#}");
    let key = message.split('`').nth(1).map(str::to_owned);
    json!({ "ok": false, "error": message, "key": key })
}

impl Workbench {
    /// Reads a scenario file and the motor file it names; answers the scenario as JSON with
    /// the motor inline, and what [`Workbench::check`] says of it.
    pub fn load(&self, request: &LoadRequest) -> Result<Value> {
        let mut value: toml::Table = toml::from_str(&request.text)
            .map_err(|e| anyhow!("{}: {}", request.name, e.message()))?;
        if let Some(toml::Value::String(file)) = value.get("motor") {
            let dir = Path::new(&request.name).parent().unwrap_or(Path::new(""));
            let key = dir.join(file);
            let text = request
                .files
                .get(file)
                .or_else(|| request.files.get(&key.to_string_lossy().into_owned()))
                .ok_or_else(|| anyhow!("{}: no motor file `{file}` was given", request.name))?;
            let motor: toml::Table =
                toml::from_str(text).map_err(|e| anyhow!("{file}: {}", e.message()))?;
            value.insert("motor".into(), toml::Value::Table(motor));
        }
        let scenario = serde_json::to_value(&value)?;
        let check = self.check(&ScenarioRequest {
            name: request.name.clone(),
            scenario: scenario.clone(),
        });
        Ok(json!({ "ok": true, "scenario": scenario, "check": check }))
    }

    /// A motor file's text as JSON (a dropped or pasted file), checked.
    pub fn motor(&self, text: &str) -> Result<Value> {
        let table: toml::Table =
            toml::from_str(text).map_err(|e| anyhow!("motor file: {}", e.message()))?;
        motor_file::parse(text, Path::new("motor file"))?;
        Ok(json!({ "ok": true, "motor": serde_json::to_value(&table)? }))
    }

    /// Reads the scenario and designs its drive and plant without running them: what the
    /// defaults chose, or the first error (which names its key).
    pub fn check(&self, request: &ScenarioRequest) -> Value {
        match scenario(request).and_then(|sc| {
            let setup = build_drive(&sc)?;
            build_plant(&sc, &setup.inverter)?;
            Ok((sc, setup))
        }) {
            Ok((sc, setup)) => json!({
                "ok": true,
                "estimator": format!("{:?}", sc.control.observer),
                "estimator_auto": sc.control.observer_auto,
                "startup": format!("{:?}", setup.config.design.startup),
                "sample_hz": setup.sample_hz,
                "samples": (sc.duration_s * setup.sample_hz).round(),
            }),
            Err(e) => error_answer(&e),
        }
    }

    /// Starts a run of the scenario (the drive designed, the plant built, nothing stepped).
    pub fn start(&mut self, request: &ScenarioRequest) -> Result<Value> {
        self.run = None;
        let sc = scenario(request)?;
        let setup = build_drive(&sc)?;
        let plant = build_plant(&sc, &setup.inverter)?;
        let sim = Simulation::new(&sc, setup, plant);
        let samples = sim.progress().1;
        self.run = Some((sc, sim));
        Ok(json!({ "ok": true, "samples": samples }))
    }

    /// Steps the run at most `samples` samples: the fraction done (1 when complete).
    pub fn advance(&mut self, samples: usize) -> Result<f64> {
        let Some((sc, sim)) = &mut self.run else {
            bail!("no run in progress");
        };
        sim.advance(sc, samples)?;
        let (done, all) = sim.progress();
        Ok(if all == 0 {
            1.0
        } else {
            done as f64 / all as f64
        })
    }

    /// Ends the run: the CLI's summary, the faults with their times and the rows as
    /// [`SERIES`] columns of `f32` (column after column).
    pub fn finish(&mut self) -> Result<(Value, Vec<f32>)> {
        let (sc, sim) = self
            .run
            .take()
            .ok_or_else(|| anyhow!("no run in progress"))?;
        let run = sim.finish();
        let text = summary(&sc, &run);
        let mut faults = Vec::new();
        let mut last = "";
        for r in &run.rows {
            let f = r.fault();
            if f != last && !f.is_empty() {
                faults.push(json!({ "t_s": r.t_s, "fault": f, "state": format!("{:?}", r.state) }));
            }
            last = f;
        }
        let columns = series(&run.rows);
        Ok((
            json!({
                "ok": true,
                "summary": text,
                "faults": faults,
                "rows": run.rows.len(),
                "columns": SERIES,
            }),
            columns,
        ))
    }

    /// Runs the identification on the motor as `pmsm identify` does: the report (the CLI's
    /// lines), identified and true values, and the identified motor file.
    pub fn identify(&self, ask: &IdentifyAsk) -> Result<Value> {
        let truth = motor_from(&ask.motor)?;
        let request = IdentifyRequest {
            vdc_v: ask.vdc_v,
            pwm_hz: ask.pwm_hz,
            dead_time_s: ask.dead_time_s,
            current_limit_a: None,
            theta_deg: 40.0,
            accel_rad_s2: 200.0,
            adc_noise_a: 0.0,
            averaged: false,
        };
        let done = commission(&truth, &request, "motor")?;
        let t = truth.model.params;
        let m = done.motor;
        let rows: Vec<Value> = [
            ("rs_ohm", m.rs_ohm, t.rs_ohm),
            ("ld_h", m.ld_h, t.ld_h),
            ("lq_h", m.lq_h, t.lq_h),
            ("flux_wb", m.flux_wb, t.flux_wb),
            ("j_kg_m2", m.j_kg_m2, t.j_kg_m2),
            ("b_nm_s", m.b_nm_s, t.b_nm_s),
        ]
        .iter()
        .map(|(k, got, want)| json!({ "key": k, "identified": got, "true": want }))
        .collect();
        Ok(json!({
            "ok": true,
            "report": done.report,
            "rows": rows,
            "motor_toml": done.toml,
        }))
    }

    /// The files a user takes away: the scenario (motor inline) and the motor as TOML, and
    /// the C firmware's `pmsm_config_t` for `pmsm_drive_init`.
    pub fn export(&self, request: &ScenarioRequest) -> Result<Value> {
        let table = toml_table(&request.scenario)?;
        let scenario_toml = toml::to_string(&table)?;
        let motor = table
            .get("motor")
            .and_then(toml::Value::as_table)
            .ok_or_else(|| anyhow!("the scenario has no motor table"))?;
        let motor_toml = toml::to_string(motor)?;
        let sc = scenario(request)?;
        let delay = build_drive(&sc)?.pwm_delay_periods;
        Ok(json!({
            "ok": true,
            "scenario_toml": scenario_toml,
            "motor_toml": motor_toml,
            "c_config": c_config(&sc, delay),
        }))
    }
}

/// The JSON image of a TOML table, back to TOML.
fn toml_table(value: &Value) -> Result<toml::Table> {
    serde_json::from_value(value.clone()).context("the scenario is not a table of TOML values")
}

/// Reads the scenario of `request` with the parser of `pmsm simulate`.
fn scenario(request: &ScenarioRequest) -> Result<Scenario> {
    let text = toml::to_string(&toml_table(&request.scenario)?)?;
    let name = PathBuf::from(&request.name);
    scenario_file::parse(&text, &name, &|p: &Path| {
        bail!(
            "{}: a motor file cannot be read in the browser; load it into the form",
            p.display()
        )
    })
}

/// A motor from the JSON image of its file's keys.
fn motor_from(value: &Value) -> Result<Motor> {
    let table: toml::Table =
        serde_json::from_value(value.clone()).context("the motor is not a table of values")?;
    motor_file::parse(&toml::to_string(&table)?, Path::new("motor"))
}

/// `pmsm_config_t` for `pmsm_drive_init` (pmsm.h): the motor, the inverter and the control
/// keys the scenario sets, and the timer's PWM update delay `pwm_delay` (periods); every
/// field it leaves at 0 takes the library's default.
pub fn c_config(sc: &Scenario, pwm_delay: usize) -> String {
    use std::fmt::Write as _;
    let m = &sc.motor.model.params;
    let inv = &sc.inverter;
    let c = &sc.control;
    let mut s = String::new();
    let _ = writeln!(
        s,
        "/* {}: pmsm_drive_init (pmsm.h); 0 = the default */",
        sc.motor.name
    );
    let _ = writeln!(s, "pmsm_config_t c = {{0}};");
    let estimator = if c.observer_auto {
        "PMSM_ESTIMATOR_AUTO"
    } else {
        match c.observer {
            scenario_file::ObserverKind::Nlo => "PMSM_ESTIMATOR_NLO",
            scenario_file::ObserverKind::Ao => "PMSM_ESTIMATOR_AO",
            scenario_file::ObserverKind::MrasEmf => "PMSM_ESTIMATOR_MRAS_EMF",
            scenario_file::ObserverKind::MrasCurrent => "PMSM_ESTIMATOR_MRAS_CURRENT",
            scenario_file::ObserverKind::Auto => "PMSM_ESTIMATOR_AUTO",
        }
    };
    let _ = writeln!(s, "c.pole_pairs = {};", m.pole_pairs);
    let _ = writeln!(s, "c.estimator = {estimator};");
    for (key, v) in [
        ("rs_ohm", Some(m.rs_ohm)),
        ("ld_h", Some(m.ld_h)),
        ("lq_h", Some(m.lq_h)),
        ("flux_wb", Some(m.flux_wb)),
        ("j_kg_m2", Some(m.j_kg_m2)),
        ("b_nm_s", Some(m.b_nm_s)),
        ("rated_current_a", m.rated_current_a),
        ("rated_speed_rpm", m.rated_speed_rpm),
        ("vdc_v", Some(inv.vdc_v)),
        ("pwm_hz", Some(inv.pwm_hz)),
        ("dead_time_s", Some(inv.dead_time_s)),
        ("current_full_scale_a", inv.current_full_scale_a),
        ("sample_hz", c.sample_hz),
        ("current_bandwidth_hz", c.current_bandwidth_hz),
        ("speed_bandwidth_hz", c.speed_bandwidth_hz),
        ("current_limit_a", c.current_limit_a),
    ] {
        if let Some(v) = v {
            let _ = writeln!(s, "c.{key} = {v:e};");
        }
    }
    let _ = writeln!(
        s,
        "c.pwm_delay_samples = {pwm_delay};  /* the timer applies the duties that many periods late */"
    );
    let _ = writeln!(
        s,
        "c.pwm_period_ticks = htim1.Init.Period;  /* ARR of the centre-aligned timer */"
    );
    s
}
