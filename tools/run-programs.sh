#!/usr/bin/env bash
# Every program in planner-host/programs/own and planner-host/programs/linuxcnc: planned by
# `feedplan plan` (chords under G64 P fitted), run to its last block by `feedsim run`, every path
# checked against its limits (1 %) and every setpoint against the programmed geometry (1 um, or
# the G64 P tolerance). Programs the planner refuses on purpose are listed in REFUSED with the
# exit code they must give. One line per program, in order; exit 1 on a failure. JOBS programs
# at a time (default: the machine's cores; each run is one process on one core).
#
#   bash tools/run-programs.sh [OUT_DIR]      (needs target/release/feedplan and feedsim)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$(mktemp -d)}
mkdir -p "$out"
export feedplan=$root/target/release/feedplan
export feedsim=$root/target/release/feedsim
export out
# (none today; NAME=CODE words: a program listed here must be refused with that exit code)
export REFUSED=""
cd "$root"

# One program: its line on stdout, "FAIL ..." and exit 1 on a failure.
one() {
  local f=$1 name plan code res summary checks want=""
  name=$(basename "$f" .ngc)
  for r in $REFUSED; do [ "${r%%=*}" = "$name" ] && want=${r#*=}; done
  set +e
  plan=$("$feedplan" plan "$f" -o "$out/$name.bin" -q 2>&1)
  code=$?
  set -e
  if [ -n "$want" ]; then
    if [ "$code" != "$want" ]; then
      echo "FAIL $name: expected exit $want, got $code: $plan"; return 1
    fi
    echo "refused $name (exit $code, as expected)"
    return 0
  fi
  if [ "$code" != 0 ]; then echo "FAIL $name: $plan"; return 1; fi
  if ! res=$("$feedsim" run "$out/$name.bin" --check --tol 0.01 --program "$f" 2>&1); then
    echo "FAIL $name:"; echo "$res" | tail -5; return 1
  fi
  summary=$(echo "$plan" | head -1 | grep -oE '[0-9]+ paths|predicted machining time [0-9.]+ s|planned in [0-9.]+ s' | paste -sd, -)
  checks=$(echo "$res" | grep -oE 'worst ratio [0-9.]+ \(|exact moves [0-9.e+-]+ mm|G64 P [0-9.e+-]+ mm \(allowed [0-9.e+-]+' | tr -d '(' | paste -sd, -)
  echo "ok $name: $summary; $checks"
}
export -f one

programs=$(git ls-files 'planner-host/programs/own/*.ngc' 'planner-host/programs/linuxcnc/*.ngc')
# each program's line into its own file (the runs overlap), then printed in order
printf '%s\n' $programs | xargs -P "${JOBS:-$(nproc)}" -I{} \
  bash -c 'one "$1" > "$out/$(basename "$1" .ngc).line" 2>&1 || true' _ {}
status=0
for f in $programs; do
  line="$out/$(basename "$f" .ngc).line"
  if [ ! -s "$line" ] || grep -q '^FAIL' "$line"; then
    cat "$line" >&2 2>/dev/null || echo "FAIL $f: no result" >&2
    status=1
  else
    cat "$line"
  fi
done
exit $status
