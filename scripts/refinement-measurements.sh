#!/usr/bin/env bash
# Issue 35, item 0: do the layered methods get worse as they refine? The close still view
# paper/paths/still-close.toml (0.8 R, fov 40°), ε = 1 px, 512², on a random and an evenly
# sampled statue: the first frame (what is loaded at once) against the converged last frame,
# for LPC (the fix `enlarge=layers` and the literal reading `enlarge=cloud`), Potree (its
# default point size and point_size=2), MWKD and QSplat. Writes OUT/refinement.md.
#
#   scripts/refinement-measurements.sh BIN OUT [POINTS]
set -euo pipefail
bin=${1:?BIN}; out=${2:?OUT}; n=${3:-240000}
here=$(cd "$(dirname "$0")/.." && pwd)
path=$here/paper/paths/still-close.toml
mkdir -p "$out"
{
  echo "# Close view: first frame against converged"
  echo
  echo "\`scripts/refinement-measurements.sh $bin $out $n\`, commit $(git -C "$here" rev-parse --short=12 HEAD), $(date -u +%F)."
  echo
  echo "| scene | method | first: points / FLIP / holes | converged: points / FLIP / holes |"
  echo "|---|---|---|---|"
  for scene in "statue:$n:1" "statue:$n:1:even"; do
    for m in "lpc" "lpc enlarge=cloud" "potree" "potree point_size=2" "voxel" "mwkd" "qsplat"; do
      set -- $m
      method=$1; shift
      params=(); for p in "$@"; do params+=(--param "$p"); done
      frames=12; [ "$method" = qsplat ] && frames=1
      dir="$out/${scene//:/_}-${m// /-}"
      NODEVICE_SELECT=1 "$bin" run --method "$method" "${params[@]}" --scene "$scene" --path "$path" \
        --frames $frames --eps 1 --width 512 --height 512 --out "$dir" --cache "$out/cache" >/dev/null 2>&1
      python3 - "$dir/frames.csv" "$scene" "$m" <<'PY'
import csv, sys
rows = list(csv.DictReader(open(sys.argv[1])))
f, l = rows[0], rows[-1]
g = lambda r: f"{int(float(r['points_drawn'])):,} / {float(r['flip_mean']):.4f} / {100*float(r['hole_ratio']):.2f} %"
print(f"| {sys.argv[2]} | {sys.argv[3]} | {g(f)} | {g(l)} |")
PY
    done
  done
} > "$out/refinement.md"
cat "$out/refinement.md"
