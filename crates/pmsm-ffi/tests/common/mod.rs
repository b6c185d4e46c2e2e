//! Shared by the integration tests.
pub mod scenario;

use pmsm_ffi::{
    PMSM_STORAGE_WORDS, pmsm_config_t, pmsm_drive_init, pmsm_drive_t, pmsm_status_t, pmsm_storage_t,
};

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
