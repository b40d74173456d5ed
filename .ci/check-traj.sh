#!/usr/bin/env bash
# Runs shared/checks/check_traj.py on a simulated CSV, plain and with --pad-rest 50, and prints
# both JSON lines. Exit status: 0 when every check besides the acceleration and jerk ratios passes
# (endpoints, contour, monotone progress, velocity ratios); acceleration and jerk failures are
# printed as known open findings. STRICT=1 makes any failure (acceleration and jerk included)
# fatal; CI runs every plan and override scenario STRICT.
set -uo pipefail
csv=$1; curve=$2; shift 2
here=$(cd "$(dirname "$0")" && pwd)
checker=${CHECKER:-$here/../../shared/checks/check_traj.py}
[ -f "$checker" ] || checker=$(dirname "$curve")/../checks/check_traj.py
status=0
for pad in 0 50; do
  out=$(python3 "$checker" "$csv" "$curve" --pad-rest "$pad" "$@")
  echo "check_traj --pad-rest $pad: $out"
  python3 - "$out" "${STRICT:-0}" <<'PY' || status=1
import json, sys
r = json.loads(sys.argv[1]); strict = sys.argv[2] == "1"
known = set() if strict else {"acc", "jerk", "tacc", "tjerk"}
bad = [f for f in r["fail"] if f not in known]
if bad:
    print("  FAILED:", bad); sys.exit(1)
if r["fail"]:
    print("  known open findings (not fatal without STRICT=1):", r["fail"])
PY
done
exit $status
