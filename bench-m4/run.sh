#!/usr/bin/env bash
# Build the bench for the Cortex-M4F and run it on the emulated mps2-an386 with
# one virtual nanosecond per instruction (-icount shift=0).
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release -p bench-m4 --target thumbv7em-none-eabihf "$@"
exec timeout 600 qemu-system-arm -machine mps2-an386 -icount shift=0 \
  -display none -monitor none -serial null \
  -semihosting-config enable=on,target=native \
  -kernel target/thumbv7em-none-eabihf/release/bench-m4
