#!/usr/bin/env bash
# Every program in planner-host/programs/own and planner-host/programs/linuxcnc: planned by
# `feedplan plan` (chords under G64 P fitted), run to its last block by `feedsim run`, every path
# checked against its limits (1 %) and every setpoint against the programmed geometry (1 um, or
# the G64 P tolerance). Programs the planner refuses on purpose are listed in REFUSED with the
# exit code they must give. One line per program; exit 1 on the first failure.
#
#   bash tools/run-programs.sh [OUT_DIR]      (needs target/release/feedplan and feedsim)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$(mktemp -d)}
mkdir -p "$out"
feedplan=$root/target/release/feedplan
feedsim=$root/target/release/feedsim
# (none today; a program listed here must be refused with that exit code)
declare -A REFUSED=()
cd "$root"
for f in $(git ls-files 'planner-host/programs/own/*.ngc' 'planner-host/programs/linuxcnc/*.ngc'); do
  name=$(basename "$f" .ngc)
  set +e
  plan=$("$feedplan" plan "$f" -o "$out/$name.bin" -q 2>&1)
  code=$?
  set -e
  if [ -n "${REFUSED[$name]:-}" ]; then
    if [ "$code" != "${REFUSED[$name]}" ]; then
      echo "FAIL $name: expected exit ${REFUSED[$name]}, got $code: $plan" >&2; exit 1
    fi
    echo "refused $name (exit $code, as expected)"
    continue
  fi
  if [ "$code" != 0 ]; then echo "FAIL $name: $plan" >&2; exit 1; fi
  if ! res=$("$feedsim" run "$out/$name.bin" --check --tol 0.01 --program "$f" 2>&1); then
    echo "FAIL $name:" >&2; echo "$res" | tail -5 >&2; exit 1
  fi
  summary=$(echo "$plan" | head -1 | grep -oE '[0-9]+ paths|predicted machining time [0-9.]+ s|planned in [0-9.]+ s' | paste -sd, -)
  checks=$(echo "$res" | grep -oE 'worst ratio [0-9.]+ \(|exact moves [0-9.e+-]+ mm|G64 P [0-9.e+-]+ mm \(allowed [0-9.e+-]+' | tr -d '(' | paste -sd, -)
  echo "ok $name: $summary; $checks"
done
