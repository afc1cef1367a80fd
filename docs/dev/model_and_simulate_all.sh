#!/bin/bash
# usage: model_and_simulate_all.sh MAMMAPLAN OUT_DIR
# Issue 21's acceptance run: `model` with its defaults on the 15 shared scans, then
# `simulate` with catalog:R-MOD-100 on both sides of each model; prints each exit status.
# OUT_DIR/NAME.json and NAME.sim.json hold their --json output, m_NAME and s_NAME the
# folders. Then: python3 docs/dev/model_and_simulate_table.py OUT_DIR
set -u
BIN=$1; OUT=$2; mkdir -p "$OUT"
HERE=$(cd "$(dirname "$0")" && pwd)
SCANS=$HERE/../../../shared/scans
for name in v02_average pair1_pre pair1_post s01 s02 s03 s04 s05 s06 s07 s08 s09 s10 s11 s12; do
  dir=$SCANS; [[ $name == s* ]] && dir=$SCANS/zoo
  "$BIN" model --scan "$dir/$name.ply" --landmarks "$dir/${name}_landmarks.json" \
    --out "$OUT/m_$name" --json > "$OUT/$name.json" 2> "$OUT/$name.err"
  echo "model $name exit $?"
  "$BIN" simulate --model "$OUT/m_$name" --left catalog:R-MOD-100 --right catalog:R-MOD-100 \
    --out "$OUT/s_$name" --json --quiet > "$OUT/$name.sim.json" 2> "$OUT/$name.sim.err"
  echo "simulate $name exit $?"
done
