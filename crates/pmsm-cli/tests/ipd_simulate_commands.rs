//! `pmsm ipd` and `pmsm simulate` end to end through the binary: outputs and one-line errors.

mod common;

use common::{one_line_error, pmsm, s as p, scratch};
use std::path::Path;

fn example(name: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
}

/// `examples/b-800rpm-load.toml` cut to `duration_s`, written to `dir/s.toml`: its path and
/// text.
fn motor_b_scenario(dir: &Path, duration_s: f64) -> (std::path::PathBuf, String) {
    let scenario = dir.join("s.toml");
    let text = std::fs::read_to_string(example("b-800rpm-load.toml"))
        .unwrap()
        .replace("duration_s = 2.0", &format!("duration_s = {duration_s}"))
        .replace(
            "motor = \"motor-b.toml\"",
            &format!("motor = \"{}\"", p(&example("motor-b.toml"))),
        );
    std::fs::write(&scenario, &text).unwrap();
    (scenario, text)
}

#[test]
fn ipd_sweep_on_motor_b_is_within_15_degrees_with_the_right_polarity() {
    let dir = scratch("ipd");
    let out = dir.join("ipd.csv");
    let motor = example("motor-b.toml");
    let r = pmsm(&[
        "ipd",
        "--motor",
        p(&motor),
        "--vdc",
        "540",
        "--sweep",
        "24",
        "--pwm-hz",
        "14000",
        "--dead-time-s",
        "2e-6",
        "--output",
        p(&out),
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let text = std::fs::read_to_string(&out).unwrap();
    assert!(text.starts_with("theta_true_deg,theta_est_deg,error_deg,polarity_ok,fault\n"));
    let rows: Vec<Vec<&str>> = text
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    assert_eq!(rows.len(), 24);
    for r in &rows {
        let err: f64 = r[2].parse().unwrap();
        assert!(err.abs() <= 15.0 && r[3] == "1", "{r:?}");
    }
    // A surface motor: the named fault, not a wrong angle.
    let r = pmsm(&[
        "ipd",
        "--motor",
        p(&example("motor-a.toml")),
        "--vdc",
        "300",
        "--theta-deg",
        "40",
        "--output",
        p(&out),
    ]);
    assert!(r.status.success());
    assert!(
        std::fs::read_to_string(&out)
            .unwrap()
            .contains(",,,0,low_saliency")
    );
    // Bad arguments.
    let err = one_line_error(&[
        "ipd",
        "--motor",
        p(&motor),
        "--vdc",
        "540",
        "--output",
        p(&out),
    ]);
    assert!(err.contains("--theta-deg X or --sweep N"), "{err}");
    let err = one_line_error(&[
        "ipd",
        "--motor",
        p(&motor),
        "--vdc",
        "-5",
        "--sweep",
        "3",
        "--output",
        p(&out),
    ]);
    assert!(err.contains("vdc_v"), "{err}");
    std::fs::remove_dir_all(&dir).ok();
}

/// `pmsm simulate SCENARIO --output OUT --plot SVG`'s arguments.
fn simulate_args<'a>(scenario: &'a Path, out: &'a Path, svg: &'a Path) -> [&'a str; 6] {
    [
        "simulate",
        p(scenario),
        "--output",
        p(out),
        "--plot",
        p(svg),
    ]
}

#[test]
fn simulate_writes_the_documented_columns_and_names_bad_keys() {
    let dir = scratch("sim");
    let (scenario, text) = motor_b_scenario(&dir, 0.4);
    let (out, svg) = (dir.join("o.csv"), dir.join("o.svg"));
    let r = pmsm(&simulate_args(&scenario, &out, &svg));
    let stdout = String::from_utf8_lossy(&r.stdout);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    assert!(
        stdout.contains("initial position: detected") && stdout.contains("faults"),
        "{stdout}"
    );
    let header = std::fs::read_to_string(&out)
        .unwrap()
        .lines()
        .next()
        .unwrap()
        .to_owned();
    assert_eq!(
        header,
        "t_s,speed_ref_rpm,speed_rpm,speed_est_rpm,theta_e_rad,theta_e_est_rad,i_d_a,i_q_a,i_q_ref_a,\
         v_alpha_v,v_beta_v,duty_a,duty_b,duty_c,pwm_on,fault,health,rs_est_ohm,flux_est_wb"
    );
    let rows = std::fs::read_to_string(&out).unwrap().lines().count() - 1;
    assert_eq!(rows, (0.4 * 14000.0) as usize);
    assert!(std::fs::metadata(&svg).unwrap().len() > 10_000);
    // Bad scenarios: one line naming the file and the key.
    for (from, to, key) in [
        ("vdc_v = 540.0", "vdc_v = 0.0", "inverter.vdc_v"),
        (
            "observer = \"mras-current\"",
            "observer = \"kalman\"",
            "observer",
        ),
        ("[initial]", "[initial]\nspeed = 3.0", "speed"),
        ("rpm = [0.0, 0.0, 800.0]", "rpm = [0.0, 800.0]", "speed_ref"),
    ] {
        std::fs::write(&scenario, text.replace(from, to)).unwrap();
        let err = one_line_error(&["simulate", p(&scenario), "--output", p(&out)]);
        assert!(err.contains("s.toml") && err.contains(key), "{err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}

/// `pmsm simulate … | head`: a reader that closes the pipe before the report is written (here
/// before the program starts) stops the report, not the command: no panic, exit status 0, and
/// the CSV (written before the report) and the plot (after it) are both there.
#[test]
fn simulate_into_a_closed_pipe_still_writes_its_files() {
    let dir = scratch("sim-pipe");
    let (scenario, _) = motor_b_scenario(&dir, 0.05);
    let (out, svg) = (dir.join("o.csv"), dir.join("o.svg"));
    let (reader, writer) = std::io::pipe().unwrap();
    drop(reader);
    let r = std::process::Command::new(env!("CARGO_BIN_EXE_pmsm"))
        .args(simulate_args(&scenario, &out, &svg))
        .stdout(writer)
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&r.stderr);
    assert!(r.status.success(), "{stderr}");
    assert!(!stderr.contains("panicked"), "{stderr}");
    let rows = std::fs::read_to_string(&out).unwrap().lines().count() - 1;
    assert_eq!(rows, (0.05 * 14000.0) as usize);
    assert!(std::fs::read_to_string(&svg).unwrap().contains("<svg"));
}
