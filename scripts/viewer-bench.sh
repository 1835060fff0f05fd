#!/usr/bin/env bash
# Frame time of `splatbench view` for each method, in a real window under Xvfb, beside
# `splatbench run` on the same poses and build; and the README's screenshot of the viewer
# with its HUD (issue 19).
#
#   scripts/viewer-bench.sh BIN OUT [SCENE] [WIDTHxHEIGHT]
#
# Per method, on SCENE (default statue:1000000:1) at WIDTHxHEIGHT (default 1280x720): the
# viewer plays the orbit path (P, --play orbit --play-frames 60: run's 60 poses) and quits;
# then `run --path orbit --frames 60 --no-metrics` on the viewer's build. Medians: the
# viewer's frame (select + draw) and present (HUD on the CPU + present pass), run's select +
# draw (cpu_select_ms + wall_ms). Writes OUT/viewer-bench.md (adapter, commit, date) and
# OUT/viewer.png (MWKD on a budget, FLIP measured, then levels coloured: the window as
# presented). Builds are made once into OUT/view/builds and reused by a rerun.
set -euo pipefail
BIN=${1:?usage: viewer-bench.sh BIN OUT [SCENE] [WxH]}
OUT=${2:?usage: viewer-bench.sh BIN OUT [SCENE] [WxH]}
SCENE=${3:-statue:1000000:1}
SIZE=${4:-1280x720}
W=${SIZE%x*}
H=${SIZE#*x}
FRAMES=60
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
CACHE="$OUT/cache"
command -v xvfb-run >/dev/null || { echo "viewer-bench: xvfb-run missing (scripts/setup.sh)" >&2; exit 1; }

echo "0 press p" >"$OUT/play.txt"
{
  echo "0 press tab"
  for ((f = 1; f < 10; f++)); do
    echo "$f drag 4 0"
    if ((f == 8)); then echo "$f press c"; fi
  done
  echo "10 press l"
  echo "13 quit"
} >"$OUT/shot.txt"

view() {
  xvfb-run -a -s "-screen 0 $((W + 64))x$((H + 64))x24" "$BIN" view --scene "$SCENE" \
    --width "$W" --height "$H" --cache "$CACHE" --out "$OUT/view" "$@"
}
# Median of column expression $2 over the rows of frames.csv $1 (columns by name).
median() {
  awk -F, -v expr="$2" 'NR == 1 { for (i = 1; i <= NF; i++) c[$i] = i; next }
    { split(expr, t, "+"); v = 0; for (k in t) v += $c[t[k]]; print v }' "$1" |
    sort -g | awk '{ a[NR] = $1 } END { printf "%.2f", (NR % 2) ? a[(NR + 1) / 2] : (a[NR / 2] + a[NR / 2 + 1]) / 2 }'
}

rows=()
adapter=""
for m in qsplat spt lpc mwkd potree; do
  # The first start builds (not timed); a start with --frames 1 quits after one frame.
  view --method "$m" --frames 1 >/dev/null 2>"$OUT/$m-build.log"
  line=$(view --method "$m" --play orbit --play-frames "$FRAMES" --script "$OUT/play.txt" \
    --frames "$FRAMES" 2>"$OUT/$m.log" | grep '^view: ')
  echo "$m: $line"
  adapter=$(sed -n "s/^view: .* on '\(.*\)' (.*/\1/p" <<<"$line")
  frame=$(sed -n 's/.*median frame \([0-9.]*\) ms.*/\1/p' <<<"$line")
  present=$(sed -n 's/.*present \([0-9.]*\) ms.*/\1/p' <<<"$line")
  hud=$(sed -n 's/.*HUD text \([0-9.]*\) ms.*/\1/p' <<<"$line")
  build=$(ls -d "$OUT/view/builds/$m"-* | head -1)
  "$BIN" run --method "$m" --scene "$SCENE" --width "$W" --height "$H" --path orbit \
    --frames "$FRAMES" --build-dir "$build" --no-metrics --cache "$CACHE" \
    --out "$OUT/run-$m" >/dev/null 2>"$OUT/run-$m.log"
  ran=$(median "$OUT/run-$m/frames.csv" "cpu_select_ms+wall_ms")
  ratio=$(awk -v f="$frame" -v r="$ran" 'BEGIN { printf "%.2f", f / r }')
  fps=$(awk -v f="$frame" -v p="$present" 'BEGIN { printf "%.1f", 1000 / (f + p) }')
  rows+=("| $m | $frame | $ran | $ratio | $present | $hud | $fps |")
done
view --method mwkd --budget 150000 --script "$OUT/shot.txt" --window-shot "$OUT/viewer.png" \
  >/dev/null 2>"$OUT/shot.log"

git_commit=$(git -C "$(dirname "$0")/.." rev-parse --short HEAD 2>/dev/null || echo unknown)
{
  echo "# splatbench view: frame time per method"
  echo
  echo "\`scripts/viewer-bench.sh $BIN $OUT $SCENE $SIZE\` — $(date -u +%Y-%m-%d), commit $git_commit,"
  echo "adapter '$adapter', in a window under Xvfb. Each method draws the orbit path's $FRAMES"
  echo "poses twice: played in the viewer (P) and by \`run --path orbit --no-metrics\` on the same"
  echo "build. Medians over the frames. *viewer frame*: the method's selection and the renderer's"
  echo "draw in the viewer; *run*: \`cpu_select_ms + wall_ms\` of the same poses; *present*: the HUD"
  echo "(redrawn when due: 4 times a second at most for its measurements) and the present pass;"
  echo "*HUD text*: the part of present spent drawing the HUD's text on the CPU; fps = 1000 /"
  echo "(viewer frame + present)."
  echo
  echo "| method | viewer frame ms | run select + draw ms | viewer / run | present ms | HUD text ms | fps |"
  echo "|---|---:|---:|---:|---:|---:|---:|"
  printf '%s\n' "${rows[@]}"
} >"$OUT/viewer-bench.md"
cat "$OUT/viewer-bench.md"
