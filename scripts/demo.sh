#!/usr/bin/env bash
# Sets up a fresh Debian machine, builds lobe and runs the pipeline on the built-in default
# input (the synthetic phantom), writing results and pictures to OUT (default: demo-out/).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-demo-out}
bash scripts/install-deps.sh
cmake --preset release >/dev/null
cmake --build --preset release
bin=build/tools
mkdir -p "$out"

echo "== 1. phantom: a synthetic abdominal CT with known ground truth" >&2
"$bin/lphantom" "$out/phantom" --png "$out/pictures/phantom"
"$bin/lio" info "$out/phantom/ct.mhd"

echo "== 2. the pipeline container: CT and ground-truth labels in HDF5 (+ XDMF for ParaView)" >&2
"$bin/lio" convert "$out/phantom/ct.mhd" "$out/phantom/ct.h5"
"$bin/lio" convert "$out/phantom/ct.mhd" "$out/phantom/ct.nii.gz"
"$bin/lio" info "$out/phantom/ct.h5"

echo "== done: results in $out/, pictures in $out/pictures/" >&2
