#!/usr/bin/env bash
# Regenerate the valid seed tables of the fuzz targets (after a table format
# change): the planner's defaults (certified formulation, jerk end segments,
# paper Table 1 limits). Density 1 point/mm for the 10 mm line (at 0.5 its
# five points leave the end segments' join singular: EndJoinSingular), 0.5 for
# the arc and the built-in Trident (planner-host/curves).
# Uses target/release/feedplan (built if missing; FEEDPLAN overrides).
set -euo pipefail
cd "$(dirname "$0")/../.."
FEEDPLAN=${FEEDPLAN:-./target/release/feedplan}
if [ ! -x "$FEEDPLAN" ]; then
  cargo build --release -q -p planner-host --bin feedplan
fi
plan() { # curve density [more feedplan arguments]
  local curve=$1 density=$2 name
  name=$(basename "$curve" .json)
  shift 2
  [ $# -gt 0 ] && name=${name}_levels
  "$FEEDPLAN" plan "$curve" --density "$density" -o "fuzz/seeds/$name.bin" "$@" >/dev/null
}
plan fuzz/seeds/line.json 1
# feedrate-override levels (table sections 16-19)
plan fuzz/seeds/line.json 1 --override-levels 50,125
plan fuzz/seeds/arc.json 0.5
plan planner-host/curves/trident.json 0.5
cp fuzz/seeds/*.bin fuzz/corpus/table_parse/
ls -l fuzz/seeds/*.bin
# stream_link seeds: planned tables cut into chunks, framed as on the link
# (planner-host's stream_budget example; PlanConfig::default()).
cargo build --release -q -p planner-host --example stream_budget
SB=./target/release/examples/stream_budget
mkdir -p fuzz/corpus/stream_link
"$SB" --chunk-mm 2 --link fuzz/corpus/stream_link/line-2mm fuzz/seeds/line.json >/dev/null
"$SB" --chunk-mm 4 --link fuzz/corpus/stream_link/arc-4mm fuzz/seeds/arc.json >/dev/null
"$SB" --chunk-mm 4 --link fuzz/corpus/stream_link/trident-4mm trident >/dev/null
ls -l fuzz/corpus/stream_link
