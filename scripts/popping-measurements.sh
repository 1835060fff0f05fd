#!/usr/bin/env bash
# The popping table of results/measurements/issue-38-warped-popping.md (issue 38; the
# issue-15 table came from the first version of this script, unwarped only): every
# registered method at its defaults (the papers' choices; the default 1 px tolerance) on
# statue:1000000:1 at 1024², along `zoom`, `flythrough` and `orbit` (the reproduction's
# paths), 24 frames each. One markdown row per run: the unwarped popping FLIP beside the
# warped one at lags 1 and 7 (median and 95th percentile over the frames that have them),
# the reference's own warped FLIP at lag 1 (what the motion-free change of the reference
# is), the pop events at lag 1 and 7 (medians) and the valid share at lag 1; then, per path,
# the methods ranked by the unwarped and by the warped lag-1 median. Writes a comparison
# plot per path to OUT/PATH/comparison.svg.
#   scripts/popping-measurements.sh BIN OUT [CACHE]
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [CACHE]}
out=${2:?usage: $0 BIN OUT [CACHE]}
cache=${3:-${SPLATBENCH_CACHE:-$HOME/.cache/splatbench}}
scene=statue:1000000:1
methods=(full qsplat spt lpc mwkd potree)
paths=(zoom flythrough orbit)
# `frames.csv` median of COLUMN over the rows that have it ("-" when none).
median() {
  python3 - "$1/frames.csv" "$2" <<'PY'
import csv, statistics, sys
v = [float(r[sys.argv[2]]) for r in csv.DictReader(open(sys.argv[1])) if r[sys.argv[2]]]
print(f"{statistics.median(v):.4f}" if v else "-")
PY
}
echo "| path | method | flip_mean | popping_flip (unwarped) | warped l1: median / p95 | warped l7: median / p95 | reference's warped FLIP l1 | pop events l1 / l7 | valid l1 |"
echo "|---|---|---|---|---|---|---|---|---|"
for path in "${paths[@]}"; do
  mkdir -p "$out/$path"
  for m in "${methods[@]}"; do
    run="$out/$path/$m"
    NODEVICE_SELECT=1 "$bin" run --method "$m" --scene "$scene" --path "$path" --frames 24 \
      --width 1024 --height 1024 --cache "$cache" --out "$run" >/dev/null 2>"$run.log" \
      || { cat "$run.log" >&2; exit 1; }
    jq -r --arg path "$path" --arg m "$m" \
      --arg ref "$(median "$run" warped_ref_flip_l1)" --arg valid "$(median "$run" warp_valid_l1)" \
      'def f: if . == null then "-" else (. * 10000 | round / 10000 | tostring) end;
       def n: if . == null then "-" else (. | round | tostring) end;
       "| \($path) | \($m) | \(.medians.flip_mean|f) | \(.medians.popping_flip|f) | \(.medians.popping_warped_l1|f) / \(.p95.popping_warped_l1|f) | \(.medians.popping_warped_l7|f) / \(.p95.popping_warped_l7|f) | \($ref) | \(.medians.pop_events_l1|n) / \(.medians.pop_events_l7|n) | \($valid) |"' \
      "$run/summary.json"
  done
  "$bin" plot "${methods[@]/#/$out/$path/}" --out "$out/$path" >/dev/null
done
echo
echo "Ranking, most popping first (median over the frames; \`full\` is 0 by construction):"
echo
for path in "${paths[@]}"; do
  for key in popping_flip popping_warped_l1; do
    ranked=$(for m in "${methods[@]}"; do
      jq -r --arg m "$m" --arg k "$key" '"\(.medians[$k] // -1e9) \($m)"' "$out/$path/$m/summary.json"
    done | sort -gr | awk '{printf "%s%s", (NR>1?" > ":""), $2} END{print ""}')
    echo "- $path, $key: $ranked"
  done
done
