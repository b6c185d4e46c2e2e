//! Integer conversions from ADC codes and r/min to the drive's Q8.24 per-unit values.
#![allow(unsafe_code)]

use crate::handle::pmsm_drive_t;
use crate::handle::{arg, drive, put};
use crate::types::*;

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
/// A/LSB) to Q8.24 per unit: `i_pu = pmsm_scale_apply(&s, code - offset)`. The sign is part
/// of the scale: the drive takes a current as positive when it flows into the motor, so pass
/// a negative `amps_per_unit` when the code falls as current flows into the motor (an
/// inverting shunt amplifier); the gain of the returned scale then is negative.
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
    unsafe { scale_out(drive, out, |d| amps_per_unit / d.core.base.current_a) }
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
    unsafe { scale_out(drive, out, |d| volts_per_unit / d.core.base.voltage_v) }
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
            rpm_per_unit * core::f64::consts::TAU / 60.0 * d.core.pole_pairs as f64
                / d.core.base.omega_e_rad_s
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
