#!/usr/bin/env bash
# Processor-in-the-loop runs of pmsm-core in QEMU (examples/qemu, see its README.md):
#
#   1. records the replay cases on the host (pil-record, x86_64),
#   2. builds the firmware for thumbv7em-none-eabihf (Cortex-M4, QEMU mps2-an386) and
#      thumbv6m-none-eabi (Cortex-M0, QEMU microbit) in release, with the recording embedded,
#   3. runs each in qemu-system-arm -icount shift=8 (the runners of examples/qemu/.cargo),
#   4. prints every `PIL ...` line the firmware printed, then `PIL PASS` (exit 0) if both runs
#      exited 0 with an exact calibration, benchmark figures, a bit-exact replay (on the
#      Cortex-M4 also of the drive and the plant in a closed loop on the target, and of the
#      drive's image written on the host, read and designed on the target), at least
#      `stack_margin` bytes of the stack never used, and the
#      drive's two steps within their instruction budgets (below: the interrupt step
#      `isr_<estimator>` with the current-model MRAS by default, with MTPA and field weakening
#      on (`isr_flux`), with the voltage on the circle (`isr_saturated`) and with the
#      high-frequency injection on (`isr_injection`, docs/injection.md), the back-EMF
#      estimators' in a closed loop; the task step `task`, once per `task_period` samples,
#      also on the low bus (`task_saturated`) and with the tracker's learning stage on top
#      (`task` + `task_tracker`)), else `PIL FAIL` (exit 1); the interrupt step with a bus
#      reading that changes at every sample (`isr_bus_noise`) is reported, not held to a
#      budget;
#   5. builds and runs, on both machines, the image of feature `identify` (the
#      identification's benchmarks and the back-EMF estimators' drives in a closed loop with a
#      plant, no recording: the micro:bit cannot hold both), which must identify its plant
#      with `identify_step` within the interrupt's budget; and runs a low-inductance and a
#      high-pole-count published motor's drive with its defaults in a closed loop
#      (`isr_low_l`, `isr_high_p` and their tasks, within the NLO's budgets), each of which
#      must compute the host's bits (a digest over every step) and hold its rotor;
#   6. builds and runs, on both machines, the image of feature `injection`: motor B's drive
#      with the high-frequency injection in a closed loop with a plant (`isr_injection_loop`,
#      `task_injection_loop`: at 0 and 60 r/min, the injection giving the angle), within the
#      drive's budgets.
#
# Needs: rustup target add thumbv7em-none-eabihf thumbv6m-none-eabi;
#        apt-get install -y qemu-system-arm.
# Output: the PIL lines on stdout; progress, diagnostics and the firmware's `#` lines (image
# size, peak stack, per-case replay) on stderr; full logs in examples/qemu/target/pil/ (or
# $CARGO_TARGET_DIR/pil/).
set -euo pipefail

root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
qemu_dir="$root/examples/qemu"
target_dir="${CARGO_TARGET_DIR:-$qemu_dir/target}"
out="$target_dir/pil"
timeout_s="${PIL_TIMEOUT_S:-300}"
mkdir -p "$out"

log() { printf 'pil: %s\n' "$*" >&2; }
fail() {
  log "$*"
  printf 'PIL FAIL\n'
  exit 1
}

command -v qemu-system-arm >/dev/null ||
  fail "qemu-system-arm not found: apt-get install -y qemu-system-arm"
for t in thumbv7em-none-eabihf thumbv6m-none-eabi; do
  if command -v rustup >/dev/null && ! (cd "$qemu_dir" && rustup target list --installed) | grep -qx "$t"; then
    fail "Rust target $t not installed: rustup target add thumbv7em-none-eabihf thumbv6m-none-eabi"
  fi
done

cd "$qemu_dir"

# 1. Host recording (the same pmsm-core source, built for the host).
recording="$out/recording.bin"
log "recording on the host -> $recording"
cargo build --release -p pmsm-pil-host >&2 || fail "host recorder does not build"
cargo run --release -q -p pmsm-pil-host -- --output "$recording" >&2 ||
  fail "host recorder failed"

# 2. Firmware for both machines (one cargo invocation: both targets build in parallel).
log "building the firmware (thumbv7em-none-eabihf, thumbv6m-none-eabi)"
PIL_RECORDING="$recording" cargo build --release -p pmsm-pil-firmware \
  --target thumbv7em-none-eabihf --target thumbv6m-none-eabi >&2 ||
  fail "firmware does not build"

# 3. Run each in QEMU (cargo run execs the runner of .cargo/config.toml: its exit status is
#    QEMU's, which is the firmware's semihosting exit status).
status=0
lines=()
declare -A components
# Instruction budgets, worst case over the run: a run over its budget fails. The interrupt
# step per estimator (the current-model MRAS also with MTPA and field weakening, and saturated)
# and the task step; the identification's step shares the interrupt's largest budget.
declare -A budgets=([cortex-m4]=1500 [cortex-m0]=4000)
declare -A isr_budget=(
  [cortex-m4:isr_mras_current]=1500 [cortex-m0:isr_mras_current]=4000
  [cortex-m4:isr_flux]=1500 [cortex-m0:isr_flux]=4000
  [cortex-m4:isr_saturated]=1500 [cortex-m0:isr_saturated]=4000
  [cortex-m4:isr_injection]=1500
  [cortex-m4:isr_injection_loop]=1500 [cortex-m0:isr_injection_loop]=4000
  [cortex-m4:task_injection_loop]=4000 [cortex-m0:task_injection_loop]=12000
  [cortex-m4:isr_nlo]=2600 [cortex-m0:isr_nlo]=6500
  [cortex-m4:isr_ao]=2300 [cortex-m0:isr_ao]=5600
  [cortex-m4:isr_mras_emf]=3100 [cortex-m0:isr_mras_emf]=7700
  [cortex-m4:isr_low_l]=2600 [cortex-m0:isr_low_l]=6500
  [cortex-m4:isr_high_p]=2600 [cortex-m0:isr_high_p]=6500
  [cortex-m4:task_low_l]=4000 [cortex-m0:task_low_l]=12000
  [cortex-m4:task_high_p]=4000 [cortex-m0:task_high_p]=12000
  [cortex-m4:task]=4000 [cortex-m0:task]=12000
  [cortex-m4:task_saturated]=4000 [cortex-m0:task_saturated]=12000
)
# The task period (samples), for the mean cost per sample of both steps.
task_period=8
# Least stack left unused in the runs of the recorded cases (bytes): the micro:bit's 16 KiB
# hold the drive's state and the benchmarks' frames, and an overflow there may corrupt the
# static data and hang rather than fault, so a run is held to a margin before it overflows.
stack_margin=1024
# Checks the `# <cpu> stack: peak <p> of <s> bytes` line of $1 (a log) against the margin.
check_stack() {
  local log=$1 cpu=$2 peak size
  read -r peak size < <(sed -nE "s/^# $cpu stack: peak ([0-9]+) of ([0-9]+) bytes$/\1 \2/p" "$log")
  if [[ -z $peak ]]; then
    echo "no stack figure"
  elif ((size - peak < stack_margin)); then
    echo "stack peak $peak of $size bytes: less than $stack_margin bytes left"
  fi
}
# Checks `PIL <cpu> <name> ... insn_max=<n>` of $1 (a log) against its budget.
check_budget() {
  local log=$1 cpu=$2 name=$3 budget=${isr_budget[$2:$3]}
  local worst
  worst="$(grep -oE "^PIL $cpu $name insn_mean=[0-9]+ insn_max=[0-9]+$" "$log" | sed -E 's/.*insn_max=//')"
  if [[ -z $worst ]]; then
    echo "no $name figure"
  elif ((worst > budget)); then
    echo "$name insn_max=$worst over the budget of $budget"
  fi
}
for run in "cortex-m4 thumbv7em-none-eabihf" "cortex-m0 thumbv6m-none-eabi"; do
  read -r cpu triple <<<"$run"
  run_log="$out/$cpu.log"
  log "running $cpu in QEMU (timeout ${timeout_s}s) -> $run_log"
  rc=0
  PIL_RECORDING="$recording" timeout "$timeout_s" \
    cargo run --release -q -p pmsm-pil-firmware --target "$triple" </dev/null >"$run_log" 2>&1 || rc=$?
  grep -E "^# $cpu " "$run_log" | sed 's/^/pil: /' >&2 || true
  mapfile -t got < <(grep -E "^PIL $cpu " "$run_log" || true)
  lines+=("${got[@]}")
  problems=()
  if [[ $rc -eq 124 ]]; then
    problems+=("timed out after ${timeout_s}s (on the micro:bit, also what a stack overflow into the static data can do)")
  elif grep -q 'Lockup' "$run_log"; then
    problems+=("CPU lockup (a fault in the fault handler: stack overflow?)")
  elif [[ $rc -ne 0 ]]; then
    problems+=("exit status $rc")
  fi
  grep -qE "^PIL $cpu calibration .*exact=true$" "$run_log" || problems+=("no exact calibration")
  grep -qE "^PIL $cpu replay bit_exact=true steps=[1-9][0-9]*$" "$run_log" ||
    problems+=("replay not bit-exact")
  # The drive and the plant together on the target (Cortex-M4 only: the micro:bit has no room
  # for the soft-float plant).
  if [[ $cpu == cortex-m4 ]]; then
    grep -qE "^PIL $cpu closed_loop bit_exact=true steps=[1-9][0-9]*$" "$run_log" ||
      problems+=("no bit-exact closed loop")
    # The drive image the host wrote, read here, and this target's own design, word for word
    # the host's (docs/image.md; the board's core: the micro:bit has no room for its code).
    grep -qE "^PIL $cpu image bit_exact=true words=[1-9][0-9]*$" "$run_log" ||
      problems+=("drive image not bit-exact")
  fi
  names="$(grep -oE "^PIL $cpu [a-z0-9_]+ insn_mean=[0-9]+ insn_max=[0-9]+$" "$run_log" |
    awk '{print $3}' | sort | tr '\n' ' ')"
  [[ -n $names ]] || problems+=("no benchmark figures")
  components[$cpu]="$names"
  # The interrupt step's budget (worst case over the recorded run), with the default
  # configuration, with MTPA and field weakening on, and with the voltage on the current
  # loops' circle and the modulator's hexagon (the bus read at a quarter); the task's.
  steps="isr_mras_current isr_flux isr_saturated task task_saturated"
  # The injection is built for the Cortex-M4 only (examples/qemu/firmware/Cargo.toml).
  [[ $cpu == cortex-m4 ]] && steps+=" isr_injection"
  for step in $steps; do
    p="$(check_budget "$run_log" "$cpu" "$step")"
    [[ -z $p ]] || problems+=("$p")
  done
  p="$(check_stack "$run_log" "$cpu")"
  [[ -z $p ]] || problems+=("$p")
  # The tracker of R and psi is frozen in the recorded runs: its learning stage
  # (`task_tracker`) on top of the task's worst case must fit the task's budget too.
  task_max="$(grep -oE "^PIL $cpu task insn_mean=[0-9]+ insn_max=[0-9]+$" "$run_log" | sed -E 's/.*insn_max=//')"
  tracker_max="$(grep -oE "^PIL $cpu task_tracker insn_mean=[0-9]+ insn_max=[0-9]+$" "$run_log" | sed -E 's/.*insn_max=//')"
  if [[ -z $task_max || -z $tracker_max ]]; then
    problems+=("no task or task_tracker figure")
  elif ((task_max + tracker_max > ${isr_budget[$cpu:task]})); then
    problems+=("task insn_max=$task_max with task_tracker insn_max=$tracker_max over the budget of ${isr_budget[$cpu:task]}")
  fi
  # The mean cost per sample of both steps: the interrupt's mean and the task's over its
  # period.
  isr_mean="$(grep -oE "^PIL $cpu isr_mras_current insn_mean=[0-9]+" "$run_log" | sed -E 's/.*=//')"
  task_mean="$(grep -oE "^PIL $cpu task insn_mean=[0-9]+" "$run_log" | sed -E 's/.*=//')"
  if [[ -n $isr_mean && -n $task_mean ]]; then
    lines+=("PIL $cpu per_sample insn_mean=$((isr_mean + task_mean / task_period)) task_period=$task_period")
  fi
  if ((${#problems[@]})); then
    status=1
    log "$cpu: ${problems[*]}; last lines of $run_log:"
    tail -n 20 "$run_log" | sed 's/^/    /' >&2
  fi
done

# 5. The identification's image (feature `identify`).
log "building the identification's image (feature identify)"
if PIL_RECORDING="$recording" cargo build --release -p pmsm-pil-firmware --features identify \
  --target thumbv7em-none-eabihf --target thumbv6m-none-eabi >&2; then
  for run in "cortex-m4 thumbv7em-none-eabihf" "cortex-m0 thumbv6m-none-eabi"; do
    read -r cpu triple <<<"$run"
    run_log="$out/$cpu-identify.log"
    log "running $cpu's identification in QEMU (timeout ${timeout_s}s) -> $run_log"
    rc=0
    PIL_RECORDING="$recording" timeout "$timeout_s" \
      cargo run --release -q -p pmsm-pil-firmware --features identify --target "$triple" \
      </dev/null >"$run_log" 2>&1 || rc=$?
    grep -E "^# $cpu " "$run_log" | sed 's/^/pil: /' >&2 || true
    mapfile -t got < <(grep -E "^PIL $cpu identify_" "$run_log" || true)
    lines+=("${got[@]}")
    mapfile -t got < <(grep -E "^PIL $cpu (isr|task)_" "$run_log" || true)
    lines+=("${got[@]}")
    worst="$(grep -oE "^PIL $cpu identify_step insn_mean=[0-9]+ insn_max=[0-9]+$" "$run_log" |
      sed -E 's/.*insn_max=//')"
    budget=${budgets[$cpu]}
    for step in isr_nlo isr_ao isr_mras_emf isr_low_l task_low_l isr_high_p task_high_p; do
      p="$(check_budget "$run_log" "$cpu" "$step")"
      if [[ -n $p ]]; then
        status=1
        log "$cpu: $p"
      fi
    done
    # The low-inductance and the high-pole-count motor's closed loops: the host's bits, the
    # rotor held.
    mapfile -t got < <(grep -E "^PIL $cpu loop_" "$run_log" || true)
    lines+=("${got[@]}")
    for name in low_l high_p; do
      if ! grep -qE "^PIL $cpu loop_$name bit_exact=true held=true$" "$run_log"; then
        status=1
        log "$cpu: the closed loop $name is not the host's, or did not hold its rotor"
      fi
    done
    if [[ $rc -ne 0 ]]; then
      status=1
      log "$cpu identification: exit status $rc (did not identify its plant?); last lines:"
      tail -n 20 "$run_log" | sed 's/^/    /' >&2
    elif [[ -z $worst ]]; then
      status=1
      log "$cpu identification: no identify_step figure"
    elif ((worst > budget)); then
      status=1
      log "$cpu identification: identify_step insn_max=$worst over the budget of $budget"
    fi
  done
else
  status=1
  log "the identification's image does not build"
fi

# 6. The injection's image (feature `injection`).
log "building the injection's image (feature injection)"
if PIL_RECORDING="$recording" cargo build --release -p pmsm-pil-firmware --features injection \
  --target thumbv7em-none-eabihf --target thumbv6m-none-eabi >&2; then
  for run in "cortex-m4 thumbv7em-none-eabihf" "cortex-m0 thumbv6m-none-eabi"; do
    read -r cpu triple <<<"$run"
    run_log="$out/$cpu-injection.log"
    log "running $cpu's injection drive in QEMU (timeout ${timeout_s}s) -> $run_log"
    rc=0
    PIL_RECORDING="$recording" timeout "$timeout_s" \
      cargo run --release -q -p pmsm-pil-firmware --features injection --target "$triple" \
      </dev/null >"$run_log" 2>&1 || rc=$?
    grep -E "^# $cpu " "$run_log" | sed 's/^/pil: /' >&2 || true
    mapfile -t got < <(grep -E "^PIL $cpu (isr|task)_" "$run_log" || true)
    lines+=("${got[@]}")
    if [[ $rc -ne 0 ]]; then
      status=1
      log "$cpu injection drive: exit status $rc; last lines:"
      tail -n 20 "$run_log" | sed 's/^/    /' >&2
    fi
    for step in isr_injection_loop task_injection_loop; do
      p="$(check_budget "$run_log" "$cpu" "$step")"
      if [[ -n $p ]]; then
        status=1
        log "$cpu: $p"
      fi
    done
  done
else
  status=1
  log "the injection's image does not build"
fi

# The same components on both, but the injection's (the Cortex-M4's only).
if [[ "${components[cortex-m4]/isr_injection /}" != "${components[cortex-m0]}" ]]; then
  status=1
  log "the two machines report different components:"
  log "  cortex-m4: ${components[cortex-m4]}"
  log "  cortex-m0: ${components[cortex-m0]}"
fi

# 4. Report.
printf '%s\n' "${lines[@]}"
if [[ $status -eq 0 ]]; then
  printf 'PIL PASS\n'
else
  printf 'PIL FAIL\n'
fi
exit "$status"
