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

echo "== 2. the pipeline container phantom.h5 (CT, ground-truth labels, provenance; phantom.xdmf opens it in ParaView)" >&2
"$bin/lio" info "$out/phantom/phantom.h5"
"$bin/lio" convert "$out/phantom/ct.mhd" "$out/phantom/ct.nii.gz"   # for 3D Slicer, ITK-SNAP, ...

echo "== done: results in $out/, pictures in $out/pictures/" >&2
