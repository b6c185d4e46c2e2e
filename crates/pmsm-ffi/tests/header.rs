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
