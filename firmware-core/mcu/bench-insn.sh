#!/usr/bin/env bash
# Thumb instructions per marked window (per servo tick for firmware-mcu, per
# float operation for fbench), measured under QEMU; see bench_insn.py.
#
#   ./bench-insn.sh                      # ticks over the whole path of tables/butterfly.bin
#   ./bench-insn.sh fbench               # f64 vs f32 operation costs
#   ./bench-insn.sh firmware-mcu --profile 20 --csv /tmp/ticks.csv
#   ./bench-insn.sh fbench --method exec-log   # cross-check without the plugin (slow)
# Needs qemu-system-arm, python3, a C compiler (for the plugin) and
# arm-none-eabi-nm (binutils-arm-none-eabi). Exit code: the firmware's, or 2.
set -euo pipefail
cd "$(dirname "$0")"
BIN=firmware-mcu
if [ $# -gt 0 ] && [ "${1#-}" = "$1" ]; then BIN=$1; shift; fi
cargo build --release --bin "$BIN"
ELF=target/thumbv7em-none-eabihf/release/$BIN
arm-none-eabi-size "$ELF"
exec python3 bench_insn.py "$ELF" "$@"
