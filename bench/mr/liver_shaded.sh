#!/usr/bin/env bash
# The liver pipeline's MR path on T1-weighted phantoms with a known shading, with and without
# `lseg liver --bias-field` (docs/algorithms/bias_field.md, "The liver pipeline on them").
#   bash bench/mr/liver_shaded.sh   -> docs/benchmarks/bias_field_liver.csv
# Builds nothing: needs bias_bench (`cmake --build --preset bench --target bias_bench`, which
# writes the volumes) and lseg (`cmake --build --preset release`). BENCH_BIN=dir and BIN=dir
# point at them (defaults build-bench/bench and build/tools); OUT_DIR=dir writes elsewhere.
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bench_bin="${BENCH_BIN:-$repo/build-bench/bench}"
bin="${BIN:-$repo/build/tools}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"

# The same shaded phantoms as bias_bench's rows (the "none" method only: no correction timed).
"$bench_bin/bias_bench" --methods none --reps 1 --inputs phantom --out "$work" --volumes "$work/volumes" > /dev/null

csv="$out/bias_field_liver.csv"
echo "input,bias_field,dice,asd_mm,rvd_percent,score,gain" > "$csv.tmp"
for image in "$work"/volumes/*.mhd; do
  case "$image" in *_liver.mhd) continue ;; esac
  name="$(basename "$image" .mhd)"
  ref="$work/volumes/${name%%_*}_liver.mhd"
  for flag in "" "--bias-field"; do
    rm -f "$work/out.h5"
    "$bin/lseg" liver "$image" -o "$work/out.h5" --quiet $flag
    # Recorded only when the field was divided out.
    gain="$( (h5dump -a /provenance/000_lseg/parameters/result.bias_field.gain "$work/out.h5" 2> /dev/null || true) |
            sed -n 's/.*(0): "\(.*\)"/\1/p')"
    "$bin/lseg" eval "$work/out.h5" "$ref" --seg-name liver --quiet --json |
      /usr/bin/python3 -c 'import json, sys
e = json.load(sys.stdin)
print(",".join([sys.argv[1], sys.argv[2], "%.3f" % e["dice"], "%.2f" % e["asd_mm"], "%+.1f" % e["rvd_percent"],
                "%.1f" % e["score"]["total"], sys.argv[3]]))' "$name" "$([ -n "$flag" ] && echo on || echo off)" "$gain" >> "$csv.tmp"
    echo "$(tail -1 "$csv.tmp")" >&2
  done
done
mv "$csv.tmp" "$csv"
echo "wrote $csv" >&2
