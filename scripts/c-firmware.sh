#!/usr/bin/env bash
# The C interface in C firmware (issue 7): builds libpmsm_ffi.a for the host and for the
# Cortex-M4, records a scenario of the Rust drive against the plant, replays it from C on the
# host (gcc) and on a Cortex-M4 in QEMU mps2-an386 (arm-none-eabi-gcc, semihosting), checks
# both bit for bit, and measures the flash and RAM the library adds to a minimal firmware.
# Prints `CFFI ...` lines and, last, `CFFI PASS` (exit 0) or `CFFI FAIL` (exit 1).
# Needs the Rust toolchain with the thumbv7em-none-eabihf target, gcc, qemu-system-arm; installs
# gcc-arm-none-eabi with apt-get when missing.
set -uo pipefail
cd "$(dirname "$0")/.."
root=$PWD
out=$root/target/c-firmware
src=$root/examples/c-firmware
inc=$root/crates/pmsm-ffi/include
mkdir -p "$out"
fail=0
say() { printf 'CFFI %s\n' "$*"; }
die() { say "error: $*"; say FAIL; exit 1; }

# 1. Host static library and the recording (the Rust drive against the plant).
cargo build -q -p pmsm-ffi --lib || die "host build of pmsm-ffi"
cargo run -q -p pmsm-ffi --example record -- "$out/record.bin" || die "recording"
host_lib=$root/target/debug/libpmsm_ffi.a

# 2. Host C replay.
gcc -std=c11 -O2 -Wall -Wextra -Werror -I"$inc" -o "$out/replay-host" \
  "$src/host_main.c" "$src/replay.c" "$host_lib" -lpthread -ldl -lm -lrt -lutil ||
  die "host C build"
if "$out/replay-host" "$out/record.bin" | tee "$out/host.log" | grep -q '^CFFI host replay bit_exact=true '; then
  grep '^CFFI' "$out/host.log"
else
  cat "$out/host.log"; say "host replay failed"; fail=1
fi

# 3. Cortex-M4: the cross compiler, the thumb static library, the firmware in QEMU.
if ! command -v arm-none-eabi-gcc >/dev/null; then
  sudo=""; [ "$(id -u)" = 0 ] || sudo=sudo
  ($sudo apt-get update -qq && $sudo apt-get install -y -qq gcc-arm-none-eabi) >/dev/null ||
    die "apt-get install gcc-arm-none-eabi"
fi
cargo build -q -p pmsm-ffi --lib --release --target thumbv7em-none-eabihf ||
  die "thumbv7em build of pmsm-ffi"
m4_lib=$root/target/thumbv7em-none-eabihf/release/libpmsm_ffi.a
m4=(arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16
  -std=c11 -O2 -Wall -Wextra -Werror -ffreestanding -nostdlib -ffunction-sections
  -fdata-sections -Wl,--gc-sections -Wl,-z,noexecstack -T "$src/mps2-an386.ld" -I"$inc" -I"$src")
"${m4[@]}" -DRECORD_PATH="\"$out/record.bin\"" -o "$out/replay-m4.elf" \
  "$src/startup_m4.c" "$src/m4_main.c" "$src/replay.c" "$src/record.S" "$m4_lib" -lgcc ||
  die "Cortex-M4 C build"
timeout 120 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none \
  -semihosting-config enable=on,target=native -kernel "$out/replay-m4.elf" >"$out/m4.log" 2>&1
status=$?
if [ $status = 0 ] && grep -q '^CFFI cortex-m4 replay bit_exact=true ' "$out/m4.log"; then
  grep '^CFFI' "$out/m4.log"
else
  cat "$out/m4.log"; say "cortex-m4 replay failed (qemu exit status $status)"; fail=1
fi

# 4. Flash and RAM the library adds to a minimal firmware (init + one step per ISR).
"${m4[@]}" -o "$out/minimal-without.elf" "$src/startup_m4.c" "$src/minimal.c" -lgcc ||
  die "minimal firmware build"
"${m4[@]}" -DWITH_PMSM -o "$out/minimal-with.elf" "$src/startup_m4.c" "$src/minimal.c" \
  "$m4_lib" -lgcc || die "minimal firmware build with the library"
read -r t0 d0 b0 _ < <(arm-none-eabi-size "$out/minimal-without.elf" | tail -1)
read -r t1 d1 b1 _ < <(arm-none-eabi-size "$out/minimal-with.elf" | tail -1)
say "size without-library text=$t0 data=$d0 bss=$b0"
say "size text=$t1 data=$d1 bss=$b1"
say "size added flash=$(( t1 + d1 - t0 - d0 )) ram=$(( d1 + b1 - d0 - b0 )) (flash = text+data, ram = data+bss)"

if [ $fail = 0 ]; then say PASS; else say FAIL; fi
exit $fail
