//! Read access to a drive: state and fault, estimate, telemetry, initial position, what the
//! task learnt, bases, the fault record.
//! Integer only except `pmsm_get_bases`; none of them changes the drive.
#![allow(unsafe_code)]

use crate::convert;
use crate::handle::pmsm_drive_t;
use crate::handle::{drive, isr_side, put, task_side};
use crate::types::*;
use core::ffi::{CStr, c_char};

/// The state and the latched fault.
///
/// # Safety
/// `drive` as `pmsm_start`, read from the context of `pmsm_step` (or with it masked):
/// an interrupt-side read; `out` NULL or pointing to a writable `pmsm_state_info_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_state(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_state_info_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { isr_side(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let s = d.isr.state();
    let (fault, value) = convert::fault_code(&s);
    // SAFETY: forwarded contract.
    unsafe {
        put(
            out,
            pmsm_state_info_t {
                state: convert::state_code(&s),
                fault,
                fault_value: value,
            },
        )
    }
}

/// The rotor angle and speed estimated at the last step (integer only, ISR-safe).
///
/// # Safety
/// `drive` as `pmsm_start`, read from the context of `pmsm_step` (or with it masked):
/// an interrupt-side read; `out` NULL or pointing to a writable `pmsm_estimate_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_estimate(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_estimate_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { isr_side(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let e = d.isr.telemetry().estimate;
    // SAFETY: forwarded contract.
    unsafe {
        put(
            out,
            pmsm_estimate_t {
                theta: e.theta.0,
                omega: e.omega.to_bits(),
            },
        )
    }
}

/// What the drive's task has learnt: the tracker's `R` and `psi`, the learner's dead-time
/// scale (task side; `f32` to Q8.24 for the tracker's ratios).
///
/// # Safety
/// As `pmsm_start` (a task-side function); `out` NULL or pointing to a writable
/// `pmsm_learned_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_learned(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_learned_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let (t, _) = match unsafe { task_side(drive) } {
        Ok(t) => t,
        Err(e) => return e,
    };
    let q24 = |x: f32| (x * (1u32 << 24) as f32) as i32;
    let tracker = tracked(t);
    let ((rs, flux), updates) = tracker.unwrap_or(((1.0, 1.0), 0));
    #[cfg(feature = "distortion-learner")]
    let learner = t.learner().is_some();
    #[cfg(not(feature = "distortion-learner"))]
    let learner = false;
    // SAFETY: forwarded contract.
    unsafe {
        put(
            out,
            pmsm_learned_t {
                tracking: u32::from(tracker.is_some()),
                rs_ratio: q24(rs),
                flux_ratio: q24(flux),
                tracker_updates: updates,
                deadtime_learning: u32::from(learner),
                deadtime_scale: t.deadtime_scale().to_bits(),
            },
        )
    }
}

/// The tracker's `(R/R_0, psi/psi_0)` as the drive is given them and its updates that learnt,
/// when the drive runs one.
#[cfg(feature = "tracking")]
fn tracked(t: &pmsm_core::DriveTask) -> Option<((f32, f32), u32)> {
    t.tracker().map(|k| (k.applied(), k.status().learnt))
}

/// Without the feature: no tracker.
#[cfg(not(feature = "tracking"))]
fn tracked(_: &pmsm_core::DriveTask) -> Option<((f32, f32), u32)> {
    None
}

/// The per-unit bases, SI doubles.
///
/// # Safety
/// `drive` as `pmsm_start`; `out` NULL or pointing to a writable `pmsm_bases_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_bases(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_bases_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { self::drive(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let b = d.core.base;
    // SAFETY: forwarded contract.
    unsafe {
        put(
            out,
            pmsm_bases_t {
                current_a: b.current_a,
                voltage_v: b.voltage_v,
                omega_e_rad_s: b.omega_e_rad_s,
                sample_s: b.sample_s,
            },
        )
    }
}

/// What the last step computed: the controller's frame, the measured and reference currents,
/// the commanded voltage, the estimate and the estimator's health figure (integer only).
///
/// # Safety
/// `drive` as `pmsm_start`, read from the context of `pmsm_step` (or with it masked):
/// an interrupt-side read; `out` NULL or pointing to a writable `pmsm_telemetry_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_telemetry(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_telemetry_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { isr_side(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let t = d.isr.telemetry();
    let value = pmsm_telemetry_t {
        theta: t.theta.0,
        theta_est: t.estimate.theta.0,
        omega_est: t.estimate.omega.to_bits(),
        i_d: t.i_dq.d.to_bits(),
        i_q: t.i_dq.q.to_bits(),
        i_d_ref: t.i_ref.d.to_bits(),
        i_q_ref: t.i_ref.q.to_bits(),
        v_alpha: t.v.alpha.to_bits(),
        v_beta: t.v.beta.to_bits(),
        health: t.health.to_bits(),
        saturated: u32::from(t.saturated),
    };
    // SAFETY: forwarded contract.
    unsafe { put(out, value) }
}

/// The last initial position detection: the detected angle, sector and pulse peaks once one
/// has completed, and which check failed while the drive is in
/// `PMSM_FAULT_INITIAL_POSITION` (integer only).
///
/// # Safety
/// `drive` as `pmsm_start`, read from the context of `pmsm_step` (or with it masked):
/// an interrupt-side read; `out` NULL or pointing to a writable `pmsm_ipd_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_ipd(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_ipd_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { isr_side(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let (fault, fault_value) = convert::ipd_fault(&d.isr.state());
    let mut value = pmsm_ipd_t {
        fault,
        fault_value,
        ..pmsm_ipd_t::default()
    };
    if let Some(r) = d.isr.ipd_result() {
        value.found = 1;
        value.theta = r.theta.0;
        value.theta_mod_pi = r.theta_mod_pi.0;
        value.sector = u32::from(r.sector);
        value.peaks = r.peaks.map(|p| p.to_bits());
    }
    // SAFETY: forwarded contract.
    unsafe { put(out, value) }
}

/// A static, NUL-terminated short name of a `pmsm_fault_t` code (the core's `Fault::name()`,
/// "none" for 0, "unknown" beyond the last code).
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_fault_name(fault: u32) -> *const c_char {
    let s: &'static CStr = match fault {
        0 => c"none",
        1 => c"overcurrent",
        2 => c"bus_undervoltage",
        3 => c"bus_overvoltage",
        4 => c"initial_position",
        5 => c"handover",
        6 => c"current_sensor",
        7 => c"phase_loss",
        8 => c"stall",
        9 => c"loss_of_lock",
        10 => c"overrun",
        12 => c"driven_backwards",
        _ => c"unknown",
    };
    s.as_ptr()
}

/// A static, NUL-terminated short name of a `pmsm_ipd_fault_t` code (the core's
/// `IpdFault::name()`, "none" for 0, "unknown" beyond the last code).
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_ipd_fault_name(fault: u32) -> *const c_char {
    let s: &'static CStr = match fault {
        0 => c"none",
        1 => c"overcurrent",
        2 => c"no_current",
        3 => c"low_saliency",
        4 => c"no_polarity",
        5 => c"bus_low",
        _ => c"unknown",
    };
    s.as_ptr()
}

/// Number of samples in the drive's fault recorder, 0 to `PMSM_FAULT_RECORD_DEPTH` (0 for a
/// NULL or invalid handle). `pmsm_step` records every sample until the drive faults; the
/// record then stays frozen, ending with the sample that tripped, until `pmsm_clear_fault`
/// or the next `pmsm_start` from idle empties it. Integer only, ISR-safe.
///
/// # Safety
/// `drive` as `pmsm_start`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_fault_record_len(drive: *mut pmsm_drive_t) -> u32 {
    // SAFETY: forwarded contract.
    match unsafe { self::drive(drive) } {
        Ok(d) => d.recorder.len() as u32,
        Err(_) => 0,
    }
}

/// Sample `index` of the fault recorder, oldest first (0 to `pmsm_fault_record_len() - 1`;
/// the last is the newest, once frozen the one at which the drive tripped). Returns
/// `PMSM_ERR_INVALID_ARGUMENT` for an index out of that range, writing nothing. Integer only.
///
/// # Safety
/// `drive` as `pmsm_start`; `out` NULL or pointing to a writable `pmsm_fault_sample_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_fault_record_get(
    drive: *mut pmsm_drive_t,
    index: u32,
    out: *mut pmsm_fault_sample_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { self::drive(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let Some(s) = d.recorder.sample(index as usize) else {
        return pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT;
    };
    let value = pmsm_fault_sample_t {
        i_a: s.i_abc.a.to_bits(),
        i_b: s.i_abc.b.to_bits(),
        i_c: s.i_abc.c.to_bits(),
        vdc: s.vdc.to_bits(),
        v_alpha: s.v.alpha.to_bits(),
        v_beta: s.v.beta.to_bits(),
        theta_est: s.estimate.theta.0,
        omega_est: s.estimate.omega.to_bits(),
        state: u32::from(s.state),
    };
    // SAFETY: forwarded contract.
    unsafe { put(out, value) }
}
