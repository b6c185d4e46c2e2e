//! A drive built once on the host and loaded on the target without the design code.
//!
//! `pmsm_drive_init` computes the fixed-point coefficients in double precision: on a
//! Cortex-M4 (single-precision FPU) that is software floating point, `libm` and every
//! estimator's design, about 30 KiB of flash used once at start-up. A firmware that knows its
//! motor can instead build the drive on the host with the same library, save its image
//! (`pmsm_drive_image`), and link only `pmsm_drive_init_image` and the per-sample path.
//!
//! The image is the drive's memory as the library lays it out (without the fault recorder,
//! which starts empty), behind a header: magic, the build id (a hash of the pmsm-core and pmsm-ffi sources, the compiler version and the
//! estimator features, from `build.rs`), the payload's size and its CRC-32. The target
//! accepts only an image of the same build and size, intact; that the host and target
//! libraries then lay the drive out alike (no pointer or `usize` in it, 8-byte alignment of
//! 64-bit words on both) is what `scripts/c-firmware.sh` checks by replaying a host image bit
//! for bit on a Cortex-M4.
#![allow(unsafe_code)]

use crate::handle::{DriveCore, MARK, aligned, drive, pmsm_drive_t, put};
use crate::types::pmsm_status_t;
use core::ffi::c_void;
use core::mem::{offset_of, size_of};

/// "PMIG", the first word of an image (little-endian).
pub const PMSM_IMAGE_MAGIC: u32 = 0x4749_4D50;

/// Bytes of the image header: magic, build id, payload size, CRC-32 of the payload.
pub const PMSM_IMAGE_HEADER_SIZE: usize = 16;

/// The build id of this library (see the module documentation).
fn build_id() -> u32 {
    const ID: &str = env!("PMSM_FFI_BUILD_ID");
    // Eight hex digits written by build.rs.
    ID.bytes().fold(0u32, |acc, b| {
        let digit = match b {
            b'0'..=b'9' => b - b'0',
            b'a'..=b'f' => b - b'a' + 10,
            _ => 0,
        };
        (acc << 4) | u32::from(digit)
    })
}

/// CRC-32 (IEEE 802.3, reflected, the zlib one), bitwise: no table in flash.
fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = (crc >> 1) ^ (0xEDB8_8320 & 0u32.wrapping_sub(crc & 1));
        }
    }
    !crc
}

/// The little-endian `u32` at byte `offset` (0 past the end).
fn word(bytes: &[u8], offset: usize) -> u32 {
    let mut w = [0u8; 4];
    if let Some(b) = bytes.get(offset..offset + 4) {
        w.copy_from_slice(b);
    }
    u32::from_le_bytes(w)
}

/// Bytes of the image of a drive of this library (`PMSM_IMAGE_HEADER_SIZE` and the drive
/// without its fault recorder).
#[unsafe(no_mangle)]
pub extern "C" fn pmsm_image_size() -> usize {
    PMSM_IMAGE_HEADER_SIZE + size_of::<DriveCore>()
}

/// Writes the image of `drive` as it is now (call it right after `pmsm_drive_init`, with the
/// drive idle) into `image` of `len` bytes, for `pmsm_drive_init_image` on a target built from
/// the same sources with the same estimator features. Returns the image's size
/// (`pmsm_image_size()`); nothing is written when `len` is smaller. Returns 0 when `drive` is
/// not a valid handle.
///
/// # Safety
/// `drive` as `pmsm_start`; `image` NULL or pointing to `len` writable bytes.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_drive_image(
    drive: *mut pmsm_drive_t,
    image: *mut c_void,
    len: usize,
) -> usize {
    // SAFETY: forwarded contract.
    let Ok(d) = (unsafe { self::drive(drive) }) else {
        return 0;
    };
    let size = pmsm_image_size();
    if image.is_null() || len < size {
        return size;
    }
    let d: *const DriveCore = &d.core;
    // SAFETY: `d` is a valid `DriveCore` of `size_of::<DriveCore>()` bytes. Its padding bytes
    // are copied as they are; the CRC covers them as written, and the target overwrites
    // them with its own values at the first write of each field.
    let payload = unsafe { core::slice::from_raw_parts(d.cast::<u8>(), size_of::<DriveCore>()) };
    // SAFETY: `image` is non-null with `len >= size` writable bytes (contract, checked).
    let out = unsafe { core::slice::from_raw_parts_mut(image.cast::<u8>(), size) };
    let header = [
        PMSM_IMAGE_MAGIC,
        build_id(),
        size_of::<DriveCore>() as u32,
        crc32(payload),
    ];
    let (head, body) = out.split_at_mut(PMSM_IMAGE_HEADER_SIZE);
    for (dst, w) in head.chunks_exact_mut(4).zip(header) {
        dst.copy_from_slice(&w.to_le_bytes());
    }
    body.copy_from_slice(payload);
    size
}

/// Builds a drive in caller-provided `storage` of `len` bytes (as `pmsm_drive_init`) from an
/// `image` of `image_len` bytes written by `pmsm_drive_image`, and writes the handle to
/// `*drive`. No floating point and no design code: the firmware links only this and the
/// per-sample path. Returns `PMSM_ERR_IMAGE` for an image of another build of the library
/// (sources, compiler or estimator features), of another size, or corrupted (CRC); nothing is
/// written to the storage then.
///
/// # Safety
/// `storage` as in `pmsm_drive_init`; `image` NULL or pointing to `image_len` readable bytes;
/// `drive` NULL or pointing to a writable pointer.
#[unsafe(no_mangle)]
pub unsafe extern "C" fn pmsm_drive_init_image(
    storage: *mut c_void,
    len: usize,
    image: *const c_void,
    image_len: usize,
    drive: *mut *mut pmsm_drive_t,
) -> pmsm_status_t {
    if storage.is_null() || drive.is_null() || image.is_null() {
        return pmsm_status_t::PMSM_ERR_NULL;
    }
    if len < size_of::<pmsm_drive_t>() {
        return pmsm_status_t::PMSM_ERR_BUFFER_TOO_SMALL;
    }
    let p = storage.cast::<pmsm_drive_t>();
    if !aligned(p) || !aligned(drive) {
        return pmsm_status_t::PMSM_ERR_MISALIGNED;
    }
    if image_len < pmsm_image_size() {
        return pmsm_status_t::PMSM_ERR_IMAGE;
    }
    // SAFETY: non-null, `image_len` readable bytes (contract); u8 has alignment 1.
    let bytes = unsafe { core::slice::from_raw_parts(image.cast::<u8>(), pmsm_image_size()) };
    let (head, payload) = bytes.split_at(PMSM_IMAGE_HEADER_SIZE);
    // Both ends are little-endian ARM or x86: the mark reads as written.
    let valid = word(head, 0) == PMSM_IMAGE_MAGIC
        && word(head, 4) == build_id()
        && word(head, 8) as usize == size_of::<DriveCore>()
        && word(head, 12) == crc32(payload)
        && word(payload, offset_of!(DriveCore, mark)) == MARK;
    if !valid {
        return pmsm_status_t::PMSM_ERR_IMAGE;
    }
    // SAFETY: the payload is the bytes of a valid `DriveCore` of this build (checked above:
    // same build, size and contents as written by `pmsm_drive_image`); the storage has room
    // for a `pmsm_drive_t` and is aligned (checked), writable per the contract, and does not
    // overlap the image (the image is read-only data). The recorder is written as new.
    unsafe {
        let dst = core::ptr::addr_of_mut!((*p).core);
        core::ptr::copy_nonoverlapping(payload.as_ptr(), dst.cast::<u8>(), payload.len());
        core::ptr::addr_of_mut!((*p).recorder).write(pmsm_core::FaultRecorder::new());
    }
    // SAFETY: `drive` is non-null and aligned (checked), writable per the contract.
    unsafe { put(drive, p) }
}

#[cfg(test)]
mod tests {
    #[test]
    fn crc32_is_the_zlib_one() {
        assert_eq!(super::crc32(b"123456789"), 0xCBF4_3926);
        assert_eq!(super::crc32(b""), 0);
    }
}
