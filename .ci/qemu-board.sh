#!/usr/bin/env bash
# Runs the STM32F407 board firmware (boards/stm32f4: RTIC app, HAL start-up, the
# servo tick in the TIM2 interrupt, StepDirSink into the step slot plans) on QEMU's
# netduinoplus2 (STM32F405) with one table built into flash, and compares its number of
# servo ticks and its setpoint digest with the host's (feedsim: firmware-core compiled for
# x86-64). Then counts the Thumb instructions of each servo tick (the whole tick path:
# interpolator, step generator, slot plan, digest) with firmware-core/mcu's plugin, runs
# the image with a feed hold, and sends the table over USART2 when it fits the RAM buffer.
#
# What QEMU 7.2 cannot show (docs/board.md): the servo rate. Its TIM2-5 model does not
# keep the programmed period, so the rate printed ("servo: ... Hz", against SysTick in
# QEMU's virtual time) is QEMU's, not the board's; the run uses -icount (deterministic).
# Usage: qemu-board.sh CURVE.json   (needs target/release/feedplan and feedsim, or
# FEEDPLAN=... FEEDSIM=... pointing at them). The QEMU images are built in
# boards/stm32f4/target/qemu (BOARD_TARGET_DIR=DIR, relative to boards/stm32f4, to
# choose: CI builds them over the board's own release build, sharing its dependencies).
set -euo pipefail
curve=$1
root=$(cd "$(dirname "$0")/.." && pwd)
table=$(mktemp --suffix=.bin)
trap 'rm -f "$table"' EXIT
"${FEEDPLAN:-$root/target/release/feedplan}" plan "$curve" -o "$table" >/dev/null
host=$("${FEEDSIM:-$root/target/release/feedsim}" run "$table" --json)
host_ticks=$(python3 -c 'import json,sys; print(json.loads(sys.argv[1])["setpoints"])' "$host")
host_digest=$(python3 -c 'import json,sys; print(json.loads(sys.argv[1])["setpoint_digest"])' "$host")
board=$root/boards/stm32f4
tdir=${BOARD_TARGET_DIR:-target/qemu}
(
  cd "$board"
  export BOARD_TABLE="$table"
  cargo clippy --release --features qemu,baked-table --target-dir "$tdir" -- -D warnings
  cargo build --release --features qemu,baked-table --target-dir "$tdir"
)
case $tdir in /*) ;; *) tdir=$board/$tdir ;; esac
elf=$tdir/thumbv7em-none-eabihf/release/board-stm32f4
qemu_args=(-M netduinoplus2 -nographic -icount shift=3,sleep=off -semihosting-config enable=on,target=native)
out=$(timeout -k 5 120 qemu-system-arm "${qemu_args[@]}" -kernel "$elf" </dev/null 2>&1) || {
  echo "$out"; echo "board firmware under QEMU failed" >&2; exit 1; }
qemu_ticks=$(sed -n 's/^ticks: \([0-9]*\).*/\1/p' <<<"$out")
qemu_digest=$(sed -n 's/^digest: fnv1a64-pos-le=\([0-9a-f]*\).*/\1/p' <<<"$out")
echo "$(basename "$curve"): host ${host_ticks} ticks digest ${host_digest}; board firmware on QEMU netduinoplus2 ${qemu_ticks} ticks digest ${qemu_digest}"
grep -E '^(self-check|servo|run):' <<<"$out" | sed 's/^/  qemu /'
if [ "$host_ticks" != "$qemu_ticks" ] || [ "$host_digest" != "$qemu_digest" ]; then
  echo "host and board setpoints differ" >&2; exit 1
fi
python3 "$root/firmware-core/mcu/bench_insn.py" "$elf" --machine netduinoplus2 \
  --marks board_stm32f4::qemu::mark_begin,board_stm32f4::qemu::mark_end \
  --qemu-arg=-icount --qemu-arg=shift=3,sleep=off --timeout 120 | grep -E '^(==|group|\(marker|servo-tick)'
# A feed hold on the board image: the (simulated) hold input active for 4,000 servo
# interrupts (1 s of plan time) from the 2,000th; the hold must be taken, the machine held
# at rest when the input is released, the resume taken, the run must end, and the steps
# emitted must equal the last setpoint's position in steps.
(cd "$board" && BOARD_TABLE="$table" BOARD_QEMU_HOLD_AT=2000 BOARD_QEMU_HOLD_TICKS=4000 \
  cargo build --release --features qemu,baked-table --target-dir "$tdir")
out=$(timeout -k 5 120 qemu-system-arm "${qemu_args[@]}" -kernel "$elf" </dev/null 2>&1) || {
  echo "$out"; echo "hold run failed" >&2; exit 1; }
if ! grep -q '^feed hold:' <<<"$out" || ! grep -q '^resume:.*Held$' <<<"$out" || ! grep -q '^run: done' <<<"$out"; then
  echo "$out"; echo "hold run: no hold, not held at rest before the resume, or not done" >&2; exit 1
fi
grep -E '^(feed hold|resume|ticks|steps):' <<<"$out" | sed 's/^/  hold run: /'
# The same table through the link: framed (boards/stm32f4/frame-table.py), sent into USART2
# through a FIFO, checked, parsed and run; only tables that fit the board's RAM buffer.
frame=$(mktemp --suffix=.frame)
if python3 "$board/frame-table.py" "$table" "$frame" 2>/dev/null; then
  # (the same target directory: only this crate is built again, over the image above)
  (cd "$board" && cargo build --release --features qemu --target-dir "$tdir")
  link_elf=$elf
  fifo=$(mktemp -d)
  mkfifo "$fifo/link.in" "$fifo/link.out"
  exec 3<>"$fifo/link.in" 4<>"$fifo/link.out"
  timeout -k 5 120 qemu-system-arm "${qemu_args[@]}" -serial null -chardev "pipe,id=link,path=$fifo/link" \
    -serial chardev:link -kernel "$link_elf" </dev/null >"$fifo/out.txt" 2>&1 &
  qemu=$!
  # QEMU's USART drops what arrives before the firmware enables it: send once the
  # firmware says it waits (at most 30 s)
  for _ in $(seq 300); do
    grep -q '^link: waiting' "$fifo/out.txt" && break
    sleep 0.1
  done
  cat "$frame" >&3
  rc=0; wait "$qemu" || rc=$?
  out=$(cat "$fifo/out.txt")
  exec 3>&- 4>&-
  rm -rf "$fifo" "$frame"
  if [ "$rc" -ne 0 ]; then echo "$out"; echo "link run failed" >&2; exit 1; fi
  link_ticks=$(sed -n 's/^ticks: \([0-9]*\).*/\1/p' <<<"$out")
  link_digest=$(sed -n 's/^digest: fnv1a64-pos-le=\([0-9a-f]*\).*/\1/p' <<<"$out")
  echo "  table sent over USART2 ($(stat -c %s "$table") bytes): ${link_ticks} ticks digest ${link_digest}"
  if [ "$host_ticks" != "$link_ticks" ] || [ "$host_digest" != "$link_digest" ]; then
    echo "host and board (table over the link) setpoints differ" >&2; exit 1
  fi
else
  rm -f "$frame"
  echo "  table over USART2: not run ($(stat -c %s "$table") bytes do not fit the 96 KiB RAM buffer)"
fi
