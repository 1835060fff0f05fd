#!/usr/bin/env bash
# The parameter-choice measurements of results/measurements/issue-14-check-tune.md:
# `splatbench tune` of LPC's M and of MWKD's fan-out × VBO size on statue and terrain,
# 2 M points each, three budgets, a 12-frame orbit at 512², every other parameter at the
# method's default (the paper's choice). Cost: points drawn (deterministic on any machine;
# the times are in tune.csv beside them).
#   scripts/tune-measurements.sh BIN OUT [CACHE]
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [CACHE]}
out=${2:?usage: $0 BIN OUT [CACHE]}
cache=${3:-${SPLATBENCH_CACHE:-$HOME/.cache/splatbench}}
common=(--path orbit --frames 12 --width 512 --height 512 --budgets 50000,200000,800000
        --cost points --repeats 2 --cache "$cache")
for scene in statue:2000000:1 terrain:2000000:1; do
  name=${scene%%:*}
  "$bin" tune --method lpc --scene "$scene" --grid m=512,1024,2048,4096,8192 \
    "${common[@]}" --out "$out/lpc-$name"
  "$bin" tune --method mwkd --scene "$scene" --grid fanout=2,4,8,16 \
    --grid vbo=2048,8192,32768 "${common[@]}" --out "$out/mwkd-$name"
done
