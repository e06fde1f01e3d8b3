#!/usr/bin/env bash
# Instruments (issue 8; docs/benchmarks.md, "Instruments"): step time with cutting and with
# refinement against the same scenes without them, on the default phantom's liver meshed at about
# 10k and 100k nodes.
#   cmake --preset release && cmake --build build --target lphantom lmesh
#   cmake --preset bench && cmake --build --preset bench --target instrument_bench
#   bash bench/mss/run_instruments.sh   -> docs/benchmarks/instruments.csv, instruments_cut.{csv,png}
# BIN, BENCH, OUT_DIR, MESHES as in bench/mss/run.sh.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${BIN:-$repo/build/tools}"
bench="${BENCH:-$repo/build-bench/bench}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc --all) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
export OMP_NUM_THREADS=1 # Debian's CHOLMOD links libgomp; every figure is one thread
mkdir -p "$out"
source "$repo/bench/mss/liver_meshes.sh"
files=("$(liver_mesh 5 2)" "$(liver_mesh 2.2 2)") # about 10k and 100k nodes (bench/mss/run.sh's sizes)
"$bench/instrument_bench" "$out/instruments.csv" "$out/instruments_cut.csv" "${files[@]}"
/usr/bin/python3 "$repo/bench/mss/plot_instruments.py" "$out/instruments_cut.csv" "$out/instruments_cut.png"
