#!/usr/bin/env bash
# Checks that the release B-G431B-ESC1 firmware has no panic path: no function of the image
# calls into core::panicking (panic, panic_fmt, bounds checks, unwrap/expect failures), except
# the re-entrancy assertion inside the defmt-rtt logger (_defmt_acquire/_defmt_release), which
# is the logging library's, not the drive's. The same for the firmware's interior-motor
# variant when scripts/firmware-size.sh has built it. Needs arm-none-eabi-objdump
# (apt-get install -y binutils-arm-none-eabi) and a built firmware (scripts/firmware-size.sh).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
fw="$root/examples/b-g431b-esc1"
target_dir="${CARGO_TARGET_DIR:-$fw/target}"
elf="$target_dir/thumbv7em-none-eabihf/release/b-g431b-esc1"
[ -f "$elf" ] || (cd "$root" && cargo firmware --locked >&2)
status=0
for elf in "$elf" "$target_dir/thumbv7em-none-eabihf/release/b-g431b-esc1-interior"; do
  [ -f "$elf" ] || continue
  callers=$(arm-none-eabi-objdump -d -C "$elf" | awk '
    /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn) }
    /\t(bl|b|b\.w|blx)\t+[0-9a-f]+ <core::panicking::/ { print fn }' | sort -u)
  allowed='^(_defmt_acquire|_defmt_release|core::panicking::.*)$'
  bad=$(printf '%s\n' "$callers" | grep -Ev "$allowed" | grep -v '^$' || true)
  if [ -n "$bad" ]; then
    echo "no-panic: panic paths in ${elf##*/}, called from:" >&2
    printf '  %s\n' $bad >&2
    status=1
  else
    echo "no-panic: ${elf##*/}: callers of core::panicking: $(printf '%s ' $callers)(allowed: the defmt-rtt logger's re-entrancy check)"
  fi
done
if [ "$status" != 0 ]; then
  echo "NO-PANIC FAIL"
  exit 1
fi
echo "NO-PANIC PASS"
