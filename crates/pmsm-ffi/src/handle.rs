//! The opaque drive handle and the checked access to C pointers.
//!
//! Pointer contract of every function: a pointer argument is either null (the function
//! returns an error) or points to valid memory of the documented type. Handles are checked for
//! alignment and for the mark written at initialisation, so storage that was never
//! initialised is refused, not used.
#![allow(unsafe_code)]

use crate::types::{PMSM_FAULT_RECORD_DEPTH, PMSM_STORAGE_SIZE, PMSM_STORAGE_WORDS, pmsm_status_t};
use core::mem::{align_of, size_of};
use core::ptr::{addr_of, addr_of_mut};
use pmsm_core::{DriveIsr, DriveTask, FaultRecorder, Handoff, PerUnit};

/// A drive and its fault recorder, in caller-provided storage. Opaque to C.
#[derive(Debug)]
pub struct pmsm_drive_t {
    /// What a drive image holds (`src/image.rs`).
    pub(crate) core: DriveCore,
    /// Fed by `pmsm_step`; not in the image (it is run-time history, and its ring index is a
    /// `usize`, laid out differently on the host and the target).
    pub(crate) recorder: FaultRecorder<PMSM_FAULT_RECORD_DEPTH>,
}

/// The imaged part of a drive: the handle's mark, the timer period, the pole pairs (for the
/// speed scale), the bases, and the core drive's two sides and their handoff. The interrupt's
/// functions touch `isr` (and the recorder), the task's `task`; both share `handoff`, whose
/// mailboxes are atomic words.
#[derive(Debug)]
pub(crate) struct DriveCore {
    pub(crate) mark: u32,
    pub(crate) period: u16,
    pub(crate) pole_pairs: u32,
    pub(crate) base: PerUnit,
    pub(crate) handoff: Handoff,
    pub(crate) isr: DriveIsr,
    pub(crate) task: DriveTask,
}

pub(crate) const MARK: u32 = 0x504D_534D; // "PMSM"

const _: () = assert!(PMSM_STORAGE_WORDS * 8 == PMSM_STORAGE_SIZE);
const _: () = assert!(
    size_of::<pmsm_drive_t>() <= PMSM_STORAGE_SIZE && align_of::<pmsm_drive_t>() <= 8,
    "the drive outgrew PMSM_STORAGE_SIZE: raise it (and regenerate pmsm.h)"
);

pub(crate) fn aligned<T>(p: *const T) -> bool {
    (p as usize).is_multiple_of(align_of::<T>())
}

/// A shared reference to `*p` if it is non-null and aligned.
///
/// # Safety
/// `p` is null or points to a valid `T` (all bit patterns of the `T`s used here are valid).
pub(crate) unsafe fn arg<'a, T>(p: *const T) -> Result<&'a T, pmsm_status_t> {
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
pub(crate) unsafe fn put<T>(p: *mut T, value: T) -> pmsm_status_t {
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

/// The handle checked for null, alignment and the init mark.
///
/// # Safety
/// `d` is null or points to at least `size_of::<pmsm_drive_t>()` readable bytes.
unsafe fn checked(d: *mut pmsm_drive_t) -> Result<*mut pmsm_drive_t, pmsm_status_t> {
    if d.is_null() {
        return Err(pmsm_status_t::PMSM_ERR_NULL);
    }
    if !aligned(d) {
        return Err(pmsm_status_t::PMSM_ERR_MISALIGNED);
    }
    // SAFETY: non-null, aligned, readable (contract); the mark is read through a raw place
    // before any reference to the drive exists, so uninitialised storage is only read as a
    // `u32` (any bit pattern is a valid `u32`).
    let mark = unsafe { addr_of!((*d).core.mark).read_volatile() };
    if mark != MARK {
        return Err(pmsm_status_t::PMSM_ERR_NOT_INITIALIZED);
    }
    Ok(d)
}

/// What the interrupt's functions use: its side of the drive, the handoff and the recorder.
pub(crate) struct IsrSide<'a> {
    pub isr: &'a mut DriveIsr,
    pub handoff: &'a Handoff,
    pub recorder: &'a mut FaultRecorder<PMSM_FAULT_RECORD_DEPTH>,
    pub period: u16,
}

/// The interrupt's side of the drive behind a handle, checked.
///
/// # Safety
/// `d` is null or points to at least `size_of::<pmsm_drive_t>()` readable and writable bytes
/// whose interrupt side and recorder nothing else accesses during the call (the task's
/// functions may run: they touch the task side and the handoff's atomic words only).
pub(crate) unsafe fn isr_side<'a>(d: *mut pmsm_drive_t) -> Result<IsrSide<'a>, pmsm_status_t> {
    // SAFETY: forwarded contract.
    let d = unsafe { checked(d)? };
    // SAFETY: the mark is only written by `pmsm_drive_init` together with a whole valid
    // `pmsm_drive_t`. Each reference covers one field: disjoint from the task side, which
    // another context may hold; the handoff is shared (atomic words).
    unsafe {
        Ok(IsrSide {
            isr: &mut *addr_of_mut!((*d).core.isr),
            handoff: &*addr_of!((*d).core.handoff),
            recorder: &mut *addr_of_mut!((*d).recorder),
            period: addr_of!((*d).core.period).read(),
        })
    }
}

/// The task's side of the drive behind a handle and the handoff, checked.
///
/// # Safety
/// `d` is null or points to at least `size_of::<pmsm_drive_t>()` readable and writable bytes
/// whose task side nothing else accesses during the call (the interrupt's functions may run).
pub(crate) unsafe fn task_side<'a>(
    d: *mut pmsm_drive_t,
) -> Result<(&'a mut DriveTask, &'a Handoff), pmsm_status_t> {
    // SAFETY: forwarded contract.
    let d = unsafe { checked(d)? };
    // SAFETY: as in `isr_side`, the task's field only.
    unsafe {
        Ok((
            &mut *addr_of_mut!((*d).core.task),
            &*addr_of!((*d).core.handoff),
        ))
    }
}

/// The whole drive behind a handle, checked, for the functions outside both contexts
/// (initialisation, images, the recorder's reads, the bases).
///
/// # Safety
/// `d` is null or points to at least `size_of::<pmsm_drive_t>()` readable and writable bytes
/// that nothing else accesses during the call.
pub(crate) unsafe fn drive<'a>(
    d: *mut pmsm_drive_t,
) -> Result<&'a mut pmsm_drive_t, pmsm_status_t> {
    // SAFETY: forwarded contract; exclusive access.
    Ok(unsafe { &mut *checked(d)? })
}

/// Writes a new drive built from `config` (and an empty recorder) into `p`, field by field
/// (no copy of the whole on the stack), the mark last.
///
/// # Safety
/// `p` is non-null, aligned and points to `size_of::<pmsm_drive_t>()` writable bytes not
/// otherwise in use.
pub(crate) unsafe fn emplace(
    p: *mut pmsm_drive_t,
    config: &pmsm_core::DriveConfig,
    period: u16,
    pole_pairs: u32,
) {
    // SAFETY: forwarded contract; `write` does not read or drop the old contents.
    unsafe {
        addr_of_mut!((*p).core.period).write(period);
        addr_of_mut!((*p).core.pole_pairs).write(pole_pairs);
        addr_of_mut!((*p).core.base).write(config.base);
        addr_of_mut!((*p).core.handoff).write(Handoff::new());
        addr_of_mut!((*p).core.isr).write(DriveIsr::new(config));
        addr_of_mut!((*p).core.task).write(DriveTask::new(config));
        addr_of_mut!((*p).recorder).write(FaultRecorder::new());
        addr_of_mut!((*p).core.mark).write(MARK);
    }
}

pub(crate) fn status(r: Result<(), pmsm_status_t>) -> pmsm_status_t {
    match r {
        Ok(()) => pmsm_status_t::PMSM_OK,
        Err(e) => e,
    }
}
