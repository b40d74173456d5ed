#!/usr/bin/env bash
# Executes one table on the host (feedsim: firmware-core compiled for x86-64) and on a
# Cortex-M4F under QEMU (firmware-core/mcu on mps2-an386), and compares the number of
# servo ticks and the FNV-1a digest of every setpoint's position bits. Equal digests mean
# bit-identical setpoints (so certainly within 0.1 µm). Usage: qemu-compare.sh CURVE.json
set -euo pipefail
curve=$1
root=$(cd "$(dirname "$0")/.." && pwd)
table=$(mktemp --suffix=.bin)
"$root/target/release/feedplan" plan "$curve" -o "$table" >/dev/null
host=$("$root/target/release/feedsim" run "$table" --json)
host_ticks=$(python3 -c 'import json,sys; print(json.loads(sys.argv[1])["setpoints"])' "$host")
host_digest=$(python3 -c 'import json,sys; print(json.loads(sys.argv[1])["setpoint_digest"])' "$host")
mcu=$(MCU_TABLE="$table" bash "$root/firmware-core/mcu/run-qemu.sh" 2>&1) || {
  echo "$mcu"; echo "QEMU run failed" >&2; exit 1; }
mcu_ticks=$(sed -n 's/^ticks: \([0-9]*\).*/\1/p' <<<"$mcu")
mcu_digest=$(sed -n 's/^digest: fnv1a64-pos-le=\([0-9a-f]*\).*/\1/p' <<<"$mcu")
echo "$(basename "$curve"): host ${host_ticks} ticks digest ${host_digest}; QEMU Cortex-M4 ${mcu_ticks} ticks digest ${mcu_digest}"
grep -E '^(final|stack):' <<<"$mcu" | sed 's/^/  qemu /'
rm -f "$table"
if [ "$host_ticks" != "$mcu_ticks" ] || [ "$host_digest" != "$mcu_digest" ]; then
  echo "host and QEMU setpoints differ" >&2; exit 1
fi
