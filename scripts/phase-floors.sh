#!/usr/bin/env bash
# Issue 40's evidence where a build goal is not met: each method's phases beside floors
# measured on the same data in the same minute, so that the remaining gap is located.
#   scripts/phase-floors.sh BIN LAS OUT [METHODS]
# For each method (default "qsplat spt mwkd lpc"): its build with the default working memory
# (out of core in units where the scene is larger than one unit) and the same build in memory
# (`--param mem_mb=16384`: one unit, no spill files; the files are the same, byte for byte,
# `methods/tests/mem_budget.rs`). Floors, each the median of 3:
# - read: `cat LAS > /dev/null` with the file in the page cache (the "scene: load" phase
#   reads it and converts it to columns);
# - write: `dd` of as many bytes as the build wrote, into a file on the same disk, no sync (a
#   build's write phase does not sync either);
# - the in-memory build's own phases are the floor of the out-of-core ones (the same work
#   without units, spill files and boundary queries).
# Prints markdown; keeps OUT/METHOD-{units,core}.{json,time}.
set -euo pipefail
usage="usage: $0 BIN LAS OUT [METHODS]"
bin=$(realpath "${1:?$usage}")
las=$(realpath "${2:?$usage}")
out=${3:?$usage}
methods=${4:-qsplat spt mwkd lpc}
command -v jq >/dev/null || { echo "$0: needs jq" >&2; exit 1; }
mkdir -p "$out"
out=$(realpath "$out")
median() { sort -g | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
secs() { # a command's wall seconds
  local t0 t1
  t0=$(date +%s.%N)
  "$@"
  t1=$(date +%s.%N)
  awk -v a="$t0" -v b="$t1" 'BEGIN { print b - a }'
}

cat "$las" >/dev/null
read_floor=$(for _ in 1 2 3; do secs sh -c "cat '$las' > /dev/null"; done | median)

for m in $methods; do
  for mode in units core; do
    params=()
    [ "$mode" = core ] && params=(--param mem_mb=16384)
    rm -rf "$out/build" "$out/cache"
    /usr/bin/time -f '%e %M' -o "$out/$m-$mode.time" "$bin" build --method "$m" "${params[@]}" \
      --scene "$las" --out "$out/build" --cache "$out/cache" >"$out/$m-$mode.json" 2>"$out/$m-$mode.log"
    du -sb "$out/build" | cut -f1 >"$out/$m-$mode.bytes"
  done
  rm -rf "$out/build" "$out/cache"
done

echo "Read floor (\`cat\` of the $(stat -L -c %s "$las")-byte LAS, page cache): $(printf %.2f "$read_floor") s."
echo
echo "| method | wall s: units / in memory | peak RSS MB: units / in memory | units | write floor s (\`dd\` of the output) |"
echo "|---|---|---|---|---|"
for m in $methods; do
  read -r wu ru <"$out/$m-units.time"
  read -r wc rc <"$out/$m-core.time"
  bytes=$(cat "$out/$m-units.bytes")
  wf=$(for _ in 1 2 3; do secs dd if=/dev/zero of="$out/dd.tmp" bs=1M count=$(((bytes + 1048575) / 1048576)) status=none; rm -f "$out/dd.tmp"; done | median)
  units=$(jq -r '.extra.units // "?"' "$out/$m-units.json")
  printf '| %s | %.2f / %.2f | %d / %d | %s | %.2f |\n' "$m" "$wu" "$wc" $((ru / 1024)) $((rc / 1024)) "$units" "$wf"
done
echo
for m in $methods; do
  for mode in units core; do
    label="in units"
    [ "$mode" = core ] && label="in memory"
    printf '**%s** phases %s (s): ' "$m" "$label"
    jq -r '[.extra.phases[]? | "\(.phase) \(.seconds * 100 | round / 100)"] | join("; ")' "$out/$m-$mode.json"
    echo
  done
done
echo "$("$bin" --version), measured $(date -u +%F); $(nproc) cores; $(grep -m1 -o 'model name.*' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
