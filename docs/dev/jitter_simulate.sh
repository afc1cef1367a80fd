#!/bin/bash
# usage: jitter_simulate.sh MAMMAPLAN OUT_DIR SEED...
# For each seed and each of the 14 shared bodies with their own landmarks: moves every
# landmark up to 10 mm along the skin (jitter_on_surface.py), builds the default model,
# simulates catalog:R-MOD-115 on both sides, and prints the inverted element count.
set -u
BIN=$1; OUT=$2; shift 2; mkdir -p "$OUT"
HERE=$(cd "$(dirname "$0")" && pwd)
SCANS=$HERE/../../../shared/scans
for seed in "$@"; do
  for body in v02_average pair1_pre s01 s02 s03 s04 s05 s06 s07 s08 s09 s10 s11 s12; do
    dir=$SCANS; [[ $body == s* ]] && dir=$SCANS/zoo
    landmarks=$OUT/landmarks_${body}_$seed.json
    python3 "$HERE/jitter_on_surface.py" "$dir/$body.ply" "$dir/${body}_landmarks.json" "$landmarks" "$seed" 10 > /dev/null
    if "$BIN" model --scan "$dir/$body.ply" --landmarks "$landmarks" --out "$OUT/model_${body}_$seed" --quiet > /dev/null 2>&1; then
      inverted=$("$BIN" simulate --model "$OUT/model_${body}_$seed" --left catalog:R-MOD-115 \
        --right catalog:R-MOD-115 --out "$OUT/sim_${body}_$seed" --json --quiet 2> /dev/null |
        python3 -c "import json, sys; print(json.load(sys.stdin)['solver']['inverted_elements'])" 2> /dev/null)
      echo "$body $seed inverted=${inverted:-simulate failed}"
    else
      echo "$body $seed model failed"
    fi
  done
done
