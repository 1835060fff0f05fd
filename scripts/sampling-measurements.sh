#!/usr/bin/env bash
# How regularly the generators and real scans sample their surfaces (issue 35, item 1):
# nearest-neighbour CV and the bare fraction of discs of the average spacing, for random and
# even sampling beside real files. Writes OUT/sampling.md.
#
#   scripts/sampling-measurements.sh BIN OUT [POINTS]
#
# bunny.ply was written from the npm package `bunny` 1.0.1 (public domain) by:
#   npm pack bunny && tar xzf bunny-1.0.1.tgz && node -e 'const b=require("./package"); …'
# (positions as `x y z`, cells as `3 i j k`, an ASCII PLY header) — see
# scenes/tests/data/real/README.md.
set -euo pipefail
bin=${1:?BIN}; out=${2:?OUT}; n=${3:-240000}
here=$(cd "$(dirname "$0")/.." && pwd)
real=$here/scenes/tests/data/real
mkdir -p "$out"
{
  echo "# Sampling regularity"
  echo
  echo "\`scripts/sampling-measurements.sh $bin $out $n\`, commit $(git -C "$here" rev-parse --short=12 HEAD), $(date -u +%F)."
  echo
  NODEVICE_SELECT=1 "$bin" sampling --cache "$out/cache" \
    "statue:$n:1:random" "statue:$n:1:even" "isosurface:$n:1:random" "isosurface:$n:1:even" \
    "terrain:$n:1:random" "terrain:$n:1:even" "isosurface-deep:$n:1:even" "$real/bunny.ply" "$real/plane.laz" "$real/pipeSpherical.e57" 2>/dev/null
} > "$out/sampling.md"
cat "$out/sampling.md"
