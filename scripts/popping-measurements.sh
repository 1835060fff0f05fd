#!/usr/bin/env bash
# The popping measurements of results/measurements/issue-15-metrics-popping.md: the four
# methods at their defaults (the papers' choices; target: the default 1 px tolerance) on
# statue:1000000:1 at 1024², along `zoom` and `flythrough`, 24 frames each. Prints one
# markdown table row per run from its summary.json (medians over the frames; popping_flip
# over frames 1..23), and writes a comparison plot per path (FLIP vs points, splats/s,
# median popping) to OUT/PATH/comparison.svg.
#   scripts/popping-measurements.sh BIN OUT [CACHE]
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [CACHE]}
out=${2:?usage: $0 BIN OUT [CACHE]}
cache=${3:-${SPLATBENCH_CACHE:-$HOME/.cache/splatbench}}
scene=statue:1000000:1
methods=(qsplat spt lpc mwkd)
echo "| path | method | points drawn | flip_mean | popping_flip | popping max | metrics ms |"
echo "|---|---|---|---|---|---|---|"
for path in zoom flythrough; do
  for m in "${methods[@]}"; do
    run="$out/$path/$m"
    mkdir -p "$out/$path"
    "$bin" run --method "$m" --scene "$scene" --path "$path" --frames 24 \
      --width 1024 --height 1024 --cache "$cache" --out "$run" >/dev/null 2>"$run.log" \
      || { cat "$run.log" >&2; exit 1; }
    # Column positions by name, so the method's own columns after them do not matter.
    max_pop=$(awk -F, 'NR==1{for(i=1;i<=NF;i++)c[$i]=i; next}
      $c["popping_flip"]!=""{v=$c["popping_flip"]+0; if(!s||v>m){m=v;s=1}} END{printf "%.4f", m}' \
      "$run/frames.csv")
    jq -r --arg path "$path" --arg m "$m" --arg max "$max_pop" \
      '.medians | "| \($path) | \($m) | \(.points_drawn|floor) | \(.flip_mean*10000|round/10000) | \(.popping_flip*10000|round/10000) | \($max) | \(.metrics_ms // "-") |"' \
      "$run/summary.json"
  done
  "$bin" plot "${methods[@]/#/$out/$path/}" --out "$out/$path" >/dev/null
done
