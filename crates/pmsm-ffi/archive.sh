#!/usr/bin/env bash
# Builds libpmsm_ffi.a for linking into C firmware, exporting nothing but pmsm_*.
#
#   crates/pmsm-ffi/archive.sh TARGET FEATURES OUT_DIR
#     TARGET    host, or a Rust target (thumbv7em-none-eabihf, thumbv6m-none-eabi)
#     FEATURES  default, or the estimators to build in, comma-separated (mras-current,nlo)
#     OUT_DIR   where libpmsm_ffi.a is written
#
# A Rust staticlib carries the Rust runtime it needs (compiler_builtins: soft-float, 64-bit
# division, memcpy, memset; on the host also std) as global symbols, which can clash with or
# silently replace the firmware's own libgcc or libc. So the archive is partially linked into
# one relocatable object (`ld -r`, every internal reference resolved inside it), every global
# symbol but pmsm_* is made local (`objcopy --keep-global-symbol`), and that one object is the
# new archive. The firmware then provides its own memcpy/memset (libc) as usual. The LLVM
# bitcode sections rustc embeds are dropped: nothing links them, and binutils' LLVM plugin,
# when older than rustc's LLVM, aborts on them in `ar` and `nm`.
set -euo pipefail
[ $# = 3 ] || { echo "usage: $0 TARGET FEATURES OUT_DIR" >&2; exit 2; }
target=$1 features=$2 out=$3
root=$(cd "$(dirname "$0")/../.." && pwd)
# The workspace's release profile is set for quick host builds; a library for firmware is
# built as the board's image is, for size and speed: one codegen unit, fat LTO.
args=(-q -p pmsm-ffi --lib --release --config 'profile.release.lto="fat"'
  --config profile.release.codegen-units=1)
if [ "$features" != default ]; then args+=(--no-default-features --features "$features"); fi
if [ "$target" = host ]; then
  lib=$root/target/release/libpmsm_ffi.a ld=ld objcopy=objcopy ar=ar
else
  args+=(--target "$target")
  lib=$root/target/$target/release/libpmsm_ffi.a ld=arm-none-eabi-ld objcopy=arm-none-eabi-objcopy
  ar=arm-none-eabi-ar
fi
(cd "$root" && cargo build "${args[@]}")
mkdir -p "$out"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$ld" -r -z noexecstack -o "$tmp/pmsm_ffi.o" --whole-archive "$lib"
"$objcopy" --wildcard --keep-global-symbol='pmsm_*' --remove-section=.llvmbc \
  --remove-section=.llvmcmd "$tmp/pmsm_ffi.o"
rm -f "$out/libpmsm_ffi.a"
"$ar" rcs "$out/libpmsm_ffi.a" "$tmp/pmsm_ffi.o"
