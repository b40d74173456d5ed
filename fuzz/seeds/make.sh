#!/usr/bin/env bash
# Regenerate the valid seed tables of the fuzz targets (after a table format
# change): the planner's defaults (certified formulation, jerk end segments,
# paper Table 1 limits). Density 1 point/mm for the 10 mm line (at 0.5 its
# five points leave the end segments' join singular: EndJoinSingular), 0.5 for
# the arc and the Trident (/work/shared/curves, or $SHARED/curves).
# Uses target/release/feedplan (built if missing; FEEDPLAN overrides).
set -euo pipefail
cd "$(dirname "$0")/../.."
SHARED=${SHARED:-../shared}
FEEDPLAN=${FEEDPLAN:-./target/release/feedplan}
if [ ! -x "$FEEDPLAN" ]; then
  cargo build --release -q -p planner-host --bin feedplan
fi
plan() { # curve density
  "$FEEDPLAN" plan "$1" --density "$2" -o "fuzz/seeds/$(basename "$1" .json).bin" >/dev/null
}
plan fuzz/seeds/line.json 1
plan fuzz/seeds/arc.json 0.5
plan "$SHARED/curves/trident.json" 0.5
cp fuzz/seeds/*.bin fuzz/corpus/table_parse/
ls -l fuzz/seeds/*.bin
