//! The checked-in `include/pmsm.h` is the header cbindgen generates from the sources.
//! `PMSM_FFI_BLESS=1 cargo test -p pmsm-ffi --test header` rewrites it.

#[test]
fn header_is_current() {
    let generated = include_str!(concat!(env!("OUT_DIR"), "/pmsm.h"));
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("include/pmsm.h");
    if std::env::var_os("PMSM_FFI_BLESS").is_some() {
        std::fs::write(&path, generated).expect("write include/pmsm.h");
        return;
    }
    let checked_in = std::fs::read_to_string(&path).unwrap_or_default();
    assert!(
        checked_in == generated,
        "{} is stale (the C API changed): regenerate it with \
         `PMSM_FFI_BLESS=1 cargo test -p pmsm-ffi --test header` and commit it",
        path.display()
    );
}

#[test]
fn the_header_names_every_fault_and_ipd_check() {
    let h = include_str!("../include/pmsm.h");
    let faults = [
        "NONE = 0",
        "OVERCURRENT = 1",
        "BUS_UNDERVOLTAGE = 2",
        "BUS_OVERVOLTAGE = 3",
        "INITIAL_POSITION = 4",
        "HANDOVER = 5",
        "CURRENT_SENSOR = 6",
        "PHASE_LOSS = 7",
        "STALL = 8",
        "LOSS_OF_LOCK = 9",
        "OVERRUN = 10",
    ];
    for f in faults {
        assert!(h.contains(&format!("PMSM_FAULT_{f},")), "PMSM_FAULT_{f}");
    }
    assert!(!h.contains("PMSM_FAULT_OTHER"), "no catch-all fault");
    for f in [
        "OVERCURRENT = 1",
        "NO_CURRENT = 2",
        "LOW_SALIENCY = 3",
        "NO_POLARITY = 4",
        "BUS_LOW = 5",
    ] {
        assert!(
            h.contains(&format!("PMSM_IPD_FAULT_{f},")),
            "PMSM_IPD_FAULT_{f}"
        );
    }
    // The conventions a firmware engineer needs, stated in the header.
    for text in [
        "positive when it flows from the inverter leg into the",
        "measured from the axis of phase a",
        "apply over the PWM period that starts at t_k",
        "pass a negative A per code",
    ] {
        assert!(h.contains(text), "{text}");
    }
}
