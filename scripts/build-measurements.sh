#!/usr/bin/env bash
# The build measurements of results/measurements/issue-16-builds.md: splatbench's four
# methods and PotreeConverter 2.0 building the same LAS file (terrain:N:1 exported as LAS 1.2
# format 2), one after the other on an otherwise idle machine. Each row is one whole process,
# from the LAS file to a finished build: wall seconds and peak RSS from /usr/bin/time, points/s
# = N / wall. splatbench builds start from an empty cache, so the LAS → column-file read is
# in their time (and reported apart from build.json's `seconds`). PotreeConverter's own
# logged duration is quoted too: its wall time is held to whole seconds by its status thread.
#   scripts/build-measurements.sh BIN OUT N [POTREE_BIN] [METHODS]
# N: points (e.g. 10000000); POTREE_BIN: PotreeConverter built from source (rows skipped when
# absent); METHODS: space-separated (default "lpc mwkd qsplat spt"), each METHOD or
# METHOD:key=value,… for --param (e.g. "potree potree:sampling=random").
# Prints one markdown row per build, and writes OUT/N/*.json|log.
set -euo pipefail
bin=${1:?usage: $0 BIN OUT N [POTREE_BIN] [METHODS]}
out=${2:?usage: $0 BIN OUT N [POTREE_BIN] [METHODS]}
n=${3:?usage: $0 BIN OUT N [POTREE_BIN] [METHODS]}
potree=${4:-}
methods=${5:-lpc mwkd qsplat spt}
dir="$out/$n"
mkdir -p "$dir"
las="$dir/terrain-$n.las"
if [ ! -s "$las" ]; then
  "$bin" export --scene "terrain:$n:1" --out "$las" --cache "$dir/export-cache" >/dev/null
  rm -rf "$dir/export-cache"
fi
bytes=$(stat -L -c %s "$las")
# time's %e is seconds, %M KiB.
timed() { /usr/bin/time -f '%e %M' -o "$1" "${@:2}"; }
row() { # name, wall, rss KiB, extra
  awk -v name="$1" -v w="$2" -v m="$3" -v n="$n" -v extra="$4" 'BEGIN {
    printf "| %s | %d | %.1f | %.2f M | %d | %s |\n", name, n, w, n / w / 1e6, m / 1024, extra }'
}
echo "| build | points | wall s | points/s | peak RSS MB | notes |"
echo "|---|---|---|---|---|---|"
if [ -n "$potree" ] && [ -x "$potree" ]; then
  pdir=$(dirname "$potree")
  for mode in default fastest; do
    args=()
    [ "$mode" = fastest ] && args=(--encoding DEFAULT -m random --attributes rgb)
    rm -rf "$dir/potree-$mode"
    (cd "$pdir" && timed "$dir/potree-$mode.time" ./PotreeConverter "$las" -o "$dir/potree-$mode" \
      "${args[@]}" >"$dir/potree-$mode.log" 2>&1)
    read -r w m <"$dir/potree-$mode.time"
    # Its own totals: "duration: 6.028s" and the chunking / indexing phases.
    total=$(grep -E '^duration:' "$dir/potree-$mode.log" | grep -o '[0-9.]*' | head -1 || echo "?")
    chunking=$(grep -F 'duration(chunking-total)' "$dir/potree-$mode.log" | grep -o '[0-9.]*$' || echo "?")
    indexing=$(grep -F 'duration(indexing)' "$dir/potree-$mode.log" | grep -o '[0-9.]*$' || echo "?")
    logged="own log: ${total} s (chunking ${chunking} s, indexing ${indexing} s)"
    row "PotreeConverter $mode" "$w" "$m" "$logged"
    rm -rf "$dir/potree-$mode"
  done
fi
for spec in $methods; do
  # METHOD or METHOD:key=value,key=value (e.g. potree:sampling=random).
  meth=${spec%%:*}
  params=()
  if [ "$spec" != "$meth" ]; then
    IFS=, read -r -a kv <<<"${spec#*:}"
    for p in "${kv[@]}"; do params+=(--param "$p"); done
  fi
  meth=$(tr ':=,' '-' <<<"$spec")
  rm -rf "$dir/$meth" "$dir/cache-$meth"
  timed "$dir/$meth.time" "$bin" build --method "${spec%%:*}" "${params[@]}" --scene "$las" --out "$dir/$meth" \
    --cache "$dir/cache-$meth" >"$dir/$meth.json" 2>"$dir/$meth.log" \
    || { cat "$dir/$meth.log" >&2; exit 1; }
  read -r w m <"$dir/$meth.time"
  # LPC's temporary-file bytes per point (its linearity goal); every build's phases stay in
  # OUT/N/METHOD.json (`extra.phases`).
  note=$(jq -r --argjson n "$n" '"build \(.seconds*10|round/10) s after the LAS read; \(.bytes_out*8/$n*10|round/10) bits/point; units \(.extra.units // "-")"
    + (if .extra.temp_bytes then "; temp \(.extra.temp_bytes/$n*10|round/10) B/point" else "" end)' \
    "$dir/$meth.json")
  row "$spec" "$w" "$m" "$note"
  rm -rf "$dir/$meth" "$dir/cache-$meth"
done
echo
echo "LAS: $bytes bytes; splatbench $(git -C "$(dirname "$0")/.." rev-parse --short HEAD), $(date -u +%F); $(nproc) cores"
