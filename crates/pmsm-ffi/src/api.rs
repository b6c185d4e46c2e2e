//! The `extern "C"` functions and the C types of `pmsm.h`.
//!
//! Pointer contract of every function: a pointer argument is either null (the function
//! returns an error) or points to valid memory of the documented type. Handles are checked for
//! alignment and for the mark written by `pmsm_drive_init`, so storage that was never
//! initialised is refused, not used.
#![allow(unsafe_code)]

use crate::convert::{self, CBuf};
use core::ffi::{c_char, c_void};
use core::mem::{align_of, size_of};
use pmsm_core::Abc;
use pmsm_core::Pu;
use pmsm_core::{Drive, DriveInput};

/// Status returned by every function that can fail. `PMSM_OK` (0) is success; errors are
/// negative. `pmsm_status_message` gives a one-line description of each.
#[repr(i32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_status_t {
    /// Success.
    PMSM_OK = 0,
    /// A required pointer argument is NULL.
    PMSM_ERR_NULL = -1,
    /// The storage is smaller than `pmsm_drive_size()` bytes.
    PMSM_ERR_BUFFER_TOO_SMALL = -2,
    /// A pointer is not aligned for its type (storage: `pmsm_drive_align()` bytes).
    PMSM_ERR_MISALIGNED = -3,
    /// The handle does not point to a drive initialised by `pmsm_drive_init`.
    PMSM_ERR_NOT_INITIALIZED = -4,
    /// An enumerated code or integer argument is out of range.
    PMSM_ERR_INVALID_ARGUMENT = -5,
    /// A physical parameter of the configuration is invalid (not finite, not positive, out of
    /// its physical range); `pmsm_config_error_message` names it.
    PMSM_ERR_CONFIG_PARAM = -6,
    /// The motor, bus and sample rate fall outside the fixed-point envelope.
    PMSM_ERR_CONFIG_ENVELOPE = -7,
    /// A controller or estimator gain is outside its stable, representable range.
    PMSM_ERR_CONFIG_GAIN = -8,
}

/// The drive's rotor-position estimator (`pmsm_config_t.estimator`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_estimator_t {
    /// Current-model MRAS (seed 001), works from standstill after IPD. The default (0).
    PMSM_ESTIMATOR_MRAS_CURRENT = 0,
    /// Nonlinear reduced-order back-EMF observer (seed 000); open-loop start.
    PMSM_ESTIMATOR_NLO = 1,
    /// Linear reduced-order back-EMF observer (seed 000); open-loop start.
    PMSM_ESTIMATOR_AO = 2,
    /// MRAS speed estimator on the back-EMF observer (seed 000); open-loop start.
    PMSM_ESTIMATOR_MRAS_EMF = 3,
}

/// How the drive finds the rotor on `pmsm_start` (`pmsm_config_t.startup`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_startup_t {
    /// The estimator's default: IPD for the current-model MRAS, alignment otherwise (0).
    PMSM_STARTUP_DEFAULT = 0,
    /// Initial position detection from voltage pulses (needs saliency, L_d < L_q).
    PMSM_STARTUP_IPD = 1,
    /// Pull the rotor to electrical angle 0 with a d-axis current first.
    PMSM_STARTUP_ALIGN = 2,
    /// The rotor is at `pmsm_config_t.startup_angle`.
    PMSM_STARTUP_KNOWN = 3,
}

/// Dead-time compensation (`pmsm_config_t.deadtime_compensation`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_deadtime_t {
    /// The default: both (0).
    PMSM_DEADTIME_DEFAULT = 0,
    /// No compensation.
    PMSM_DEADTIME_OFF = 1,
    /// Added to the voltage command only.
    PMSM_DEADTIME_COMMAND = 2,
    /// Removed from the voltage the estimator sees only.
    PMSM_DEADTIME_ESTIMATOR = 3,
    /// Both.
    PMSM_DEADTIME_BOTH = 4,
}

/// What the drive is doing (`pmsm_state_info_t.state`, `pmsm_output_t.state`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_state_t {
    /// Outputs off, waiting for `pmsm_start`.
    PMSM_STATE_IDLE = 0,
    /// Detecting the initial rotor position.
    PMSM_STATE_IPD = 1,
    /// Aligning the rotor to angle 0.
    PMSM_STATE_ALIGN = 2,
    /// Open-loop current-vector start (back-EMF estimators).
    PMSM_STATE_OPEN_LOOP = 3,
    /// Sensorless closed loop.
    PMSM_STATE_RUN = 4,
    /// Outputs off after a fault, latched until `pmsm_clear_fault` or `pmsm_stop`.
    PMSM_STATE_FAULT = 5,
    /// A state of a newer core that this interface does not name.
    PMSM_STATE_OTHER = 255,
}

/// Why the drive stopped switching (`pmsm_state_info_t.fault`).
#[repr(u32)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum pmsm_fault_t {
    /// No fault (the state is not `PMSM_STATE_FAULT`).
    PMSM_FAULT_NONE = 0,
    /// A phase current beyond the trip threshold; value: the current, Q8.24 pu.
    PMSM_FAULT_OVERCURRENT = 1,
    /// The bus voltage below its minimum; value: the bus, Q8.24 pu.
    PMSM_FAULT_BUS_UNDERVOLTAGE = 2,
    /// The bus voltage above its maximum; value: the bus, Q8.24 pu.
    PMSM_FAULT_BUS_OVERVOLTAGE = 3,
    /// The initial position detection failed (no current, low saliency, overcurrent).
    PMSM_FAULT_INITIAL_POSITION = 4,
    /// The estimator disagreed with the open-loop frame at handover; value: the angle
    /// difference, turn (2^32 = one electrical turn).
    PMSM_FAULT_HANDOVER = 5,
    /// A fault of a newer core that this interface does not name.
    PMSM_FAULT_OTHER = 255,
}

/// Configuration of a drive: motor, inverter and control, SI units. Zero-initialise it
/// (`pmsm_config_t c = {0};`), then set the motor and inverter: every optional field left at 0
/// takes the library's default, computed from the motor and inverter.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct pmsm_config_t {
    /// Pole pairs `p` (1..100).
    pub pole_pairs: u32,
    /// A `pmsm_estimator_t` (0: current-model MRAS).
    pub estimator: u32,
    /// A `pmsm_startup_t` (0: the estimator's default).
    pub startup: u32,
    /// A `pmsm_deadtime_t` (0: compensation on, both command and estimator).
    pub deadtime_compensation: u32,
    /// Rotor electrical angle for `PMSM_STARTUP_KNOWN`, turn (2^32 = one turn, signed).
    pub startup_angle: i32,
    /// Period of the centre-aligned PWM timer in counts (the compare value of duty 1), 0 to
    /// 65535, for `pmsm_output_t.compare` (0: the compare values are 0).
    pub pwm_period_ticks: u32,
    /// Stator phase resistance `R`, ohm.
    pub rs_ohm: f64,
    /// Direct-axis inductance `L_d`, H.
    pub ld_h: f64,
    /// Quadrature-axis inductance `L_q`, H (`L_d = L_q`: surface motor).
    pub lq_h: f64,
    /// Peak magnet flux linkage `psi`, V*s/rad electrical.
    pub flux_wb: f64,
    /// Torque constant, N*m/A peak (optional; 0: `1.5 p psi`).
    pub kt_nm_per_a: f64,
    /// Rotor and load inertia, kg*m^2.
    pub j_kg_m2: f64,
    /// Viscous friction, N*m*s/rad (0 allowed).
    pub b_nm_s: f64,
    /// Rated phase current, A RMS (optional; 0: from the envelope). 1 pu current = sqrt(2)
    /// times this.
    pub rated_current_a: f64,
    /// Rated mechanical speed, r/min (optional).
    pub rated_speed_rpm: f64,
    /// Nominal DC bus voltage, V. 1 pu voltage = `vdc_v / sqrt(3)`.
    pub vdc_v: f64,
    /// PWM switching frequency, Hz.
    pub pwm_hz: f64,
    /// Dead time, s.
    pub dead_time_s: f64,
    /// Full scale of the current sensing, A peak (optional; 0: 4 pu).
    pub current_full_scale_a: f64,
    /// Control sample rate (calls of `pmsm_step` per second), Hz (optional; 0: `pwm_hz`).
    pub sample_hz: f64,
    /// Current-loop bandwidth, Hz (optional).
    pub current_bandwidth_hz: f64,
    /// Speed-loop bandwidth, Hz (optional).
    pub speed_bandwidth_hz: f64,
    /// Current limit of the speed loop (and of the open-loop start), A peak (optional).
    pub current_limit_a: f64,
    /// Gain of the back-EMF observers, rad/s (optional).
    pub observer_gain_rad_s: f64,
}

/// The measurements of one control sample, Q8.24 per unit (`2^24` = 1.0 pu).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_input_t {
    /// Phase current a, sampled at the PWM centre, per unit of `I_b` (`pmsm_get_bases`).
    pub i_a: i32,
    /// Phase current b, per unit of `I_b`.
    pub i_b: i32,
    /// Phase current c, per unit of `I_b`.
    pub i_c: i32,
    /// DC bus voltage, per unit of `V_b = vdc_v / sqrt(3)` (the nominal bus is 1.7320508 pu
    /// = 29058991).
    pub vdc: i32,
}

/// What to apply over the next PWM period.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_output_t {
    /// Leg duties a, b, c (high-side on-time over the period), Q2.30 in [0, 2^30].
    pub duty: [i32; 3],
    /// The same as compare values of a centre-aligned timer counting to
    /// `pmsm_config_t.pwm_period_ticks`: `round(duty * period)`.
    pub compare: [u16; 3],
    /// 1: switch with these duties; 0: turn every switch off (duties are 0.5 then).
    pub pwm_on: u8,
    /// The state after this step, a `pmsm_state_t`.
    pub state: u8,
}

/// The state and the latched fault.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_state_info_t {
    /// A `pmsm_state_t`.
    pub state: u32,
    /// A `pmsm_fault_t` (`PMSM_FAULT_NONE` unless `state` is `PMSM_STATE_FAULT`).
    pub fault: u32,
    /// The fault's value (see `pmsm_fault_t`), 0 if none.
    pub fault_value: i32,
}

/// The rotor estimate of the last step.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_estimate_t {
    /// Electrical angle of the rotor d axis, turn (2^32 = one turn, wrapping; signed).
    pub theta: i32,
    /// Signed electrical speed, Q8.24 per unit of `omega_b` (`pmsm_get_bases`).
    pub omega: i32,
}

/// Per-unit bases of a drive, SI (for logs and conversions outside the ISR).
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct pmsm_bases_t {
    /// 1 pu current `I_b`, A peak.
    pub current_a: f64,
    /// 1 pu voltage `V_b = vdc / sqrt(3)`, V.
    pub voltage_v: f64,
    /// 1 pu speed `omega_b`, electrical rad/s.
    pub omega_e_rad_s: f64,
    /// Control sample period, s.
    pub sample_s: f64,
}

/// An integer conversion to Q8.24 per unit: `pu = (x * gain) >> shift`, rounded to nearest
/// and saturated (`pmsm_scale_apply`). For ADC codes, subtract the offset first.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct pmsm_scale_t {
    /// Multiplier.
    pub gain: i32,
    /// Right shift, 0..62.
    pub shift: u32,
}

/// Size of static storage that holds a drive on every supported target, bytes. The C
/// firmware can declare `static pmsm_storage_t storage;` (`sizeof` = this, aligned to 8).
pub const PMSM_STORAGE_SIZE: usize = 4096;

/// `PMSM_STORAGE_SIZE / 8`: the `uint64_t` words of `pmsm_storage_t`.
pub const PMSM_STORAGE_WORDS: usize = 512;

/// Statically allocatable storage for one drive: `static pmsm_storage_t storage;` then
/// `pmsm_drive_init(&storage, sizeof storage, &config, &drive)`.
#[repr(C)]
#[derive(Clone, Copy, Debug)]
pub struct pmsm_storage_t {
    /// The bytes, as `uint64_t` for 8-byte alignment.
    pub words: [u64; PMSM_STORAGE_WORDS],
}

/// A drive, in caller-provided storage. Opaque to C.
#[derive(Debug)]
pub struct pmsm_drive_t {
    mark: u32,
    period: u16,
    pole_pairs: u32,
    drive: Drive,
}

const MARK: u32 = 0x504D_534D; // "PMSM"

const _: () = assert!(PMSM_STORAGE_WORDS * 8 == PMSM_STORAGE_SIZE);
const _: () = assert!(
    size_of::<pmsm_drive_t>() <= PMSM_STORAGE_SIZE && align_of::<pmsm_drive_t>() <= 8,
    "the drive outgrew PMSM_STORAGE_SIZE: raise it (and regenerate pmsm.h)"
);

fn aligned<T>(p: *const T) -> bool {
    (p as usize).is_multiple_of(align_of::<T>())
}

/// A shared reference to `*p` if it is non-null and aligned.
///
/// # Safety
/// `p` is null or points to a valid `T` (all bit patterns of the `T`s used here are valid).
unsafe fn arg<'a, T>(p: *const T) -> Result<&'a T, pmsm_status_t> {
    if p.is_null() {
        Err(pmsm_status_t::PMSM_ERR_NULL)
    } else if !aligned(p) {
        Err(pmsm_status_t::PMSM_ERR_MISALIGNED)
    } else {
        // SAFETY: non-null and aligned (checked); valid per the caller's contract.
        Ok(unsafe { &*p })
    }
}

/// Writes `value` to `*p` if it is non-null and aligned.
///
/// # Safety
/// `p` is null or points to writable memory for a `T`.
unsafe fn put<T>(p: *mut T, value: T) -> pmsm_status_t {
    if p.is_null() {
        pmsm_status_t::PMSM_ERR_NULL
    } else if !aligned(p) {
        pmsm_status_t::PMSM_ERR_MISALIGNED
    } else {
        // SAFETY: non-null and aligned (checked); writable per the caller's contract. `write`
        // does not read or drop the old contents.
        unsafe { core::ptr::write(p, value) };
        pmsm_status_t::PMSM_OK
    }
}

/// The drive behind a handle, checked for null, alignment and the init mark.
///
/// # Safety
/// `d` is null or points to at least `size_of::<pmsm_drive_t>()` readable and writable bytes
/// that nothing else accesses during the call.
unsafe fn drive<'a>(d: *mut pmsm_drive_t) -> Result<&'a mut pmsm_drive_t, pmsm_status_t> {
    if d.is_null() {
        return Err(pmsm_status_t::PMSM_ERR_NULL);
    }
    if !aligned(d) {
        return Err(pmsm_status_t::PMSM_ERR_MISALIGNED);
    }
    // SAFETY: non-null, aligned, readable (contract); the mark is read through a raw place
    // before any reference to the drive exists, so uninitialised storage is only read as a
    // `u32` (any bit pattern is a valid `u32`).
    let mark = unsafe { core::ptr::addr_of!((*d).mark).read_volatile() };
    if mark != MARK {
        return Err(pmsm_status_t::PMSM_ERR_NOT_INITIALIZED);
    }
    // SAFETY: the mark is only written by `pmsm_drive_init` together with a whole valid
    // `pmsm_drive_t`; exclusive access per the contract.
    Ok(unsafe { &mut *d })
}

fn status(r: Result<(), pmsm_status_t>) -> pmsm_status_t {
    match r {
        Ok(()) => pmsm_status_t::PMSM_OK,
        Err(e) => e,
    }
}

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
    let _ = match convert::build(c) {
        Ok(_) => core::fmt::Write::write_str(&mut w, "ok"),
        Err(r) => core::fmt::write(&mut w, format_args!("{r}")),
    };
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
    let value = pmsm_drive_t {
        mark: MARK,
        period: built.period,
        pole_pairs: built.pole_pairs,
        drive: Drive::new(built.config),
    };
    // SAFETY: `p` is non-null, aligned and has room for a `pmsm_drive_t` (checked above),
    // writable per the contract; `put` writes without reading the old contents.
    let _ = unsafe { put(p, value) };
    // SAFETY: `drive` is non-null and aligned (checked), writable per the contract.
    unsafe { put(drive, p) }
}

/// Starts the drive from `PMSM_STATE_IDLE` with the configured start-up (IPD, alignment or
/// known angle); does nothing in other states.
///
/// # Safety
/// `drive` is NULL or a handle from `pmsm_drive_init` (or storage of `pmsm_drive_size()`
/// bytes), not used concurrently (e.g. from the ISR) during the call.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_start(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { self::drive(drive) }.map(|d| d.drive.start()))
}

/// Turns the outputs off and returns to `PMSM_STATE_IDLE` (also from a fault).
///
/// # Safety
/// As `pmsm_start`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_stop(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { self::drive(drive) }.map(|d| d.drive.stop()))
}

/// Leaves `PMSM_STATE_FAULT` for `PMSM_STATE_IDLE` (then `pmsm_start` again); does nothing in
/// other states.
///
/// # Safety
/// As `pmsm_start`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_clear_fault(drive: *mut pmsm_drive_t) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { self::drive(drive) }.map(|d| d.drive.clear_fault()))
}

/// Sets the speed reference: signed electrical speed, Q8.24 per unit of `omega_b`
/// (`pmsm_get_bases`; `pmsm_scale_speed` converts r/min). Takes effect at the next step.
///
/// # Safety
/// As `pmsm_start`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_set_speed_ref(drive: *mut pmsm_drive_t, omega: i32) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    status(unsafe { self::drive(drive) }.map(|d| d.drive.set_speed_ref(Pu::from_bits(omega))))
}

/// One control sample, integer arithmetic only: from the phase currents and the bus voltage
/// sampled at the PWM centre (`input`, Q8.24 pu) to the duties of the next period (`output`).
/// Call it once per sample period (`pmsm_config_t.sample_hz`) from the ADC/PWM interrupt. The
/// drive is not stepped when a pointer is NULL or invalid.
///
/// # Safety
/// `drive` as `pmsm_start`; `input` NULL or pointing to a `pmsm_input_t`; `output` NULL or
/// pointing to a writable `pmsm_output_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_step(
    drive: *mut pmsm_drive_t,
    input: *const pmsm_input_t,
    output: *mut pmsm_output_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { self::drive(drive) } {
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
    let out = d.drive.step(&DriveInput {
        i_abc: Abc {
            a: Pu::from_bits(i.i_a),
            b: Pu::from_bits(i.i_b),
            c: Pu::from_bits(i.i_c),
        },
        vdc: Pu::from_bits(i.vdc),
    });
    let cmp = out.duties.to_compare(d.period);
    let value = pmsm_output_t {
        duty: [
            out.duties.a.to_bits(),
            out.duties.b.to_bits(),
            out.duties.c.to_bits(),
        ],
        compare: cmp,
        pwm_on: u8::from(out.pwm_on),
        state: convert::state_code(&d.drive.state()) as u8,
    };
    // SAFETY: non-null and aligned (checked), writable per the contract.
    unsafe { put(output, value) }
}

/// The state and the latched fault.
///
/// # Safety
/// `drive` as `pmsm_start`; `out` NULL or pointing to a writable `pmsm_state_info_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_state(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_state_info_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { self::drive(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let s = d.drive.state();
    let (fault, value) = convert::fault_code(&s);
    // SAFETY: forwarded contract.
    unsafe {
        put(
            out,
            pmsm_state_info_t {
                state: convert::state_code(&s) as u32,
                fault: fault as u32,
                fault_value: value,
            },
        )
    }
}

/// The rotor angle and speed estimated at the last step.
///
/// # Safety
/// `drive` as `pmsm_start`; `out` NULL or pointing to a writable `pmsm_estimate_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_get_estimate(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_estimate_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { self::drive(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    let e = d.drive.telemetry().estimate;
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
    let b = d.drive.config().base;
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

/// The scale of `per_unit_in` / `base` as Q8.24 per input unit, with the largest shift that
/// keeps the gain in an `int32_t`.
fn scale(k: f64) -> Result<pmsm_scale_t, pmsm_status_t> {
    let k = k * (1u64 << 24) as f64;
    if !k.is_finite() || k == 0.0 {
        return Err(pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT);
    }
    let max = i32::MAX as f64;
    let mut shift = 0u32;
    let mut g = k;
    if (g.abs() + 0.5) >= max {
        return Err(pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT);
    }
    while shift < 62 && (g.abs() * 2.0 + 0.5) < max {
        g *= 2.0;
        shift += 1;
    }
    // Round to nearest (no libm needed: |g| < 2^31).
    let r = if g < 0.0 { g - 0.5 } else { g + 0.5 } as i32;
    if r == 0 {
        return Err(pmsm_status_t::PMSM_ERR_INVALID_ARGUMENT);
    }
    Ok(pmsm_scale_t { gain: r, shift })
}

/// # Safety
/// `drive` and `out` as in `pmsm_scale_current`.
unsafe fn scale_out(
    drive: *mut pmsm_drive_t,
    out: *mut pmsm_scale_t,
    k: impl FnOnce(&pmsm_drive_t) -> f64,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    let d = match unsafe { self::drive(drive) } {
        Ok(d) => d,
        Err(e) => return e,
    };
    match scale(k(d)) {
        // SAFETY: forwarded contract.
        Ok(s) => unsafe { put(out, s) },
        Err(e) => e,
    }
}

/// The integer conversion of a current measured in units of `amps_per_unit` A (the ADC's
/// A/LSB, sign included) to Q8.24 per unit: `i_pu = pmsm_scale_apply(&s, code - offset)`.
///
/// # Safety
/// `drive` as `pmsm_start`; `out` NULL or pointing to a writable `pmsm_scale_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_scale_current(
    drive: *mut pmsm_drive_t,
    amps_per_unit: f64,
    out: *mut pmsm_scale_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    unsafe {
        scale_out(drive, out, |d| {
            amps_per_unit / d.drive.config().base.current_a
        })
    }
}

/// The integer conversion of a bus voltage measured in units of `volts_per_unit` V (the
/// ADC's V/LSB after the divider) to Q8.24 per unit.
///
/// # Safety
/// As `pmsm_scale_current`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_scale_voltage(
    drive: *mut pmsm_drive_t,
    volts_per_unit: f64,
    out: *mut pmsm_scale_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    unsafe {
        scale_out(drive, out, |d| {
            volts_per_unit / d.drive.config().base.voltage_v
        })
    }
}

/// The integer conversion of a mechanical speed in units of `rpm_per_unit` r/min (1.0 for
/// whole r/min) to the Q8.24 per-unit electrical speed of `pmsm_set_speed_ref`.
///
/// # Safety
/// As `pmsm_scale_current`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_scale_speed(
    drive: *mut pmsm_drive_t,
    rpm_per_unit: f64,
    out: *mut pmsm_scale_t,
) -> pmsm_status_t {
    // SAFETY: forwarded contract.
    unsafe {
        scale_out(drive, out, |d| {
            rpm_per_unit * core::f64::consts::TAU / 60.0 * d.pole_pairs as f64
                / d.drive.config().base.omega_e_rad_s
        })
    }
}

/// `(x * scale->gain) >> scale->shift`, rounded to nearest, saturated to `int32_t`; 0 when
/// `scale` is NULL, misaligned or its shift is over 62. Integer only (ISR-safe).
///
/// # Safety
/// `scale` is NULL or points to a `pmsm_scale_t`.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_scale_apply(scale: *const pmsm_scale_t, x: i32) -> i32 {
    // SAFETY: forwarded contract.
    let Ok(s) = (unsafe { arg(scale) }) else {
        return 0;
    };
    if s.shift > 62 {
        return 0;
    }
    let p = x as i64 * s.gain as i64;
    let r = if s.shift == 0 {
        p
    } else {
        (p + (1i64 << (s.shift - 1))) >> s.shift
    };
    r.clamp(i32::MIN as i64, i32::MAX as i64) as i32
}
