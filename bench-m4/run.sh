#!/usr/bin/env bash
# Build the bench for the Cortex-M4F and run it on the emulated mps2-an386 with
# one virtual nanosecond per instruction (-icount shift=0).
#
#   bench-m4/run.sh                          # the firmware's profile (opt-level 3)
#   BENCH_PROFILE=release bench-m4/run.sh    # the host release profile, for comparison
set -euo pipefail
cd "$(dirname "$0")/.."
profile="${BENCH_PROFILE:-firmware}"
target_dir="${CARGO_TARGET_DIR:-$PWD/target}"
cargo build --profile "$profile" -p bench-m4 --target thumbv7em-none-eabihf "$@"
exec timeout 600 qemu-system-arm -machine mps2-an386 -icount shift=0 \
  -display none -monitor none -serial null \
  -semihosting-config enable=on,target=native \
  -kernel "$target_dir/thumbv7em-none-eabihf/$profile/bench-m4"
