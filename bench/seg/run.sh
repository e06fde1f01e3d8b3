#!/usr/bin/env bash
# Builds seg_bench with the `bench` CMake preset, runs it and draws the chart:
#   docs/benchmarks/seg_speed_accuracy.csv and docs/benchmarks/seg_speed_accuracy.png
#
#   bash bench/seg/run.sh [seg_bench options: --quick, --data DIR, --inputs .., --methods .., --reps N]
#
# Needs ITK and matplotlib: `bash scripts/install-deps.sh --bench`. BUILD_DIR=dir builds there
# instead of the preset's build-bench/ (same cache settings); JOBS=n sets the build parallelism;
# OUT_DIR=dir writes the CSV and PNG there. --quick writes to BUILD_DIR/seg-quick by default.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
cd "$repo"
build="${BUILD_DIR:-build-bench}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
for a in "$@"; do # a smoke run must not overwrite the recorded results
  if [ "$a" = "--quick" ] && [ -z "${OUT_DIR:-}" ]; then out="$repo/$build/seg-quick"; fi
done

if [ -n "${BUILD_DIR:-}" ]; then
  cmake --preset bench -B "$build" >/dev/null
else
  cmake --preset bench >/dev/null
fi
cmake --build "$build" --target seg_bench -j "${JOBS:-2}"
if [ ! -x "$build/bench/seg_bench" ]; then
  echo "run.sh: $build/bench/seg_bench was not built (is ITK installed? see the cmake output)" >&2
  exit 1
fi

echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
"$build/bench/seg_bench" --out "$out" "$@"
/usr/bin/python3 "$repo/bench/seg/plot_speed_accuracy.py" "$out/seg_speed_accuracy.csv" "$out/seg_speed_accuracy.png"
