#!/usr/bin/env bash
# Flat instruction profile of the pick's control period on the emulated
# Cortex-M4F: builds the bench with BENCH_M4_ONLY=pick (warm-up into the search
# arc, then the measured periods, nothing else), runs it under QEMU with an
# execution trace (-d in_asm,exec,nochain) and sums the instructions executed
# per function, then the cycles the STM32F407 would spend at 168 MHz
# (cycles.py). Needs python3; the trace is about 50 MB, in a temporary file.
#
#   bench-m4/profile.sh [top-N]
set -euo pipefail
cd "$(dirname "$0")/.."
profile="${BENCH_PROFILE:-firmware}"
target_dir="${CARGO_TARGET_DIR:-$PWD/target}"
BENCH_M4_ONLY=pick cargo build --profile "$profile" -p bench-m4 --target thumbv7em-none-eabihf
trace="$(mktemp /tmp/bench-m4-trace.XXXXXX)"
trap 'rm -f "$trace"' EXIT
timeout 600 qemu-system-arm -machine mps2-an386 -icount shift=0 \
  -display none -monitor none -serial null \
  -semihosting-config enable=on,target=native \
  -d in_asm,exec,nochain -D "$trace" \
  -kernel "$target_dir/thumbv7em-none-eabihf/$profile/bench-m4"
python3 bench-m4/profile.py "$trace" "${1:-40}"
# Cycles on the STM32F407 at 168 MHz (bench-m4/cycles.py states the model);
# the worst period must fit half the default 1 kHz period (84,000 cycles).
python3 bench-m4/cycles.py "$trace" run_period 84000
