//! The high-frequency injection (docs/injection.md; on by default on a salient motor) on motor
//! B through `pmsm simulate`'s own code, with the defaults: standstill without the d current,
//! standstill and a reversal through zero under load, the hand-over to the estimator and back;
//! a surface motor without it, and why.

use pmsm_cli::commands::simulate::stats::{first_fault, max_angle, rms_angle, window};
use pmsm_cli::commands::simulate::{Row, run_scenario};
use pmsm_core::DriveState;

mod common;
use common::scenario_text;

/// Motor B on its switching inverter with the drive's defaults (the injection among them),
/// from `theta0_deg`, for `duration` s, with the speed and load tables given.
fn motor_b(duration: f64, theta0_deg: f64, speed: &str, load: &str) -> Vec<Row> {
    motor_b_with(duration, theta0_deg, speed, load, "")
}

/// [`motor_b`] with `control` lines added to `[control]`.
fn motor_b_with(
    duration: f64,
    theta0_deg: f64,
    speed: &str,
    load: &str,
    control: &str,
) -> Vec<Row> {
    let text = format!(
        "duration_s = {duration}\nmotor = \"motor-b.toml\"\n\
         [inverter]\nvdc_v = 540.0\npwm_hz = 14000.0\ndead_time_s = 2e-6\nmodel = \"switching\"\n\
         [control]\n{control}\
         [initial]\ntheta_e_deg = {theta0_deg}\n\
         [speed_ref]\n{speed}\n[load]\n{load}\n"
    );
    let sc = scenario_text("injection", &text);
    run_scenario(&sc).unwrap().rows
}

/// The rotor's electrical angle, unwrapped, over `rows`: its largest distance from the first.
fn rotor_travel(rows: &[&Row]) -> f64 {
    let mut angle = 0.0f64;
    let mut worst = 0.0f64;
    for w in rows.windows(2) {
        angle += pmsm_cli::commands::simulate::wrap(w[1].theta_e_rad - w[0].theta_e_rad);
        worst = worst.max(angle.abs());
    }
    worst
}

/// Current per phase, rms, of the rows (the plant's rotor-frame currents).
fn current_rms(rows: &[&Row]) -> f64 {
    let n = rows.len().max(1) as f64;
    (rows
        .iter()
        .map(|r| r.i_dq_a[0].powi(2) + r.i_dq_a[1].powi(2))
        .sum::<f64>()
        / n
        / 2.0)
        .sqrt()
}

#[test]
fn standstill_without_load_costs_the_injection_not_a_d_current() {
    let rows = motor_b(
        0.8,
        137.0,
        "t_s = [0.0]\nrpm = [0.0]",
        "t_s = [0.0]\nnm = [0.0]",
    );
    assert!(first_fault(&rows).is_none());
    let still = window(&rows, 0.4, 0.8);
    assert!(still.iter().all(|r| r.state == DriveState::Run));
    let i = current_rms(&still);
    // Rated 2.53 A rms; without the injection the low-speed current holds 2.53 A.
    assert!(i <= 0.1 * 2.53, "{i} A rms");
    let rms = rms_angle(&still);
    assert!(rms <= 0.05, "{rms} rad");
}

#[test]
fn standstill_under_half_and_rated_load_holds_the_angle_and_the_rotor() {
    for (load, theta0) in [(2.0, 37.0), (4.0, 211.0)] {
        let rows = motor_b(
            2.5,
            theta0,
            "t_s = [0.0]\nrpm = [0.0]",
            &format!("t_s = [0.0, 0.3, 0.31]\nnm = [0.0, 0.0, {load}]"),
        );
        assert!(first_fault(&rows).is_none(), "{load} N·m");
        // The step is taken by 0.5 s; then 2 s under load.
        let held = window(&rows, 0.5, 2.5);
        let rms = rms_angle(&held);
        let travel = rotor_travel(&held);
        println!("{load} N·m: {rms:.4} rad rms, rotor within {travel:.4} rad");
        assert!(rms <= 0.05, "{load} N·m: {rms} rad rms");
        assert!(travel <= 0.1, "{load} N·m: the rotor moved {travel} rad");
    }
}

#[test]
fn the_demodulation_follows_the_pwm_delay_the_drive_was_not_told() {
    // The timer applies the duties a period late; the drive is told none: the injection's
    // response arrives a sample later than the drive expects, its sign the other way.
    let rows = motor_b_with(
        1.5,
        300.0,
        "t_s = [0.0]\nrpm = [0.0]",
        "t_s = [0.0, 0.3, 0.31]\nnm = [0.0, 0.0, 4.0]",
        "pwm_update_delay_periods = 1\npwm_delay_compensation_periods = 0\n",
    );
    assert!(first_fault(&rows).is_none());
    let rms = rms_angle(&window(&rows, 0.5, 1.5));
    assert!(rms <= 0.05, "{rms} rad");
}

#[test]
fn a_reversal_through_zero_under_rated_load_keeps_the_angle() {
    // +3 % to −3 % of rated speed (90 r/min) in 2 s, rated load throughout.
    let rows = motor_b(
        3.5,
        250.0,
        "t_s = [0.0, 0.2, 0.5, 1.0, 3.0]\nrpm = [0.0, 0.0, 90.0, 90.0, -90.0]",
        "t_s = [0.0, 0.6, 0.61]\nnm = [0.0, 0.0, 4.0]",
    );
    assert!(first_fault(&rows).is_none());
    let running: Vec<&Row> = window(&rows, 0.3, 3.5)
        .into_iter()
        .filter(|r| r.state == DriveState::Run)
        .collect();
    let worst = max_angle(&running);
    assert!(worst <= 0.1, "{worst} rad");
    let end = window(&rows, 3.2, 3.5);
    let speed = end.iter().map(|r| r.speed_rpm).sum::<f64>() / end.len() as f64;
    assert!((speed + 90.0).abs() < 5.0, "{speed} r/min");
}

#[test]
fn the_estimator_takes_over_above_the_hand_over_and_gives_back_below() {
    // To 800 r/min under no load and back to 20 r/min.
    let rows = motor_b(
        2.0,
        137.0,
        "t_s = [0.0, 0.1, 0.6, 1.2, 1.5]\nrpm = [0.0, 0.0, 800.0, 800.0, 20.0]",
        "t_s = [0.0]\nnm = [0.0]",
    );
    assert!(first_fault(&rows).is_none());
    let running: Vec<&Row> = window(&rows, 0.2, 2.0)
        .into_iter()
        .filter(|r| r.state == DriveState::Run)
        .collect();
    let worst = max_angle(&running);
    assert!(worst <= 0.1, "{worst} rad");
    let end = window(&rows, 1.8, 2.0);
    let speed = end.iter().map(|r| r.speed_rpm).sum::<f64>() / end.len() as f64;
    assert!((speed - 20.0).abs() < 2.0, "{speed} r/min");
}

#[test]
fn the_defaults_inject_on_a_salient_motor_and_say_why_not_on_a_surface_one() {
    let run = |motor: &str, control: &str| {
        let text = format!(
            "duration_s = 0.05\nmotor = {motor}\n[inverter]\nvdc_v = 540.0\npwm_hz = 14000.0\n\
             [control]\n{control}\n"
        );
        run_scenario(&scenario_text("injection-default", &text)).unwrap()
    };
    let salient = run("\"motor-b.toml\"", "");
    let f = salient.injection.expect("motor B injects by default");
    // 8 ADC steps of 14.3 A full scale over 4096 steps each way: K = 0.056 A.
    assert!((f.response_a - 0.056).abs() < 0.002, "{}", f.response_a);
    assert!(salient.injection_declined.is_none());
    let surface = run(
        "{ pole_pairs = 3, rs_ohm = 1.6, ld_h = 0.0134, lq_h = 0.0134, flux_wb = 0.288, \
         j_kg_m2 = 0.04, rated_current_a = 5.0, rated_speed_rpm = 2000 }",
        // The current-model MRAS holds a surface motor at low speed with a d current (the
        // back-EMF estimators pass zero speed in their open loop instead).
        "observer = \"mras-current\"",
    );
    assert!(surface.injection.is_none());
    let (why, id, _, loss) = surface.injection_declined.expect("the reason");
    assert!(why.to_string().contains("L_q/L_d of at least 1.1"), "{why}");
    // The low-speed d current holds the rotor instead, and costs 1.5 R i_d² at standstill.
    assert!(
        id > 0.0 && (loss - 1.5 * 1.6 * id * id).abs() < 1e-9,
        "{id} A, {loss} W"
    );
}

#[test]
fn a_surface_motor_is_refused_by_name() {
    let text = "duration_s = 0.1\n\
        motor = { pole_pairs = 3, rs_ohm = 1.6, ld_h = 0.0134, lq_h = 0.0134, flux_wb = 0.288, j_kg_m2 = 0.04 }\n\
        [inverter]\nvdc_v = 300.0\npwm_hz = 10000.0\n[control]\ninjection = true\n";
    let path = std::env::temp_dir().join(format!(
        "pmsm-injection-surface-{}.toml",
        std::process::id()
    ));
    std::fs::write(&path, text).unwrap();
    let sc = pmsm_cli::scenario_file::read(&path).unwrap();
    std::fs::remove_file(&path).ok();
    let e = format!("{:#}", run_scenario(&sc).unwrap_err());
    assert!(
        e.contains("`injection`") && e.contains("L_q/L_d of at least 1.1"),
        "{e}"
    );
}

/// The saliency `L_q/L_inc,d` a d current `x` (per unit of the rated peak current) gives a
/// motor whose d axis saturates as the plant's interior motors do (`Saturation::Tanh` at its
/// default strength), and the least such `x` that reaches the injection's `MIN_SALIENCY`.
fn saturation_saliency(m: &pmsm_core::MotorParams) -> (f64, f64) {
    let i_b = core::f64::consts::SQRT_2 * m.rated_current_a.unwrap();
    // The interior motors' default (it depends on L_d, ψ and the rating, not on L_q).
    let mut interior = *m;
    interior.lq_h *= 1.1;
    let sat = pmsm_plant::Saturation::default_for(&interior);
    assert!(!sat.is_linear());
    let saliency = |x: f64| m.lq_h / sat.inductance_d_h(m, x * i_b);
    let needed = (0..=400)
        .map(|k| f64::from(k) * 0.01)
        .find(|&x| saliency(x) >= pmsm_core::INJECTION_MIN_SALIENCY)
        .unwrap_or(f64::INFINITY);
    (saliency(1.0), needed)
}

#[test]
fn a_surface_motors_saturation_gives_no_usable_saliency_within_its_rated_current() {
    // Motor A (Solsona, Valla, Muravchik (2000)) and the board's gimbal motor, given the d-axis
    // saturation of the plant's interior motors: the saliency under a d current reaches the
    // injection's 1.1 only beyond the current the low-speed hold uses (1 pu).
    for (name, mut m) in [
        (
            "motor A",
            pmsm_core::MotorParams::new(3, 1.6, 0.0134, 0.0134, 0.288, 0.04256, 0.004256),
        ),
        (
            "GBM2804H-100T",
            pmsm_core::MotorParams::new(7, 5.3, 0.00106, 0.00106, 0.0056, 6e-6, 1e-6),
        ),
    ] {
        m.rated_current_a = Some(if name == "motor A" { 6.1 } else { 0.8 });
        let (at_rated, needed) = saturation_saliency(&m);
        println!(
            "{name}: L_q/L_inc,d {at_rated:.3} at the rated peak d current; 1.1 from {needed:.2} pu"
        );
        assert!(
            at_rated < 1.1 && needed > 1.5,
            "{name}: {at_rated} at 1 pu, 1.1 from {needed} pu"
        );
    }
}
