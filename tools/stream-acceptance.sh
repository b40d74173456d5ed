#!/usr/bin/env bash
# The streaming measurements of docs/streaming-design.md, as `feedsim stream` makes them with its
# defaults (a path longer than 400 mm planned in windows of 400/350 mm while it runs, 32 mm chunks,
# 2 Mbaud, 5 ms latency, 16 KiB ring): the 11 m meander RUNS times, a long curve (the 603 m
# meander) and a long program (a repeated part), one line each with the first motion, the planning
# and host real-time factors, the peak RSS, the machining time against the plan's, the starvation
# and the worst ratio to a limit on the setpoints. Wall times are this machine's, measured as it
# runs: nothing else should run beside it.
#
#   bash tools/stream-acceptance.sh [RUNS] [ROWS] [N]   (defaults 3, 1440 rows: 603 m, 100 parts: 47 m)
#
# STREAM_ARGS adds `feedsim stream` options to the two curves' runs (a part program's paths keep
# theirs), e.g. the long smooth path's layout of docs/streaming-design.md:
#
#   STREAM_ARGS="--density 0.25 --window-mm 400 --commit-mm 350 --chunk-mm 128" bash tools/stream-acceptance.sh
#
# The 603 m curve takes ~3 min, the 1,270-part program (600.7 m) over an hour of simulation.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
runs=${1:-3}
rows=${2:-1440}
parts=${3:-100}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$root"
cargo build --release -q -p sim-harness
feedsim=$root/target/release/feedsim
one() { # NAME FILE [OPTIONS…]: a line from feedsim stream --json
  local name=$1 file=$2
  shift 2
  "$feedsim" stream "$file" "$@" --json | python3 -c "
import json, sys
d = json.load(sys.stdin)
rss = d.get('peak_rss_kib')
print('%-22s first motion %7.2f ms  planning %6.1fx  with hold points %6.1fx  peak RSS %s  machining %.4f s (plan %.4f)  starved %d ticks  worst ratio %.4f  check %s' % (
    sys.argv[1], d['first_motion_ms'], d['plan_realtime_factor'], d['host_realtime_factor'],
    '%.1f MB' % (rss / 1024) if rss else 'n/a', d['machining_time_s'], d['planned_time_s'],
    d['starved_ticks'], max(d['ratios'].values()), 'ok' if d['check_ok'] else 'FAILED'))
" "$name"
}
read -r -a extra <<< "${STREAM_ARGS:-}"
[ ${#extra[@]} -eq 0 ] || echo "the curves with: ${extra[*]}"
for k in $(seq 1 "$runs"); do
  one "meander 11 m ($k)" planner-host/curves/long/meander-11m.json "${extra[@]}"
done
python3 tools/make-meander.py --rows "$rows" > "$tmp/long.json"
one "meander, $rows rows" "$tmp/long.json" "${extra[@]}"
python3 tools/make-repeated.py planner-host/programs/linuxcnc/g5-butterfly-xy.ngc "$parts" > "$tmp/rep.ngc"
one "butterfly part x $parts" "$tmp/rep.ngc"
