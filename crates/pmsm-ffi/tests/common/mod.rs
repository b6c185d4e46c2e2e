//! Shared by the integration tests.
pub mod scenario;

use pmsm_ffi::{
    PMSM_STORAGE_WORDS, pmsm_clear_fault, pmsm_config_t, pmsm_drive_init, pmsm_drive_t,
    pmsm_input_t, pmsm_output_t, pmsm_set_speed_ref, pmsm_start, pmsm_status_t, pmsm_step,
    pmsm_stop, pmsm_storage_t, pmsm_task,
};
use scenario::{CMD_CLEAR_FAULT, CMD_START, CMD_STOP, WORDS, Word};

/// Zeroed, aligned storage for one drive.
#[allow(dead_code)]
pub fn storage() -> Box<pmsm_storage_t> {
    Box::new(pmsm_storage_t {
        words: [0; PMSM_STORAGE_WORDS],
    })
}

/// `pmsm_drive_init` in `s` with `c`: the handle, or the status it refused with.
#[allow(dead_code)]
pub fn init(s: &mut pmsm_storage_t, c: &pmsm_config_t) -> Result<*mut pmsm_drive_t, pmsm_status_t> {
    let mut d = core::ptr::null_mut();
    // SAFETY: valid storage, config and out pointer.
    let r = unsafe {
        pmsm_drive_init(
            (s as *mut pmsm_storage_t).cast(),
            size_of::<pmsm_storage_t>(),
            c,
            &mut d,
        )
    };
    if r == pmsm_status_t::PMSM_OK {
        Ok(d)
    } else {
        Err(r)
    }
}

/// One recorded step through the C ABI: the row's commands, its speed reference and its
/// inputs (each call asserted `PMSM_OK`), and the task when the step says it is due; the
/// step's output.
///
/// # Safety
/// `d` is a live drive handle.
#[allow(dead_code)]
pub unsafe fn step_row(d: *mut pmsm_drive_t, row: &[i32; WORDS]) -> pmsm_output_t {
    let cmd = row[Word::Cmd as usize];
    // SAFETY: `d` is live (the caller's contract); the structs are valid.
    unsafe {
        if cmd & CMD_STOP != 0 {
            pmsm_stop(d);
        }
        if cmd & CMD_CLEAR_FAULT != 0 {
            pmsm_clear_fault(d);
        }
        if cmd & CMD_START != 0 {
            pmsm_start(d);
        }
        assert_eq!(
            pmsm_set_speed_ref(d, row[Word::SpeedRef as usize]),
            pmsm_status_t::PMSM_OK
        );
        let input = pmsm_input_t {
            i_a: row[Word::Ia as usize],
            i_b: row[Word::Ib as usize],
            i_c: row[Word::Ic as usize],
            vdc: row[Word::Vdc as usize],
        };
        let mut out = pmsm_output_t::default();
        assert_eq!(pmsm_step(d, &input, &mut out), pmsm_status_t::PMSM_OK);
        if out.task_due != 0 {
            assert_eq!(pmsm_task(d), pmsm_status_t::PMSM_OK);
        }
        out
    }
}
