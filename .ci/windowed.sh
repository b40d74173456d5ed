#!/usr/bin/env bash
# Windowed planning against the whole-path plan: CURVE planned whole and window by window
# (--window-mm W --commit-mm C); the windowed plan's predicted machining time must be within
# 1 % of the whole plan's (or shorter), and its table, run through the firmware interpolator,
# must hold every limit on the setpoints with 50 ticks at rest padding (1 %), joins included.
# Prints one line of figures.
#
#   bash .ci/windowed.sh CURVE W C      (needs target/release/feedplan and feedsim)
set -euo pipefail
curve=$1; w=$2; c=$3
root=$(cd "$(dirname "$0")/.." && pwd)
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
"$root/target/release/feedplan" plan "$curve" -o "$out/whole.bin" --json -q > "$out/whole.json"
"$root/target/release/feedplan" plan "$curve" --window-mm "$w" --commit-mm "$c" -o "$out/win.bin" --json -q > "$out/win.json"
"$root/target/release/feedsim" run "$out/win.bin" --check --tol 0.01 --pad-rest 50 --json > "$out/run.json"
python3 - "$out" <<'PY'
import json, sys
d = sys.argv[1]
whole = json.load(open(f"{d}/whole.json"))
win = json.load(open(f"{d}/win.json"))
run = json.load(open(f"{d}/run.json"))
tw, tf = whole["predicted_time_s"], win["predicted_time_s"]
st = win["windows"]
ratio = tf / tw
print(f"{win['curve']}: L {win['path_length_mm']:.1f} mm, {st['windows']} windows of "
      f"{win['config']['windows']['window_mm']} mm committing {win['config']['windows']['commit_mm']} mm: "
      f"{tf:.4f} s against the whole plan's {tw:.4f} s ({(ratio - 1) * 100:+.3f} %); "
      f"first window {st['first_window_s'] * 1e3:.1f} ms, all {st['windows_s']:.2f} s "
      f"(whole plan {whole['total_time_s']:.2f} s); setpoints, worst ratio "
      + ", ".join(f"{k} {v['ratio']:.4f}" for k, v in run["check"]["ratios"].items()))
if not run["check"]["ok"]:
    sys.exit(f"a limit is exceeded on the setpoints: {run['check']['fail']}")
if ratio > 1.01:
    sys.exit("the windowed plan is more than 1 % slower than the whole plan")
PY
