//! Drive images: a drive built by `pmsm_drive_init`, saved with `pmsm_drive_image` and loaded
//! with `pmsm_drive_init_image` behaves bit for bit like the original; a damaged or foreign
//! image is refused without touching the storage.
#![allow(unsafe_code)] // calling the extern "C" functions

mod common;
use common::{step_row, storage};

use common::scenario::{self, WORDS, Word};
use core::ptr::{null, null_mut};
use pmsm_ffi::*;

/// The image of the recorded scenario's drive, freshly initialised.
fn image() -> Vec<u8> {
    let mut s = storage();
    let mut d = null_mut();
    let c = scenario::config_c();
    // SAFETY: valid storage, config, out pointer and buffers.
    unsafe {
        assert_eq!(
            pmsm_drive_init(
                (&mut *s as *mut pmsm_storage_t).cast(),
                size_of::<pmsm_storage_t>(),
                &c,
                &mut d
            ),
            pmsm_status_t::PMSM_OK
        );
        let n = pmsm_drive_image(d, null_mut(), 0);
        assert_eq!(n, pmsm_image_size());
        // The drive without its fault recorder (at least the C view of its samples).
        let record = PMSM_FAULT_RECORD_DEPTH * size_of::<pmsm_fault_sample_t>();
        assert!(n <= PMSM_IMAGE_HEADER_SIZE + pmsm_drive_size() - record);
        let mut buf = vec![0u8; n];
        assert_eq!(
            pmsm_drive_image(d, buf.as_mut_ptr().cast(), n - 1),
            n,
            "too short"
        );
        assert!(
            buf.iter().all(|&b| b == 0),
            "nothing written when too short"
        );
        assert_eq!(pmsm_drive_image(d, buf.as_mut_ptr().cast(), n), n);
        assert_eq!(pmsm_drive_image(null_mut(), buf.as_mut_ptr().cast(), n), 0);
        buf
    }
}

fn load(s: &mut pmsm_storage_t, img: &[u8]) -> Result<*mut pmsm_drive_t, pmsm_status_t> {
    let mut d = null_mut();
    // SAFETY: valid storage, image and out pointer.
    let r = unsafe {
        pmsm_drive_init_image(
            (s as *mut pmsm_storage_t).cast(),
            size_of::<pmsm_storage_t>(),
            img.as_ptr().cast(),
            img.len(),
            &mut d,
        )
    };
    if r == pmsm_status_t::PMSM_OK {
        Ok(d)
    } else {
        Err(r)
    }
}

#[test]
fn a_loaded_image_replays_the_rust_drive_bit_for_bit() {
    let img = image();
    assert_eq!(
        u32::from_le_bytes([img[0], img[1], img[2], img[3]]),
        PMSM_IMAGE_MAGIC
    );
    let rows = scenario::record();
    let mut s = storage();
    let d = load(&mut s, &img).expect("load");
    let mut differing = 0usize;
    for row in &rows {
        // SAFETY: live handle, valid structs.
        let got = unsafe {
            let out = step_row(d, row);
            let mut e = pmsm_estimate_t::default();
            pmsm_get_estimate(d, &mut e);
            [
                out.duty[0],
                out.duty[1],
                out.duty[2],
                i32::from(out.compare[0]),
                i32::from(out.pwm_on),
                i32::from(out.state),
                e.theta,
                e.omega,
            ]
        };
        let want = [
            row[Word::DutyA as usize],
            row[Word::DutyB as usize],
            row[Word::DutyC as usize],
            row[Word::CmpA as usize],
            row[Word::PwmOn as usize],
            row[Word::State as usize],
            row[Word::Theta as usize],
            row[Word::Omega as usize],
        ];
        differing += usize::from(got != want);
    }
    assert_eq!(rows.len(), scenario::STEPS);
    assert_eq!(differing, 0, "of {} steps (WORDS {WORDS})", rows.len());
}

#[test]
fn damaged_or_foreign_images_are_refused() {
    use pmsm_status_t::*;
    let img = image();
    let mut s = storage();
    // Every byte of the header and a spread of payload bytes, flipped one at a time.
    let n = img.len();
    let mut positions: Vec<usize> = (0..PMSM_IMAGE_HEADER_SIZE).collect();
    positions.extend((PMSM_IMAGE_HEADER_SIZE..n).step_by(97));
    positions.push(n - 1);
    for k in positions {
        let mut bad = img.clone();
        bad[k] ^= 0x10;
        assert_eq!(load(&mut s, &bad), Err(PMSM_ERR_IMAGE), "byte {k}");
    }
    assert!(
        s.words.iter().all(|&w| w == 0),
        "the storage is untouched by refused images"
    );
    assert_eq!(
        load(&mut s, &img[..n - 1]),
        Err(PMSM_ERR_IMAGE),
        "truncated"
    );
    let mut d = null_mut();
    let sp = (&mut *s as *mut pmsm_storage_t).cast();
    // SAFETY: NULL, short or misaligned arguments into valid memory.
    unsafe {
        assert_eq!(
            pmsm_drive_init_image(sp, size_of::<pmsm_storage_t>(), null(), n, &mut d),
            PMSM_ERR_NULL
        );
        assert_eq!(
            pmsm_drive_init_image(sp, 16, img.as_ptr().cast(), n, &mut d),
            PMSM_ERR_BUFFER_TOO_SMALL
        );
        assert_eq!(
            pmsm_drive_init_image(
                sp.cast::<u8>().add(4).cast(),
                size_of::<pmsm_storage_t>() - 8,
                img.as_ptr().cast(),
                n,
                &mut d
            ),
            PMSM_ERR_MISALIGNED
        );
    }
    assert!(d.is_null());
    let d = load(&mut s, &img).expect("the intact image");
    let mut st = pmsm_state_info_t::default();
    // SAFETY: live handle.
    assert_eq!(unsafe { pmsm_get_state(d, &mut st) }, PMSM_OK);
    assert_eq!(st.state, pmsm_state_t::PMSM_STATE_IDLE as u32);
}
