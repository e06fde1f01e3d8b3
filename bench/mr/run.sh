#!/usr/bin/env bash
# MR bias-field correction, speed against accuracy: libseg's correct_bias_field against ITK's N4.
#   bash bench/mr/run.sh [bias_bench options: --quick, --reps N, --inputs .., --methods ..]
#     -> docs/benchmarks/bias_field.{csv,png}
# Builds nothing: build first with
#   cmake --preset bench && cmake --build --preset bench --target bias_bench
# (needs ITK: `bash scripts/install-deps.sh --bench`). BIN=dir uses the bias_bench there (default
# build-bench/bench); OUT_DIR=dir writes elsewhere (a --quick run defaults to BIN/bias-quick so
# it never overwrites the recorded results); DATA=dir points at the shared scans (mr-small is
# skipped if absent).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${BIN:-$repo/build-bench/bench}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
data="${DATA:-$repo/../shared/data}"
for a in "$@"; do
  if [ "$a" = "--quick" ] && [ -z "${OUT_DIR:-}" ]; then out="$bin/bias-quick"; fi
done
if [ ! -x "$bin/bias_bench" ]; then
  echo "run.sh: $bin/bias_bench not found; build it with the commands at the top of this script" >&2
  exit 1
fi
mkdir -p "$out"

echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
"$bin/bias_bench" --out "$out" --data "$data" "$@"
/usr/bin/python3 "$repo/bench/mr/plot.py" "$out/bias_field.csv" "$out/bias_field.png"
echo "load average at the end: $(cut -d' ' -f1-3 /proc/loadavg)" >&2
