//! Building, commanding and stepping a drive.
#![allow(unsafe_code)]

use crate::convert::{self, CBuf};
use crate::handle::pmsm_drive_t;
use crate::handle::{aligned, arg, emplace, isr_side, put, status, task_side};
use crate::types::*;
use core::ffi::{c_char, c_void};
use core::mem::{align_of, size_of};
use pmsm_core::Abc;
use pmsm_core::Pu;
use pmsm_core::{DriveInput, DriveState};

/// Bytes of storage a drive needs (`<= PMSM_STORAGE_SIZE`).
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_drive_size() -> usize {
    size_of::<pmsm_drive_t>()
}

/// Alignment the storage of a drive needs, bytes (a power of two, `<= 8`).
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_drive_align() -> usize {
    align_of::<pmsm_drive_t>()
}

/// A static, NUL-terminated, one-line description of a status code (also of unknown codes).
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_status_message(status: i32) -> *const c_char {
    use pmsm_status_t::*;
    let s: &'static core::ffi::CStr = match status {
        x if x == PMSM_OK as i32 => c"ok",
        x if x == PMSM_ERR_NULL as i32 => c"a required pointer argument is NULL",
        x if x == PMSM_ERR_BUFFER_TOO_SMALL as i32 => {
            c"the storage is smaller than pmsm_drive_size() bytes"
        }
        x if x == PMSM_ERR_MISALIGNED as i32 => c"a pointer is not aligned for its type",
        x if x == PMSM_ERR_NOT_INITIALIZED as i32 => {
            c"the handle is not a drive initialised by pmsm_drive_init"
        }
        x if x == PMSM_ERR_INVALID_ARGUMENT as i32 => {
            c"an enumerated code or integer argument is out of range"
        }
        x if x == PMSM_ERR_CONFIG_PARAM as i32 => {
            c"a physical parameter of the configuration is invalid"
        }
        x if x == PMSM_ERR_CONFIG_ENVELOPE as i32 => {
            c"the motor, bus and sample rate are outside the fixed-point envelope"
        }
        x if x == PMSM_ERR_CONFIG_GAIN as i32 => {
            c"a gain is outside its stable, representable range"
        }
        x if x == PMSM_ERR_IMAGE as i32 => {
            c"the drive image is of another library build or size, or corrupted"
        }
        _ => c"unknown status code",
    };
    s.as_ptr()
}

/// Checks a configuration without building a drive: `PMSM_OK` or the error
/// `pmsm_drive_init` would return.
///
/// # Safety
/// `config` is NULL or points to a `pmsm_config_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_config_check(config: *const pmsm_config_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    match unsafe { arg(config) } {
        Err(e) => e,
        Ok(c) => match convert::build(c) {
            Ok(_) => pmsm_status_t::PMSM_OK,
            Err(r) => r.status(),
        },
    }
}

/// Writes why `config` is rejected, naming the field and its accepted range (for example
/// "`rs_ohm` must be greater than zero"), or "ok", into `buf` of `len` bytes, truncated and
/// always NUL-terminated when `len > 0`. Returns the length of the whole message without the
/// NUL (like `snprintf`), 0 when `config` is NULL or misaligned. Not for the ISR (it formats).
///
/// # Safety
/// `config` is NULL or points to a `pmsm_config_t`; `buf` is NULL or points to `len` writable
/// bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_config_error_message(
    config: *const pmsm_config_t,
    buf: *mut c_char,
    len: usize,
) -> usize {
    // SAFETY: forwarded contract.
    unsafe {
        message(config, buf, len, |w, built| match built {
            Ok(_) => core::fmt::Write::write_str(w, "ok"),
            Err(r) => core::fmt::write(w, format_args!("{r}")),
        })
    }
}

/// Writes whether the drive `config` builds runs the high-frequency injection at standstill
/// (`pmsm_config_t.injection`, docs/injection.md), into `buf` as `pmsm_config_error_message`
/// does: "on: " and its design (amplitude, mV; frequency, Hz; the current across the axis at 45°
/// of error and the ripple along d, mA), or "off: " and why (the key, a surface motor, a library built
/// without it), or the configuration's error. Returns the length of the whole message. Not for
/// the ISR (it formats).
///
/// # Safety
/// `config` is NULL or points to a `pmsm_config_t`; `buf` is NULL or points to `len` writable
/// bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_injection_message(
    config: *const pmsm_config_t,
    buf: *mut c_char,
    len: usize,
) -> usize {
    // SAFETY: forwarded contract.
    unsafe {
        message(config, buf, len, |w, built| match built {
            Err(r) => core::fmt::write(w, format_args!("{r}")),
            Ok(b) => convert::write_injection(w, &b.config),
        })
    }
}

/// Builds `config` and writes what `write` makes of it into the C buffer `buf` of `len` bytes,
/// truncated and NUL-terminated; the whole message's length (0 for a NULL or misaligned
/// `config`).
///
/// # Safety
/// As `pmsm_config_error_message`.
unsafe fn message(
    config: *const pmsm_config_t,
    buf: *mut c_char,
    len: usize,
    write: impl FnOnce(&mut CBuf<'_>, Result<convert::Built, convert::Rejected>) -> core::fmt::Result,
) -> usize {
    // SAFETY: forwarded contract.
    let Ok(c) = (unsafe { arg(config) }) else {
        return 0;
    };
    let mut empty = [0u8; 0];
    let out: &mut [u8] = if buf.is_null() || len == 0 {
        &mut empty
    } else {
        // SAFETY: non-null, `len` writable bytes (contract); u8 has alignment 1.
        unsafe { core::slice::from_raw_parts_mut(buf.cast::<u8>(), len) }
    };
    let mut w = CBuf {
        buf: out,
        used: 0,
        needed: 0,
    };
    let _ = write(&mut w, convert::build(c));
    if let Some(b) = w.buf.get_mut(w.used) {
        *b = 0;
    }
    w.needed
}

/// Builds a drive from `config` in caller-provided `storage` of `len` bytes (at least
/// `pmsm_drive_size()`, aligned to `pmsm_drive_align()`; `pmsm_storage_t` is both) and
/// writes the handle (the storage's address) to `*drive`. The drive starts in
/// `PMSM_STATE_IDLE` with a zero speed reference. Computes the fixed-point coefficients in
/// double precision (software floating point on an MCU without a double FPU: call it once,
/// outside the ISR). Nothing is written to the storage on error.
///
/// # Safety
/// `storage` is NULL or points to `len` writable bytes not otherwise in use; `config` is NULL
/// or points to a `pmsm_config_t`; `drive` is NULL or points to a writable pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_drive_init(
    storage: *mut c_void,
    len: usize,
    config: *const pmsm_config_t,
    drive: *mut *mut pmsm_drive_t,
) -> pmsm_status_t {
    if storage.is_null() || drive.is_null() {
        return pmsm_status_t::PMSM_ERR_NULL;
    }
    if len < size_of::<pmsm_drive_t>() {
        return pmsm_status_t::PMSM_ERR_BUFFER_TOO_SMALL;
    }
    let p = storage.cast::<pmsm_drive_t>();
    if !aligned(p) || !aligned(drive) {
        return pmsm_status_t::PMSM_ERR_MISALIGNED;
    }
    // SAFETY: forwarded contract.
    let c = match unsafe { arg(config) } {
        Ok(c) => c,
        Err(e) => return e,
    };
    let built = match convert::build(c) {
        Ok(b) => b,
        Err(r) => return r.status(),
    };
    // SAFETY: `p` is non-null, aligned and has room for a `pmsm_drive_t` (checked above),
    // writable and not otherwise in use per the contract.
    unsafe { emplace(p, &built.config, built.period, built.pole_pairs) };
    // SAFETY: `drive` is non-null and aligned (checked), writable per the contract.
    unsafe { put(drive, p) }
}

/// Starts the drive from `PMSM_STATE_IDLE` with the configured start-up (IPD, alignment or
/// known angle) and empties the fault recorder; does nothing in other states. Acts at the
/// task's next `pmsm_task`; the outputs follow from the `pmsm_step` after it.
///
/// # Safety
/// `drive` is NULL or a handle from `pmsm_drive_init` (or storage of `pmsm_drive_size()`
/// bytes). A task-side function: call it from the context of `pmsm_task`, or where
/// `pmsm_task` cannot run during the call (and, for the recorder, not during a `pmsm_step`:
/// with the control interrupt masked, or before the drive runs).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_start(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let (task, _) = match unsafe { task_side(drive) } {
        Ok(t) => t,
        Err(e) => return e,
    };
    if task.state() == DriveState::Idle {
        // SAFETY: forwarded contract (the recorder is not in use during the call).
        if let Ok(i) = unsafe { isr_side(drive) } {
            i.recorder.rearm();
        }
    }
    task.start();
    pmsm_status_t::PMSM_OK
}

/// Turns the outputs off and returns to `PMSM_STATE_IDLE` (also from a fault; the fault
/// record stays frozen until the next `pmsm_start`), from the `pmsm_step` after the next
/// `pmsm_task`.
///
/// # Safety
/// As `pmsm_start` (a task-side function).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_stop(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { task_side(drive) }.map(|(t, _)| t.stop()))
}

/// Leaves `PMSM_STATE_FAULT` for `PMSM_STATE_IDLE` (then `pmsm_start` again) and empties the
/// fault recorder (read it first); does nothing in other states. A trip of the interrupt
/// side reaches the task at its next `pmsm_task`: clear after it.
///
/// # Safety
/// As `pmsm_start` (a task-side function).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_clear_fault(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let (task, _) = match unsafe { task_side(drive) } {
        Ok(t) => t,
        Err(e) => return e,
    };
    if matches!(task.state(), DriveState::Fault(_)) {
        // SAFETY: forwarded contract (the recorder is not in use during the call).
        if let Ok(i) = unsafe { isr_side(drive) } {
            i.recorder.rearm();
        }
    }
    task.clear_fault();
    pmsm_status_t::PMSM_OK
}

/// Reports that a control step did not finish within its period (for example: the PWM
/// update interrupt found the ADC interrupt still running, or a cycle counter read at the end
/// of the ISR exceeded the period). Trips `PMSM_FAULT_OVERRUN` (outputs off from the next
/// step on) unless the drive is idle or already faulted. Integer only; an interrupt-side
/// function.
///
/// # Safety
/// `drive` as `pmsm_start`; call it from the context of `pmsm_step` (or with it masked).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_report_overrun(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { isr_side(drive) }.map(|i| i.isr.report_overrun()))
}

/// Sets the speed reference: signed electrical speed, Q8.24 per unit of `omega_b`
/// (`pmsm_get_bases`; `pmsm_scale_speed` converts r/min). Taken at the task's next
/// `pmsm_task`.
///
/// # Safety
/// As `pmsm_start` (a task-side function).
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_set_speed_ref(drive: *mut pmsm_drive_t, omega: i32) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { task_side(drive) }.map(|(t, _)| t.set_speed_ref(Pu::from_bits(omega))))
}

/// The interrupt step, once per control sample, integer arithmetic only: from the phase
/// currents and the bus voltage sampled at the PWM centre (`input`, Q8.24 pu) to the duties
/// of the next period (`output`). Call it once per sample period (`pmsm_config_t.sample_hz`)
/// from the ADC/PWM interrupt. When `output->task_due` is 1, a task period has ended: pend
/// the task that calls `pmsm_task`, at a lower priority; it must return before the next task
/// period ends (`PMSM_TASK_PERIOD` samples later), else the drive trips
/// `PMSM_FAULT_OVERRUN`. The drive is not stepped when a pointer is NULL or invalid. Also
/// records the sample in the drive's fault recorder (`pmsm_fault_record_get`) until a fault
/// freezes it.
///
/// # Safety
/// `drive` as `pmsm_start`, called from the control interrupt only (it may preempt
/// `pmsm_task`, not be preempted by it); `input` NULL or pointing to a `pmsm_input_t`;
/// `output` NULL or pointing to a writable `pmsm_output_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_step(
    drive: *mut pmsm_drive_t,
    input: *const pmsm_input_t,
    output: *mut pmsm_output_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { isr_side(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    // SAFETY: forwarded contract.
    let i = match unsafe { arg(input) } {
        Ok(i) => *i,
        Err(e) => return e,
    };
    if output.is_null() {
        return pmsm_status_t::PMSM_ERR_NULL;
    }
    if !aligned(output) {
        return pmsm_status_t::PMSM_ERR_MISALIGNED;
    }
    let input = DriveInput {
        i_abc: Abc {
            a: Pu::from_bits(i.i_a),
            b: Pu::from_bits(i.i_b),
            c: Pu::from_bits(i.i_c),
        },
        vdc: Pu::from_bits(i.vdc),
    };
    let out = d.isr.step(d.handoff, &input);
    // Here, not left to the caller, so that a C firmware always has the record of a fault.
    d.recorder.record(d.isr, &input);
    let cmp = out.duties.to_compare(d.period);
    let value = pmsm_output_t {
        duty: [
            out.duties.a.to_bits(),
            out.duties.b.to_bits(),
            out.duties.c.to_bits(),
        ],
        compare: cmp,
        pwm_on: u8::from(out.pwm_on),
        state: convert::state_code(&d.isr.state()) as u8,
        task_due: u8::from(d.isr.task_due()),
    };
    // SAFETY: non-null and aligned (checked), writable per the contract.
    unsafe { put(output, value) }
}

/// The task step, once per task period (`PMSM_TASK_PERIOD` samples), at a priority below the
/// control interrupt, pended when `pmsm_step` returns `task_due`: the state machine, the speed
/// loop, the d-axis reference, the slower fault checks. Its result acts from the next
/// `pmsm_step`; it must return before the next task period ends (else `PMSM_FAULT_OVERRUN`).
/// Integer, but for a few double-precision operations at the end of the standstill dead-time
/// calibration (once per start); no allocation.
///
/// # Safety
/// `drive` as `pmsm_start`; called from one context (the task's), which `pmsm_step` may
/// preempt.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_task(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { task_side(drive) }.map(|(t, h)| t.step(h)))
}
