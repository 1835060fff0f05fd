#!/usr/bin/env bash
# The streaming measurements of results/measurements/issue-17-streaming.md: LPC and MWKD along
# a camera path on one build, read locally (--build-dir) and over HTTP from `splatbench
# serve` on loopback at several bandwidths with a fixed latency (--build-url), one run after
# the other on an otherwise idle machine.
#   scripts/stream-measurements.sh BIN OUT [SCENE] [FRAMES] [RATES] [LATENCY_MS] [PATH] [METHODS]
# SCENE: default statue:10000000:1; FRAMES: default 60; RATES: MB/s, space-separated (default
# "5 20 100"); LATENCY_MS: default 20; PATH: default flythrough (a still camera, e.g.
# paper/paths/still-near.toml, measures how many frames a cold start takes to converge);
# METHODS: default "lpc mwkd".
# Renders 640x480 at eps 1 px, no image metrics (the
# reference of a 10 M scene would dominate the time), default parameters (LPC M = 2048, MWKD
# N = 4, VBO 8192; in_flight 1 local, 4 remote).
# Prints one markdown row per run, and writes OUT/build-<method>/ (reused when present) and
# OUT/<path>/<method>/{local,rate-R}/. With ROWS_ONLY=1 it runs nothing and prints the rows
# of the runs already in OUT (the table again, from the same data).
set -euo pipefail
bin=${1:?usage: $0 BIN OUT [SCENE] [FRAMES] [RATES] [LATENCY_MS]}
out=${2:?usage: $0 BIN OUT [SCENE] [FRAMES] [RATES] [LATENCY_MS]}
scene=${3:-statue:10000000:1}
frames=${4:-60}
rates=${5:-5 20 100}
latency=${6:-20}
path=${7:-flythrough}
methods=${8:-lpc mwkd}
cache="$out/cache"
runs="$out/$(basename "$path" .toml)"
mkdir -p "$out"
common=(--scene "$scene" --path "$path" --frames "$frames" --eps 1 --width 640 --height 480
  --no-metrics --cache "$cache")

# One markdown row from a run directory: frames with coarse stand-ins (LPC: clouds drawn for
# children not yet loaded; MWKD: stand-ins), the last of them, the frame from which none is
# drawn and nothing is pending (converged), bytes fetched (stored), bytes uploaded (decoded,
# drawn), requests issued / cancelled / failed, stale deliveries, the final bandwidth
# estimate, peak RSS, run seconds.
row() { # method, label, run dir
  python3 - "$1" "$2" "$3" <<'PY'
import csv, json, sys
method, label, d = sys.argv[1:]
rows = list(csv.DictReader(open(f"{d}/frames.csv")))
s = json.load(open(f"{d}/summary.json"))
coarse_col = "clouds_coarse" if method == "lpc" else "stand_ins"
coarse = [int(float(r[coarse_col])) for r in rows]
busy = [c > 0 or float(r["loader_pending"]) > 0 for c, r in zip(coarse, rows)]
frames_coarse = sum(1 for c in coarse if c > 0)
last = max((i for i, c in enumerate(coarse) if c > 0), default=-1)
settled = next((i for i in range(len(rows)) if not any(busy[i:])), None)
t = s["traffic"]
up = sum(float(r["upload_bytes"]) for r in rows)
bw = t["bandwidth_est_bytes_per_s"]
print(f"| {method} | {label} | {frames_coarse} | {last if last >= 0 else '–'} | "
      f"{'–' if settled is None else settled} | {sum(coarse)} | {t['bytes_fetched']/1e6:.1f} | {up/1e6:.1f} | {t['requests_issued']} | "
      f"{t['requests_cancelled']} | {t['requests_failed']} | {t['stale_deliveries']} | "
      f"{(bw or 0)/1e6:.1f} | {s['medians']['points_drawn']/1e6:.2f} | "
      f"{s['peak_rss_bytes']/2**20:.0f} | {s['run_seconds']:.1f} |")
PY
}

echo "| method | source | frames with stand-ins | last such frame | converged from frame | stand-ins in all | MB fetched | MB uploaded | requests | cancelled | failed | stale | bandwidth est. MB/s | median Mpoints | peak RSS MB | run s |"
echo "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"
for method in $methods; do
  b="$out/build-$method"
  m="$runs/$method"
  mkdir -p "$m"
  if [ "${ROWS_ONLY:-0}" = 1 ]; then
    row "$method" local "$m/local"
    for rate in $rates; do
      row "$method" "HTTP ${rate} MB/s, ${latency} ms" "$m/rate-$rate"
    done
    continue
  fi
  if [ ! -f "$b/method.json" ]; then
    "$bin" build --method "$method" --scene "$scene" --out "$b" --cache "$cache" >/dev/null 2>&1
  fi
  rm -rf "$m/local"
  "$bin" run --method "$method" "${common[@]}" --build-dir "$b" --out "$m/local" \
    >/dev/null 2>"$m/local.log"
  row "$method" local "$m/local"
  for rate in $rates; do
    log="$m/serve-$rate.log"
    "$bin" serve "$b" --addr 127.0.0.1:0 --bandwidth "$rate" --latency "$latency" \
      >"$log" 2>&1 &
    pid=$!
    url=""
    for _ in $(seq 100); do
      url=$(sed -n 's/.* at \(http[^ ]*\).*/\1/p' "$log" | head -1)
      [ -n "$url" ] && break
      sleep 0.1
    done
    [ -n "$url" ] || { echo "serve did not start: $(cat "$log")" >&2; kill "$pid"; exit 1; }
    rm -rf "$m/rate-$rate"
    "$bin" run --method "$method" "${common[@]}" --build-url "$url" --out "$m/rate-$rate" \
      >/dev/null 2>"$m/rate-$rate.log" || { kill "$pid"; cat "$m/rate-$rate.log" >&2; exit 1; }
    kill "$pid"
    wait "$pid" 2>/dev/null || true
    row "$method" "HTTP ${rate} MB/s, ${latency} ms" "$m/rate-$rate"
  done
done
