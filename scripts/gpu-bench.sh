#!/usr/bin/env bash
# One command for the GPU rows of the papers' tables and quads vs compute for every method:
#   scripts/gpu-bench.sh BIN OUT [gpu|ci] [CACHE]
# BIN a release build of splatbench (`cargo build --release`: target/release/splatbench).
# For every registered method: one build of the statue, then a 12-frame orbit drawn with the
# instanced quads and, from the same build, with the compute rasteriser (paired, back to back;
# no image metrics: speed only). Targets: the methods' defaults (1 px tolerance), MWKD at the
# paper's Table III budget B = 3 M points (scaled with the scene in `ci`). Writes
# OUT/gpu-bench.md (the table beside the papers' GPU figures, with adapter, commit, date and
# the wall time) and OUT/gpu-bench.csv; each run's folder is OUT/METHOD/RASTER.
# Sizes: `gpu` (default) 10 M points at 1920×1080, for a real GPU (README: "A GPU
# benchmark"); `ci` 50 k points at 128², which CI runs on lavapipe so the command cannot rot.
# An adapter without 64-bit atomics gets "n/a" for compute and the reason in the report.
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [gpu|ci] [CACHE]}
out=${2:?usage: $0 BIN OUT [gpu|ci] [CACHE]}
size=${3:-gpu}
cache=${4:-${SPLATBENCH_CACHE:-$HOME/.cache/splatbench}}
case "$size" in
  gpu) points=10000000; width=1920; height=1080; frames=12; mwkd_budget=3000000 ;;
  ci) points=50000; width=128; height=128; frames=3; mwkd_budget=15000 ;;
  *) echo "size must be gpu or ci, not '$size'" >&2; exit 2 ;;
esac
command -v jq >/dev/null || { echo "gpu-bench: jq not found (scripts/setup.sh installs it)" >&2; exit 1; }
scene="statue:$points:1"
start=$(date +%s)
mkdir -p "$out"
# The papers' GPU figures (METHODS.md), per method.
paper() {
  case "$1" in
    qsplat) echo "3.6–6.6 M splats/s (as measured by the SPT and LPC papers)" ;;
    spt) echo "50–60 M points/s after culling (Radeon 9700)" ;;
    lpc) echo "≈ 40 M splats/s average, 68 M peak" ;;
    mwkd) echo "262–282 M points/s at B = 3 M (GeForce 8800 GT, Table III)" ;;
    *) echo "-" ;;
  esac
}
csv="$out/gpu-bench.csv"
echo "method,target,points_drawn,quads_splats_per_s,quads_gpu_ms,compute_splats_per_s,compute_gpu_ms,compute_over_quads" >"$csv"
rows=()
compute_note=""
for m in full qsplat spt lpc mwkd; do
  mkdir -p "$out/$m"
  target=(--eps 1); target_text="1 px"
  if [ "$m" = mwkd ]; then target=(--budget "$mwkd_budget"); target_text="B = $mwkd_budget"; fi
  "$bin" build --method "$m" --scene "$scene" --out "$out/$m/build" --cache "$cache" \
    >/dev/null 2>"$out/$m/build.log" || { cat "$out/$m/build.log" >&2; exit 1; }
  for r in quads compute; do
    if ! "$bin" run --method "$m" --build-dir "$out/$m/build" --raster "$r" --scene "$scene" \
        --path orbit --frames "$frames" --width "$width" --height "$height" "${target[@]}" \
        --no-metrics --cache "$cache" --out "$out/$m/$r" >/dev/null 2>"$out/$m/$r.log"; then
      if [ "$r" = compute ] && grep -q "64-bit integer atomics" "$out/$m/$r.log"; then
        compute_note=$(grep -o "needs 64-bit.*" "$out/$m/$r.log" | head -1)
        continue
      fi
      cat "$out/$m/$r.log" >&2; exit 1
    fi
  done
  get() { [ -f "$out/$m/$1/summary.json" ] && jq -r ".medians.$2 // empty" "$out/$m/$1/summary.json" || true; }
  pts=$(get quads points_drawn); qs=$(get quads splats_per_s); qg=$(get quads gpu_ms)
  cs=$(get compute splats_per_s); cg=$(get compute gpu_ms)
  ratio=""; [ -n "$cs" ] && ratio=$(jq -n "$cs / $qs")
  echo "$m,$target_text,$pts,$qs,$qg,$cs,$cg,$ratio" >>"$csv"
  fmt() { [ -n "$1" ] && jq -rn "($1/1e6*100|round/100|tostring) + \" M\"" || echo "n/a"; }
  ms() { [ -n "$1" ] && jq -rn "$1*100|round/100" || echo "-"; }
  x() { [ -n "$1" ] && jq -rn "\"×\" + ($1*10|round/10|tostring)" || echo "-"; }
  rows+=("| $m | $target_text | $(jq -rn "$pts|floor") | $(fmt "$qs") | $(ms "$qg") | $(fmt "$cs") | $(ms "$cg") | $(x "$ratio") | $(paper "$m") |")
done
seconds=$(( $(date +%s) - start ))
summary="$out/full/quads/summary.json"
{
  echo "# GPU benchmark ($size)"
  echo
  echo "Adapter: **$(jq -r '"\(.adapter.name) (\(.adapter.backend), \(.adapter.device_type), driver \(.adapter.driver) \(.adapter.driver_info))"' "$summary")**;"
  echo "commit $(jq -r '.git_commit' "$summary"), $(date -u +%Y-%m-%d), $seconds s wall in all."
  echo "Command: \`scripts/gpu-bench.sh $bin $out $size\`; scene $scene, orbit of $frames frames at"
  echo "${width}×${height}, each method's defaults; medians over the frames; splats/s = splats drawn ÷ GPU time"
  echo "(timestamps; wall time where the adapter has none). SPT's splats drawn are those its interval"
  echo "test passes (\"points/s after culling\")."
  echo
  echo "| method | target | points drawn | quads splats/s | quads GPU ms | compute splats/s | compute GPU ms | compute / quads | paper (GPU of its day) |"
  echo "|---|---|---|---|---|---|---|---|---|"
  printf '%s\n' "${rows[@]}"
  if [ -n "$compute_note" ]; then echo; echo "Compute rasteriser: n/a — $compute_note"; fi
} >"$out/gpu-bench.md"
cat "$out/gpu-bench.md"
if [ "$size" = gpu ] && [ "$seconds" -gt 480 ]; then
  echo "gpu-bench: took $seconds s, over the 8 minutes this command is meant to fit" >&2
fi
