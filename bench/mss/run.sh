#!/usr/bin/env bash
# libmss accuracy and speed (issue 7; docs/benchmarks.md, "Mass-spring step"):
#   cmake --preset release && cmake --build build --target lphantom lmesh
#   cmake --preset bench && cmake --build --preset bench --target mss_accuracy mss_scaling
#   bash bench/mss/run.sh     -> docs/benchmarks/mss_accuracy.{csv,png}, mss_scaling.{csv,png}
# BIN=dir: lphantom and lmesh (default build/tools); BENCH=dir: the benchmarks (default
# build-bench/bench); OUT_DIR=dir: where the CSV and PNG go; MESHES=dir keeps the liver meshes
# there (default: a temporary folder); ONLY=accuracy|scaling runs one half; REPEAT=n runs the
# speed benchmark n times and keeps, per row, the run with the least CPU time (merge_runs.py).
# OMP_NUM_THREADS=1: Debian's CHOLMOD links libgomp; every single-simulation figure is one thread.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${BIN:-$repo/build/tools}"
bench="${BENCH:-$repo/build-bench/bench}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
only="${ONLY:-}"
export OMP_NUM_THREADS=1
mkdir -p "$out"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc --all) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2

if [ "$only" != scaling ]; then
  "$bench/mss_accuracy" "$out/mss_accuracy.csv"
  /usr/bin/python3 "$repo/bench/mss/plot_accuracy.py" "$out/mss_accuracy.csv" "$out/mss_accuracy.png"
fi
[ "$only" = accuracy ] && exit 0

# The default phantom's liver (label 1) at sizes giving about 1k, 10k, 40k, 100k and 190k nodes.
# Below ~3.4k nodes the boundary's curvature bound sets the count, so the 1k mesh relaxes it.
source "$repo/bench/mss/liver_meshes.sh"
files=()
for spec in "12:3" "5:2" "3:2" "2.2:2" "1.75:2"; do
  files+=("$(liver_mesh "${spec%%:*}" "${spec##*:}")")
done
# The same meshes renumbered along a Morton curve, and mss_bench's cubes, for the explicit
# springs-only and HAVP steps (the order's effect, and the earlier cube figures in the same run).
for f in "${files[@]}"; do files+=("$f+morton"); done
files+=(cube:10 cube:20 cube:45)
runs=()
for k in $(seq "${REPEAT:-1}"); do
  "$bench/mss_scaling" "$meshes/scaling.$k.csv" "${files[@]}"
  runs+=("$meshes/scaling.$k.csv")
done
/usr/bin/python3 "$repo/bench/mss/merge_runs.py" "$out/mss_scaling.csv" "${runs[@]}"
/usr/bin/python3 "$repo/bench/mss/plot_scaling.py" "$out/mss_scaling.csv" "$out/mss_scaling.png"
