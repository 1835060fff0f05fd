#!/usr/bin/env bash
# The modern-vs-classic table of results/measurements/issue-39-modern-vs-classic.md (issue 39):
# the four papers' methods, Potree and the two modern baselines (`voxel`, colour-filtered
# voxel LOD; `clod`, continuous LOD) at equal points drawn — one point budget for all, a tenth
# of the samples — on the statue, the terrain and the isosurface at 1 M samples, along the
# `zoom` path (an approach: levels come in, so popping shows), 16 frames at 512². One
# markdown row per run: points drawn, FLIP, holes (medians), the warped popping at lag 1
# (median / p95; issue 38) and its pop events, the build rate and bits per stored point
# (build.json), then the adapter and commit. Methods that draw whole nodes (LPC, MWKD,
# Potree, voxel) may draw less than the budget: compare FLIP at the points they drew; one
# whose root alone exceeds the budget refuses it, and its row says so.
#   scripts/modern-vs-classic.sh BIN OUT [CACHE]
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [CACHE]}
out=${2:?usage: $0 BIN OUT [CACHE]}
cache=${3:-${SPLATBENCH_CACHE:-$HOME/.cache/splatbench}}
budget=100000
methods=(qsplat spt lpc mwkd potree voxel clod)
scenes=(statue:1000000:1 terrain:1000000:1 isosurface:1000000:1)
echo "| scene | method | points drawn | FLIP | holes | warped popping l1: median / p95 | pop events l1 | build points/s | bits/point |"
echo "|---|---|---|---|---|---|---|---|---|"
for scene in "${scenes[@]}"; do
  name=${scene%%:*}
  for m in "${methods[@]}"; do
    run="$out/$name/$m"
    mkdir -p "$out/$name"
    if ! NODEVICE_SELECT=1 "$bin" run --method "$m" --scene "$scene" --path zoom --frames 16 \
      --width 512 --height 512 --budget "$budget" --cache "$cache" --out "$run" \
      >/dev/null 2>"$run.log"; then
      # A whole-node method whose root exceeds the budget refuses it (it cannot draw less):
      # a row saying so; any other failure stops the table.
      grep -q "smaller than its root" "$run.log" || { cat "$run.log" >&2; exit 1; }
      root=$(grep -o 'root node of [0-9]* points' "$run.log" | grep -o '[0-9]*')
      echo "| $name | $m | refused: its root holds $root points | - | - | - | - | - | - |"
      continue
    fi
    jq -r --arg s "$name" --arg m "$m" \
      'def f: if . == null then "-" else (. * 10000 | round / 10000 | tostring) end;
       def n: if . == null then "-" else (. | round | tostring) end;
       "| \($s) | \($m) | \(.medians.points_drawn|n) | \(.medians.flip_mean|f) | \(.medians.hole_ratio|f) | \(.medians.popping_warped_l1|f) / \(.p95.popping_warped_l1|f) | \(.medians.pop_events_l1|n) | \(.build.points_per_s|n) | \(.build.bits_per_sample*100|round/100) |"' \
      "$run/summary.json"
  done
done
echo
jq -r '"adapter: \(.adapter.name) (\(.adapter.backend), \(.adapter.driver_info)), commit \(.git_commit)"' \
  "$out/statue/qsplat/summary.json"
