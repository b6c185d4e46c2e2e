#!/usr/bin/env bash
# The C interface in C firmware: builds libpmsm_ffi.a with crates/pmsm-ffi/archive.sh for the
# host and the Cortex-M4 (every symbol but pmsm_* hidden: the count of the others is printed
# and must be 0), records a scenario of the Rust drive against the plant, replays it from C on
# the host (gcc) and on a Cortex-M4 in QEMU mps2-an386 (arm-none-eabi-gcc, semihosting), the
# drive designed on the target and loaded from a host-written drive image, checks every run
# bit for bit, compiles the README's C snippets against pmsm.h with stub registers, and
# measures the flash and RAM the library adds to a minimal firmware for three estimator
# selections (all, mras-current, nlo), designed on the target or loaded from an image.
# Prints `CFFI ...` lines and, last, `CFFI PASS` (exit 0) or `CFFI FAIL` (exit 1).
# Needs the Rust toolchain with the thumbv7em-none-eabihf target, gcc, binutils,
# qemu-system-arm; installs gcc-arm-none-eabi with apt-get when missing.
set -uo pipefail
cd "$(dirname "$0")/.."
root=$PWD
out=$root/target/c-firmware
src=$root/examples/c-firmware
inc=$root/crates/pmsm-ffi/include
archive=$root/crates/pmsm-ffi/archive.sh
mkdir -p "$out"
fail=0
say() { printf 'CFFI %s\n' "$*"; }
die() { say "error: $*"; say FAIL; exit 1; }
# Defined global symbols of an archive other than pmsm_*.
foreign() { "$1" -g --defined-only "$2" | grep -E '^[0-9a-f]+ [A-Za-z] ' | grep -vc ' pmsm_'; }
period=3000 # the recording's timer period (scenario.rs PERIOD)
configs=(default mras-current nlo)
estimator_code() { case $1 in nlo) echo 1 ;; *) echo 0 ;; esac; }

if ! command -v arm-none-eabi-gcc >/dev/null; then
  sudo=""; [ "$(id -u)" = 0 ] || sudo=sudo
  ($sudo apt-get update -qq && $sudo apt-get install -y -qq gcc-arm-none-eabi) >/dev/null ||
    die "apt-get install gcc-arm-none-eabi"
fi

# 1. The archives, the recording (the Rust drive against the plant), the drive images.
for cfg in "${configs[@]}"; do
  "$archive" host "$cfg" "$out/lib/host-$cfg" || die "host archive ($cfg)"
  "$archive" thumbv7em-none-eabihf "$cfg" "$out/lib/m4-$cfg" || die "thumbv7em archive ($cfg)"
done
cargo run -q -p pmsm-ffi --example record -- "$out/record.bin" || die "recording"
host_libs=(-lpthread -ldl -lm -lrt -lutil)
for cfg in "${configs[@]}"; do
  gcc -std=c11 -O2 -Wall -Wextra -Werror -I"$inc" -I"$src" -o "$out/replay-host-$cfg" \
    "$src/host_main.c" "$src/replay.c" "$out/lib/host-$cfg/libpmsm_ffi.a" "${host_libs[@]}" ||
    die "host C build ($cfg)"
  "$out/replay-host-$cfg" --image "$out/image-$cfg.bin" "$(estimator_code "$cfg")" "$period" ||
    die "drive image ($cfg)"
done
say "exported non-pmsm symbols host=$(foreign nm "$out/lib/host-default/libpmsm_ffi.a")" \
  "cortex-m4=$(foreign arm-none-eabi-nm "$out/lib/m4-default/libpmsm_ffi.a")"
for cfg in "${configs[@]}"; do
  for pair in "nm host" "arm-none-eabi-nm m4"; do
    set -- $pair
    n=$(foreign "$1" "$out/lib/$2-$cfg/libpmsm_ffi.a")
    [ "$n" = 0 ] || { say "$2-$cfg archive exports $n symbols besides pmsm_*"; fail=1; }
  done
done

# 2. Host C replay.
if "$out/replay-host-default" "$out/record.bin" | tee "$out/host.log" |
  grep -q '^CFFI host replay bit_exact=true '; then
  grep '^CFFI' "$out/host.log"
else
  cat "$out/host.log"; say "host replay failed"; fail=1
fi

# 3. The README's C snippets (between `<!-- c-snippet: NAME -->` and the next marker),
# compiled and linked against pmsm.h and the host archive with stub registers, and run: the
# ISR must switch the outputs on within three task periods of a start.
snippet() {
  awk -v name="$1" '/^<!-- c-snippet: / { on = ($3 == name); next } on { sub(/^    /, ""); print }' \
    README.md
}
{
  cat <<'C'
#include <stdint.h>
/* Stub registers of an STM32 (HAL names). */
typedef struct { volatile uint32_t JDR1, JDR2, JDR3, JDR4; } ADC_TypeDef;
typedef struct { volatile uint32_t CCR1, CCR2, CCR3, BDTR; } TIM_TypeDef;
static ADC_TypeDef adc1, adc2;
static TIM_TypeDef tim1;
#define ADC1 (&adc1)
#define ADC2 (&adc2)
#define TIM1 (&tim1)
#define TIM_BDTR_MOE (1u << 15)
static struct { struct { uint32_t Period; } Init; } htim1 = {{3000}};
/* Stub NVIC: the pended task runs after the ISR returns. */
enum { SPI1_IRQn = 35 };
static int task_pending;
#define NVIC_SetPendingIRQ(irq) ((void)(irq), task_pending = 1)
C
  snippet globals
  echo 'void ADC1_2_IRQHandler(void);'
  echo 'void SPI1_IRQHandler(void);'
  echo 'void ADC1_2_IRQHandler(void) {'
  snippet isr
  echo '}'
  snippet task
  echo 'int main(void) {'
  snippet init
  # A nominal bus (540 V at 0.2 V per code), no current: the first detection pulse switches,
  # so the ISR must have set the main output enable within three task periods of the start
  # (the task takes the start at its next run, the outputs follow a period later).
  echo '    adc2.JDR1 = 2700;'
  echo '    for (int k = 0; k < 3 * PMSM_TASK_PERIOD; k++) {'
  echo '        ADC1_2_IRQHandler();'
  echo '        if (tim1.BDTR & TIM_BDTR_MOE) return 0;'
  echo '        if (task_pending) { task_pending = 0; SPI1_IRQHandler(); }'
  echo '    }'
  echo '    return 1;'
  echo '}'
} >"$out/readme.c"
if [ "$(snippet isr | grep -c pmsm_step)" = 1 ] && [ "$(snippet task | grep -c pmsm_task)" = 1 ] &&
  [ "$(snippet init | grep -c pmsm_drive_init)" = 1 ] &&
  gcc -std=c11 -O2 -Wall -Wextra -Werror -I"$inc" -o "$out/readme" "$out/readme.c" \
    "$out/lib/host-default/libpmsm_ffi.a" "${host_libs[@]}" && "$out/readme"; then
  say "readme snippets compiled=true outputs_on_at_start=true"
else
  say "readme snippets failed: not compiled, or the ISR left the outputs off ($out/readme.c)"
  fail=1
fi

# 4. Cortex-M4 in QEMU: designed on the target, then loaded from the host's image.
m4=(arm-none-eabi-gcc -mcpu=cortex-m4 -mthumb -mfloat-abi=hard -mfpu=fpv4-sp-d16
  -std=c11 -O2 -Wall -Wextra -Werror -ffreestanding -nostdlib -ffunction-sections
  -fdata-sections -Wl,--gc-sections -Wl,-z,noexecstack -T "$src/mps2-an386.ld" -I"$inc" -I"$src")
# The archive hides its runtime routines: the C code's own memcpy/memset come from libc.
m4_libs=(-lc -lgcc)
for mode in design image; do
  extra=(); label="cortex-m4 replay"
  if [ $mode = image ]; then
    extra=(-DWITH_IMAGE -DIMAGE_PATH="\"$out/image-default.bin\"" "$src/image.S")
    label="cortex-m4 image replay"
  fi
  "${m4[@]}" -DRECORD_PATH="\"$out/record.bin\"" "${extra[@]}" -o "$out/replay-m4-$mode.elf" \
    "$src/startup_m4.c" "$src/m4_main.c" "$src/replay.c" "$src/record.S" \
    "$out/lib/m4-default/libpmsm_ffi.a" "${m4_libs[@]}" || die "Cortex-M4 C build ($mode)"
  timeout 120 qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none \
    -semihosting-config enable=on,target=native -kernel "$out/replay-m4-$mode.elf" \
    >"$out/m4-$mode.log" 2>&1
  status=$?
  if [ $status = 0 ] && grep -q "^CFFI $label bit_exact=true " "$out/m4-$mode.log"; then
    grep '^CFFI' "$out/m4-$mode.log"
  else
    cat "$out/m4-$mode.log"; say "$label failed (qemu exit status $status)"; fail=1
  fi
done

# 5. Flash and RAM the library adds to a minimal firmware (init + one step per ISR).
"${m4[@]}" -o "$out/minimal-without.elf" "$src/startup_m4.c" "$src/minimal.c" "${m4_libs[@]}" ||
  die "minimal firmware build"
read -r t0 d0 b0 _ < <(arm-none-eabi-size "$out/minimal-without.elf" | tail -1)
say "size without-library text=$t0 data=$d0 bss=$b0"
for cfg in "${configs[@]}"; do
  name=$cfg; [ "$cfg" = default ] && name=all
  for init in design image; do
    extra=(-DESTIMATOR="$(estimator_code "$cfg")")
    if [ $init = image ]; then
      extra=(-DFROM_IMAGE -DIMAGE_PATH="\"$out/image-$cfg.bin\"" "$src/image.S")
    fi
    elf=$out/minimal-$name-$init.elf
    "${m4[@]}" -DWITH_PMSM "${extra[@]}" -o "$elf" "$src/startup_m4.c" "$src/minimal.c" \
      "$out/lib/m4-$cfg/libpmsm_ffi.a" "${m4_libs[@]}" || die "minimal firmware ($name, $init)"
    read -r t1 d1 b1 _ < <(arm-none-eabi-size "$elf" | tail -1)
    say "size added flash=$(( t1 + d1 - t0 - d0 )) ram=$(( d1 + b1 - d0 - b0 ))" \
      "estimators=$name init=$init"
  done
done
echo "(size: flash = text+data, ram = data+bss; init=image counts the image in flash)"
# What the flash of the one-estimator firmware designed on the target is spent on.
breakdown() {
  local design=0 float=0 est=0 rest=0 size type name n
  while read -r _ size type name; do
    case $type in [bBdD]) continue ;; esac
    n=$((16#$size))
    case $name in
      *Config::new* | *from_f64* | *validate* | *PerUnit::new* | *rise_time* | *coef_in* | \
        *Gain::new* | *Coef*::new* | *default_for* | *convert::build* | pmsm_drive_init | \
        *EmfMeter::new* | *Reciprocal* | *observer_pole*) design=$((design + n)) ;;
      *compiler_builtins::float* | __aeabi_d* | __aeabi_f* | *libm* | *RSQRT*) float=$((float + n)) ;;
      *mras_current* | *MrasCurrent* | *nlo::* | *Nlo*) est=$((est + n)) ;;
      *) rest=$((rest + n)) ;;
    esac
  done < <(arm-none-eabi-nm --size-sort -S -C "$1" | grep -v ' main$')
  say "flash of $2 design_code=$design soft_float_and_libm=$float estimator=$est" \
    "per_sample_path_and_rest=$rest"
}
breakdown "$out/minimal-mras-current-design.elf" "mras-current init=design"

# 6. No panic path in the library: no function of the minimal firmwares calls into
# core::panicking (a panic would stop the firmware in the library's handler).
panics=""
for elf in "$out"/minimal-*-design.elf "$out"/minimal-*-image.elf; do
  callers=$(arm-none-eabi-objdump -d -C "$elf" | awk '
    /^[0-9a-f]+ <.*>:$/ { fn = $0; sub(/^[0-9a-f]+ </, "", fn); sub(/>:$/, "", fn) }
    /\t(bl|b|b\.w|blx)\t+[0-9a-f]+ <core::panicking::/ { print fn }' |
    grep -v '^core::panicking::' | sort -u)
  [ -z "$callers" ] || panics+="$(basename "$elf"): $(printf '%s ' $callers)"$'\n'
done
if [ -z "$panics" ]; then
  say "panic paths in the minimal firmwares: none"
else
  printf '%s' "$panics" | sed 's/^/CFFI panic path in /'; fail=1
fi

if [ $fail = 0 ]; then say PASS; else say FAIL; fi
exit $fail
