//! `pmsm plant` end to end, through the binary: agreement with an independent high-accuracy
//! integration (another formulation, another integrator: `pmsm_tests::reference`), on motors
//! and voltage sequences generated here, and the one-line errors for bad input.

mod common;

use common::{one_line_error, pmsm as run_pmsm, s as p, scratch};
use pmsm_core::MotorParams;
use pmsm_tests::reference::{RefMotor, RefState};
use pmsm_tests::signals::{VoltageRow, random_steps, vf_ramp_with_steps};
use std::fmt::Write as _;
use std::path::Path;

fn motor_toml(name: &str, p: &MotorParams) -> String {
    let mut s = format!(
        "name = \"{name}\"\npole_pairs = {}\nrs_ohm = {}\nld_h = {}\nlq_h = {}\nflux_wb = {}\n\
         kt_nm_per_a = {}\nj_kg_m2 = {}\nb_nm_s = {}\n",
        p.pole_pairs, p.rs_ohm, p.ld_h, p.lq_h, p.flux_wb, p.kt_nm_per_a, p.j_kg_m2, p.b_nm_s
    );
    s.push_str("\n[saturation]\nmodel = \"none\"\n");
    s
}

fn write_input(path: &Path, rows: &[VoltageRow]) {
    let mut s = String::from("v_beta_v,t_s,load_nm,v_alpha_v\n"); // column order is free
    for r in rows {
        writeln!(s, "{},{},{},{}", r.v_beta_v, r.t_s, r.load_nm, r.v_alpha_v).unwrap();
    }
    std::fs::write(path, s).unwrap();
}

/// Output rows: t_s, i_alpha_a, i_beta_a, theta_e_rad, omega_m_rad_s.
fn read_output(path: &Path) -> Vec<[f64; 5]> {
    let text = std::fs::read_to_string(path).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next().unwrap(),
        "t_s,i_alpha_a,i_beta_a,theta_e_rad,omega_m_rad_s"
    );
    lines
        .map(|l| {
            let v: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
            [v[0], v[1], v[2], v[3], v[4]]
        })
        .collect()
}

struct Errors {
    peak_speed_rad_s: f64,
    current_rms_rel: f64,
    angle_max_rad: f64,
    speed_max_rel: f64,
}

/// Runs `pmsm plant` and the reference on the same input and compares them.
fn compare(
    name: &str,
    p: MotorParams,
    rows: &[VoltageRow],
    theta0_deg: f64,
    speed0_rpm: f64,
) -> Errors {
    let dir = scratch(name);
    let (motor, input, output) = (dir.join("m.toml"), dir.join("v.csv"), dir.join("out.csv"));
    std::fs::write(&motor, motor_toml(name, &p)).unwrap();
    write_input(&input, rows);
    let th0 = format!("{theta0_deg}");
    let n0 = format!("{speed0_rpm}");
    let out = run_pmsm(&[
        "plant",
        "--motor",
        motor.to_str().unwrap(),
        "--input",
        input.to_str().unwrap(),
        "--output",
        output.to_str().unwrap(),
        "--theta0-deg",
        &th0,
        "--speed0-rpm",
        &n0,
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let got = read_output(&output);
    assert_eq!(got.len(), rows.len());

    let reference = RefMotor {
        params: p,
        h5: 0.0,
        h7: 0.0,
    };
    let mut s: RefState = reference.state(
        [0.0, 0.0],
        theta0_deg.to_radians(),
        speed0_rpm * std::f64::consts::TAU / 60.0,
    );
    let (mut e2, mut r2, mut angle, mut speed, mut speed_scale) =
        (0.0, 0.0, 0.0f64, 0.0f64, 0.0f64);
    for (k, row) in rows.iter().enumerate() {
        let i = reference.currents(&s);
        let g = got[k];
        assert!((g[0] - row.t_s).abs() < 1e-12);
        e2 += (g[1] - i[0]).powi(2) + (g[2] - i[1]).powi(2);
        r2 += i[0] * i[0] + i[1] * i[1];
        let d = (g[3] - s.theta_e_rad + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU)
            - std::f64::consts::PI;
        angle = angle.max(d.abs());
        speed = speed.max((g[4] - s.omega_m_rad_s).abs());
        speed_scale = speed_scale.max(s.omega_m_rad_s.abs());
        if let Some(next) = rows.get(k + 1) {
            reference.advance(
                &mut s,
                [row.v_alpha_v, row.v_beta_v],
                row.load_nm,
                next.t_s - row.t_s,
                1e-10,
            );
        }
    }
    std::fs::remove_dir_all(&dir).ok();
    Errors {
        peak_speed_rad_s: speed_scale,
        current_rms_rel: (e2 / r2).sqrt(),
        angle_max_rad: angle,
        speed_max_rel: speed / speed_scale.max(1e-9),
    }
}

fn check(name: &str, e: &Errors) {
    eprintln!(
        "{name}: peak speed {:.1} rad/s, current rms {:.2e}, angle max {:.2e} rad, speed max {:.2e}",
        e.peak_speed_rad_s, e.current_rms_rel, e.angle_max_rad, e.speed_max_rel
    );
    // The motor must really have moved, or the comparison says little.
    assert!(
        e.peak_speed_rad_s > 10.0,
        "{name}: peak speed {}",
        e.peak_speed_rad_s
    );
    // The required bounds are 0.5 %, 0.01 rad and 0.5 %; the model does far better.
    assert!(
        e.current_rms_rel < 1e-4,
        "{name}: current {}",
        e.current_rms_rel
    );
    assert!(e.angle_max_rad < 1e-5, "{name}: angle {}", e.angle_max_rad);
    assert!(e.speed_max_rel < 1e-5, "{name}: speed {}", e.speed_max_rel);
}

fn motor_a() -> MotorParams {
    let mut m = MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256);
    m.kt_nm_per_a = 1.108;
    m
}

fn motor_b() -> MotorParams {
    MotorParams::new(3, 7.2, 0.025025, 0.04017, 0.305, 0.0036, 0.0011)
}

#[test]
fn surface_motor_a_vf_start_with_load_steps() {
    let rows = vf_ramp_with_steps(11, 3000, 1.5, 0.288, 300.0, 3.0);
    check("motor A", &compare("a", motor_a(), &rows, 37.0, 600.0));
}

#[test]
fn interior_motor_b_vf_start_with_load_steps() {
    let rows = vf_ramp_with_steps(12, 2000, 1.0, 0.305, 400.0, 1.0);
    check("motor B", &compare("b", motor_b(), &rows, -100.0, 0.0));
}

#[test]
fn interior_motor_b_random_steps_spinning() {
    let rows = random_steps(13, 1500, 2e-4, 200.0);
    check(
        "motor B steps",
        &compare("b-steps", motor_b(), &rows, 10.0, 700.0),
    );
}

#[test]
fn small_fast_interior_motor() {
    // 24 V, 7 pole pairs, 0.3/0.5 mH, spun to about 1000 rad/s electrical.
    let mut m = MotorParams::new(7, 0.05, 0.3e-3, 0.5e-3, 0.004, 5e-5, 1e-6);
    m.kt_nm_per_a = 1.5 * 7.0 * 0.004 * 0.9;
    let rows = vf_ramp_with_steps(14, 3000, 0.3, 0.004, 2000.0, 0.002);
    check("drone", &compare("drone", m, &rows, 200.0, 0.0));
}

#[test]
fn bad_input_gets_one_line_naming_file_and_place() {
    let dir = scratch("errors");
    let motor = dir.join("m.toml");
    std::fs::write(&motor, motor_toml("m", &motor_a())).unwrap();
    let out = dir.join("out.csv");
    let cases: [(&str, &str, &str); 4] = [
        (
            "missing-col.csv",
            "t_s,v_alpha_v\n0,1\n",
            "missing column `v_beta_v`",
        ),
        (
            "nan.csv",
            "t_s,v_alpha_v,v_beta_v\n0,1,2\n0.1,nan,2\n",
            "row 2 (line 3), column `v_alpha_v`",
        ),
        (
            "short.csv",
            "t_s,v_alpha_v,v_beta_v\n0,1,2\n0.1,1\n",
            "row 2 (line 3) has 2 fields",
        ),
        (
            "time.csv",
            "t_s,v_alpha_v,v_beta_v\n0,1,2\n0,1,2\n",
            "row 2, column `t_s`: time must increase",
        ),
    ];
    let plant = |motor: &Path, input: &Path| {
        one_line_error(&[
            "plant",
            "--motor",
            p(motor),
            "--input",
            p(input),
            "--output",
            p(&out),
        ])
    };
    for (file, text, expect) in cases {
        let input = dir.join(file);
        std::fs::write(&input, text).unwrap();
        let err = plant(&motor, &input);
        assert!(err.contains(file) && err.contains(expect), "{err}");
    }
    // Motor file errors name the file and the key.
    let bad_motor = dir.join("bad.toml");
    let input = dir.join("ok.csv");
    std::fs::write(&input, "t_s,v_alpha_v,v_beta_v\n0,1,2\n").unwrap();
    for (text, key) in [
        (
            motor_toml("m", &motor_a()).replace("rs_ohm = 1.6", "rs_ohm = 0"),
            "rs_ohm",
        ),
        (
            motor_toml("m", &motor_a()).replace("ld_h = 0.0134", "ld_h = nan"),
            "ld_h",
        ),
        (
            format!(
                "{}\nspeed_max = 3\n",
                motor_toml("m", &motor_a()).replace("[saturation]\nmodel = \"none\"\n", "")
            ),
            "speed_max",
        ),
    ] {
        std::fs::write(&bad_motor, text).unwrap();
        let err = plant(&bad_motor, &input);
        assert!(err.contains("bad.toml") && err.contains(key), "{err}");
    }
    // A missing file.
    let err = plant(Path::new("nope.toml"), Path::new("x.csv"));
    assert!(err.contains("nope.toml: cannot read"), "{err}");
    // Absurd but well-formed data: megavolts. Either a clean error or finite output, no panic.
    let input = dir.join("huge.csv");
    std::fs::write(
        &input,
        "t_s,v_alpha_v,v_beta_v\n0,1e12,-1e12\n0.5,1e12,1e12\n1,0,0\n",
    )
    .unwrap();
    let r = run_pmsm(&[
        "plant",
        "--motor",
        motor.to_str().unwrap(),
        "--input",
        input.to_str().unwrap(),
        "--output",
        out.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&r.stderr);
    assert!(!err.contains("panicked"), "{err}");
    if r.status.success() {
        assert!(!std::fs::read_to_string(&out).unwrap().contains("NaN"));
    } else {
        assert_eq!(err.lines().count(), 1, "{err}");
    }
    std::fs::remove_dir_all(&dir).ok();
}
