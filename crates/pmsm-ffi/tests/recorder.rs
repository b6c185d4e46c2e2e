//! The fault recorder through the C interface: `pmsm_step` feeds it, a fault freezes it with
//! the samples that led there (oldest first, each the words the step was given and computed),
//! `pmsm_clear_fault` and `pmsm_start` empty it, and every bad argument is refused.
#![allow(unsafe_code)] // calling the extern "C" functions

mod common;
use common::storage;

use core::ptr::null_mut;
use pmsm_ffi::*;

const DEPTH: u32 = PMSM_FAULT_RECORD_DEPTH as u32;
/// 1 pu in Q8.24.
const ONE: i32 = 1 << 24;
/// The nominal bus, Q8.24 per unit of `V_b` (√3).
const VDC: i32 = 29_058_991;

/// A drive of the C test configuration that starts at a known angle (no detection pulses,
/// so the recorded inputs are only the ones fed here).
fn init(s: &mut pmsm_storage_t) -> *mut pmsm_drive_t {
    let c = pmsm_config_t {
        startup: pmsm_startup_t::PMSM_STARTUP_KNOWN as u32,
        ..common::scenario::config_c()
    };
    common::init(s, &c).expect("a valid configuration")
}

/// Small, balanced currents, distinct at every sample (0.1 pu scale), and a bus that moves by
/// a few LSB, so that each recorded sample can be told from its neighbours.
fn input(k: i32) -> pmsm_input_t {
    let a = (k % 50) * (ONE / 500);
    let b = -(k % 7) * (ONE / 300);
    pmsm_input_t {
        i_a: a,
        i_b: b,
        i_c: -a - b,
        vdc: VDC + k,
    }
}

/// 4 pu on phase a: beyond the default overcurrent trip (3 rated currents, about 3 pu).
fn overcurrent() -> pmsm_input_t {
    pmsm_input_t {
        i_a: 4 * ONE,
        i_b: -2 * ONE,
        i_c: -2 * ONE,
        vdc: VDC,
    }
}

/// One step (and the task when it is due); the output's state code and the telemetry after
/// it.
fn step(d: *mut pmsm_drive_t, x: &pmsm_input_t) -> (u8, pmsm_telemetry_t) {
    let mut out = pmsm_output_t::default();
    let mut t = pmsm_telemetry_t::default();
    // SAFETY: valid handle, input, output and telemetry.
    unsafe {
        assert_eq!(pmsm_step(d, x, &mut out), pmsm_status_t::PMSM_OK);
        assert_eq!(pmsm_get_telemetry(d, &mut t), pmsm_status_t::PMSM_OK);
        if out.task_due != 0 {
            assert_eq!(pmsm_task(d), pmsm_status_t::PMSM_OK);
        }
    }
    (out.state, t)
}

/// Samples from a task-side call to the interrupt side's acting on it, at most.
const FOLLOW: i32 = 2 * PMSM_TASK_PERIOD as i32;

fn len(d: *mut pmsm_drive_t) -> u32 {
    // SAFETY: valid handle (or NULL, on purpose).
    unsafe { pmsm_fault_record_len(d) }
}

fn get(d: *mut pmsm_drive_t, n: u32) -> Result<pmsm_fault_sample_t, pmsm_status_t> {
    let mut s = pmsm_fault_sample_t::default();
    // SAFETY: valid handle and out pointer.
    match unsafe { pmsm_fault_record_get(d, n, &mut s) } {
        pmsm_status_t::PMSM_OK => Ok(s),
        e => Err(e),
    }
}

fn all(d: *mut pmsm_drive_t) -> Vec<pmsm_fault_sample_t> {
    (0..len(d)).map(|n| get(d, n).unwrap()).collect()
}

/// What the recorder must hold for a step: the input as given, the voltage and estimate the
/// step computed (read back through the telemetry), the state it returned.
fn expected(x: &pmsm_input_t, state: u8, t: &pmsm_telemetry_t) -> pmsm_fault_sample_t {
    pmsm_fault_sample_t {
        i_a: x.i_a,
        i_b: x.i_b,
        i_c: x.i_c,
        vdc: x.vdc,
        v_alpha: t.v_alpha,
        v_beta: t.v_beta,
        theta_est: t.theta_est,
        omega_est: t.omega_est,
        state: u32::from(state),
    }
}

#[test]
fn holds_the_last_samples_before_an_overcurrent_oldest_first_and_freezes() {
    let mut s = storage();
    let d = init(&mut s);
    assert_eq!(len(d), 0);
    // SAFETY: valid handle.
    assert_eq!(unsafe { pmsm_start(d) }, pmsm_status_t::PMSM_OK);

    // 150 healthy samples, then the overcurrent at sample 150.
    let fault_at = 150;
    let mut fed = Vec::new();
    for k in 0..=fault_at {
        let x = if k == fault_at {
            overcurrent()
        } else {
            input(k)
        };
        let (state, t) = step(d, &x);
        if k < fault_at {
            assert_ne!(
                state,
                pmsm_state_t::PMSM_STATE_FAULT as u8,
                "tripped at {k}"
            );
            assert_eq!(len(d), (k as u32 + 1).min(DEPTH));
        }
        fed.push(expected(&x, state, &t));
    }
    let mut st = pmsm_state_info_t::default();
    // SAFETY: valid handle and out pointer.
    unsafe { pmsm_get_state(d, &mut st) };
    assert_eq!(st.state, pmsm_state_t::PMSM_STATE_FAULT as u32);
    assert_eq!(st.fault, pmsm_fault_t::PMSM_FAULT_OVERCURRENT as u32);

    // Exactly the last DEPTH samples, oldest first, ending with the tripping one.
    let held = all(d);
    assert_eq!(held.len(), PMSM_FAULT_RECORD_DEPTH);
    let tail = &fed[fed.len() - PMSM_FAULT_RECORD_DEPTH..];
    for (n, (h, e)) in held.iter().zip(tail).enumerate() {
        assert_eq!(h, e, "sample {n}");
    }
    let last = held.last().unwrap();
    assert_eq!(
        (last.i_a, last.i_b, last.i_c),
        (4 * ONE, -2 * ONE, -2 * ONE)
    );
    assert_eq!(last.state, pmsm_state_t::PMSM_STATE_FAULT as u32);
    // The tripping step computes no voltage: the sample keeps the last one commanded.
    let before = &held[PMSM_FAULT_RECORD_DEPTH - 2];
    assert_eq!((last.v_alpha, last.v_beta), (before.v_alpha, before.v_beta));
    // The one before it is the healthy sample 149, the first is sample 150 − 63.
    assert_eq!(held[PMSM_FAULT_RECORD_DEPTH - 2].vdc, VDC + fault_at - 1);
    assert_eq!(held[0].vdc, VDC + fault_at + 1 - DEPTH as i32);
    assert!(
        held[..PMSM_FAULT_RECORD_DEPTH - 1]
            .iter()
            .all(|h| h.state == pmsm_state_t::PMSM_STATE_RUN as u32)
    );
    // The drive ran closed loop at zero speed: some voltage was commanded before the trip.
    assert!(held.iter().any(|h| h.v_alpha != 0 || h.v_beta != 0));

    // Frozen: more steps (healthy again, and another overcurrent) change nothing.
    for k in 0..100 {
        let x = if k == 50 {
            overcurrent()
        } else {
            input(1000 + k)
        };
        step(d, &x);
    }
    assert_eq!(all(d), held);
    // Stopping keeps the record for reading at leisure.
    // SAFETY: valid handle.
    assert_eq!(unsafe { pmsm_stop(d) }, pmsm_status_t::PMSM_OK);
    step(d, &input(7));
    assert_eq!(all(d), held);
    // A new start (once the stop has reached the interrupt side) empties it and records
    // again.
    for _ in 0..FOLLOW {
        step(d, &input(7));
    }
    // SAFETY: valid handle.
    assert_eq!(unsafe { pmsm_start(d) }, pmsm_status_t::PMSM_OK);
    assert_eq!(len(d), 0);
    let (state, t) = step(d, &input(3));
    assert_eq!(all(d), vec![expected(&input(3), state, &t)]);
}

#[test]
fn clear_fault_empties_it_and_start_does_not_while_running() {
    let mut s = storage();
    let d = init(&mut s);
    // SAFETY: valid handle.
    unsafe { pmsm_start(d) };
    for k in 0..FOLLOW + 10 {
        step(d, &input(k));
    }
    // A start while running does nothing, to the drive or to its record.
    // SAFETY: valid handle.
    unsafe { pmsm_start(d) };
    assert_eq!(len(d), FOLLOW as u32 + 10);
    step(d, &overcurrent());
    assert_eq!(len(d), FOLLOW as u32 + 11);
    // The task takes the trip at the end of its period; cleared then, the record empties.
    for k in 0..FOLLOW {
        step(d, &input(k));
    }
    assert_eq!(len(d), FOLLOW as u32 + 11);
    // SAFETY: valid handle.
    assert_eq!(unsafe { pmsm_clear_fault(d) }, pmsm_status_t::PMSM_OK);
    assert_eq!(len(d), 0);
    // The samples until the outputs are idle again are recorded, the old trip not taken for
    // a new fault; idle samples are recorded too (the record shows what preceded a start).
    let mut fed = Vec::new();
    for _ in 0..FOLLOW {
        let (state, t) = step(d, &input(5));
        fed.push(expected(&input(5), state, &t));
    }
    let (state, t) = step(d, &input(5));
    fed.push(expected(&input(5), state, &t));
    assert_eq!(state, pmsm_state_t::PMSM_STATE_IDLE as u8);
    assert_eq!(all(d), fed);
    // A clear outside a fault leaves the record alone.
    // SAFETY: valid handle.
    unsafe { pmsm_clear_fault(d) };
    assert_eq!(len(d), FOLLOW as u32 + 1);
}

#[test]
fn refuses_out_of_range_indexes_and_bad_pointers_without_writing() {
    let mut s = storage();
    let d = init(&mut s);
    let sentinel = pmsm_fault_sample_t {
        i_a: 0x5A5A_5A5A,
        ..Default::default()
    };
    let mut out = sentinel;
    // SAFETY: valid handle and out pointer; NULL and a never-initialised storage on purpose.
    unsafe {
        assert_eq!(
            pmsm_fault_record_get(d, 0, &mut out),
            pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT
        );
        assert_eq!(pmsm_fault_record_len(null_mut()), 0);
        assert_eq!(
            pmsm_fault_record_get(null_mut(), 0, &mut out),
            pmsm_status_t::PMSM_ERR_NULL
        );
        let mut blank = storage();
        let fake = (&mut *blank as *mut pmsm_storage_t).cast::<pmsm_drive_t>();
        assert_eq!(pmsm_fault_record_len(fake), 0);
        assert_eq!(
            pmsm_fault_record_get(fake, 0, &mut out),
            pmsm_status_t::PMSM_ERR_NOT_INITIALIZED
        );
    }
    // SAFETY: valid handle.
    unsafe { pmsm_start(d) };
    for k in 0..(DEPTH as i32 + 10) {
        step(d, &input(k));
    }
    assert_eq!(len(d), DEPTH);
    for n in [DEPTH, DEPTH + 1, u32::MAX / 2, u32::MAX] {
        // SAFETY: valid handle and out pointer.
        let r = unsafe { pmsm_fault_record_get(d, n, &mut out) };
        assert_eq!(r, pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT, "index {n}");
    }
    assert_eq!(out, sentinel);
    // SAFETY: valid handle; NULL and a misaligned out pointer on purpose (never written).
    unsafe {
        assert_eq!(
            pmsm_fault_record_get(d, 0, null_mut()),
            pmsm_status_t::PMSM_ERR_NULL
        );
        let mut buf = [0u32; 16];
        let odd = buf
            .as_mut_ptr()
            .cast::<u8>()
            .add(1)
            .cast::<pmsm_fault_sample_t>();
        assert_eq!(
            pmsm_fault_record_get(d, 0, odd),
            pmsm_status_t::PMSM_ERR_MISALIGNED
        );
        assert_eq!(buf, [0; 16]);
    }
    // The newest in-range index is the last sample fed.
    let newest = get(d, DEPTH - 1).unwrap();
    let x = input(DEPTH as i32 + 9);
    assert_eq!((newest.i_a, newest.i_b, newest.vdc), (x.i_a, x.i_b, x.vdc));
}

#[test]
fn a_drive_loaded_from_an_image_starts_with_an_empty_recorder() {
    let mut s = storage();
    let d = init(&mut s);
    // SAFETY: valid handle.
    unsafe { pmsm_start(d) };
    for k in 0..20 {
        step(d, &input(k));
    }
    // SAFETY: valid handle; NULL to read the size.
    unsafe { pmsm_stop(d) };
    let size = unsafe { pmsm_drive_image(d, null_mut(), 0) };
    // The image holds the drive without its recorder.
    assert!(size < PMSM_IMAGE_HEADER_SIZE + pmsm_drive_size());
    let mut image = vec![0u8; size];
    // SAFETY: valid handle and buffer of `size` bytes.
    assert_eq!(
        unsafe { pmsm_drive_image(d, image.as_mut_ptr().cast(), size) },
        size
    );
    let mut s2 = storage();
    let mut d2 = null_mut();
    // SAFETY: valid storage, image and out pointer.
    let r = unsafe {
        pmsm_drive_init_image(
            (&mut *s2 as *mut pmsm_storage_t).cast(),
            size_of::<pmsm_storage_t>(),
            image.as_ptr().cast(),
            size,
            &mut d2,
        )
    };
    assert_eq!(r, pmsm_status_t::PMSM_OK);
    assert_eq!(len(d2), 0);
    // SAFETY: valid handle.
    unsafe { pmsm_start(d2) };
    let (state, t) = step(d2, &input(1));
    assert_eq!(all(d2), vec![expected(&input(1), state, &t)]);
}
