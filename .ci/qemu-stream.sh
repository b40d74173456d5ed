#!/usr/bin/env bash
# Cuts one curve's planned table into chunks (planner-host's stream_budget example), decodes
# the framed stream on the host and on a Cortex-M4F under QEMU (firmware-core/mcu, bin
# stream-decode: byte by byte through the frame decoder into the chunk ring, every chunk
# decoded) and compares the decode digests. Equal digests mean the MCU decodes every q span
# and piece bit for bit as the host does. Usage: qemu-stream.sh CURVE.json CHUNK_MM [MAX_BYTES]
# (MAX_BYTES: halve longer chunks; the MCU's frame buffer is 16 KiB)
# (the example must be built: cargo build --release -p planner-host --example stream_budget).
set -euo pipefail
curve=$1
chunk_mm=$2
max=()
[ $# -gt 2 ] && max=(--max-bytes "$3")
root=$(cd "$(dirname "$0")/.." && pwd)
link=$(mktemp --suffix=.link)
host=$("$root/target/release/examples/stream_budget" --chunk-mm "$chunk_mm" "${max[@]}" --digest --link "$link" "$curve")
host_digest=$(sed -n 's/^.*: decode digest 0x\([0-9a-f]*\)$/\1/p' <<<"$host")
mcu=$(MCU_STREAM="$link" BIN=stream-decode bash "$root/firmware-core/mcu/run-qemu.sh" 2>&1) || {
  echo "$mcu" | grep -v '^BENCH'; echo "QEMU run failed" >&2; exit 1; }
mcu_digest=$(sed -n 's/^decode digest: 0x\([0-9a-f]*\)$/\1/p' <<<"$mcu")
echo "$(basename "$curve") in $chunk_mm mm chunks: host decode digest ${host_digest}; QEMU Cortex-M4 ${mcu_digest}"
grep -E '^(frames|stack)' <<<"$mcu" | sed 's/^/  qemu /'
rm -f "$link"
if [ -z "$host_digest" ] || [ "$host_digest" != "$mcu_digest" ]; then
  echo "host and QEMU decode differently" >&2; exit 1
fi
