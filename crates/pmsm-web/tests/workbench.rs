//! The workbench's binding against `pmsm simulate`: the same scenario gives the same report,
//! errors name their key, and the exported files read back to the same motor.

use pmsm_cli::commands::simulate::{run_scenario, summary};
use pmsm_cli::scenario_file;
use pmsm_web::{LoadRequest, SERIES, ScenarioRequest, Workbench};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

fn examples() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples")
}

/// A shipped scenario loaded as the page loads it (its motor file given by name).
fn load(bench: &Workbench, scenario: &str, motor: &str) -> (String, Value) {
    let dir = examples();
    let name = dir.join(scenario).to_string_lossy().into_owned();
    let mut files = BTreeMap::new();
    files.insert(
        motor.to_owned(),
        std::fs::read_to_string(dir.join(motor)).unwrap(),
    );
    let answer = bench
        .load(&LoadRequest {
            name: name.clone(),
            text: std::fs::read_to_string(dir.join(scenario)).unwrap(),
            files,
        })
        .unwrap();
    assert_eq!(answer["ok"], true, "{answer}");
    assert_eq!(answer["check"]["ok"], true, "{answer}");
    (name, answer["scenario"].clone())
}

#[test]
fn a_run_in_steps_reports_what_pmsm_simulate_reports() {
    let mut bench = Workbench::default();
    let (name, scenario) = load(&bench, "b-800rpm-load.toml", "motor-b.toml");
    // Shortened: the same scenario, its first 0.7 s (detection, start, ramp).
    let mut scenario = scenario;
    scenario["duration_s"] = 0.7.into();
    let request = ScenarioRequest {
        name: name.clone(),
        scenario: scenario.clone(),
    };
    let started = bench.start(&request).unwrap();
    assert_eq!(started["samples"], 9800);
    let mut steps = 0;
    let mut done = 0.0;
    while done < 1.0 {
        let next = bench.advance(1000).unwrap();
        assert!(next > done, "progress moves: {done} then {next}");
        done = next;
        steps += 1;
    }
    assert_eq!(steps, 10);
    let (answer, columns) = bench.finish().unwrap();
    let rows = answer["rows"].as_u64().unwrap() as usize;
    assert_eq!(rows, 9800);
    assert_eq!(columns.len(), SERIES.len() * rows);

    // The host: the same text through `pmsm simulate`'s reader and loop.
    let text = bench.export(&request).unwrap()["scenario_toml"]
        .as_str()
        .unwrap()
        .to_owned();
    let sc = scenario_file::parse(&text, Path::new(&name), &|_: &Path| unreachable!()).unwrap();
    let run = run_scenario(&sc).unwrap();
    assert_eq!(answer["summary"].as_str().unwrap(), summary(&sc, &run));
    // The columns are the rows' (speed, column 2), and the angle error is only in the closed
    // loop (NaN during the detection at the start).
    let speed = &columns[2 * rows..3 * rows];
    for (k, r) in run.rows.iter().enumerate().step_by(97) {
        assert_eq!(speed[k], r.speed_rpm as f32);
    }
    assert!(columns[4 * rows].is_nan());
    assert!(columns[5 * rows - 1].abs() < 0.1);
}

#[test]
fn a_bad_value_is_refused_with_its_key_and_a_second_run_needs_a_start() {
    let mut bench = Workbench::default();
    let (name, mut scenario) = load(&bench, "b-800rpm-load.toml", "motor-b.toml");
    scenario["motor"]["ld_h"] = (-0.025).into();
    let request = ScenarioRequest { name, scenario };
    let check = bench.check(&request);
    assert_eq!(check["ok"], false);
    assert_eq!(check["key"], "ld_h");
    assert!(
        check["error"]
            .as_str()
            .unwrap()
            .contains("`ld_h` must be greater than zero"),
        "{check}"
    );
    assert!(bench.start(&request).is_err());
    assert!(
        bench.advance(10).is_err(),
        "nothing runs after a refused start"
    );
    assert!(bench.finish().is_err());
}

#[test]
fn the_exported_files_read_back_to_the_same_motor_and_inverter() {
    let bench = Workbench::default();
    let (name, scenario) = load(&bench, "c-24v-mtpa-1000rpm.toml", "motor-c-24v.toml");
    let request = ScenarioRequest { name, scenario };
    let out = bench.export(&request).unwrap();
    let motor_text = out["motor_toml"].as_str().unwrap();
    let motor = pmsm_cli::motor_file::parse(motor_text, Path::new("m.toml")).unwrap();
    let file = pmsm_cli::motor_file::read(&examples().join("motor-c-24v.toml")).unwrap();
    assert_eq!(motor.model.params, file.model.params);
    let c = out["c_config"].as_str().unwrap();
    let ld = format!("c.ld_h = {:e};", file.model.params.ld_h);
    assert!(c.contains(&ld), "{c}");
    assert!(c.contains("c.pwm_delay_samples = 1;"), "{c}");
}

#[test]
fn a_motor_file_with_an_unknown_key_is_refused_by_name() {
    let bench = Workbench::default();
    let e = bench
        .motor("pole_pairs = 3\nrs_ohm = 1.0\nld_h = 0.01\nlq_h = 0.01\nflux_wb = 0.1\nj_kg_m2 = 0.001\nresistance = 2\n")
        .unwrap_err();
    assert!(format!("{e:#}").contains("resistance"), "{e:#}");
    let ok = bench
        .motor("pole_pairs = 3\nrs_ohm = 1.0\nld_h = 0.01\nlq_h = 0.01\nflux_wb = 0.1\nj_kg_m2 = 0.001\n")
        .unwrap();
    assert_eq!(ok["motor"]["pole_pairs"], 3);
}
