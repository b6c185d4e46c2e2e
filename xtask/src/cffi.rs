//! Flash and RAM that the C static library adds to a minimal C firmware, from
//! `scripts/c-firmware.sh` (arm-none-eabi-gcc, Cortex-M4).

use std::process::Command;

/// The markdown section; says how to get it when the toolchain is missing.
pub fn section() -> String {
    let mut s = String::from(
        "## The C static library in a C firmware\n\n\
         `scripts/c-firmware.sh` builds `libpmsm_ffi.a` with `crates/pmsm-ffi/archive.sh` (every \
         symbol but `pmsm_*` hidden) for the host and `thumbv7em-none-eabihf`, replays a recorded \
         drive run from C on the host and on a Cortex-M4 in QEMU (the drive designed on the target, \
         and loaded from a drive image written on the host) and compares every output with the \
         Rust drive's, compiles the README's C snippets, and links a minimal C firmware with \
         `arm-none-eabi-gcc -O2 --gc-sections` (init and one `pmsm_step` per interrupt) for three \
         estimator selections (all four, `mras-current` only, `nlo` only), the drive designed on the \
         target (`init=design`: `pmsm_drive_init`, double-precision software floating point) or \
         loaded from an image (`init=image`: `pmsm_drive_init_image`, the image counted in \
         flash). Flash = text + data, RAM = data + bss, added to the firmware without the \
         library.\n\n",
    );
    let out = Command::new("bash")
        .arg(super::root().join("scripts/c-firmware.sh"))
        .output();
    let text = match out {
        Ok(o) if o.status.success() => String::from_utf8_lossy(&o.stdout).into_owned(),
        _ => {
            s.push_str("Not measured here: `scripts/c-firmware.sh` did not pass.\n\n");
            return s;
        }
    };
    s.push_str("| measure | value |\n|---|---|\n");
    for line in text
        .lines()
        .filter(|l| l.starts_with("CFFI ") && !l.ends_with("PASS"))
    {
        // "CFFI <words> <key=value>... [(comment)]"
        let rest = line
            .trim_start_matches("CFFI ")
            .split(" (")
            .next()
            .unwrap_or("");
        let words: Vec<&str> = rest.split_whitespace().collect();
        let name: Vec<&str> = words
            .iter()
            .copied()
            .take_while(|w| !w.contains('='))
            .collect();
        let values: Vec<&str> = words.iter().copied().filter(|w| w.contains('=')).collect();
        s.push_str(&format!("| {} | {} |\n", name.join(" "), values.join(", ")));
    }
    s.push('\n');
    s
}
