//! The drive away from the papers' operating point: the drive told a dead time apart from the
//! plant's, the hard current sign of the averaged plant, the automatic start-up, a speed
//! reference below what an estimator can run at, a rotor driven backwards by its load (and a
//! light one stopped by it), and the plot's angle error before the estimator runs. Each through `pmsm simulate`'s own code.

// The values compared exactly are copied from the file, not computed.
#![allow(clippy::float_cmp)]

use pmsm_cli::commands::simulate::stats::{
    first_fault, max_speed_off, rms_angle, speed_err, std_dev, window,
};
use pmsm_cli::commands::simulate::{build_drive, build_plant, run_scenario};
use pmsm_cli::scenario_file;

mod common;
use common::{example, example_edited, scenario_text};

const MOTOR_B_SHORT: &str = "duration_s = 0.8\nmotor = \"motor-b.toml\"\n\
    [inverter]\nvdc_v = 540.0\npwm_hz = 14000.0\ndead_time_s = 2e-6\n\
    [control]\nobserver = \"mras-current\"\nstartup = \"ipd\"\ndeadtime_compensation = true\n\
    [speed_ref]\nt_s = [0.0, 0.3]\nrpm = [0.0, 300.0]\n";

#[test]
fn the_drive_is_told_its_dead_time_apart_from_the_plant() {
    // Default: the drive is told the inverter's dead time; the plant's averaged model has the
    // 1 % band of the full scale.
    let sc = scenario_text("dt-default", MOTOR_B_SHORT);
    let setup = build_drive(&sc).unwrap();
    assert_eq!(setup.drive_inverter.dead_time_s, 2e-6);
    assert_eq!(setup.inverter.dead_time_s, 2e-6);
    let plant = build_plant(&sc, &setup.inverter).unwrap();
    let fs = setup.inverter.current_full_scale_a;
    let band = plant.inverter().model().sign_band_a;
    assert!((band - 0.01 * fs).abs() < 1e-12, "{band} vs {fs}");

    // Told 1.5 µs while the plant has 2 µs, and the hard sign in the plant.
    let text = MOTOR_B_SHORT
        .replace(
            "deadtime_compensation = true\n",
            "deadtime_compensation = true\ndead_time_s = 1.5e-6\n",
        )
        .replace(
            "dead_time_s = 2e-6\n",
            "dead_time_s = 2e-6\nsign_band_a = 0.0\n",
        );
    let sc = scenario_text("dt-told", &text);
    let setup = build_drive(&sc).unwrap();
    assert_eq!(setup.drive_inverter.dead_time_s, 1.5e-6);
    assert_eq!(setup.inverter.dead_time_s, 2e-6);
    let plant = build_plant(&sc, &setup.inverter).unwrap();
    assert_eq!(plant.inverter().model().params.dead_time_s, 2e-6);
    assert_eq!(plant.inverter().model().sign_band_a, 0.0);
    // The compensation's dead-time voltage: 1.5 µs · 14 kHz · 540 V = 11.34 V, not 15.12 V.
    let v = setup.config.v_dead_nominal_v();
    assert!((v - 11.34).abs() < 1e-9, "{v}");

    // The hard sign in the plant, the drive told the right dead time: an ordinary start, the
    // detection, then the closed loop to 300 r/min without a fault. (Told 1.5 µs of the
    // plant's 2 µs, the current-model MRAS drifts to half a turn of angle error at 300 r/min:
    // what the compensation is told matters.)
    let text = MOTOR_B_SHORT.replace(
        "dead_time_s = 2e-6\n",
        "dead_time_s = 2e-6\nsign_band_a = 0.0\n",
    );
    let run = run_scenario(&scenario_text("hard-run", &text)).unwrap();
    if let Some(r) = first_fault(&run.rows) {
        panic!("fault at {} s: {:?}", r.t_s, r.state);
    }
    let (est, truth) = run.ipd.expect("detected");
    let ipd_err = ((est - truth + 180.0).rem_euclid(360.0) - 180.0).abs();
    let tail: Vec<f64> = run
        .rows
        .iter()
        .filter(|r| r.t_s >= 0.6)
        .map(|r| r.speed_rpm)
        .collect();
    let mean = tail.iter().sum::<f64>() / tail.len() as f64;
    println!("hard sign: detection error {ipd_err:.1}°, mean speed over 0.6–0.8 s {mean:.1} r/min");
    assert!(ipd_err < 15.0, "{ipd_err}");
    assert!((mean - 300.0).abs() < 15.0, "{mean}");

    // Bad values name their key.
    for (from, to, key) in [
        (
            "deadtime_compensation = true\n",
            "deadtime_compensation = true\ndead_time_s = -1e-6\n",
            "control.dead_time_s",
        ),
        (
            "dead_time_s = 2e-6\n",
            "dead_time_s = 2e-6\nsign_band_a = -0.1\n",
            "inverter.sign_band_a",
        ),
        (
            "deadtime_compensation = true\n",
            "deadtime_compensation = true\nmras_d_weight = 1.5\n",
            "control.mras_d_weight",
        ),
    ] {
        let path = std::env::temp_dir().join(format!(
            "pmsm-drive-robustness-{}-bad.toml",
            std::process::id()
        ));
        let motor_dir = example("").canonicalize().unwrap();
        let text = MOTOR_B_SHORT
            .replace(from, to)
            .replace("motor = \"", &format!("motor = \"{}/", motor_dir.display()));
        std::fs::write(&path, text).unwrap();
        let e = format!("{:#}", scenario_file::read(&path).unwrap_err());
        std::fs::remove_file(&path).ok();
        assert!(e.contains(key), "{e}");
    }
}

/// The shipped scenario `name` with text replacements.

#[test]
fn auto_start_up_aligns_a_surface_motor_and_detects_on_a_salient_one() {
    use pmsm_core::StartupMode;
    // Motor A (surface, L_d = L_q) with `startup` omitted: alignment, then the NLO's open-loop
    // start and the closed loop to 1146 r/min under load, as with `startup = "align"`.
    let sc = example_edited(
        "a-nlo-start-load.toml",
        &[
            ("startup = \"align\"\n", ""),
            ("duration_s = 3.0", "duration_s = 2.3"),
        ],
    );
    assert_eq!(sc.control.startup, scenario_file::Startup::Auto);
    let run = run_scenario(&sc).unwrap();
    assert_eq!(run.startup, StartupMode::Align);
    if let Some(r) = first_fault(&run.rows) {
        panic!("fault at {} s: {:?}", r.t_s, r.state);
    }
    let last = run.rows.last().unwrap();
    println!(
        "motor A, auto: {:?}, {:.1} r/min at 2.3 s",
        run.startup, last.speed_rpm
    );
    assert!(
        (last.speed_rpm - 1146.0).abs() < 0.03 * 1146.0,
        "{}",
        last.speed_rpm
    );
    // The current-model MRAS on motor A, which an IPD start cannot serve (no saliency): auto
    // aligns too.
    let sc = example_edited(
        "a-nlo-start-load.toml",
        &[
            ("startup = \"align\"\n", ""),
            ("observer = \"nlo\"", "observer = \"mras-current\""),
        ],
    );
    let setup = build_drive(&sc).unwrap();
    assert_eq!(setup.config.design.startup, StartupMode::Align);

    // Motor B (23 % saliency) with auto: the detection, then 300 r/min.
    let text = MOTOR_B_SHORT.replace("startup = \"ipd\"\n", "startup = \"auto\"\n");
    let run = run_scenario(&scenario_text("auto-b", &text)).unwrap();
    assert_eq!(run.startup, StartupMode::Ipd);
    let (est, truth) = run.ipd.expect("detected");
    let err = ((est - truth + 180.0).rem_euclid(360.0) - 180.0).abs();
    assert!(err < 15.0, "{err}");
    assert!(run.rows.iter().all(|r| r.fault().is_empty()));
}

#[test]
fn a_reference_below_the_estimators_minimum_is_held_and_said() {
    use pmsm_cli::commands::simulate::speed_ref_notice;
    // Motor A on the NLO asked for 60 r/min, half its least speed (the handover speed, 10 % of
    // the rated 1200 r/min): the closed loop holds 120 r/min, and says so.
    let sc = example_edited(
        "a-nlo-start-load.toml",
        &[
            ("duration_s = 3.0", "duration_s = 2.2"),
            ("rpm = [0.0, 0.0, 1146.0]", "rpm = [0.0, 0.0, 60.0]"),
        ],
    );
    let run = run_scenario(&sc).unwrap();
    assert!(run.rows.iter().all(|r| r.fault().is_empty()));
    let held: Vec<f64> = run
        .rows
        .iter()
        .filter_map(|r| r.speed_ref_held_rpm)
        .collect();
    let run_rows = run
        .rows
        .iter()
        .filter(|r| r.state == pmsm_core::DriveState::Run)
        .count();
    // Every closed-loop sample holds 120 r/min (to the per-unit LSB).
    assert_eq!(held.len(), run_rows);
    assert!(
        held.iter().all(|h| (h - 120.0).abs() < 0.01),
        "{:?}",
        held.first()
    );
    let tail: Vec<f64> = run
        .rows
        .iter()
        .filter(|r| r.t_s >= 2.0)
        .map(|r| r.speed_rpm)
        .collect();
    let mean = tail.iter().sum::<f64>() / tail.len() as f64;
    assert!((mean - 120.0).abs() < 6.0, "{mean}");
    let notice = speed_ref_notice(&sc, &run.rows).expect("a notice");
    println!("{notice}; mean speed over 2.0–2.2 s {mean:.1} r/min");
    assert!(
        notice.contains(
            "speed reference 60.00 r/min below the NLO's minimum 120.0 r/min: held at 120.0 r/min"
        ),
        "{notice}"
    );
    // At the reference itself nothing is held and nothing said.
    let sc = example_edited(
        "a-nlo-start-load.toml",
        &[("duration_s = 3.0", "duration_s = 2.2")],
    );
    let run = run_scenario(&sc).unwrap();
    let late: Vec<_> = run.rows.iter().filter(|r| r.t_s > 1.0).collect();
    assert!(late.iter().all(|r| r.speed_ref_held_rpm.is_none()));
}

#[test]
fn a_light_rotor_stopped_by_its_load_ends_in_a_named_fault_within_50_ms_of_the_slip() {
    // examples/servo-400w-load-step.toml: a bare 400 W servo under a step of its rated torque
    // at half its rated speed, with the defaults (the NLO). The first sample of the closed
    // loop whose angle error passes a quarter turn, and the first fault.
    let sc = scenario_file::read(&example("servo-400w-load-step.toml")).unwrap();
    let run = run_scenario(&sc).unwrap();
    let fault = first_fault(&run.rows).expect("a named fault");
    let slip = run
        .rows
        .iter()
        .find(|r| {
            r.state == pmsm_core::DriveState::Run
                && r.t_s > 1.0
                && r.angle_error_rad().abs() > std::f64::consts::FRAC_PI_2
        })
        .expect("the estimate slips");
    let delay_ms = 1e3 * (fault.t_s - slip.t_s);
    println!(
        "slip at {:.4} s, {} at {:.4} s ({delay_ms:.1} ms)",
        slip.t_s,
        fault.fault(),
        fault.t_s
    );
    assert!(fault.t_s > 1.0, "{} at {} s", fault.fault(), fault.t_s);
    assert!((0.0..=50.0).contains(&delay_ms), "{delay_ms} ms");
    assert!(
        ["loss_of_lock", "handover"].contains(&fault.fault()),
        "{}",
        fault.fault()
    );
}

/// Motor B's start to 1500 r/min with the drive's model of the flux 20 % high and of the
/// inductances 30 % low (a cell of `cargo xtask robustness`): the current-model MRAS adapts its
/// speed to the EMF it expects and its angle falls behind through a fifth of rated speed,
/// until the speed loop pushes its limit's torque into a frame turning against the rotor.
/// The estimate then slows against that torque; with its health figure high the drive names
/// the loss before the angle error passes a quarter turn. Without that check the stall was
/// named 90 ms after the slip, which the random family's judge counts as silent.
#[test]
fn a_model_flux_20_percent_high_that_slips_in_the_ramp_is_named_before_the_slip() {
    let sc = example_edited(
        "b-800rpm-load.toml",
        &[
            ("duration_s = 2.0", "duration_s = 0.6"),
            ("rpm = [0.0, 0.0, 800.0]", "rpm = [0.0, 0.0, 1500.0]"),
            (
                "deadtime_compensation = true",
                "deadtime_compensation = true\nmodel_l_factor = 0.7\nmodel_flux_factor = 1.2",
            ),
        ],
    );
    let run = run_scenario(&sc).unwrap();
    let fault = first_fault(&run.rows).expect("a named fault");
    let slip = run.rows.iter().find(|r| {
        r.state == pmsm_core::DriveState::Run
            && r.angle_error_rad().abs() > std::f64::consts::FRAC_PI_2
    });
    let worst = run
        .rows
        .iter()
        .take_while(|r| r.t_s < fault.t_s)
        .filter(|r| r.state == pmsm_core::DriveState::Run)
        .map(|r| r.angle_error_rad().abs())
        .fold(0.0, f64::max);
    println!(
        "{} at {:.4} s; angle error up to {worst:.2} rad before it; the first past a quarter \
         turn at {:?} s",
        fault.fault(),
        fault.t_s,
        slip.map(|r| r.t_s)
    );
    assert_eq!(fault.fault(), "loss_of_lock");
    assert!((0.2..0.35).contains(&fault.t_s), "{} s", fault.t_s);
    assert!(worst < std::f64::consts::FRAC_PI_2, "{worst} rad");
}

#[test]
fn a_bare_400_w_servo_holds_a_step_of_half_its_rated_torque_with_the_load_observer() {
    // The same servo under half its rated torque (0.64 N·m in 1 ms), which stops its rotor in
    // 8 ms: the load observer (`DriveDesign::load_observer_rad_s`) moves the speed loop's
    // output with the load a period after the step. Without it the rotor turned back and the
    // drive ended in `loss_of_lock` 10 ms after the step.
    let half = [("nm = [0.0, 0.0, 1.27]", "nm = [0.0, 0.0, 0.638]")];
    let run = run_scenario(&example_edited("servo-400w-load-step.toml", &half)).unwrap();
    assert!(first_fault(&run.rows).is_none());
    let settled = window(&run.rows, 1.05, 1.2);
    let worst = max_speed_off(&settled, 1500.0);
    let rms = rms_angle(&settled);
    println!("after the step: speed within {worst:.1} r/min, angle {rms:.4} rad rms");
    assert!(worst <= 75.0 && rms <= 0.05, "{worst} r/min, {rms} rad");
    let off = [
        ("nm = [0.0, 0.0, 1.27]", "nm = [0.0, 0.0, 0.638]"),
        ("[initial]", "[control]\nload_observer = false\n\n[initial]"),
    ];
    let run = run_scenario(&example_edited("servo-400w-load-step.toml", &off)).unwrap();
    let fault = first_fault(&run.rows).expect("without the observer, a named fault");
    println!(
        "without the observer: {} at {:.4} s",
        fault.fault(),
        fault.t_s
    );
    assert!(fault.t_s > 1.0 && fault.t_s < 1.05, "{}", fault.t_s);
}

#[test]
fn a_gimbal_motor_without_its_load_holds_half_its_rated_torque_on_the_stiff_loop() {
    // The GM4108H-120T gimbal motor of examples/published/motors.toml (11 pole pairs, 5.55 Ω,
    // τ_m 3 ms) at half its rated speed, a step of half its rated torque in 1 ms, with the
    // defaults (the NLO): above twice the handover speed its speed loop runs at 4/τ_b within
    // 0.01/T_s (`DriveDesign::speed_stiff_rad_s`), which answers before the load turns the
    // rotor back (at 0.005/T_s it did not: `loss_of_lock` 11 ms after the step).
    let text = "duration_s = 1.5\n\
        motor = { name = \"GM4108H-120T\", pole_pairs = 11, rs_ohm = 5.55, ld_h = 0.0014, \
        lq_h = 0.0014, flux_wb = 0.01856, j_kg_m2 = 1.5e-5, b_nm_s = 4.8e-5, \
        rated_current_a = 0.35, rated_speed_rpm = 300.0 }\n\
        [inverter]\nvdc_v = 24.0\npwm_hz = 25000.0\ndead_time_s = 5e-7\nmodel = \"switching\"\n\
        [speed_ref]\nt_s = [0.0, 0.6, 0.7]\nrpm = [0.0, 0.0, 150.0]\n\
        [load]\nt_s = [0.0, 1.0, 1.001]\nnm = [0.0, 0.0, 0.0757]\n";
    let run = run_scenario(&scenario_text("gimbal-load-step", text)).unwrap();
    assert!(first_fault(&run.rows).is_none());
    let settled = window(&run.rows, 1.2, 1.5);
    let worst = max_speed_off(&settled, 150.0);
    let rms = rms_angle(&settled);
    println!("after the step: speed within {worst:.2} r/min, angle {rms:.4} rad rms");
    assert!(worst <= 15.0 && rms <= 0.15, "{worst} r/min, {rms} rad");
}

#[test]
fn a_rotor_driven_backwards_ends_in_a_named_fault_within_100_ms() {
    // The 24 V servo at +90 r/min, known start, a load above its rated torque from 0.2 s: for
    // each estimator, the first sample with the true speed below zero after the load, and
    // the first fault.
    // The current-model MRAS follows the rotor backwards (driven_backwards) or loses it
    // (loss_of_lock, with its design gains).
    // A back-EMF estimator whose estimate follows the rotor backwards makes the drive try to
    // turn it back through the open loop (drive/startup.rs, reversal): the load wins and that
    // reversal's handover check trips (driven_backwards if the estimate still turns
    // backwards then, handover otherwise; the rotor, 2e-5 kg·m² under 0.5 N·m, may reach
    // −3500 r/min first, and the overspeed trip takes it: the AO's, and the NLO's 26 ms after
    // it turned with the current loops at 0.1/T_s).
    for (observer, expected) in [
        ("mras-current", &["driven_backwards", "loss_of_lock"][..]),
        // Or the estimate settles on the mirror solution (the rotor's speed with the other sign,
        // its angle half a turn off) and its angle turns against its speed: loss_of_lock.
        (
            "nlo",
            &["driven_backwards", "handover", "overspeed", "loss_of_lock"][..],
        ),
        (
            "ao",
            &["driven_backwards", "handover", "overspeed", "loss_of_lock"][..],
        ),
        // The MRAS on the EMF holds the reference at its least speed (300 r/min here).
        (
            "mras-emf",
            &["driven_backwards", "handover", "overspeed", "loss_of_lock"][..],
        ),
    ] {
        let sc = example_edited(
            "servo-24v-backwards.toml",
            &[(
                "observer = \"mras-current\"",
                &format!("observer = \"{observer}\""),
            )],
        );
        let run = run_scenario(&sc).unwrap();
        let back = run
            .rows
            .iter()
            .find(|r| r.t_s > 0.2 && r.speed_rpm < 0.0)
            .expect("the load drives the rotor backwards");
        let fault = first_fault(&run.rows).expect("a fault");
        let delay_ms = 1e3 * (fault.t_s - back.t_s);
        println!(
            "{observer}: backwards from {:.4} s, {} at {:.4} s ({delay_ms:.1} ms, rotor at {:.0} r/min)",
            back.t_s,
            fault.fault(),
            fault.t_s,
            fault.speed_rpm
        );
        // Before the load the drive ran at its reference without a fault.
        assert!(
            fault.t_s > 0.2,
            "{observer}: {} at {} s",
            fault.fault(),
            fault.t_s
        );
        assert!(delay_ms < 100.0, "{observer}: {delay_ms} ms");
        assert!(
            expected.contains(&fault.fault()),
            "{observer}: {} not in {expected:?}",
            fault.fault()
        );
    }
}

#[test]
fn a_locked_rotor_ends_in_a_named_fault_within_100_ms_with_every_estimator() {
    // Motor A at 1146 r/min, no load, each estimator; the rotor locked at 2.4 s. (Motor B's
    // locked rotor under the current-model MRAS, whose estimate follows it down, is a stall:
    // tests/faults.rs.)
    for observer in ["nlo", "ao", "mras-emf", "mras-current"] {
        let sc = example_edited(
            "a-nlo-start-load.toml",
            &[
                ("observer = \"nlo\"", &format!("observer = \"{observer}\"")),
                ("duration_s = 3.0", "duration_s = 2.6"),
                ("nm = [2.0, 2.0, 5.0]", "nm = [0.0, 0.0, 0.0]"),
                ("[load]", "[faults]\nlocked_rotor_at_s = 2.4\n[load]"),
            ],
        );
        let run = run_scenario(&sc).unwrap();
        let fault = first_fault(&run.rows).expect("a fault");
        let delay_ms = 1e3 * (fault.t_s - 2.4);
        println!(
            "{observer}: {} {delay_ms:.1} ms after the lock",
            fault.fault()
        );
        assert!(
            (0.0..100.0).contains(&delay_ms),
            "{observer}: {delay_ms} ms"
        );
        assert!(
            ["loss_of_lock", "stall", "driven_backwards"].contains(&fault.fault()),
            "{observer}: {}",
            fault.fault()
        );
    }
}

#[test]
fn the_plot_shows_no_angle_error_before_the_estimator_runs() {
    use pmsm_cli::commands::simulate::{draw, plotted_angle_error};
    use pmsm_core::DriveState;
    // Motor B from 137°: during the detection the estimate is not an estimate yet (the raw
    // difference is about −2.4 rad), nor during the dead-time calibration that follows; the
    // plot leaves them out, and shows the closed loop's error.
    let text = MOTOR_B_SHORT
        .replace("duration_s = 0.8", "duration_s = 0.4")
        .replace("[speed_ref]", "[initial]\ntheta_e_deg = 137.0\n[speed_ref]");
    let sc = scenario_text("plot", &text);
    let run = run_scenario(&sc).unwrap();
    let ipd: Vec<_> = run
        .rows
        .iter()
        .filter(|r| r.state == DriveState::Ipd)
        .collect();
    assert!(ipd.len() > 10, "{} detection samples", ipd.len());
    let raw = ipd
        .iter()
        .fold(0.0f64, |a, r| a.max(r.angle_error_rad().abs()));
    assert!(ipd.iter().all(|r| plotted_angle_error(r).is_nan()));
    let shown: Vec<f64> = run
        .rows
        .iter()
        .map(plotted_angle_error)
        .filter(|x| x.is_finite())
        .collect();
    let worst = shown.iter().fold(0.0f64, |a, x| a.max(x.abs()));
    println!(
        "raw angle error during the detection up to {raw:.2} rad; plotted up to {worst:.3} rad"
    );
    assert!(raw > 1.0, "{raw}");
    assert!(shown.len() > run.rows.len() / 2);
    assert!(worst < 0.5, "{worst}");
    // The SVG draws it without a NaN anywhere.
    let path =
        std::env::temp_dir().join(format!("pmsm-drive-robustness-{}.svg", std::process::id()));
    draw(&path, &sc, &run.rows).unwrap();
    let svg = std::fs::read_to_string(&path).unwrap();
    std::fs::remove_file(&path).ok();
    assert!(svg.len() > 1000 && !svg.contains("NaN"));
}

/// A 1.4 kW, 320 V surface motor of the random family (`cargo xtask family 40 --seed 2`,
/// #28), reversed from half rated speed under a load that follows the direction of
/// rotation, with the IP speed loop of Khlaief, Boussak, Gossa (2012), without the low-speed
/// current and with the MRAS's plain design (`ω_n = 0.02/T_s`, 60.5 Hz, not raised for the
/// light rotor, and no low-speed schedule), the current loops at `0.05/T_s` (151.2 Hz) and
/// eq. 21's full weight on the MRAS's d-axis error: through zero speed the
/// current-model MRAS slips to the wrong side while the rotor keeps turning the old way. (The
/// drive's defaults carry it through: below.)
const LOST_REVERSAL: &str = "duration_s = 2.9\n\
    motor = { name = \"family 28\", pole_pairs = 7, rs_ohm = 2.0122711730066065, \
    ld_h = 0.002504521734108593, lq_h = 0.002504521734108593, flux_wb = 0.04944300841185866, \
    j_kg_m2 = 0.0009699618872963698, b_nm_s = 0.00033785475463329163, \
    rated_current_a = 5.544267117992307, rated_speed_rpm = 3327 }\n\
    [inverter]\nvdc_v = 320\npwm_hz = 19000\ndead_time_s = 0.00000135\nmodel = \"switching\"\n\
    [control]\nobserver = \"mras-current\"\nstartup = \"auto\"\ndeadtime_compensation = true\n\
    speed_loop = \"ip\"\nlow_speed_id_a = 0.0\nmras_low_speed_schedule = false\n\
    mras_bandwidth_hz = 60.5\ncurrent_bandwidth_hz = 151.2\nmras_d_weight = 1.0\n\
    [initial]\ntheta_e_deg = 227.280\n\
    [speed_ref]\nt_s = [0.0, 0.6, 0.76604, 2.56604, 2.89812]\n\
    rpm = [0.0, 0.0, 1663.5, 1663.5, -1663.5]\n\
    [load]\nt_s = [0.0, 2.26604, 2.26704, 2.698872, 2.765288]\n\
    nm = [0.0, 0.0, 2.442331, 2.442331, -2.442331]\n";

#[test]
fn a_lock_lost_in_a_reversal_under_load_is_named_within_100_ms() {
    // Without the current loops' tracking check this run went 0.6 s with the estimate on
    // the wrong side and no fault. The slip: the first sample whose angle error passes π/2.
    let run = run_scenario(&scenario_text("lost-reversal", LOST_REVERSAL)).unwrap();
    let slip = run
        .rows
        .iter()
        .find(|r| r.t_s > 2.5 && r.angle_error_rad().abs() > std::f64::consts::FRAC_PI_2)
        .expect("the estimate slips in the reversal");
    let fault = first_fault(&run.rows).expect("a named fault");
    let delay_ms = 1e3 * (fault.t_s - slip.t_s);
    println!(
        "slip at {:.4} s, {} at {:.4} s ({delay_ms:.1} ms)",
        slip.t_s,
        fault.fault(),
        fault.t_s
    );
    assert_eq!(fault.fault(), "loss_of_lock");
    assert!((-20.0..=100.0).contains(&delay_ms), "{delay_ms} ms");
}

/// The same reversal with the current-model MRAS's low-speed gain schedule on (`[control]
/// mras_low_speed_schedule = true`, docs/khlaief2012.md), then held at −half rated speed
/// for 0.5 s: no fault. Through zero speed the estimate still slips, by one electrical turn,
/// past a quarter turn for under 15 ms (8.7 ms measured), and locks again from the other side;
/// over the last 0.4 s the angle error is within 0.01 rad rms and the speed within 0.1 %.
#[test]
fn the_low_speed_schedule_carries_that_reversal_through() {
    let text = LOST_REVERSAL
        .replace("duration_s = 2.9", "duration_s = 3.4")
        .replace("2.89812]", "2.89812, 3.4]")
        .replace("-1663.5]", "-1663.5, -1663.5]")
        .replace(
            "mras_low_speed_schedule = false\n",
            "mras_low_speed_schedule = true\n",
        );
    let run = run_scenario(&scenario_text("scheduled-reversal", &text)).unwrap();
    assert!(first_fault(&run.rows).is_none());
    let slipped: Vec<f64> = run
        .rows
        .iter()
        .filter(|r| r.t_s > 2.5 && r.angle_error_rad().abs() > std::f64::consts::FRAC_PI_2)
        .map(|r| r.t_s)
        .collect();
    let slip_ms = slipped
        .last()
        .zip(slipped.first())
        .map_or(0.0, |(b, a)| 1e3 * (b - a));
    let tail = window(&run.rows, 3.0, 3.4);
    println!(
        "slip {slip_ms:.1} ms; then {:.4} rad rms, speed {:.4} %",
        rms_angle(&tail),
        100.0 * speed_err(&tail)
    );
    assert!(slip_ms < 15.0, "{slip_ms} ms");
    assert!(rms_angle(&tail) <= 0.01, "{}", rms_angle(&tail));
    assert!(speed_err(&tail) <= 0.001, "{}", speed_err(&tail));
}

/// The same reversal with the drive's defaults (the reference weighed by a half in the speed
/// loop, the low-speed current: docs/drive.md), then held at −half rated speed for 0.5 s: no
/// fault, the estimate never a quarter turn off the rotor, and over the last 0.4 s the angle
/// error within 0.01 rad rms and the speed within 0.1 %.
#[test]
fn the_low_speed_current_carries_that_reversal_through() {
    let text = LOST_REVERSAL
        .replace("duration_s = 2.9", "duration_s = 3.4")
        .replace("2.89812]", "2.89812, 3.4]")
        .replace("-1663.5]", "-1663.5, -1663.5]")
        .replace("speed_loop = \"ip\"\nlow_speed_id_a = 0.0\n", "")
        .replace("current_bandwidth_hz = 151.2\nmras_d_weight = 1.0\n", "");
    let run = run_scenario(&scenario_text("default-reversal", &text)).unwrap();
    assert!(first_fault(&run.rows).is_none());
    let worst = run
        .rows
        .iter()
        .filter(|r| r.t_s > 2.5)
        .fold(0.0f64, |a, r| a.max(r.angle_error_rad().abs()));
    let tail = window(&run.rows, 3.0, 3.4);
    println!(
        "largest angle error {worst:.3} rad; then {:.4} rad rms, speed {:.4} %",
        rms_angle(&tail),
        100.0 * speed_err(&tail)
    );
    assert!(worst < std::f64::consts::FRAC_PI_4, "{worst} rad");
    assert!(rms_angle(&tail) <= 0.01, "{}", rms_angle(&tail));
    assert!(speed_err(&tail) <= 0.001, "{}", speed_err(&tail));
}

/// A 5 kW, 540 V interior motor of the random family (`cargo xtask family 40 --seed 5`, #39:
/// `L_q/L_d` = 2.09, 14 kHz, 1.91 µs of dead time), started by detection, run at half rated
/// speed, then loaded to 60 % of rated torque. With the compensation's signs from the current
/// reference the drive settles into a cycle at the electrical frequency (a DC current in the
/// stationary frame whose distortion the reference's signs misjudge), ±24 r/min of estimated
/// speed at no load, which grew under the load into `loss_of_lock` with the current loops at
/// `0.05/T_s` and eq. 21's full weight on the MRAS's d-axis error, and stays (σ 15 r/min at no
/// load) without a fault with the drive's faster loops; with the measured current's signs
/// (`[control] deadtime_current = "measured"`) the cycle is gone. The default,
/// the reference's signs at light load and the measured under load
/// (`"measured-under-load"`), keeps the no-load cycle and holds the load.
const SALIENT_540V: &str = "duration_s = 2.1\n\
    motor = { name = \"family 39\", pole_pairs = 3, rs_ohm = 0.41285354949128833, \
    ld_h = 0.005418573234970563, lq_h = 0.011317155400954253, flux_wb = 0.24570648451733323, \
    j_kg_m2 = 0.015566672329631026, b_nm_s = 0.0019529172850882984, \
    rated_current_a = 13.388368780955178, rated_speed_rpm = 2323 }\n\
    [inverter]\nvdc_v = 540\npwm_hz = 14000\ndead_time_s = 0.00000191\nmodel = \"switching\"\n\
    [control]\nobserver = \"mras-current\"\nstartup = \"auto\"\ndeadtime_compensation = true\n\
    [initial]\ntheta_e_deg = 175.444\n\
    [speed_ref]\nt_s = [0.0, 0.6, 0.961769, 2.1]\nrpm = [0.0, 0.0, 1161.5, 1161.5]\n\
    [load]\nt_s = [0.0, 1.461769, 1.462769, 2.1]\nnm = [0.0, 0.0, 12.560966, 12.560966]\n";

/// `scenario` with `[control] deadtime_current = source`.
fn with_deadtime_current(scenario: &str, source: &str) -> String {
    with_control(scenario, &format!("deadtime_current = \"{source}\"\n"))
}

/// `scenario` with `lines` added to its `[control]` (after `deadtime_compensation = true`).
fn with_control(scenario: &str, lines: &str) -> String {
    scenario.replace(
        "deadtime_compensation = true\n",
        &format!("deadtime_compensation = true\n{lines}"),
    )
}

#[test]
fn the_measured_currents_signs_hold_a_salient_540_v_motor() {
    let sigma = |rows: &[&pmsm_cli::commands::simulate::Row]| std_dev(rows, |r| r.speed_est_rpm);
    let with = |source: &str| with_deadtime_current(SALIENT_540V, source);
    // The reference's signs with the current loops at 0.05/T_s (111.4 Hz) and eq. 21's full
    // weight on the MRAS's d-axis error.
    let former = with_control(
        &with("reference"),
        "current_bandwidth_hz = 111.4\nmras_d_weight = 1.0\ntracking = false\n",
    );
    let reference = run_scenario(&scenario_text("salient-540v-reference", &former)).unwrap();
    let no_load = window(&reference.rows, 1.2, 1.46);
    let fault = first_fault(&reference.rows).map(|r| (r.fault(), r.t_s));
    println!(
        "reference signs, former loops: no-load estimated speed σ {:.1} r/min, fault {fault:?}",
        sigma(&no_load)
    );
    assert!(sigma(&no_load) > 15.0);
    assert_eq!(fault.map(|f| f.0), Some("loss_of_lock"));
    // With the drive's loops the cycle no longer trips, but it stays: the signs still matter.
    let now = run_scenario(&scenario_text("salient-540v-ref-now", &with("reference"))).unwrap();
    let fault = first_fault(&now.rows).map(|r| (r.fault(), r.t_s));
    let no_load = window(&now.rows, 1.2, 1.46);
    println!(
        "reference signs: no-load estimated speed σ {:.1} r/min, fault {fault:?}",
        sigma(&no_load)
    );
    assert!(fault.is_none());
    assert!(sigma(&no_load) > 10.0);

    let measured =
        run_scenario(&scenario_text("salient-540v-measured", &with("measured"))).unwrap();
    assert!(first_fault(&measured.rows).is_none());
    let (no_load, loaded) = (
        window(&measured.rows, 1.2, 1.46),
        window(&measured.rows, 1.8, 2.1),
    );
    println!(
        "measured signs: no-load estimated speed σ {:.2} r/min, angle {:.4} rad rms; loaded \
         {:.4} rad rms, speed error {:.3} %",
        sigma(&no_load),
        rms_angle(&no_load),
        rms_angle(&loaded),
        speed_err(&loaded)
    );
    assert!(sigma(&no_load) < 6.0);
    assert!(rms_angle(&no_load) < 0.01);
    assert!(rms_angle(&loaded) < 0.02);

    // The default: the reference's signs below six bands of q current, the measured above.
    let default = run_scenario(&scenario_text("salient-540v-default", SALIENT_540V)).unwrap();
    let fault = first_fault(&default.rows).map(|r| (r.fault(), r.t_s));
    let (no_load, loaded) = (
        window(&default.rows, 1.2, 1.46),
        window(&default.rows, 1.8, 2.1),
    );
    println!(
        "default: no-load estimated speed σ {:.2} r/min; loaded {:.4} rad rms, speed error \
         {:.3} %, fault {fault:?}",
        sigma(&no_load),
        rms_angle(&loaded),
        speed_err(&loaded)
    );
    assert!(fault.is_none());
    assert!(rms_angle(&loaded) < 0.02);
    assert!(speed_err(&loaded) < 0.01);
}

/// Family seed 3 #23: a 320 V surface motor, 7 pole pairs, the NLO with the defaults: the
/// family's manoeuvre, reversed under 60 % of rated torque that opposes the motion and changes
/// sign mid-ramp.
const SURFACE_320V_NLO: &str = "duration_s = 4.615267\n\
    motor = { name = \"family 23\", pole_pairs = 7, rs_ohm = 0.6496940474133075, \
    ld_h = 0.002166987411651082, lq_h = 0.002166987411651082, flux_wb = 0.06711119335295594, \
    j_kg_m2 = 0.002540272634386322, b_nm_s = 0.00017804595980845547, \
    rated_current_a = 6.833417914857802, rated_speed_rpm = 3111 }\n\
    [inverter]\nvdc_v = 320\npwm_hz = 19000\ndead_time_s = 0.00000177\nmodel = \"switching\"\n\
    [control]\nobserver = \"nlo\"\nstartup = \"auto\"\ndeadtime_compensation = true\n\
    [initial]\ntheta_e_deg = 275.753\n\
    [speed_ref]\nt_s = [0.0, 0.6, 0.843053, 2.643053, 3.12916, 3.62916, 4.115267]\n\
    rpm = [0.0, 0.0, 1555.5, 1555.5, -1555.5, -1555.5, 1555.5]\n\
    [load]\nt_s = [0.0, 1.343053, 1.344053, 1.843053, 1.844053, 2.343053, 2.344053, 2.837496, \
    2.934717, 3.823603, 3.920824]\n\
    nm = [0.0, 0.0, 4.085907, 4.085907, 0.0, 0.0, 4.085907, 4.085907, -4.085907, -4.085907, \
    4.085907]\n";

#[test]
fn the_back_emf_estimators_reverse_under_load_with_the_measured_signs() {
    // The default with the NLO: the measured currents' signs.
    let measured = run_scenario(&scenario_text("surface-320v-nlo", SURFACE_320V_NLO)).unwrap();
    assert!(first_fault(&measured.rows).is_none());
    let reversed = window(&measured.rows, 3.3, 3.6);
    println!(
        "measured signs: reversed under load {:.4} rad rms, speed error {:.3} %",
        rms_angle(&reversed),
        100.0 * speed_err(&reversed)
    );
    assert!(rms_angle(&reversed) < 0.02);
    assert!(speed_err(&reversed) < 0.01);

    // Out of the second reversal (its closed loop's first 0.115 s, the reference still
    // ramping): 0.043 rad rms measured.
    let back = window(&measured.rows, 4.0, 4.115);
    assert!(rms_angle(&back) < 0.1, "{}", rms_angle(&back));

    // The reference's signs: through the open-loop reversal the current leaves its reference.
    // With the current loops at 0.05/T_s (151.2 Hz) and the reversal begun at the sampled
    // estimated speed the NLO turned to the mirror angle and the reversal's handover check
    // tripped (`handover` at 3.110 s); begun at the filtered speed it holds, but comes out of
    // the second reversal 0.20 rad rms off (0.083 with the loops at 0.1/T_s).
    let text = with_control(
        &with_deadtime_current(SURFACE_320V_NLO, "reference"),
        "current_bandwidth_hz = 151.2\n",
    );
    let reference = run_scenario(&scenario_text("surface-320v-nlo-reference", &text)).unwrap();
    let fault = first_fault(&reference.rows).map(|r| (r.fault(), r.t_s));
    let back_ref = window(&reference.rows, 4.0, 4.115);
    println!(
        "out of the second reversal: measured signs {:.4} rad rms; reference signs {:.4} rad rms, fault {fault:?}",
        rms_angle(&back),
        rms_angle(&back_ref)
    );
    assert!(
        fault.is_some() || rms_angle(&back_ref) > 0.15,
        "{}",
        rms_angle(&back_ref)
    );
}

/// The MRAS on the EMF through the same reversal: its estimate used to lag the rotor as the
/// current limit decelerated it, the open-loop reversal then began at a speed the rotor no
/// longer had, and the load drove the rotor backwards (`driven_backwards` at 3.059 s). With its
/// integral taken of `ε/ω̂_AO` and its adaptation at `0.025/T_s` (docs/solsona2000.md §5) it
/// reverses and holds in most runs. The second reversal, against the load that changed sign,
/// is marginal: over the bus from 318 to 322 V and the start from 270° to 281° it holds in 8
/// of 11 runs, and each of the others names the lost rotor (`loss_of_lock` or `handover`)
/// before the closed loop runs on.
#[test]
fn the_mras_on_the_emf_reverses_that_motor_under_load() {
    let text = SURFACE_320V_NLO.replace("observer = \"nlo\"", "observer = \"mras-emf\"");
    let runs = [318.0, 319.0, 319.5, 320.0, 320.5, 321.0, 322.0]
        .map(|v| (v, 275.753))
        .into_iter()
        .chain([270.0, 273.0, 278.0, 281.0].map(|t| (320.0, t)));
    let mut held = 0;
    for (k, (vdc, theta)) in runs.enumerate() {
        let text = text
            .replace("vdc_v = 320\n", &format!("vdc_v = {vdc}\n"))
            .replace("theta_e_deg = 275.753", &format!("theta_e_deg = {theta}"));
        let run =
            run_scenario(&scenario_text(&format!("surface-320v-mras-emf-{k}"), &text)).unwrap();
        let fault = first_fault(&run.rows).map(|r| (r.fault(), r.t_s));
        let reversed = window(&run.rows, 3.3, 3.6);
        let back = window(&run.rows, 4.3, 4.6);
        println!(
            "{vdc} V, {theta}°: fault {fault:?}; reversed under load {:.4} rad rms, speed \
             error {:.3} %; back {:.4} rad rms",
            rms_angle(&reversed),
            100.0 * speed_err(&reversed),
            rms_angle(&back)
        );
        // The first reversal, with the load opposing, holds in every run.
        assert!(rms_angle(&reversed) < 0.02 && speed_err(&reversed) < 0.01);
        match fault {
            None => {
                assert!(rms_angle(&back) < 0.02, "{}", rms_angle(&back));
                held += 1;
            }
            Some((name, t)) => {
                assert!(matches!(name, "loss_of_lock" | "handover"), "{name}");
                // Named within the second reversal's closed loop or its handover.
                assert!((3.9..4.2).contains(&t), "{t} s");
            }
        }
    }
    assert!(held >= 7, "held in {held} of 11");
}

/// Family seed 12 #23: a 540 V surface motor, 2 pole pairs, 39 ms mechanical time constant,
/// the MRAS on the EMF with the defaults: the family's manoeuvre, reversed under 60 % of rated
/// torque that opposes the motion and changes sign mid-ramp.
const SURFACE_540V_MRAS_EMF: &str = "duration_s = 3.792512\n\
    motor = { name = \"family 23\", pole_pairs = 2, rs_ohm = 2.954297424029833, \
    ld_h = 0.010055611039489567, lq_h = 0.010055611039489567, flux_wb = 0.38308319289498555, \
    j_kg_m2 = 0.0015907780792747878, b_nm_s = 0.000898439088830342, \
    rated_current_a = 8.463205640259869, rated_speed_rpm = 3241 }\n\
    [inverter]\nvdc_v = 540\npwm_hz = 12000\ndead_time_s = 0.00000227\nmodel = \"switching\"\n\
    [control]\nobserver = \"mras-emf\"\nstartup = \"auto\"\ndeadtime_compensation = true\n\
    [initial]\ntheta_e_deg = 126.222\n\
    [speed_ref]\nt_s = [0.0, 0.6, 0.678502, 2.478502, 2.635507, 3.135507, 3.292512]\n\
    rpm = [0.0, 0.0, 1620.5, 1620.5, -1620.5, -1620.5, 1620.5]\n\
    [load]\nt_s = [0.0, 1.178502, 1.179502, 1.678502, 1.679502, 2.178502, 2.179502, 2.541304, \
    2.572705, 3.198309, 3.22971]\n\
    nm = [0.0, 0.0, 8.253069, 8.253069, 0.0, 0.0, 8.253069, 8.253069, -8.253069, -8.253069, \
    8.253069]\n";

/// The open-loop reversal restarts the estimator at zero speed and holds the new direction
/// until its handover, as the start does. Without the hold the AO inside the MRAS, restarted
/// 0.46 rad off the rotor's angle, saw its EMF turn the old way while it converged and took
/// that direction: the estimate turned one way, the rotor the other, and the load drove it
/// backwards (`driven_backwards` at 2.706 s).
#[test]
fn a_reversal_holds_the_new_direction_until_its_handover() {
    let run = run_scenario(&scenario_text(
        "surface-540v-mras-emf",
        SURFACE_540V_MRAS_EMF,
    ))
    .unwrap();
    let fault = first_fault(&run.rows).map(|r| (r.fault(), r.t_s));
    let reversed = window(&run.rows, 2.9355, 3.1355);
    let back = window(&run.rows, 3.5925, 3.7925);
    println!(
        "fault {fault:?}; reversed under load {:.4} rad rms, speed error {:.3} %; back {:.4} rad rms, {:.3} %",
        rms_angle(&reversed),
        100.0 * speed_err(&reversed),
        rms_angle(&back),
        100.0 * speed_err(&back)
    );
    assert!(fault.is_none());
    assert!(rms_angle(&reversed) < 0.01 && rms_angle(&back) < 0.01);
    assert!(speed_err(&reversed) < 0.02 && speed_err(&back) < 0.02);
}

/// Family seed 8 #8: a 540 V surface motor, 2 pole pairs, 64 ms mechanical time constant, the
/// AO with the defaults, brought back from −half rated speed under 60 % of rated torque that
/// turns to help the motion mid-ramp.
const SURFACE_540V_AO: &str = "duration_s = 4.04\n\
    motor = { name = \"family 8\", pole_pairs = 2, rs_ohm = 6.651622952478391, \
    ld_h = 0.16376512962727718, lq_h = 0.16376512962727718, flux_wb = 1.1850347822038392, \
    j_kg_m2 = 0.005750546970894597, b_nm_s = 0.0015811642636608181, \
    rated_current_a = 2.0557462752514946, rated_speed_rpm = 1097 }\n\
    [inverter]\nvdc_v = 540\npwm_hz = 9000\ndead_time_s = 0.00000261\nmodel = \"switching\"\n\
    [control]\nobserver = \"ao\"\nstartup = \"auto\"\ndeadtime_compensation = true\n\
    [initial]\ntheta_e_deg = 265.701\n\
    [speed_ref]\nt_s = [0.0, 0.6, 0.727831, 2.527831, 2.783494, 3.283494, 3.539157]\n\
    rpm = [0.0, 0.0, 548.5, 548.5, -548.5, -548.5, 548.5]\n\
    [load]\nt_s = [0.0, 1.227831, 1.228831, 1.727831, 1.728831, 2.227831, 2.228831, 2.630097, \
    2.681229, 3.385759, 3.436892]\n\
    nm = [0.0, 0.0, 6.201377, 6.201377, 0.0, 0.0, 6.201377, 6.201377, -6.201377, -6.201377, \
    6.201377]\n";

#[test]
fn a_rotor_held_back_by_the_current_limit_is_said() {
    let run = run_scenario(&scenario_text("surface-540v-ao", SURFACE_540V_AO)).unwrap();
    assert!(first_fault(&run.rows).is_none());
    // Back from −548 r/min the reference ramps faster than the IP loop at 40 % of the default
    // bandwidth follows, and then than the current limit (the rated peak, 2.907 A) carries the
    // rotor against the load. Off the reference by more than 20 % of rated speed (219 r/min),
    // the drive's estimate is within 5 % of rated of the rotor's speed; every such sample with
    // the speed loop at its limit is said (`SpeedRefLimit::AtCurrentLimit`), and what is not
    // said lasts less than the family's 0.2 s of a silent run.
    let rated = 1097.0;
    let back = window(&run.rows, 3.283, 3.84);
    // In the closed loop, as the family judges a silent run (in the open loop of the reversal
    // the state says what the drive does, and the estimate near zero speed is not its frame).
    let off: Vec<_> = back
        .iter()
        .filter(|r| r.state == pmsm_core::DriveState::Run)
        .filter(|r| (r.speed_rpm - r.speed_ref_rpm).abs() > 0.2 * rated)
        .collect();
    // (2100 samples before the speed loop's bandwidth was raised for light rotors,
    // `SPEED_STIFFNESS`, about 1500 since, counting the open loop's; 390 of the closed loop's
    // with the load observer, which carries the rotor against the load sooner: 43 ms.)
    assert!(off.len() > 300, "{} samples off", off.len());
    assert!(
        off.iter()
            .all(|r| (r.speed_est_rpm - r.speed_rpm).abs() < 0.05 * rated)
    );
    // The limit is 2.0557 A rms · √2 = 2.90726 A.
    let limited: Vec<_> = off.iter().filter(|r| r.i_q_ref_a.abs() > 2.907).collect();
    let said = |r: &pmsm_cli::commands::simulate::Row| {
        r.current_limited_est_rpm
            .is_some_and(|est| (est - r.speed_rpm).abs() < 0.05 * rated)
    };
    assert!(
        limited.len() > 200,
        "{} samples at the limit",
        limited.len()
    );
    // Said from the task period after the loop reaches its limit: at most one period unsaid.
    let unsaid = limited.iter().filter(|r| !said(r)).count();
    assert!(
        unsaid <= pmsm_core::TASK_PERIOD as usize,
        "{unsaid} samples unsaid"
    );
    let mut longest = 0.0f64;
    let mut since: Option<f64> = None;
    for r in &back {
        let unsaid = (r.speed_rpm - r.speed_ref_rpm).abs() > 0.2 * rated && !said(r);
        since = match (unsaid, since) {
            (true, None) => Some(r.t_s),
            (true, s) => s,
            (false, _) => None,
        };
        if let Some(t0) = since {
            longest = longest.max(r.t_s - t0);
        }
    }
    println!(
        "{} samples off the reference by more than 219 r/min, {} at the current limit and said; \
         longest stretch off and not said {longest:.3} s",
        off.len(),
        limited.len()
    );
    assert!(longest < 0.2);
    // Back at the reference, the limit is no longer said.
    let steady = window(&run.rows, 3.84, 4.04);
    assert!(steady.iter().all(|r| r.current_limited_est_rpm.is_none()));
    assert!(speed_err(&steady) < 0.02);
}
