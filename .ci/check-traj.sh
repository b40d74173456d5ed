#!/usr/bin/env bash
# Checks a simulated CSV against its curve and every limit, with the machine at rest 50 ticks
# before and after (--pad-rest 50).
#
# Usage: check-traj.sh CSV CURVE [feedsim check options, e.g. --tol 0.02]
#
# 1. The project's own checker, `feedsim check` (own NURBS evaluation, every ratio, contour,
#    end points, monotone progress): always fatal.
# 2. A second opinion where ../shared exists: shared/checks/check_traj.py (Python, numpy,
#    scipy), plain and with --pad-rest 50, both JSON lines printed. Its failures other than
#    acceleration and jerk ratios are fatal; with STRICT=1 every failure is (CI runs STRICT).
#    CHECKER=path overrides where it is looked for; without it the second opinion is skipped.
set -uo pipefail
csv=$1; curve=$2; shift 2
here=$(cd "$(dirname "$0")" && pwd)
feedsim=${FEEDSIM:-$here/../target/release/feedsim}
status=0
"$feedsim" check "$csv" --curve "$curve" --pad-rest 50 "$@" || status=1

checker=${CHECKER:-${SHARED:-$here/../../shared}/checks/check_traj.py}
if [ ! -f "$checker" ]; then
  echo "second opinion skipped: no $checker"
  exit $status
fi
# (both paddings at once: each is one Python process on one core)
runs=$(mktemp -d)
trap 'rm -rf "$runs"' EXIT
for pad in 0 50; do
  python3 "$checker" "$csv" "$curve" --pad-rest "$pad" >"$runs/$pad" &
done
wait
for pad in 0 50; do
  out=$(cat "$runs/$pad")
  echo "check_traj.py --pad-rest $pad: $out"
  python3 - "$out" "${STRICT:-0}" <<'PY' || status=1
import json, sys
r = json.loads(sys.argv[1]); strict = sys.argv[2] == "1"
known = set() if strict else {"acc", "jerk", "tacc", "tjerk"}
bad = [f for f in r["fail"] if f not in known]
if bad:
    print("  FAILED:", bad); sys.exit(1)
if r["fail"]:
    print("  acceleration or jerk above the limit (not fatal without STRICT=1):", r["fail"])
PY
done
exit $status
