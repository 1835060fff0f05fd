#!/usr/bin/env bash
# Issue 40's record of the papers' profile's largest builds: each build once, as a whole
# process, with its wall time, points/s, peak RSS and peak disk (the output directory, which
# holds the build's spill files while it runs, sampled every 2 s), then deleted.
#   scripts/paper-builds.sh BIN OUT [BUILDS]
# BUILDS: default the profile's largest (LPC's statue and isosurface, QSplat's on both, the
# multi-way kd-tree's St. Matthew size), each METHOD@SCENE with SCENE as `--scene` takes it.
# Scenes come from the cache ($SPLATBENCH_CACHE or --cache's default): a scene not cached yet
# is generated inside its first build, in the phase "scene: load", which the table gives
# apart. Prints markdown; keeps OUT/NAME.{time,json,log,disk}.
set -euo pipefail
usage="usage: $0 BIN OUT [BUILDS]"
bin=$(realpath "${1:?$usage}")
out=${2:?$usage}
builds=${3:-lpc@statue:167000000:1:even qsplat@statue:167000000:1:even mwkd@statue:186850683:1:even lpc@isosurface-deep:234000000:1:even qsplat@isosurface-deep:234000000:1:even}
command -v jq >/dev/null || { echo "$0: needs jq" >&2; exit 1; }
mkdir -p "$out"
out=$(realpath "$out")

for b in $builds; do
  method=${b%%@*} scene=${b#*@}
  tag=$(tr ':@' '__' <<<"$b")
  rm -rf "$out/build"
  mkdir -p "$out/build"
  # Peak disk of the build directory (output and spill), sampled while the build runs.
  (
    peak=0
    while sleep 2; do
      s=$(du -sb "$out/build" 2>/dev/null | cut -f1) || s=0
      [ "${s:-0}" -gt "$peak" ] && peak=$s && echo "$peak" >"$out/$tag.disk"
    done
  ) &
  sampler=$!
  rc=0
  /usr/bin/time -f '%e %M' -o "$out/$tag.time" "$bin" build --method "$method" \
    --scene "$scene" --out "$out/build" >"$out/$tag.json" 2>"$out/$tag.log" || rc=$?
  kill "$sampler" 2>/dev/null || true
  wait "$sampler" 2>/dev/null || true
  du -sb "$out/build" | cut -f1 >"$out/$tag.bytes"
  rm -rf "$out/build"
  [ "$rc" -eq 0 ] || { echo "$0: $b failed (exit $rc; $out/$tag.log)" >&2; tail -5 "$out/$tag.log" >&2; exit 1; }
done

echo "| build | samples | wall s | scene load s | points/s (wall less scene load) | peak RSS MB | output GB | peak disk GB (output + spill) |"
echo "|---|---|---|---|---|---|---|---|"
for b in $builds; do
  tag=$(tr ':@' '__' <<<"$b")
  read -r wall rss <"$out/$tag.time"
  n=$(jq -r '.points_in' "$out/$tag.json")
  load=$(jq -r '[.extra.phases[]? | select(.phase == "scene: load") | .seconds] | add // 0' "$out/$tag.json")
  disk=$(cat "$out/$tag.disk" 2>/dev/null || echo 0)
  bytes=$(cat "$out/$tag.bytes")
  awk -v b="$b" -v n="$n" -v w="$wall" -v l="$load" -v m="$rss" -v o="$bytes" -v d="$disk" 'BEGIN {
    if (d < o) d = o
    printf "| %s | %d | %.1f | %.1f | %.2f M | %d | %.2f | %.2f |\n", b, n, w, l, n / (w - l) / 1e6, m / 1024, o / 1e9, d / 1e9 }'
done
echo
for b in $builds; do
  tag=$(tr ':@' '__' <<<"$b")
  printf '**%s** phases (s): ' "$b"
  jq -r '[.extra.phases[]? | "\(.phase) \(.seconds * 100 | round / 100)"] | join("; ")' "$out/$tag.json"
  echo
done
echo "$("$bin" --version), measured $(date -u +%F); $(nproc) cores, $(awk '/MemTotal/ { printf "%.0f GiB", $2 / 1048576 }' /proc/meminfo); $(grep -m1 -o 'model name.*' /proc/cpuinfo | cut -d: -f2- | sed 's/^ *//')"
