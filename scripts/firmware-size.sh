#!/usr/bin/env bash
# Builds the B-G431B-ESC1 firmware (examples/b-g431b-esc1, release, thumbv7em-none-eabihf)
# with the root's `cargo firmware` (the documented command, .cargo/config.toml), prints its
# flash and static RAM, and fails (exit 1) if
#   - flash (text + data) exceeds 64 KiB or static RAM (data + bss, .uninit included)
#     exceeds 16 KiB, or
#   - text, data or bss differ from the checked-in snapshot
#     examples/b-g431b-esc1/size-snapshot.txt by more than SIZE_TOLERANCE_PCT (default 5) %
#     (a section under 1 KiB may move by up to 64 bytes).
# BLESS=1 rewrites the snapshot instead of comparing with it.
# Then builds the same firmware for an interior motor (a copy in the target directory with
# motor C of examples/motor-c-24v.toml in src/motor.rs, and pmsm-core's features for it: the
# current-model MRAS, the initial position detection, the tracker of R and psi and the learner
# of the inverter's distortion, the defaults with that estimator) and fails if its flash
# exceeds 64 KiB as well.
#
# Needs: rustup target add thumbv7em-none-eabihf; arm-none-eabi-size
#        (apt-get install -y binutils-arm-none-eabi).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
fw="$root/examples/b-g431b-esc1"
snapshot="$fw/size-snapshot.txt"
tol="${SIZE_TOLERANCE_PCT:-5}"
flash_max=$((64 * 1024))
ram_max=$((16 * 1024))

if ! command -v arm-none-eabi-size >/dev/null; then
  echo "firmware-size: arm-none-eabi-size not found (apt-get install -y binutils-arm-none-eabi)" >&2
  exit 1
fi

(cd "$root" && cargo firmware --locked >&2)
target_dir="${CARGO_TARGET_DIR:-$fw/target}"
elf="$target_dir/thumbv7em-none-eabihf/release/b-g431b-esc1"

read -r text data bss < <(arm-none-eabi-size -B "$elf" | awk 'NR == 2 { print $1, $2, $3 }')
status=0
# Prints an image's flash and static RAM against the limits ($1 names it, $2 $3 $4 its text,
# data and bss) and sets status=1 if either is over.
limits() {
  local flash=$(($2 + $3)) ram=$(($3 + $4))
  printf '%s: flash %d of %d bytes (%d.%d %%), static RAM %d of %d bytes (%d.%d %%)\n' "$1" \
    "$flash" "$flash_max" $((flash * 100 / flash_max)) $((flash * 1000 / flash_max % 10)) \
    "$ram" "$ram_max" $((ram * 100 / ram_max)) $((ram * 1000 / ram_max % 10))
  if ((flash > flash_max)); then
    echo "firmware-size: FAIL: $1: flash $flash > $flash_max bytes" >&2
    status=1
  fi
  if ((ram > ram_max)); then
    echo "firmware-size: FAIL: $1: static RAM $ram > $ram_max bytes" >&2
    status=1
  fi
}
printf 'firmware b-g431b-esc1: text %d data %d bss %d bytes\n' "$text" "$data" "$bss"
limits "firmware b-g431b-esc1" "$text" "$data" "$bss"

# The interior variant: its own binary name, so that it shares the target directory (and the
# compiled dependencies) without replacing the default image that scripts/no-panic.sh reads.
variant="$target_dir/interior-variant"
rm -rf "$variant"
mkdir -p "$variant"
cp -r "$fw/src" "$fw/build.rs" "$fw/Cargo.toml" "$fw/Cargo.lock" "$variant/"
sed -i -e "s#\.\./\.\./#$root/#g" \
  -e 's/"select-estimators", "nlo", "distortion-learner"/"select-estimators", "mras-current", "ipd", "tracking", "distortion-learner"/' \
  -e 's/^name = "b-g431b-esc1"$/name = "b-g431b-esc1-interior"/' "$variant/Cargo.toml"
sed -i "s#\.\./\.\./memory.x#$root/memory.x#" "$variant/build.rs"
sed -i -E -e 's/(POLE_PAIRS: u32 =) [^;]+;/\1 4;/' -e 's/(RS_OHM: f64 =) [^;]+;/\1 0.1;/' \
  -e 's/(LD_H: f64 =) [^;]+;/\1 0.0003;/' -e 's/(LQ_H: f64 =) [^;]+;/\1 0.0005;/' \
  -e 's/(FLUX_WB: f64 =) [^;]+;/\1 0.01323;/' -e 's/(RATED_A_RMS: f64 =) [^;]+;/\1 25.0;/' \
  -e 's/(J_KG_M2: f64 =) [^;]+;/\1 0.001;/' -e 's/(B_NM_S: f64 =) [^;]+;/\1 0.00001;/' \
  -e 's/(VDC_V: f64 =) [^;]+;/\1 24.0;/' "$variant/src/motor.rs"
if [[ $(grep -c '"mras-current", "ipd", "tracking"' "$variant/Cargo.toml") != 2 ]] ||
  ! grep -q '^name = "b-g431b-esc1-interior"$' "$variant/Cargo.toml" ||
  ! grep -q 'LQ_H: f64 = 0.0005;' "$variant/src/motor.rs"; then
  echo "firmware-size: FAIL: could not make the interior variant (Cargo.toml or motor.rs changed shape)" >&2
  exit 1
fi
(cd "$variant" && cargo build --release --locked --config "$fw/.cargo/config.toml" \
  --target-dir "$target_dir" >&2)
velf="$target_dir/thumbv7em-none-eabihf/release/b-g431b-esc1-interior"
read -r vtext vdata vbss < <(arm-none-eabi-size -B "$velf" | awk 'NR == 2 { print $1, $2, $3 }')
limits "firmware b-g431b-esc1, interior motor (mras-current, ipd, tracking, distortion-learner)" \
  "$vtext" "$vdata" "$vbss"

if [[ "${BLESS:-0}" == 1 ]]; then
  {
    echo "# Size of examples/b-g431b-esc1 (release, thumbv7em-none-eabihf), bytes."
    echo "# Checked by scripts/firmware-size.sh; BLESS=1 scripts/firmware-size.sh rewrites it."
    echo "text $text"
    echo "data $data"
    echo "bss $bss"
  } >"$snapshot"
  echo "firmware-size: snapshot written to ${snapshot#"$root"/}"
  exit "$status"
fi

if [[ ! -f "$snapshot" ]]; then
  echo "firmware-size: FAIL: no snapshot ${snapshot#"$root"/} (run with BLESS=1)" >&2
  exit 1
fi
for section in text data bss; do
  want=$(awk -v s="$section" '$1 == s { print $2 }' "$snapshot")
  got=${!section}
  if [[ -z "$want" ]]; then
    echo "firmware-size: FAIL: snapshot has no '$section' line" >&2
    status=1
    continue
  fi
  diff=$((got > want ? got - want : want - got))
  allowed=$((want * tol / 100))
  ((allowed < 64)) && allowed=64
  if ((diff > allowed)); then
    echo "firmware-size: FAIL: $section $got bytes vs snapshot $want (more than $tol %); BLESS=1 to accept" >&2
    status=1
  else
    printf 'firmware-size: %s %d vs snapshot %d: within %d %%\n' "$section" "$got" "$want" "$tol"
  fi
done
exit "$status"
