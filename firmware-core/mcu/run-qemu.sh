#!/usr/bin/env bash
# Build firmware-mcu (release) and run it on QEMU's mps2-an386 (Cortex-M4F),
# under `timeout`. Exits with the firmware's semihosting exit code (0 = the
# whole path ran; 1 = table refused, fault, panic or hard fault), 124 on a
# timeout.
#
#   ./run-qemu.sh                       # tables/butterfly.bin
#   MCU_TABLE=/tmp/star.bin ./run-qemu.sh
#   BIN=fbench ./run-qemu.sh            # the float micro-benchmark
# Env: MCU_TABLE (table to embed), BIN (firmware-mcu|fbench), TIMEOUT (s, 120).
set -euo pipefail
cd "$(dirname "$0")"
BIN=${BIN:-firmware-mcu}
TIMEOUT=${TIMEOUT:-120}
cargo build --release --bin "$BIN"
ELF=target/thumbv7em-none-eabihf/release/$BIN
if command -v arm-none-eabi-size >/dev/null; then arm-none-eabi-size "$ELF"; fi
set +e
timeout -k 5 "$TIMEOUT" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic \
  -semihosting-config enable=on,target=native -kernel "$ELF" </dev/null
rc=$?
set -e
if [ "$rc" -eq 124 ]; then echo "run-qemu.sh: timed out after ${TIMEOUT} s" >&2; fi
exit "$rc"
