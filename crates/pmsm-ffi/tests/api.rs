//! The C ABI called from Rust: the recorded scenario replayed through `pmsm_step` bit for bit
//! (what the C programs do), and every function with NULL, misaligned, uninitialised and
//! out-of-range arguments.
#![allow(unsafe_code)] // calling the extern "C" functions

mod common;
use common::{init, step_row, storage};

use common::scenario::{self, WORDS, Word};
use core::ffi::{CStr, c_void};
use core::ptr::{null, null_mut};
use pmsm_ffi::*;

/// A message function of the C API on `c`, as a string.
type MessageFn = unsafe extern "C" fn(*const pmsm_config_t, *mut core::ffi::c_char, usize) -> usize;

fn text(f: MessageFn, c: &pmsm_config_t) -> String {
    let mut buf = [0 as core::ffi::c_char; 300];
    // SAFETY: valid config and buffer.
    let n = unsafe { f(c, buf.as_mut_ptr(), buf.len()) };
    // SAFETY: NUL-terminated by the function.
    let s = unsafe { CStr::from_ptr(buf.as_ptr()) }
        .to_string_lossy()
        .into_owned();
    assert_eq!(n, s.len(), "fits in 300 bytes");
    s
}

fn message(c: &pmsm_config_t) -> String {
    text(pmsm_config_error_message, c)
}

/// Replays `rows` through the C ABI; the first differing step, if any.
fn replay(rows: &[[i32; WORDS]]) -> Option<(usize, [i32; WORDS])> {
    let mut s = storage();
    let d = init(&mut s, &scenario::config_c()).expect("init");
    for (k, row) in rows.iter().enumerate() {
        // SAFETY: `d` is a live handle; the structs are valid.
        let got = unsafe {
            let out = step_row(d, row);
            let mut st = pmsm_state_info_t::default();
            assert_eq!(pmsm_get_state(d, &mut st), pmsm_status_t::PMSM_OK);
            let mut e = pmsm_estimate_t::default();
            assert_eq!(pmsm_get_estimate(d, &mut e), pmsm_status_t::PMSM_OK);
            assert_eq!(out.state as u32, st.state);
            let mut got = *row;
            got[Word::DutyA as usize] = out.duty[0];
            got[Word::DutyB as usize] = out.duty[1];
            got[Word::DutyC as usize] = out.duty[2];
            got[Word::CmpA as usize] = out.compare[0] as i32;
            got[Word::CmpB as usize] = out.compare[1] as i32;
            got[Word::CmpC as usize] = out.compare[2] as i32;
            got[Word::PwmOn as usize] = out.pwm_on as i32;
            got[Word::State as usize] = st.state as i32;
            got[Word::Fault as usize] = st.fault as i32;
            got[Word::Theta as usize] = e.theta;
            got[Word::Omega as usize] = e.omega;
            got
        };
        if got != *row {
            return Some((k, got));
        }
    }
    None
}

#[test]
fn c_abi_replays_the_rust_drive_bit_for_bit() {
    let rows = scenario::record();
    let count = |state: pmsm_state_t| {
        rows.iter()
            .filter(|r| r[Word::State as usize] == state as i32)
            .count()
    };
    // The scenario covers detection, the closed loop, a fault and the restart.
    assert!(count(pmsm_state_t::PMSM_STATE_IPD) > 0);
    assert!(
        count(pmsm_state_t::PMSM_STATE_RUN) > 1000,
        "{}",
        count(pmsm_state_t::PMSM_STATE_RUN)
    );
    assert!(count(pmsm_state_t::PMSM_STATE_FAULT) > 0);
    let last = rows.last().expect("rows");
    assert!(last[Word::Omega as usize] != 0);
    if let Some((k, got)) = replay(&rows) {
        panic!("step {k}: expected {:?}, got {got:?}", rows[k]);
    }
}

#[test]
fn a_changed_output_is_detected() {
    let mut rows = scenario::record();
    rows[2000][Word::CmpB as usize] += 1;
    assert_eq!(replay(&rows).map(|(k, _)| k), Some(2000));
}

#[test]
fn null_misaligned_and_uninitialised_arguments_return_errors() {
    use pmsm_status_t::*;
    let c = scenario::config_c();
    let mut s = storage();
    let sp = (&mut *s as *mut pmsm_storage_t).cast::<c_void>();
    let len = size_of::<pmsm_storage_t>();
    let mut d = null_mut();
    // SAFETY: every pointer is NULL, valid, or (deliberately) misaligned into valid storage.
    unsafe {
        assert_eq!(pmsm_drive_init(null_mut(), len, &c, &mut d), PMSM_ERR_NULL);
        assert_eq!(pmsm_drive_init(sp, len, null(), &mut d), PMSM_ERR_NULL);
        assert_eq!(pmsm_drive_init(sp, len, &c, null_mut()), PMSM_ERR_NULL);
        assert_eq!(
            pmsm_drive_init(sp, pmsm_drive_size() - 1, &c, &mut d),
            PMSM_ERR_BUFFER_TOO_SMALL
        );
        assert_eq!(
            pmsm_drive_init(sp.cast::<u8>().add(4).cast(), len - 8, &c, &mut d),
            PMSM_ERR_MISALIGNED
        );
        assert!(d.is_null(), "nothing written on error");
        // Storage never initialised: refused.
        let raw = sp.cast::<pmsm_drive_t>();
        assert_eq!(pmsm_start(raw), PMSM_ERR_NOT_INITIALIZED);
        let mut out = pmsm_output_t::default();
        let input = pmsm_input_t::default();
        assert_eq!(pmsm_step(raw, &input, &mut out), PMSM_ERR_NOT_INITIALIZED);
        for f in [pmsm_start, pmsm_stop, pmsm_clear_fault] {
            assert_eq!(f(null_mut()), PMSM_ERR_NULL);
            assert_eq!(f(sp.cast::<u8>().add(1).cast()), PMSM_ERR_MISALIGNED);
        }
        assert_eq!(pmsm_set_speed_ref(null_mut(), 1), PMSM_ERR_NULL);

        assert_eq!(pmsm_drive_init(sp, len, &c, &mut d), PMSM_OK);
        assert_eq!(d, raw);
        assert_eq!(pmsm_step(null_mut(), &input, &mut out), PMSM_ERR_NULL);
        assert_eq!(pmsm_step(d, null(), &mut out), PMSM_ERR_NULL);
        assert_eq!(pmsm_step(d, &input, null_mut()), PMSM_ERR_NULL);
        let mut st = pmsm_state_info_t::default();
        assert_eq!(pmsm_get_state(d, null_mut()), PMSM_ERR_NULL);
        assert_eq!(pmsm_get_state(null_mut(), &mut st), PMSM_ERR_NULL);
        assert_eq!(pmsm_get_estimate(d, null_mut()), PMSM_ERR_NULL);
        assert_eq!(pmsm_get_bases(d, null_mut()), PMSM_ERR_NULL);
        assert_eq!(pmsm_scale_current(d, 1e-3, null_mut()), PMSM_ERR_NULL);
        assert_eq!(pmsm_scale_apply(null(), 5), 0);
        assert_eq!(pmsm_config_check(null()), PMSM_ERR_NULL);
        assert_eq!(pmsm_config_error_message(null(), null_mut(), 0), 0);
        assert_eq!(pmsm_config_error_message(&c, null_mut(), 0), 2, "\"ok\"");

        // Idle: the step returns outputs off; a zero bus would trip only when running.
        assert_eq!(pmsm_step(d, &input, &mut out), PMSM_OK);
        assert_eq!(
            (out.pwm_on, out.state),
            (0, pmsm_state_t::PMSM_STATE_IDLE as u8)
        );
        // Running with a zero bus: a latched undervoltage fault (at the first sample the
        // interrupt side runs the start), then cleared once the task has taken it.
        assert_eq!(pmsm_start(d), PMSM_OK);
        let follow = 2 * PMSM_TASK_PERIOD as usize;
        let step = |out: &mut pmsm_output_t| {
            assert_eq!(pmsm_step(d, &input, out), PMSM_OK);
            if out.task_due != 0 {
                assert_eq!(pmsm_task(d), PMSM_OK);
            }
        };
        for _ in 0..follow {
            step(&mut out);
        }
        assert_eq!(pmsm_get_state(d, &mut st), PMSM_OK);
        assert_eq!(st.state, pmsm_state_t::PMSM_STATE_FAULT as u32);
        assert_eq!(st.fault, pmsm_fault_t::PMSM_FAULT_BUS_UNDERVOLTAGE as u32);
        for _ in 0..follow {
            step(&mut out);
        }
        assert_eq!(pmsm_clear_fault(d), PMSM_OK);
        for _ in 0..follow {
            step(&mut out);
        }
        assert_eq!(pmsm_get_state(d, &mut st), PMSM_OK);
        assert_eq!((st.state, st.fault), (0, 0));
    }
}

#[test]
fn configuration_errors_have_codes_and_messages() {
    use pmsm_status_t::*;
    let ok = scenario::config_c();
    // SAFETY: valid config pointers.
    let check = |c: &pmsm_config_t| unsafe { pmsm_config_check(c) };
    assert_eq!(check(&ok), PMSM_OK);
    assert_eq!(message(&ok), "ok");
    type Spoil = fn(&mut pmsm_config_t);
    let cases: [(Spoil, pmsm_status_t, &str); 7] = [
        (|c| c.rs_ohm = 0.0, PMSM_ERR_CONFIG_PARAM, "rs_ohm"),
        (|c| c.ld_h = f64::NAN, PMSM_ERR_CONFIG_PARAM, "ld_h"),
        (|c| c.pole_pairs = 0, PMSM_ERR_CONFIG_PARAM, "pole_pairs"),
        (|c| c.estimator = 7, PMSM_ERR_INVALID_ARGUMENT, "estimator"),
        (|c| c.startup = 99, PMSM_ERR_INVALID_ARGUMENT, "startup"),
        (
            |c| c.pwm_period_ticks = 70_000,
            PMSM_ERR_INVALID_ARGUMENT,
            "pwm_period_ticks",
        ),
        (
            |c| c.deadtime_compensation = 5,
            PMSM_ERR_INVALID_ARGUMENT,
            "deadtime_compensation",
        ),
    ];
    for (spoil, code, key) in cases {
        let mut c = ok;
        spoil(&mut c);
        assert_eq!(check(&c), code, "{key}");
        let m = message(&c);
        assert!(m.contains(key), "{m}");
        let mut s = storage();
        assert_eq!(init(&mut s, &c), Err(code));
    }
    // A zero-size buffer only counts; a short one truncates and terminates.
    let mut bad = ok;
    bad.rs_ohm = -1.0;
    let mut buf = [1 as core::ffi::c_char; 6];
    // SAFETY: valid config and buffer.
    let n = unsafe { pmsm_config_error_message(&bad, buf.as_mut_ptr(), buf.len()) };
    // SAFETY: NUL-terminated by the function.
    let s = unsafe { CStr::from_ptr(buf.as_ptr()) };
    assert_eq!(s.to_bytes(), b"`rs_o");
    assert_eq!(n, message(&bad).len());
    for code in -9..=1 {
        // SAFETY: static NUL-terminated strings.
        let m = unsafe { CStr::from_ptr(pmsm_status_message(code)) };
        assert!(!m.to_bytes().is_empty());
    }
}

#[test]
fn scales_convert_adc_codes_with_integer_math() {
    let mut s = storage();
    let d = init(&mut s, &scenario::config_c()).expect("init");
    let mut b = pmsm_bases_t::default();
    let mut sc = pmsm_scale_t::default();
    // SAFETY: live handle, valid out pointers.
    unsafe {
        assert_eq!(pmsm_get_bases(d, &mut b), pmsm_status_t::PMSM_OK);
        assert!((b.current_a - 2.53 * 2f64.sqrt()).abs() < 1e-9);
        // A 12-bit ADC over ±10 A: 20/4096 A per code.
        let a_per_code = 20.0 / 4096.0;
        assert_eq!(
            pmsm_scale_current(d, a_per_code, &mut sc),
            pmsm_status_t::PMSM_OK
        );
        for code in [-2048, -1000, -1, 0, 1, 733, 2047] {
            let exact = code as f64 * a_per_code / b.current_a * (1 << 24) as f64;
            let got = pmsm_scale_apply(&sc, code) as f64;
            assert!((got - exact).abs() <= 1.0, "{code}: {got} vs {exact}");
        }
        assert_eq!(pmsm_scale_voltage(d, 0.2, &mut sc), pmsm_status_t::PMSM_OK);
        let got = pmsm_scale_apply(&sc, 2700) as f64 / (1 << 24) as f64;
        assert!((got - 540.0 / b.voltage_v).abs() < 1e-6, "{got}");
        assert_eq!(pmsm_scale_speed(d, 1.0, &mut sc), pmsm_status_t::PMSM_OK);
        let got = pmsm_scale_apply(&sc, 3000) as f64 / (1 << 24) as f64;
        let exact = 3000.0 * std::f64::consts::TAU / 60.0 * 3.0 / b.omega_e_rad_s;
        assert!((got - exact).abs() < 1e-6, "{got} vs {exact}");
        for bad in [0.0, f64::NAN, f64::INFINITY, 1e30] {
            assert_eq!(
                pmsm_scale_current(d, bad, &mut sc),
                pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT
            );
        }
        // Saturation instead of wrapping.
        let big = pmsm_scale_t {
            gain: i32::MAX,
            shift: 0,
        };
        assert_eq!(pmsm_scale_apply(&big, 3), i32::MAX);
    }
}

#[test]
fn storage_fits() {
    assert!(pmsm_drive_size() <= PMSM_STORAGE_SIZE);
    assert!(pmsm_drive_align() <= 8 && pmsm_drive_align().is_power_of_two());
    println!(
        "drive: {} bytes, align {}",
        pmsm_drive_size(),
        pmsm_drive_align()
    );
}

#[test]
fn version_is_the_crates() {
    let parts: Vec<u32> = env!("CARGO_PKG_VERSION")
        .split(['.', '-'])
        .take(3)
        .map(|p| p.parse().unwrap())
        .collect();
    assert_eq!(
        pmsm_version(),
        (parts[0] << 16) | (parts[1] << 8) | parts[2],
        "pmsm_version() is not the crate's version {}",
        env!("CARGO_PKG_VERSION")
    );
    assert_eq!(pmsm_version(), PMSM_VERSION);
    let header = include_str!("../include/pmsm.h");
    for (name, value) in [
        ("PMSM_VERSION_MAJOR", parts[0]),
        ("PMSM_VERSION_MINOR", parts[1]),
        ("PMSM_VERSION_PATCH", parts[2]),
    ] {
        assert!(
            header.contains(&format!("#define {name} {value}\n")),
            "pmsm.h does not define {name} {value}"
        );
    }
}

/// The outputs of a drive configured with `c` on the recorded inputs: duties and state.
fn outputs(c: &pmsm_config_t, rows: &[[i32; WORDS]]) -> Vec<[i32; 4]> {
    let mut s = storage();
    let d = init(&mut s, c).expect("init");
    rows.iter()
        .map(|row| {
            // SAFETY: `d` is a live handle; the row is valid.
            let out = unsafe { step_row(d, row) };
            [out.duty[0], out.duty[1], out.duty[2], out.state as i32]
        })
        .collect()
}

#[test]
fn auto_estimator_is_the_motors() {
    let rows = scenario::record();
    let with = |estimator: pmsm_estimator_t, lq_h: f64| {
        let mut c = scenario::config_c();
        c.estimator = estimator as u32;
        c.lq_h = lq_h;
        c.startup = pmsm_startup_t::PMSM_STARTUP_KNOWN as u32;
        outputs(&c, &rows)
    };
    use pmsm_estimator_t::*;
    // Motor B (L_q/L_d 1.6): the current-model MRAS, bit for bit.
    let lq_b = scenario::config_c().lq_h;
    assert_eq!(
        with(PMSM_ESTIMATOR_AUTO, lq_b),
        with(PMSM_ESTIMATOR_MRAS_CURRENT, lq_b)
    );
    // The same motor made surface (L_q = L_d): the NLO, and not the MRAS.
    let ld = scenario::config_c().ld_h;
    let auto = with(PMSM_ESTIMATOR_AUTO, ld);
    assert_eq!(auto, with(PMSM_ESTIMATOR_NLO, ld));
    let differ = auto
        .iter()
        .zip(with(PMSM_ESTIMATOR_MRAS_CURRENT, ld))
        .filter(|(a, m)| **a != *m)
        .count();
    assert!(
        differ > 10,
        "NLO and MRAS drives differ in {differ} steps only"
    );
}

#[cfg(feature = "injection")]
fn injection_message(c: &pmsm_config_t) -> String {
    text(pmsm_injection_message, c)
}

#[test]
#[cfg(feature = "injection")]
fn injection_is_on_by_default_where_the_motor_allows_it() {
    use pmsm_injection_t::*;
    let rows = scenario::record();
    let with = |code: pmsm_injection_t| {
        let mut c = scenario::config_c();
        c.injection = code as u32;
        c
    };
    // Motor B (L_q/L_d 1.6): on by default, the same drive as asked by name, and another
    // drive than without it (the recording starts from standstill, in the injection's band).
    let default = with(PMSM_INJECTION_DEFAULT);
    let m = injection_message(&default);
    assert!(m.starts_with("on: ") && m.contains(" Hz"), "{m}");
    assert_eq!(injection_message(&with(PMSM_INJECTION_ON)), m);
    let off = injection_message(&with(PMSM_INJECTION_OFF));
    assert!(
        off.starts_with("off: ") && off.contains("injection"),
        "{off}"
    );
    let on_out = outputs(&default, &rows);
    assert_eq!(on_out, outputs(&with(PMSM_INJECTION_ON), &rows));
    let differ = on_out
        .iter()
        .zip(outputs(&with(PMSM_INJECTION_OFF), &rows))
        .filter(|(a, b)| **a != *b)
        .count();
    assert!(differ > 100, "with and without differ in {differ} steps");
    // A surface motor: off by default, and why; refused when asked by name.
    let mut surface = default;
    surface.lq_h = surface.ld_h;
    let m = injection_message(&surface);
    assert!(m.starts_with("off: ") && m.contains("surface"), "{m}");
    // SAFETY: valid config pointers.
    let check = |c: &pmsm_config_t| unsafe { pmsm_config_check(c) };
    assert_eq!(check(&surface), pmsm_status_t::PMSM_OK);
    surface.injection = PMSM_INJECTION_ON as u32;
    assert_eq!(check(&surface), pmsm_status_t::PMSM_ERR_CONFIG_PARAM);
    assert!(message(&surface).contains("injection"));
    // An unknown code.
    let mut bad = default;
    bad.injection = 3;
    assert_eq!(check(&bad), pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT);
    assert!(
        message(&bad).contains("`injection` is 3"),
        "{}",
        message(&bad)
    );
    assert!(injection_message(&bad).contains("`injection` is 3"));
}

/// What the task learnt, read through the C interface.
fn learned(c: &pmsm_config_t) -> pmsm_learned_t {
    let mut s = storage();
    let d = init(&mut s, c).expect("init");
    let mut out = pmsm_learned_t::default();
    // SAFETY: a live handle and a writable out pointer.
    assert_eq!(
        unsafe { pmsm_get_learned(d, &mut out) },
        pmsm_status_t::PMSM_OK
    );
    out
}

#[test]
#[cfg(all(feature = "tracking", feature = "distortion-learner"))]
fn the_task_s_learners_are_on_by_default_and_each_can_be_turned_off() {
    use pmsm_option_t::*;
    let one = 1 << 24;
    // Motor B with the current-model MRAS and 2 µs of dead time: both on, nothing learnt yet.
    let default = scenario::config_c();
    let l = learned(&default);
    assert_eq!((l.tracking, l.deadtime_learning), (1, 1));
    assert_eq!(
        (l.rs_ratio, l.flux_ratio, l.deadtime_scale),
        (one, one, one)
    );
    assert_eq!(l.tracker_updates, 0);
    let with = |tracking: pmsm_option_t, learning: pmsm_option_t| {
        let mut c = default;
        c.tracking = tracking as u32;
        c.deadtime_learning = learning as u32;
        learned(&c)
    };
    let on = with(PMSM_OPTION_ON, PMSM_OPTION_ON);
    assert_eq!((on.tracking, on.deadtime_learning), (1, 1));
    let off = with(PMSM_OPTION_OFF, PMSM_OPTION_DEFAULT);
    assert_eq!((off.tracking, off.deadtime_learning), (0, 1));
    let off = with(PMSM_OPTION_DEFAULT, PMSM_OPTION_OFF);
    assert_eq!((off.tracking, off.deadtime_learning), (1, 0));
    // Without a dead time the learner has nothing to learn: off by default.
    let mut ideal = default;
    ideal.dead_time_s = 0.0;
    assert_eq!(learned(&ideal).deadtime_learning, 0);
    // An unknown code is named.
    // SAFETY: valid config pointers.
    let check = |c: &pmsm_config_t| unsafe { pmsm_config_check(c) };
    for field in ["tracking", "deadtime_learning"] {
        let mut bad = default;
        if field == "tracking" {
            bad.tracking = 3;
        } else {
            bad.deadtime_learning = 3;
        }
        assert_eq!(check(&bad), pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT);
        let m = message(&bad);
        assert!(m.contains(&format!("`{field}` is 3")), "{m}");
    }
    // A NULL drive or output is refused.
    let mut out = pmsm_learned_t::default();
    // SAFETY: NULL handle, valid out pointer.
    let r = unsafe { pmsm_get_learned(core::ptr::null_mut(), &mut out) };
    assert_ne!(r, pmsm_status_t::PMSM_OK);
}
