//! Flash and static RAM of the B-G431B-ESC1 firmware, from `scripts/firmware-size.sh`.

use std::process::Command;

/// The markdown section.
pub fn section() -> String {
    let mut s = String::from(
        "## B-G431B-ESC1 firmware size\n\n\
         `scripts/firmware-size.sh` builds `examples/b-g431b-esc1` (release, `thumbv7em-none-eabihf`, \
         `opt-level = \"z\"`, the core too, fat LTO; the drive designed on the host by its \
         `build.rs` and loaded from its image, docs/image.md) and checks it against the limits of \
         64 KiB of flash and 16 KiB of static RAM and against the snapshot \
         `examples/b-g431b-esc1/size-snapshot.txt` (CI fails on a 5 % drift); then the same \
         firmware for an interior motor (motor C, 24 V: the current-model MRAS, the initial \
         position detection, the tracker of R and ψ and the learner of the inverter's \
         distortion), against the same limits.\n\n",
    );
    match Command::new("bash")
        .arg(super::root().join("scripts/firmware-size.sh"))
        .output()
    {
        Ok(o) if o.status.success() => {
            for line in String::from_utf8_lossy(&o.stdout)
                .lines()
                .filter(|l| l.starts_with("firmware b-g431b-esc1"))
            {
                let line = line.trim_start_matches("firmware b-g431b-esc1");
                s.push_str(&format!(
                    "- {}\n",
                    line.strip_prefix(", ")
                        .or_else(|| line.strip_prefix(": "))
                        .unwrap_or(line)
                ));
            }
        }
        _ => s.push_str("Not measured here: `scripts/firmware-size.sh` did not pass.\n"),
    }
    s.push('\n');
    s
}
