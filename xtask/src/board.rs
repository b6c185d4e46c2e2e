//! Flash and static RAM of the B-G431B-ESC1 firmware, from `scripts/firmware-size.sh`.

use std::process::Command;

/// The markdown section.
pub fn section() -> String {
    let mut s = String::from(
        "## B-G431B-ESC1 firmware size\n\n\
         `scripts/firmware-size.sh` builds `examples/b-g431b-esc1` (release, `thumbv7em-none-eabihf`, \
         `opt-level = \"z\"` with the core at \"s\", fat LTO) and checks it against the limits of 64 KiB \
         of flash and 16 KiB of static RAM and against the snapshot \
         `examples/b-g431b-esc1/size-snapshot.txt` (CI fails on a 5 % drift).\n\n",
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
                s.push_str(&format!(
                    "- {}\n",
                    line.trim_start_matches("firmware b-g431b-esc1: ")
                ));
            }
        }
        _ => s.push_str("Not measured here: `scripts/firmware-size.sh` did not pass.\n"),
    }
    s.push('\n');
    s
}
