#!/usr/bin/env bash
# Extreme and bad `splatbench` invocations, as a demanding user would try them (issue 13,
# "the table of cases tried beyond the list"): each case runs under `timeout 60` and becomes
# one row of a markdown table — the command, the exit status, the first line of stderr
# (the adapter line skipped) and a verdict:
#
#   clear error   non-zero exit with a message (read the message: the verdict does not judge it)
#   ok            exit 0 (accepted)
#   PANIC         "panicked" on stderr
#   abort         killed by a signal (status > 128: SIGABRT, SIGSEGV, SIGKILL …)
#   hang          still running after 60 s (status 124)
#
#   scripts/cli-cases.sh BIN OUT_DIR   →  OUT_DIR/cli-cases.md (and OUT_DIR/logs/N.err)
#
# Runs are small (statue:2000, 2 frames, 32×32, no metrics) so that the accepted cases take
# seconds; the whole table takes a few minutes on 2 cores with lavapipe. Needs an adapter
# for the cases that get as far as rendering (without one they end in "no GPU adapter").
set -uo pipefail
bin=$(realpath "$1"); out=$(realpath -m "$2")
rm -rf "$out"; mkdir -p "$out/files" "$out/logs" "$out/runs"
f=$out/files
cache=$out/cache

# ---- the files the cases read
: >"$f/empty.ply"
mkdir -p "$f/dir.ply" "$f/plaindir"
printf 'ply\nformat ascii 1.0\nelement vertex 3\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n1 0 0\n0 1 0\n' >"$f/tri.ply"
cp "$f/tri.ply" "$f/noext"
cp "$f/tri.ply" "$f/unreadable.ply"; chmod 000 "$f/unreadable.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 1\nproperty float x\nproperty float y\nproperty float z\nend_header\n0 0 0\n' >"$f/one.ply"
printf 'ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\nend_header\n2 2 2\n2 2 2\n2 2 2\n2 2 2\n' >"$f/same.ply"
printf 'generator = "statue"\npoints = 100\nseeed = 2\n' >"$f/typo.toml"
printf 'generator = "statue"\npoints = -1\n' >"$f/negative.toml"
printf 'generator = "statue"\npoints = 100000000000000\n' >"$f/huge.toml"
printf 'generator = "statue"\npoints = "many"\n' >"$f/type.toml"
printf 'not toml at all [[[\n' >"$f/garbage.toml"
key() { printf '[[key]]\nt = %s\nposition = %s\ntarget = [0.0, 0.0, 0.0]\n' "$1" "$2"; }
{ printf 'coordinates = "relative"\n'; key 0.0 '[2.0, 0.0, 0.5]'; } >"$f/onekey.toml"
{ printf 'coordinates = "relative"\n'; key 0.0 '[2.0, 0.0, 0.5]'; key 1.0 '[nan, 0.0, 0.5]'; } >"$f/nan.toml"
{ printf 'coordinates = "relative"\nfov_deg = 180.0\n'; key 0.0 '[2.0, 0.0, 0.5]'; key 1.0 '[3.0, 0.0, 0.5]'; } >"$f/fov180.toml"
{ printf 'coordinates = "relative"\n'; key 0.0 '[2.0, 0.0, 0.5]'; key 0.7 '[3.0, 0.0, 0.5]'; key 0.5 '[4.0, 0.0, 0.5]'; key 1.0 '[5.0, 0.0, 0.5]'; } >"$f/order.toml"
{ printf 'coordinates = "relative"\n'; key 0.0 '[0.0, 0.0, 0.0]'; key 1.0 '[3.0, 0.0, 0.5]'; } >"$f/attarget.toml"
{ printf 'coordinates = "absolute"\n'; key 0.0 '[1e30, 0.0, 0.5]'; key 1.0 '[-1e30, 0.0, 0.5]'; } >"$f/far.toml"
{ printf 'coordinates = "relative"\nspeed = 2\n'; key 0.0 '[2.0, 0.0, 0.5]'; key 1.0 '[3.0, 0.0, 0.5]'; } >"$f/unknown.toml"
printf 'x' >"$f/regular-file"

# ---- the cases: one argument list per line, words split on spaces (no quoting needed;
# '' is passed as an empty argument). The loop below adds what a case does not give itself:
# run: --scene statue:2000 --frames 2 --width 32 --height 32 --no-metrics; sweep: the same
# with 1 frame and metrics; run, build, sweep: --cache C --out OUT/runs/N.
cases=(
  "run --method full --frames 0"
  "run --method full --frames=-1"
  "run --method full --frames -1"
  "run --method full --frames 1000001"
  "run --method full --frames 18446744073709551616"
  "run --method full --frames nan"
  "run --method full --width 0"
  "run --method full --width 1 --height 1"
  "run --method full --width 100000"
  "run --method full --width 4294967295 --height 4294967295"
  "run --method full --height=-5"
  "run --method full --height -5"
  "run --method full --width 16384 --height 2"
  "run --method qsplat --eps 0"
  "run --method qsplat --eps -1"
  "run --method qsplat --eps nan"
  "run --method qsplat --eps inf"
  "run --method qsplat --eps 1e-30"
  "run --method qsplat --eps 1e30"
  "run --method qsplat --budget 0"
  "run --method qsplat --budget 1"
  "run --method qsplat --budget 18446744073709551615"
  "run --method qsplat --budget nan"
  "run --method qsplat --eps 1 --budget 100"
  "run --method full --sample 1000"
  "run --method full --scene $f/tri.ply --sample 0"
  "run --method full --scene $f/tri.ply --sample=-1"
  "run --method full --scene $f/tri.ply --sample nan"
  "run --method foo"
  "run --method ''"
  "run --method full --param foo=1"
  "run --method full --param nonsense"
  "run --method qsplat --param split=xyz"
  "run --method qsplat --param two_sided=maybe"
  "run --method qsplat --param target_ms=-1"
  "run --method qsplat --param target_ms=nan"
  "run --method spt --param overlap=-1"
  "run --method spt --param overlap=nan"
  "run --method spt --param gpu_limit_mb=0"
  "run --method spt --param mode=split --param mode=unified"
  "run --method lpc --param m=0"
  "run --method lpc --param m=1"
  "run --method lpc --param m=18446744073709551615"
  "run --method lpc --param spacing_rule=foo"
  "run --method lpc --param fetch_per_frame=0"
  "run --method mwkd --param fanout=1"
  "run --method mwkd --param fanout=1000000"
  "run --method mwkd --param vbo=1"
  "run --method mwkd --param theta=0"
  "run --method mwkd --param theta=181"
  "run --method mwkd --param grid=0"
  "run --method mwkd --param c0=nan"
  "run --method mwkd --param load=later"
  "build --method full --scene statue:0"
  "build --method full --scene statue:-5"
  "build --method full --scene statue:1"
  "build --method full --scene statue:abc"
  "build --method full --scene nosuchgen:100"
  "build --method full --scene statue:100000000000"
  "build --method full --scene statue:1000:99999999999999999999"
  "build --method full --scene $f/missing.ply"
  "build --method full --scene $f/empty.ply"
  "build --method full --scene $f/dir.ply"
  "build --method full --scene $f/plaindir"
  "build --method full --scene $f/noext"
  "build --method full --scene $f/unreadable.ply"
  "build --method full --scene $f/one.ply"
  "build --method full --scene $f/same.ply"
  "build --method full --scene $f/typo.toml"
  "build --method full --scene $f/negative.toml"
  "build --method full --scene $f/huge.toml"
  "build --method full --scene $f/type.toml"
  "build --method full --scene $f/garbage.toml"
  "build --method full --scene ''"
  "run --method full --path $f/missing.toml"
  "run --method full --path nonsense"
  "run --method full --path $f/onekey.toml"
  "run --method full --path $f/nan.toml"
  "run --method full --path $f/fov180.toml"
  "run --method full --path $f/order.toml"
  "run --method full --path $f/attarget.toml"
  "run --method full --path $f/far.toml"
  "run --method full --path $f/unknown.toml"
  "run --method full --path $f/garbage.toml"
  "run --method full --up w"
  "run --method full --up ''"
  "run --method full --up=-z"
  "run --method full --up xyz"
  "run --method full --up +y"
  "run --method full --gpu-cache-mb 0"
  "run --method full --gpu-cache-mb 18446744073709551615"
  "run --method full --kernel foo"
  "run --method full --shading intensity"
  "run --method full --seed=-1"
  "run --method full --seed -1"
  "run --method full --gpu-cache-mb -1"
  "run --method full --seed 18446744073709551616"
  "run --method full --cache $f/regular-file"
  "run --method full --build-dir $f/plaindir"
  "run --method full --build-dir $f/missing"
  "plan --method mwkd --points 0"
  "plan --method mwkd --points 1G"
  "plan --method mwkd --points 99999999999999999999"
  "plan --method mwkd --points 1G --param fanout=1"
  "plan --method qsplat --points 1000"
  "export --scene statue:10 --out $out/files/x.xyz"
  "export --scene statue:10 --out $out/files/nodir/x.ply"
  "sweep --method qsplat --scene statue:2000 --budgets ''"
  "sweep --method qsplat --scene statue:2000 --eps 0,-1"
  "sweep --method qsplat --scene statue:2000 --eps 1 --budgets 100"
  "plot $f/plaindir --out $out/files/plot"
)

md=$out/cli-cases.md
{
  echo "| # | command (BIN = splatbench, F = the script's files, C = its cache) | exit | first line of stderr | verdict |"
  echo "|---:|---|---:|---|---|"
} >"$md"
declare -A tally
n=0
for c in "${cases[@]}"; do
  n=$((n + 1))
  args=()
  for w in $c; do
    if [ "$w" = "''" ]; then args+=(""); else args+=("$w"); fi
  done
  has() { [[ " $c " == *" $1 "* || " $c " == *" $1="* ]]; }
  cmd=${c%% *}
  if [ "$cmd" = run ] || [ "$cmd" = sweep ]; then
    has --scene || args+=(--scene statue:2000)
    if [ "$cmd" = run ]; then has --frames || args+=(--frames 2); else args+=(--frames 1); fi
    has --width || args+=(--width 32)
    has --height || args+=(--height 32)
    [ "$cmd" = run ] && args+=(--no-metrics)
  fi
  if [ "$cmd" = run ] || [ "$cmd" = sweep ] || [ "$cmd" = build ]; then
    has --cache || args+=(--cache "$cache")
    has --out || args+=(--out "$out/runs/$n")
  fi
  timeout 60 "$bin" "${args[@]}" >"$out/logs/$n.out" 2>"$out/logs/$n.err"
  rc=$?
  # A case killed by the timeout leaves its half-written generated scene (statue:1e11 is a
  # 2.4 TB sparse file, 4 GB written a minute): drop it before the disk fills.
  rm -f "$cache"/scenes/*.tmp
  first=$(grep -v '^adapter: ' "$out/logs/$n.err" | grep -m1 -v '^\s*$' | cut -c1-200)
  if [ "$rc" -eq 124 ]; then verdict=hang
  elif grep -q 'panicked' "$out/logs/$n.err"; then verdict=PANIC
  elif [ "$rc" -gt 128 ]; then verdict="abort (signal $((rc - 128)))"
  elif [ "$rc" -eq 0 ]; then verdict=ok
  elif [ -n "$first" ]; then verdict="clear error"
  else verdict="error, no message"
  fi
  tally[$verdict]=$(( ${tally[$verdict]:-0} + 1 ))
  shown=${c//$f/F}; shown=${shown//$cache/C}; shown=${shown//$out/OUT}
  first=${first//$f/F}; first=${first//$cache/C}; first=${first//$out/OUT}
  # A cache file is the script's own output, not an input a reader has: name it generically.
  first=$(sed -E 's#C/scenes/[^: ]+#C/scenes/<cache file>#g' <<<"$first")
  esc() { sed -e 's/|/\\|/g' -e 's/`/'"'"'/g' <<<"$1"; }
  printf '| %d | `BIN %s` | %d | %s | %s |\n' "$n" "$(esc "$shown")" "$rc" "$(esc "$first")" "$verdict" >>"$md"
done
{
  echo
  echo "Added to each case where it does not give them: \`run\`: \`--scene statue:2000 --frames 2"
  echo "--width 32 --height 32 --no-metrics\`; \`sweep\`: the same with \`--frames 1\` and metrics;"
  echo "\`run\`, \`build\`, \`sweep\`: \`--cache C --out OUT/runs/N\`."
  echo
  printf 'Cases: %d.' "$n"
  for v in "${!tally[@]}"; do printf ' %s: %d.' "$v" "${tally[$v]}"; done
  echo
} >>"$md"
chmod 644 "$f/unreadable.ply"
echo "$md"
