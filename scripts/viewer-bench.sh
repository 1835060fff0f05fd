#!/usr/bin/env bash
# Frame time of `splatbench view` for each method, in a real window under Xvfb, and the
# README's screenshot of the viewer with its HUD (issue 19).
#
#   scripts/viewer-bench.sh BIN OUT [SCENE] [WIDTHxHEIGHT]
#
# Per method: the viewer on SCENE (default statue:1000000:1) at WIDTHxHEIGHT (default
# 1280x720), orbiting (Tab, then a 4 px drag every frame: a new view every frame) for 120
# frames of a script; it prints the median frame time (select + draw, what `run` times) and
# the median present time (HUD + the present pass). Writes OUT/viewer-bench.md (with the
# adapter, commit and date) and OUT/viewer.png (MWKD, levels coloured, FLIP measured: the
# window as presented). Builds are made once into OUT/view/builds and reused by a rerun.
set -euo pipefail
BIN=${1:?usage: viewer-bench.sh BIN OUT [SCENE] [WxH]}
OUT=${2:?usage: viewer-bench.sh BIN OUT [SCENE] [WxH]}
SCENE=${3:-statue:1000000:1}
SIZE=${4:-1280x720}
W=${SIZE%x*}
H=${SIZE#*x}
FRAMES=120
mkdir -p "$OUT"
OUT=$(cd "$OUT" && pwd)
CACHE="$OUT/cache"
command -v xvfb-run >/dev/null || { echo "viewer-bench: xvfb-run missing (scripts/setup.sh)" >&2; exit 1; }

script="$OUT/orbit.txt"
{
  echo "0 press tab"
  for ((f = 1; f < FRAMES; f++)); do echo "$f drag 4 0"; done
} >"$script"

shot_script="$OUT/shot.txt"
{
  echo "0 press tab"
  for ((f = 1; f < 30; f++)); do echo "$f drag 4 0"; done
  echo "30 press l"
  echo "31 press c"
  echo "34 quit"
} >"$shot_script"

view() {
  xvfb-run -a -s "-screen 0 $((W + 64))x$((H + 64))x24" "$BIN" view --scene "$SCENE" \
    --width "$W" --height "$H" --cache "$CACHE" --out "$OUT/view" "$@"
}

rows=()
adapter=""
for m in qsplat spt lpc mwkd potree; do
  # The build (first start) is not timed: a start without --script quits after 1 frame.
  view --method "$m" --frames 1 >/dev/null 2>"$OUT/$m-build.log"
  line=$(view --method "$m" --script "$script" 2>"$OUT/$m.log" | grep '^view: ')
  echo "$m: $line"
  adapter=$(sed -n "s/^view: .* on '\(.*\)' (.*/\1/p" <<<"$line")
  frame=$(sed -n 's/.*median frame \([0-9.]*\) ms.*/\1/p' <<<"$line")
  present=$(sed -n 's/.*present \([0-9.]*\) ms.*/\1/p' <<<"$line")
  fps=$(awk -v f="$frame" -v p="$present" 'BEGIN { printf "%.1f", 1000 / (f + p) }')
  rows+=("| $m | $frame | $present | $fps |")
done
view --method mwkd --script "$shot_script" --window-shot "$OUT/viewer.png" >/dev/null 2>"$OUT/shot.log"

git_commit=$(git -C "$(dirname "$0")/.." rev-parse --short HEAD 2>/dev/null || echo unknown)
{
  echo "# splatbench view: frame time per method"
  echo
  echo "\`scripts/viewer-bench.sh $BIN $OUT $SCENE $SIZE\` — $(date -u +%Y-%m-%d), commit $git_commit,"
  echo "adapter '$adapter', under Xvfb; $FRAMES frames of an orbiting script"
  echo "(a new view every frame), medians. *frame*: the method's selection and the renderer's draw"
  echo "(what \`run\` times, plus the viewer's bookkeeping); *present*: the HUD drawn on the CPU and"
  echo "the present pass; fps = 1000 / (frame + present)."
  echo
  echo "| method | frame ms | present ms | fps |"
  echo "|---|---:|---:|---:|"
  printf '%s\n' "${rows[@]}"
} >"$OUT/viewer-bench.md"
cat "$OUT/viewer-bench.md"
