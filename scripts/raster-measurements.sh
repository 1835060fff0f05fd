#!/usr/bin/env bash
# The rasteriser measurements of results/measurements/issue-15-metrics-popping.md: each
# method at its defaults (the papers' choices; target: the default 1 px tolerance) on
# statue:1000000:1 at 1024² along a 12-frame orbit, drawn with the instanced quads and with
# the compute rasteriser from one build, back to back (paired). Image metrics are skipped
# (speed only). Prints one markdown row per method: median points drawn, splats/s and GPU ms
# of each rasteriser, and the ratio compute / quads.
#   scripts/raster-measurements.sh BIN OUT [CACHE]
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [CACHE]}
out=${2:?usage: $0 BIN OUT [CACHE]}
cache=${3:-${SPLATBENCH_CACHE:-$HOME/.cache/splatbench}}
scene=statue:1000000:1
common=(--scene "$scene" --path orbit --frames 12 --width 1024 --height 1024 --no-metrics
        --cache "$cache")
echo "| method | points drawn | quads splats/s | quads GPU ms | compute splats/s | compute GPU ms | compute / quads |"
echo "|---|---|---|---|---|---|---|"
for m in full qsplat spt lpc mwkd; do
  mkdir -p "$out/$m"
  "$bin" build --method "$m" --scene "$scene" --out "$out/$m/build" >/dev/null 2>"$out/$m/build.log" \
    || { cat "$out/$m/build.log" >&2; exit 1; }
  for r in quads compute; do
    "$bin" run --method "$m" --build-dir "$out/$m/build" --raster "$r" "${common[@]}" \
      --out "$out/$m/$r" >/dev/null 2>"$out/$m/$r.log" || { cat "$out/$m/$r.log" >&2; exit 1; }
  done
  q=$(jq -r '.medians.splats_per_s' "$out/$m/quads/summary.json")
  c=$(jq -r '.medians.splats_per_s' "$out/$m/compute/summary.json")
  jq -rn --arg m "$m" --argjson q "$q" --argjson c "$c" \
    --slurpfile qs "$out/$m/quads/summary.json" --slurpfile cs "$out/$m/compute/summary.json" \
    '"| \($m) | \($qs[0].medians.points_drawn|floor) | \($q/1e6*100|round/100) M | \($qs[0].medians.gpu_ms*10|round/10) | \($c/1e6*100|round/100) M | \($cs[0].medians.gpu_ms*10|round/10) | ×\($c/$q*10|round/10) |"'
done
jq -r '"adapter: \(.adapter.name) (\(.adapter.backend)), commit \(.git_commit // .commit // "?")"' \
  "$out/full/compute/summary.json"
