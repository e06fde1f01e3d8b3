#!/usr/bin/env bash
# The vessel pipeline's ablation benchmark: time against accuracy for `seg::segment_vessels` with
# each stage switched off in turn, on lphantom volumes (the truth liver is given, so only the
# vessel stage is timed), plus the lookup-table affinity against the exact one.
#   bash bench/vessels/run.sh     -> docs/benchmarks/vessels_ablation.{csv,png}, vessels_fc_lut.csv
# BUILD_DIR=dir builds there instead of the bench preset's build-bench/; OUT_DIR=dir writes the
# results elsewhere; REPS=n times each run n times and keeps the fastest (default 3).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$repo"
build="${BUILD_DIR:-build-bench}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
mkdir -p "$out"
if [ -n "${BUILD_DIR:-}" ]; then
  cmake --preset bench -B "$build" >/dev/null
else
  cmake --preset bench >/dev/null
fi
cmake --build "$build" --target vessel_bench -j "${JOBS:-2}"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2

"$build/bench/vessel_bench" --inputs default,large,noisy,gap35 \
  --variants full,no-vesselness,no-sharpening,tan-kernel,no-fc,no-lut,no-pruning,no-bridging,no-fc-no-bridging \
  --reps "${REPS:-3}" --csv "$out/vessels_ablation.csv.tmp"
mv "$out/vessels_ablation.csv.tmp" "$out/vessels_ablation.csv"
"$build/bench/vessel_bench" --inputs default,large --variants full --reps 1 --lut-csv "$out/vessels_fc_lut.csv.tmp" >/dev/null
mv "$out/vessels_fc_lut.csv.tmp" "$out/vessels_fc_lut.csv"
/usr/bin/python3 "$repo/bench/vessels/plot_ablation.py" "$out/vessels_ablation.csv" "$out/vessels_ablation.png"
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
echo "wrote $out/vessels_ablation.csv, vessels_ablation.png and vessels_fc_lut.csv" >&2
