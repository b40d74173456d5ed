#!/usr/bin/env bash
# Worst-case Thumb instructions per servo tick, per kind of tick (normal, start and stop
# segments, splice of an override profile, hold, held, resume), measured under QEMU on the
# Cortex-M4F image (firmware-core/mcu, `wcet.py`; docs/wcet.md). Prints ONE JSON line.
#
#   bash .ci/wcet.sh                 # small sweep (CI size)
#   WCET_FULL=1 bash .ci/wcet.sh     # 1,000 hold points and ~100 override points per curve
#   bash .ci/wcet.sh --enforce       # exit 1 when a tick kind is over the budget
#
# Environment: WCET_CURVES (default "butterfly fan star long/meander-1m": the three planar
# built-in curves and a 3-D path, whose z rows the hold and resume ticks then work through;
# any curve of planner-host/curves/), WCET_HOLDS (hold points per
# curve), WCET_OVERRIDES and WCET_CHAINS (override points per chain, chains per curve),
# WCET_BUDGET (default 4000), WCET_OUT (keep tables, profiles and images here).
# Exit code: 0 (with --enforce: 1 when over budget), 2 on a measurement error.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
mcu=$root/firmware-core/mcu
enforce=
for a in "$@"; do
  case $a in
    --enforce) enforce=--enforce ;;
    *) echo "usage: wcet.sh [--enforce]" >&2; exit 2 ;;
  esac
done
if [ -n "${WCET_FULL:-}" ]; then holds=1000 ovr=25 chains=4; else holds=6 ovr=8 chains=1; fi
holds=${WCET_HOLDS:-$holds}; ovr=${WCET_OVERRIDES:-$ovr}; chains=${WCET_CHAINS:-$chains}
curves=${WCET_CURVES:-butterfly fan star long/meander-1m}

# Tools: QEMU with TCG plugin support (Debian's qemu-system-arm has it; the plugin declares
# the few API calls it uses, so no plugin header package is needed), arm-none-eabi-nm, cc.
if ! command -v qemu-system-arm >/dev/null || ! command -v arm-none-eabi-nm >/dev/null; then
  apt-get update -qq && apt-get install -y -qq --no-install-recommends qemu-system-arm binutils-arm-none-eabi >&2
fi
if ! command -v "${CC:-cc}" >/dev/null; then
  apt-get update -qq && apt-get install -y -qq --no-install-recommends gcc libc6-dev >&2
fi
rustup target list --installed 2>/dev/null | grep -q thumbv7em-none-eabihf || rustup target add thumbv7em-none-eabihf >&2
feedplan=$root/target/release/feedplan
[ -x "$feedplan" ] || (cd "$root" && cargo build --release -q -p planner-host --bin feedplan >&2)

out=${WCET_OUT:-$(mktemp -d)}
mkdir -p "$out"
images=()
for path in $curves; do
  # (a curve of planner-host/curves/, its name without the folder: long/meander-1m)
  c=$(basename "$path")
  python3 "$mcu/wcet.py" profiles "$root/planner-host/curves/$path.json" --table "$out/$c.bin" \
    --feedplan "$feedplan" --count "$ovr" --chains "$chains" -o "$out/$c.ovr"
  (cd "$mcu" && MCU_TABLE="$out/$c.bin" MCU_OVERRIDES="$out/$c.ovr" MCU_HOLDS="$holds" \
    cargo build --release -q --bin firmware-mcu >&2)
  cp "$mcu/target/thumbv7em-none-eabihf/release/firmware-mcu" "$out/$c.elf"
  images+=("$c=$out/$c.elf")
done
echo "wcet: $holds hold points per curve, $chains x $ovr override points; measuring ${curves}" >&2
python3 "$mcu/wcet.py" measure "${images[@]}" --budget "${WCET_BUDGET:-4000}" $enforce
