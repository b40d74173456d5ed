#!/usr/bin/env bash
# A streamed run over a real serial byte stream: the firmware (firmware-core/mcu, bin
# stream-run: no table in flash, a 16 KiB chunk ring, a plan window of 64 q spans and 128
# pieces) on a Cortex-M4F under QEMU (mps2-an386) receives the plan's chunks over its UART0
# from a host process (planner-host example stream_send, through QEMU's `-chardev pipe`), with
# the credits of its ACKs taken 50 ms late each way, and runs the whole path; its setpoint
# digest must equal the host's streamed run's. Prints both runs' figures: ticks, chunks, bytes,
# the ring's and the window's peak use, the stack's high-water mark, flash and RAM; exit 1 when the
# image's flash is over 64 KiB (FLASH_BUDGET bytes).
#
#   bash .ci/qemu-uart-stream.sh CURVE.json|NAME [CHUNK_MM] [WINDOW_MM:COMMIT_MM]
#
# With WINDOW_MM:COMMIT_MM the host plans in windows and sends each chunk as soon as it is
# final, while the rest is planned (the head first without its stop segment, which follows).
#
# FAULTS=corrupt:N,drop:N,duplicate:N,reorder:N,restart:N loses every Nth DATA frame so on the
# way, and restarts the host after the Nth (stream_send --faults): the firmware must refuse the
# bad and the out-of-order frames, NAK what it expects, ACK what it has, and still run the
# host's setpoints; with frames corrupted, dropped or swapped the run must show refusals.
#
# U_FORM=1 sends the chunks with the u form (stream_send --u-form): the setpoints report u, a
# larger stream, the same positions, so the same digest.
#
# TICK_COUNT=1 runs the image built with the feature `tick-count` (its own target directory)
# under bench_insn.py's counting plugin: every servo tick's Thumb instructions, by kind (start,
# normal, stop), the streamed tick reading its rows from the plan window (docs/wcet.md); exit 1
# when a kind's worst is over TICK_BUDGET (default 4000).
#
# (the example must be built: cargo build --release -p planner-host --example stream_send)
set -euo pipefail
curve=$1
chunk_mm=${2:-8}
windows=()
if [ -n "${3:-}" ]; then windows=(--windows "$3"); fi
root=$(cd "$(dirname "$0")/.." && pwd)
mcu=$root/firmware-core/mcu
if [ -n "${TICK_COUNT:-}" ]; then
  (cd "$mcu" && CARGO_TARGET_DIR="$mcu/target/tick-count" cargo build --release -q --bin stream-run --features tick-count 2>/dev/null)
  elf=$mcu/target/tick-count/thumbv7em-none-eabihf/release/stream-run
else
  (cd "$mcu" && cargo build --release -q --bin stream-run 2>/dev/null)
  elf=$mcu/target/thumbv7em-none-eabihf/release/stream-run
fi
d=$(mktemp -d)
trap 'rm -rf "$d"' EXIT
mkfifo "$d/link.in" "$d/link.out"
"$root/target/release/examples/stream_send" "$curve" --pipe "$d/link" --chunk-mm "$chunk_mm" \
  --latency-ms 50 --digest ${FAULTS:+--faults "$FAULTS"} ${U_FORM:+--u-form} "${windows[@]}" \
  >"$d/host.txt" 2>&1 &
host_pid=$!
set +e
if [ -n "${TICK_COUNT:-}" ]; then
  timeout -k 5 "${TIMEOUT:-900}" python3 "$mcu/bench_insn.py" "$elf" --timeout "${TIMEOUT:-900}" \
    --qemu-arg=-monitor --qemu-arg=none --qemu-arg=-chardev --qemu-arg="pipe,id=link,path=$d/link" \
    --qemu-arg=-serial --qemu-arg=chardev:link >"$d/mcu.txt" 2>&1
else
  timeout -k 5 "${TIMEOUT:-900}" qemu-system-arm -cpu cortex-m4 -machine mps2-an386 -nographic -monitor none \
    -chardev pipe,id=link,path="$d/link" -serial chardev:link \
    -semihosting-config enable=on,target=native -kernel "$elf" >"$d/mcu.txt" 2>&1
fi
rc=$?
wait "$host_pid"
host_rc=$?
set -e
sed 's/^/  host /' "$d/host.txt"
grep -v '^BENCH-' "$d/mcu.txt" | sed 's/^/  qemu /'
if [ -n "${TICK_COUNT:-}" ]; then
  # the worst tick of each kind over the groups bench_insn.py printed (marker overhead subtracted)
  worst=$(awk '$1=="==" {t=1; next} t && $1 ~ /^(start|normal|stop)$/ && NF >= 6 {
      if ($6 > m[$1]) m[$1] = $6; n[$1] += $2 }
    END { for (k in m) printf "%s %d %d\n", k, m[k], n[k] }' "$d/mcu.txt" | sort)
  echo "$worst" | while read -r kind max n; do
    echo "  streamed tick, $kind: worst $max Thumb instructions over $n ticks (budget ${TICK_BUDGET:-4000})"
  done
  over=$(echo "$worst" | awk -v b="${TICK_BUDGET:-4000}" '$2 > b {print $1}')
  [ -z "$worst" ] && { echo "no tick counted" >&2; exit 1; }
  # (the image with the counting windows is not the one whose flash is measured)
  (cd "$mcu" && cargo build --release -q --bin stream-run 2>/dev/null)
  elf=$mcu/target/thumbv7em-none-eabihf/release/stream-run
fi
read -r text data bss _ < <(arm-none-eabi-size "$elf" | tail -1) || true
echo "  stream-run image: flash (text) ${text:-?} bytes, static RAM (data + bss) $(( ${data:-0} + ${bss:-0} )) bytes of 131072"
host_digest=$(sed -n 's/^.*digest: fnv1a64-pos-le=\([0-9a-f]*\)$/\1/p' "$d/host.txt")
mcu_digest=$(sed -n 's/^digest: fnv1a64-pos-le=\([0-9a-f]*\)$/\1/p' "$d/mcu.txt")
echo "$(basename "$curve") over the UART in $chunk_mm mm chunks${3:+, planned in windows $3 while sending}${FAULTS:+, frames lost ($FAULTS)}: host ${host_digest:-none}, QEMU Cortex-M4 ${mcu_digest:-none}"
if [ "$rc" -ne 0 ] || [ "$host_rc" -ne 0 ]; then
  echo "QEMU exit $rc, host exit $host_rc" >&2; exit 1
fi
if [ -z "$host_digest" ] || [ "$host_digest" != "$mcu_digest" ]; then
  echo "the streamed runs differ" >&2; exit 1
fi
if [ -n "${over:-}" ]; then
  echo "streamed ticks over the budget: $over" >&2; exit 1
fi
# the firmware without tables fits 64 KiB of flash (FLASH_BUDGET bytes)
if [ -n "${text:-}" ] && [ "$text" -gt "${FLASH_BUDGET:-65536}" ]; then
  echo "stream-run's flash, $text bytes, is over the budget of ${FLASH_BUDGET:-65536}" >&2; exit 1
fi
if [[ "${FAULTS:-}" =~ corrupt|drop|reorder ]]; then
  # (refused: a chunk that failed its checks or came out of order; bad: a frame that failed its
  # framing; a duplicate is ACKed again, a restarted host's chunks are duplicates)
  read -r refused bad < <(sed -n 's/^.*refused \([0-9]*\), bad frames \([0-9]*\),.*$/\1 \2/p' "$d/mcu.txt")
  if [ $(( ${refused:-0} + ${bad:-0} )) -eq 0 ]; then
    echo "frames were lost on the way ($FAULTS) but the firmware refused none" >&2; exit 1
  fi
fi
