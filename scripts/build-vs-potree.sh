#!/usr/bin/env bash
# Issue 40's build table: splatbench's methods and PotreeConverter 2.0 building the same LAS
# file (terrain:N:1 exported as LAS 1.2 format 2), REPEATS rounds, each round every build
# once as a whole process (the order rotated from round to round), so that every ratio is
# taken within a round, on the machine as it was then, and the table quotes medians.
#   scripts/build-vs-potree.sh BIN OUT N POTREE_BIN [REPEATS] [METHODS]
# POTREE_BIN: PotreeConverter built unmodified from its public source (scripts/setup.sh does
# not build it: see results/measurements/issue-40-builds.md for the commands). REPEATS:
# default 3. METHODS: default "qsplat spt mwkd lpc", each METHOD or METHOD:key=value,…
# (--param). Wall seconds and peak RSS come from /usr/bin/time; points/s = N / wall; each
# method's phases from its build.json (`extra.phases`). splatbench starts from an empty
# column cache, so the LAS read is in its wall time.
# Prints markdown: the builds (median wall, points/s, median of the per-round ratios
# "PotreeConverter default's wall ÷ ours" and "fastest's ÷ ours", peak RSS), then every
# method's phases (median seconds). Keeps OUT/N/rK/NAME.{time,json,log}; with REPORT_ONLY=1
# prints the tables from those files without building.
set -euo pipefail
usage="usage: $0 BIN OUT N POTREE_BIN [REPEATS] [METHODS]"
bin=$(realpath "${1:?$usage}")
out=${2:?$usage}
n=${3:?$usage}
potree=$(realpath "${4:?$usage}")
repeats=${5:-3}
methods=${6:-qsplat spt mwkd lpc}
[ -x "$potree" ] || { echo "$0: $potree is not an executable PotreeConverter" >&2; exit 1; }
command -v jq >/dev/null || { echo "$0: needs jq" >&2; exit 1; }
mkdir -p "$out/$n"
dir=$(realpath "$out/$n")
las="$dir/terrain-$n.las"
if [ ! -s "$las" ]; then
  "$bin" export --scene "terrain:$n:1" --out "$las" --cache "$dir/export-cache" >/dev/null
  rm -rf "$dir/export-cache"
fi
names=(potree-default potree-fastest)
for spec in $methods; do names+=("$spec"); done
count=${#names[@]}

# One build of NAME into round directory RD.
run() { # NAME RD
  local name=$1 rd=$2 tag
  tag=$(tr ':=,' '-' <<<"$name")
  case "$name" in
  potree-default | potree-fastest)
    local args=()
    [ "$name" = potree-fastest ] && args=(--encoding DEFAULT -m random --attributes rgb)
    rm -rf "$rd/out"
    (cd "$(dirname "$potree")" && /usr/bin/time -f '%e %M' -o "$rd/$tag.time" \
      "$potree" "$las" -o "$rd/out" "${args[@]}" >"$rd/$tag.log" 2>&1)
    ;;
  *)
    local params=()
    if [ "$name" != "${name%%:*}" ]; then
      IFS=, read -r -a kv <<<"${name#*:}"
      for p in "${kv[@]}"; do params+=(--param "$p"); done
    fi
    rm -rf "$rd/out" "$rd/cache"
    /usr/bin/time -f '%e %M' -o "$rd/$tag.time" "$bin" build --method "${name%%:*}" \
      "${params[@]}" --scene "$las" --out "$rd/out" --cache "$rd/cache" \
      >"$rd/$tag.json" 2>"$rd/$tag.log" || { cat "$rd/$tag.log" >&2; exit 1; }
    ;;
  esac
  rm -rf "$rd/out" "$rd/cache"
}

# REPORT_ONLY=1: no builds, the tables from the rounds kept in OUT/N/rK.
if [ "${REPORT_ONLY:-0}" != 1 ]; then
  for r in $(seq 1 "$repeats"); do
    rd="$dir/r$r"
    mkdir -p "$rd"
    for i in $(seq 0 $((count - 1))); do
      run "${names[$(((i + r - 1) % count))]}" "$rd"
    done
  done
fi

median() { sort -g | awk '{ v[NR] = $1 } END { if (NR == 0) print "?"; else if (NR % 2) print v[(NR + 1) / 2]; else print (v[NR / 2] + v[NR / 2 + 1]) / 2 }'; }
wall() { cut -d' ' -f1 "$dir/r$1/$2.time"; }
echo "| build | points | wall s (median of $repeats) | points/s | PotreeConverter default ÷ ours | fastest ÷ ours | peak RSS MB (largest) |"
echo "|---|---|---|---|---|---|---|"
for name in "${names[@]}"; do
  tag=$(tr ':=,' '-' <<<"$name")
  w=$(for r in $(seq 1 "$repeats"); do wall "$r" "$tag"; done | median)
  rd=$(for r in $(seq 1 "$repeats"); do awk -v a="$(wall "$r" potree-default)" -v b="$(wall "$r" "$tag")" 'BEGIN { print a / b }'; done | median)
  rf=$(for r in $(seq 1 "$repeats"); do awk -v a="$(wall "$r" potree-fastest)" -v b="$(wall "$r" "$tag")" 'BEGIN { print a / b }'; done | median)
  m=$(for r in $(seq 1 "$repeats"); do cut -d' ' -f2 "$dir/r$r/$tag.time"; done | sort -g | tail -1)
  awk -v name="$name" -v w="$w" -v n="$n" -v rd="$rd" -v rf="$rf" -v m="$m" 'BEGIN {
    printf "| %s | %d | %.2f | %.2f M | %.2f | %.2f | %d |\n", name, n, w, n / w / 1e6, rd, rf, m / 1024 }'
done
echo
for name in "${names[@]}"; do
  case "$name" in potree-*) continue ;; esac
  tag=$(tr ':=,' '-' <<<"$name")
  echo "**$name** phases (median s of $repeats; a phase that recurs, e.g. LPC's partition of"
  echo "each unit, summed within its build):"
  jq -r 'reduce .extra.phases[].phase as $p ([]; if any(.[]; . == $p) then . else . + [$p] end) | .[]' \
    "$dir/r1/$tag.json" | while read -r phase; do
    s=$(for r in $(seq 1 "$repeats"); do
      jq -r --arg p "$phase" '[.extra.phases[] | select(.phase == $p) | .seconds] | add' "$dir/r$r/$tag.json"
    done | median)
    printf '%s %.2f; ' "$phase" "$s"
  done
  echo
  echo
done
echo "LAS: $(stat -L -c %s "$las") bytes; $("$bin" --version), measured $(date -u -r "$dir/r1" +%F); $(nproc) cores; $(grep -m1 -o 'model name.*' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//'); PotreeConverter $potree"
