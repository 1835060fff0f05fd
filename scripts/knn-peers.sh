#!/usr/bin/env bash
# splatbench's exact k-NN leaf radii against two widely used k-NN libraries on the same LAS
# file and machine, one after the other (results/measurements/issue-16-builds.md, "the k-NN
# against its peers"):
# - splatbench: `build --method full`, whose "full: leaf radii" phase is the in-memory
#   whole-cloud search (`scenes::spacing::knn_spacing`, k = methods::leaf::LEAF_K = 6) and
#   the cap on isolated samples; the cache is warmed by a first build, the second is timed;
# - nanoflann (Debian's libnanoflann-dev, g++ -O3 -march=native, OpenMP): knn-peers/nanoflann.cpp;
# - SciPy's cKDTree (from PyPI, in a virtual environment under OUT): knn-peers/scipy_peer.py.
# Each peer's "knn" is its tree build plus its query of every point; the LAS read is apart.
#   scripts/knn-peers.sh BIN OUT N [THREADS]
# N: points of the terrain:N:1 scene exported as LAS (reused from OUT/N/ when present, the
# same file scripts/build-measurements.sh makes); THREADS: query threads of the peers
# (default: nproc, as rayon uses). Needs g++ and libnanoflann-dev (apt-get install g++
# libnanoflann-dev) and python3 with venv; installs SciPy into OUT/venv.
set -euo pipefail
bin=${1:?usage: $0 BIN OUT N [THREADS]}
out=${2:?usage: $0 BIN OUT N [THREADS]}
n=${3:?usage: $0 BIN OUT N [THREADS]}
threads=${4:-$(nproc)}
here=$(cd "$(dirname "$0")" && pwd)
k=6
[ -f /usr/include/nanoflann.hpp ] || { echo "needs libnanoflann-dev (apt-get install libnanoflann-dev)" >&2; exit 1; }
dir="$out/$n"
mkdir -p "$dir"
las="$dir/terrain-$n.las"
if [ ! -s "$las" ]; then
  "$bin" export --scene "terrain:$n:1" --out "$las" --cache "$dir/export-cache" >/dev/null
  rm -rf "$dir/export-cache"
fi
g++ -O3 -march=native -fopenmp -o "$out/knn-nanoflann" "$here/knn-peers/nanoflann.cpp"
if [ ! -x "$out/venv/bin/python" ]; then
  python3 -m venv "$out/venv"
  "$out/venv/bin/pip" install -q scipy numpy
fi
rm -rf "$dir/knn-full" "$dir/knn-cache"
"$bin" build --method full --scene "$las" --cache "$dir/knn-cache" --out "$dir/knn-full" >/dev/null 2>&1
rm -rf "$dir/knn-full"
"$bin" build --method full --scene "$las" --cache "$dir/knn-cache" --out "$dir/knn-full" >/dev/null 2>&1
ours=$(jq -r '.extra.phases[] | select(.phase == "full: leaf radii") | .seconds' "$dir/knn-full/build.json")
rm -rf "$dir/knn-full" "$dir/knn-cache"
nf=$(OMP_NUM_THREADS=$threads "$out/knn-nanoflann" "$las" $k)
sp=$("$out/venv/bin/python" "$here/knn-peers/scipy_peer.py" "$las" $k "$threads")
echo "splatbench $(git -C "$here/.." rev-parse --short HEAD), $(date -u +%F), $(nproc) cores, k = $k, $n points"
echo "splatbench knn $(printf %.2f "$ours") s (build --method full, phase 'full: leaf radii')"
echo "$nf"
echo "$sp"
for line in "$nf" "$sp"; do
  awk -v ours="$ours" '{ for (i = 1; i < NF; i++) if ($i == "knn") printf "%s ÷ splatbench: %.1f\n", $1, $(i + 1) / ours }' <<<"$line"
done
