//! What the C interface reports besides the duties: every fault and IPD check under the
//! core's own code, the detected initial position, telemetry, the overrun report, and the
//! configuration messages that name the accepted range.
#![allow(unsafe_code)] // calling the extern "C" functions

mod common;
use common::{init, step_row, storage};

use common::scenario::{self, FAULT_STEP, Word};
use core::ffi::CStr;
use core::ptr::null_mut;
use pmsm_core::Angle;
use pmsm_core::IpdFault;
use pmsm_core::Pu;
use pmsm_core::{DriveState, Fault};
use pmsm_ffi::*;

fn message(c: &pmsm_config_t) -> String {
    let mut buf = [0 as core::ffi::c_char; 300];
    // SAFETY: valid config and buffer.
    unsafe { pmsm_config_error_message(c, buf.as_mut_ptr(), buf.len()) };
    // SAFETY: NUL-terminated by the function.
    unsafe { CStr::from_ptr(buf.as_ptr()) }
        .to_string_lossy()
        .into_owned()
}

fn name(p: *const core::ffi::c_char) -> String {
    // SAFETY: the name functions return static NUL-terminated strings.
    unsafe { CStr::from_ptr(p) }.to_string_lossy().into_owned()
}

const TURN: f64 = 4_294_967_296.0;

/// One control sample through the C ABI: the interrupt step, then the task when it is due.
///
/// # Safety
/// `d` is a live drive handle.
unsafe fn step(d: *mut pmsm_drive_t, input: &pmsm_input_t, out: &mut pmsm_output_t) {
    // SAFETY: forwarded contract; valid structs.
    unsafe {
        assert_eq!(pmsm_step(d, input, out), pmsm_status_t::PMSM_OK);
        if out.task_due != 0 {
            assert_eq!(pmsm_task(d), pmsm_status_t::PMSM_OK);
        }
    }
}

/// The samples from a task's command to the interrupt side's acting on it, at most: the
/// command answers the period it was given in and takes effect at the end of the next.
const FOLLOW: usize = 2 * PMSM_TASK_PERIOD as usize;

#[test]
fn every_fault_state_and_ipd_check_has_the_cores_code_and_name() {
    use pmsm_fault_t::*;
    let faults = [
        (Fault::OverCurrent(Pu::ZERO), PMSM_FAULT_OVERCURRENT),
        (
            Fault::BusUnderVoltage(Pu::ZERO),
            PMSM_FAULT_BUS_UNDERVOLTAGE,
        ),
        (Fault::BusOverVoltage(Pu::ZERO), PMSM_FAULT_BUS_OVERVOLTAGE),
        (
            Fault::InitialPosition(IpdFault::BusLow),
            PMSM_FAULT_INITIAL_POSITION,
        ),
        (Fault::Handover(Angle::ZERO, Pu::ZERO), PMSM_FAULT_HANDOVER),
        (Fault::CurrentSensor(None), PMSM_FAULT_CURRENT_SENSOR),
        (Fault::PhaseLoss(1), PMSM_FAULT_PHASE_LOSS),
        (Fault::Stall, PMSM_FAULT_STALL),
        (Fault::LossOfLock, PMSM_FAULT_LOSS_OF_LOCK),
        (Fault::Overrun, PMSM_FAULT_OVERRUN),
    ];
    for (f, c) in faults {
        assert_eq!(c as u32, u32::from(f.code()), "{}", f.name());
        assert_eq!(fault_code(&DriveState::Fault(f)).0, c as u32);
        assert_eq!(name(pmsm_fault_name(c as u32)), f.name());
    }
    // Ten faults of the core, ten named codes: none left to a catch-all.
    assert_eq!(PMSM_FAULT_OVERRUN as u32, 10);
    assert_eq!(name(pmsm_fault_name(0)), "none");
    assert_eq!(name(pmsm_fault_name(11)), "unknown");
    assert_eq!(fault_code(&DriveState::Run), (0, 0));
    // The values: the current sensor's channel (-1 for the sum), the phase, the IPD check.
    assert_eq!(
        fault_code(&DriveState::Fault(Fault::CurrentSensor(Some(2)))),
        (6, 2)
    );
    assert_eq!(
        fault_code(&DriveState::Fault(Fault::CurrentSensor(None))),
        (6, -1)
    );
    assert_eq!(fault_code(&DriveState::Fault(Fault::PhaseLoss(1))), (7, 1));
    assert_eq!(
        fault_code(&DriveState::Fault(Fault::InitialPosition(
            IpdFault::NoCurrent(Pu::ZERO)
        ))),
        (4, 2)
    );

    use pmsm_state_t::*;
    let states = [
        (DriveState::Idle, PMSM_STATE_IDLE),
        (DriveState::Ipd, PMSM_STATE_IPD),
        (DriveState::Align, PMSM_STATE_ALIGN),
        (DriveState::OpenLoop, PMSM_STATE_OPEN_LOOP),
        (DriveState::Run, PMSM_STATE_RUN),
        (DriveState::Fault(Fault::Stall), PMSM_STATE_FAULT),
    ];
    for (s, c) in states {
        assert_eq!(c as u32, u32::from(s.code()));
        assert_eq!(state_code(&s), c as u32);
    }

    use pmsm_ipd_fault_t::*;
    let ipd = [
        (IpdFault::OverCurrent(Pu::ZERO), PMSM_IPD_FAULT_OVERCURRENT),
        (IpdFault::NoCurrent(Pu::ZERO), PMSM_IPD_FAULT_NO_CURRENT),
        (
            IpdFault::LowSaliency {
                modulation: Pu::ZERO,
                sum: Pu::ZERO,
            },
            PMSM_IPD_FAULT_LOW_SALIENCY,
        ),
        (
            IpdFault::NoPolarity {
                along: Pu::ZERO,
                opposite: Pu::ZERO,
            },
            PMSM_IPD_FAULT_NO_POLARITY,
        ),
        (IpdFault::BusLow, PMSM_IPD_FAULT_BUS_LOW),
    ];
    for (f, c) in ipd {
        assert_eq!(c as u32, u32::from(f.code()));
        assert_eq!(name(pmsm_ipd_fault_name(c as u32)), f.name());
    }
    assert_eq!(PMSM_IPD_FAULT_NONE as u32, 0);
}

/// Replays the recorded scenario through the C ABI up to (not including) step `end`.
fn replay_until(
    rows: &[[i32; scenario::WORDS]],
    end: usize,
) -> (Box<pmsm_storage_t>, *mut pmsm_drive_t) {
    let mut s = storage();
    let d = init(&mut s, &scenario::config_c()).expect("init");
    for row in rows.iter().take(end) {
        // SAFETY: `d` is a live handle.
        unsafe { step_row(d, row) };
    }
    (s, d)
}

#[test]
fn the_detected_angle_and_the_telemetry_are_readable() {
    let rows = scenario::record();
    // Just before the injected fault: detected, started, running at 600 r/min. The telemetry
    // is read at every step of the last `WINDOW`, 71 ms (a few periods of the swing below).
    const WINDOW: usize = 1000;
    let (_s, d) = replay_until(&rows, FAULT_STEP - WINDOW);
    let mut ipd = pmsm_ipd_t::default();
    let mut t = pmsm_telemetry_t::default();
    let mut b = pmsm_bases_t::default();
    let pu = |x: i32| x as f64 / (1 << 24) as f64;
    // SAFETY: live handle, valid out pointer.
    unsafe { assert_eq!(pmsm_get_bases(d, &mut b), pmsm_status_t::PMSM_OK) };
    // Mean commanded |v| and mean steady-state model voltage at the measured currents and
    // the estimated speed (motor B: R 7.2 ohm, L_d 25.0 mH, L_q 40.2 mH, psi 0.305 V*s).
    let (mut v_sum, mut model_sum) = (0.0, 0.0);
    // Largest |i_q| and mean tracking errors of both currents, per unit.
    let (mut iq_max, mut dq_err, mut dd_err): (f64, f64, f64) = (0.0, 0.0, 0.0);
    for (k, row) in rows[FAULT_STEP - WINDOW..FAULT_STEP].iter().enumerate() {
        // SAFETY: live handle, valid out pointer.
        unsafe {
            step_row(d, row);
            assert_eq!(pmsm_get_telemetry(d, &mut t), pmsm_status_t::PMSM_OK);
        }
        let w = pu(t.omega_est) * b.omega_e_rad_s;
        let (id, iq) = (pu(t.i_d) * b.current_a, pu(t.i_q) * b.current_a);
        let vd = 7.2 * id - w * 0.04017 * iq;
        let vq = 7.2 * iq + w * (0.025025 * id + 0.305);
        let v = pu(t.v_alpha).hypot(pu(t.v_beta)) * b.voltage_v;
        assert!(
            v <= 540.0 / 3f64.sqrt(),
            "|v| = {v} V beyond the modulator's circle"
        );
        v_sum += v;
        model_sum += vd.hypot(vq);
        iq_max = iq_max.max(pu(t.i_q).abs());
        dq_err += (pu(t.i_q) - pu(t.i_q_ref)).abs() / WINDOW as f64;
        dd_err += (pu(t.i_d) - pu(t.i_d_ref)).abs() / WINDOW as f64;
        // The d reference is the light-load current at this light load, once the low-speed
        // current of the start has faded under it (the window's first 3 ms: 0.01 pu left).
        if k >= 40 {
            assert!(pu(t.i_d_ref) < 0.0, "{k}: {t:?}");
        }
    }
    // SAFETY: live handle, valid out pointers.
    unsafe {
        assert_eq!(pmsm_get_ipd(d, &mut ipd), pmsm_status_t::PMSM_OK);
        assert_eq!(pmsm_get_telemetry(d, &mut t), pmsm_status_t::PMSM_OK);
        assert_eq!(pmsm_get_bases(d, &mut b), pmsm_status_t::PMSM_OK);
        assert_eq!(pmsm_get_ipd(d, null_mut()), pmsm_status_t::PMSM_ERR_NULL);
        assert_eq!(
            pmsm_get_telemetry(null_mut(), &mut t),
            pmsm_status_t::PMSM_ERR_NULL
        );
    }
    // The rotor of the scenario stands at 137 degrees electrical.
    assert_eq!(ipd.found, 1);
    let deg = ipd.theta as u32 as f64 / TURN * 360.0;
    assert!((deg - 137.0).abs() < 5.0, "detected {deg} degrees");
    assert_eq!(ipd.sector, 3, "137 degrees is in [120, 180)");
    assert!(ipd.peaks.iter().all(|&p| p > 0), "{:?}", ipd.peaks);
    assert_eq!((ipd.fault, ipd.fault_value), (0, [0, 0]));

    let rpm = pu(t.omega_est) * b.omega_e_rad_s * 60.0 / std::f64::consts::TAU / 3.0;
    // At or near the 600 r/min reference (ramped in 0.15 s, a heavy rotor, 0.18 s before).
    assert!((450.0..620.0).contains(&rpm), "estimated {rpm} r/min");
    // Closed loop on the estimate: the controller's frame is the estimator's.
    assert_eq!(t.theta, t.theta_est);
    // A running motor at no load: a torque current within 0.25 pu of zero, both currents
    // within 0.05 pu of their references on average (the d reference is the light-load
    // current at this light load). After the step to 600 r/min this heavy rotor swings through
    // the inverter's zero crossings (docs/drive.md "light load"): i_q by up to 0.6 A and 0.07 pu
    // off its reference at a sample, and the commanded voltage between 0.75 and 1.45 of the
    // steady-state model's, whose inductive terms the swing leaves out (nor the inverter's
    // residue near zero current, which the current loops at 0.1/T_s answer with voltage); over
    // the window the mean |v| is within 15 % of the mean model (1.10 measured).
    assert!(iq_max < 0.25, "largest |i_q| {iq_max} pu");
    assert!(
        dq_err < 0.05 && dd_err < 0.05,
        "mean errors q {dq_err}, d {dd_err} pu"
    );
    let ratio = v_sum / model_sum;
    assert!(
        (0.85..1.15).contains(&ratio),
        "mean |v| {ratio} of the model's at {rpm} r/min, {t:?}"
    );
    // The current-model MRAS explains the measurement to well within 0.2 pu when locked.
    assert!(
        (0..(1 << 24) / 5).contains(&t.health),
        "health {}",
        pu(t.health)
    );
    assert!(t.saturated <= 1);
}

#[test]
fn an_overrun_report_trips_and_turns_the_outputs_off() {
    let rows = scenario::record();
    let (_s, d) = replay_until(&rows, FAULT_STEP - 10);
    let mut out = pmsm_output_t::default();
    let mut st = pmsm_state_info_t::default();
    let input = pmsm_input_t {
        i_a: rows[FAULT_STEP - 10][Word::Ia as usize],
        i_b: rows[FAULT_STEP - 10][Word::Ib as usize],
        i_c: rows[FAULT_STEP - 10][Word::Ic as usize],
        vdc: rows[FAULT_STEP - 10][Word::Vdc as usize],
    };
    // SAFETY: live handle, valid structs.
    unsafe {
        assert_eq!(pmsm_step(d, &input, &mut out), pmsm_status_t::PMSM_OK);
        assert_eq!(out.pwm_on, 1, "running before the report");
        assert_eq!(pmsm_report_overrun(d), pmsm_status_t::PMSM_OK);
        assert_eq!(pmsm_get_state(d, &mut st), pmsm_status_t::PMSM_OK);
        assert_eq!(
            (st.state, st.fault, st.fault_value),
            (
                pmsm_state_t::PMSM_STATE_FAULT as u32,
                pmsm_fault_t::PMSM_FAULT_OVERRUN as u32,
                0
            )
        );
        assert_eq!(pmsm_step(d, &input, &mut out), pmsm_status_t::PMSM_OK);
        assert_eq!(out.pwm_on, 0);
        // Idle (once the interrupt side has taken the task's stop): nothing to trip.
        assert_eq!(pmsm_stop(d), pmsm_status_t::PMSM_OK);
        for _ in 0..FOLLOW {
            step(d, &input, &mut out);
        }
        assert_eq!(pmsm_report_overrun(d), pmsm_status_t::PMSM_OK);
        assert_eq!(pmsm_get_state(d, &mut st), pmsm_status_t::PMSM_OK);
        assert_eq!((st.state, st.fault), (0, 0));
        assert_eq!(
            pmsm_report_overrun(null_mut()),
            pmsm_status_t::PMSM_ERR_NULL
        );
    }
}

#[test]
fn a_failed_detection_says_which_check_failed() {
    // No motor connected: the pulses produce no current.
    let mut s = storage();
    let d = init(&mut s, &scenario::config_c()).expect("init");
    let vdc = (540.0 / 540.0 * 3f64.sqrt() * (1 << 24) as f64) as i32;
    let input = pmsm_input_t {
        vdc,
        ..pmsm_input_t::default()
    };
    let mut out = pmsm_output_t::default();
    let mut st = pmsm_state_info_t::default();
    let mut ipd = pmsm_ipd_t::default();
    // SAFETY: live handle, valid structs.
    unsafe {
        assert_eq!(pmsm_start(d), pmsm_status_t::PMSM_OK);
        let mut steps = 0;
        while out.state != pmsm_state_t::PMSM_STATE_FAULT as u8 && steps < 1000 {
            step(d, &input, &mut out);
            steps += 1;
        }
        // The first short pulse (3 samples on, its peak read at the end) decides, once the
        // interrupt side has taken the start.
        assert!(steps < FOLLOW + 20, "{steps} steps");
        pmsm_get_state(d, &mut st);
        pmsm_get_ipd(d, &mut ipd);
    }
    assert_eq!(st.fault, pmsm_fault_t::PMSM_FAULT_INITIAL_POSITION as u32);
    assert_eq!(
        st.fault_value,
        pmsm_ipd_fault_t::PMSM_IPD_FAULT_NO_CURRENT as i32
    );
    assert_eq!(
        ipd.fault,
        pmsm_ipd_fault_t::PMSM_IPD_FAULT_NO_CURRENT as u32
    );
    assert_eq!(ipd.fault_value, [0, 0], "the peak of no current is 0");
    assert_eq!(ipd.found, 0);
}

#[test]
fn ipd_settings_are_checked_only_for_an_ipd_start() {
    // Motor B on a 48 V bus: the IPD's long pulses (2 pu = 7.2 A through 7.2 ohm) need more
    // than the 24.9 V the pulses get; an alignment start does not use them.
    let mut c = scenario::config_c();
    c.vdc_v = 48.0;
    c.rated_speed_rpm = 0.0; // 3000 r/min needs more than 48 V: not rated at this bus
    c.startup = pmsm_startup_t::PMSM_STARTUP_ALIGN as u32;
    // SAFETY: valid config pointer.
    assert_eq!(
        unsafe { pmsm_config_check(&c) },
        pmsm_status_t::PMSM_OK,
        "{}",
        message(&c)
    );
    let mut s = storage();
    let d = init(&mut s, &c).expect("48 V with alignment");
    let mut st = pmsm_state_info_t::default();
    let input = pmsm_input_t {
        vdc: (3f64.sqrt() * (1 << 24) as f64) as i32,
        ..pmsm_input_t::default()
    };
    let mut out = pmsm_output_t::default();
    // SAFETY: live handle, valid structs.
    unsafe {
        assert_eq!(pmsm_start(d), pmsm_status_t::PMSM_OK);
        for _ in 0..FOLLOW {
            step(d, &input, &mut out);
        }
        assert_eq!(pmsm_get_state(d, &mut st), pmsm_status_t::PMSM_OK);
    }
    assert_eq!(st.state, pmsm_state_t::PMSM_STATE_ALIGN as u32);
    c.startup = pmsm_startup_t::PMSM_STARTUP_IPD as u32;
    // SAFETY: valid config pointer.
    assert_eq!(
        unsafe { pmsm_config_check(&c) },
        pmsm_status_t::PMSM_ERR_CONFIG_PARAM
    );
    assert!(
        message(&c).contains("ipd.long_current_pu"),
        "{}",
        message(&c)
    );
}

#[test]
fn integer_fields_out_of_range_name_the_range() {
    let ok = scenario::config_c();
    let mut c = ok;
    c.pwm_period_ticks = 70_000;
    assert_eq!(
        message(&c),
        "`pwm_period_ticks` is 70000; it must be in 0 to 65535"
    );
    let mut c = ok;
    c.estimator = 7;
    assert!(message(&c).contains("must be in 0 to 4"), "{}", message(&c));
    let mut c = ok;
    c.startup = 4;
    assert!(message(&c).contains("must be in 0 to 3"), "{}", message(&c));
    let mut c = ok;
    c.deadtime_compensation = 9;
    assert!(message(&c).contains("must be in 0 to 4"), "{}", message(&c));
    // A value range of the core names its bounds.
    let mut c = ok;
    c.pole_pairs = 0;
    let m = message(&c);
    assert!(m.contains("pole_pairs") && m.contains('1'), "{m}");
}

#[test]
fn a_negative_current_scale_flips_the_sign() {
    // An inverting amplifier: the code falls as current flows into the motor.
    let mut s = storage();
    let d = init(&mut s, &scenario::config_c()).expect("init");
    let (mut pos, mut neg, mut b) = (
        pmsm_scale_t::default(),
        pmsm_scale_t::default(),
        pmsm_bases_t::default(),
    );
    // SAFETY: live handle, valid out pointers.
    unsafe {
        assert_eq!(pmsm_get_bases(d, &mut b), pmsm_status_t::PMSM_OK);
        assert_eq!(
            pmsm_scale_current(d, 20.0 / 4096.0, &mut pos),
            pmsm_status_t::PMSM_OK
        );
        assert_eq!(
            pmsm_scale_current(d, -20.0 / 4096.0, &mut neg),
            pmsm_status_t::PMSM_OK
        );
    }
    assert!(neg.gain < 0 && neg.shift == pos.shift, "{neg:?} {pos:?}");
    for code in [-2048, -7, 1, 1000, 2047] {
        let exact = -(code as f64) * 20.0 / 4096.0 / b.current_a * (1 << 24) as f64;
        // SAFETY: valid scale pointer.
        let got = unsafe { pmsm_scale_apply(&neg, code) } as f64;
        assert!((got - exact).abs() <= 1.0, "{code}: {got} vs {exact}");
    }
}

#[test]
fn a_drive_without_ipd_start_refuses_to_pulse_if_forced_to() {
    use pmsm_core::EstimatorKind;
    use pmsm_core::{Drive, DriveConfig, DriveDesign, DriveInput, StartupMode};
    use pmsm_core::{InverterParams, PerUnit};
    // Motor B on 48 V: its IPD design is not reachable, and not checked for an ALIGN start.
    let m = scenario::motor_b();
    let mut m = m;
    m.rated_speed_rpm = None;
    let inv = InverterParams {
        vdc_v: 48.0,
        ..scenario::inverter_b()
    };
    let base = PerUnit::new(&m, &inv, 14_000.0).expect("bases");
    let mut design = DriveDesign::default_for(&m, &inv, &base, EstimatorKind::MrasCurrent);
    design.startup = StartupMode::Align;
    let mut config = DriveConfig::new(&m, &inv, 14_000.0, design).expect("ALIGN on 48 V");
    // Forced to IPD after the check: the unchecked detector stops at its first pulse.
    config.design.startup = StartupMode::Ipd;
    let mut drive = Drive::new(config);
    drive.start();
    let input = DriveInput {
        vdc: base.voltage_pu(48.0),
        ..DriveInput::default()
    };
    let mut steps = 0;
    // The interrupt side takes the start at the step after the task's first run.
    let begin = pmsm_core::TASK_PERIOD;
    while !matches!(drive.state(), DriveState::Fault(_)) && steps < 100 {
        let out = drive.step(&input);
        assert!(
            !out.pwm_on || (begin..begin + 4).contains(&steps),
            "switching at step {steps} with an unchecked detector"
        );
        steps += 1;
    }
    assert!(
        matches!(
            drive.state(),
            DriveState::Fault(Fault::InitialPosition(IpdFault::NoCurrent(_)))
        ),
        "{:?} after {steps} steps",
        drive.state()
    );
    assert!(steps <= begin + 4, "{steps} steps");
}
