#!/usr/bin/env bash
# Runs the instrument example scenes (examples/*.scene) and writes one strip of pictures per scene
# (before, during, after, and the force plot) into docs/images/instruments/ for
# docs/algorithms/instruments.md. Needs a release build (cmake --build --preset release) and
# python3-pil (bash scripts/install-deps.sh --bench). Usage: bash scripts/instrument_pictures.sh [WORK_DIR]
set -euo pipefail
cd "$(dirname "$0")/.."
bin=build/tools
work=${1:-$(mktemp -d)}
out=docs/images/instruments
mkdir -p "$work" "$out"

# The demo's liver mesh: the phantom, lseg liver, lmesh as scripts/demo.sh makes them.
if [ ! -f "$work/liver-mesh.h5" ]; then
  "$bin/lphantom" "$work/phantom" --quiet
  "$bin/lseg" liver "$work/phantom/ct.mhd" -o "$work/liver.h5" --quiet
  "$bin/lmesh" "$work/liver.h5" --labels liver --size 8 --curvature-factor 2 -o "$work/liver-mesh.h5" --quiet
fi
"$bin/lsim" --make-block "$work/block.h5" --cells 8,8,8 --size 60 --split 5 --tumour 30,30,36,12 --quiet

run() { # scene mesh
  rm -rf "$work/pics-$1"
  "$bin/lsim" "$2" "examples/$1.scene" -o "$work/$1.h5" --png "$work/pics-$1" --quiet
  /usr/bin/python3 - "$work/pics-$1" "$out/$1.png" <<'PY'
import sys, glob
from PIL import Image
pics = sorted(glob.glob(sys.argv[1] + "/frame_*.png"))
frames = pics[:4]  # the scene's png_times: before, during (twice), after
tiles = [Image.open(p).convert("RGB").crop((0, 40, 800, 600)) for p in frames]
force = Image.open(sys.argv[1] + "/force.png").convert("RGB")
scale = 280 / tiles[0].height
tiles = [t.resize((int(t.width * scale), 280)) for t in tiles]
force = force.resize((int(force.width * 280 / force.height), 280))
strip = Image.new("RGB", (sum(t.width for t in tiles) + force.width, 280), "white")
x = 0
for t in tiles + [force]:
    strip.paste(t, (x, 0))
    x += t.width
strip.quantize(colors=96).save(sys.argv[2], optimize=True)
PY
  echo "instrument_pictures: $out/$1.png" >&2
}
run grasp_pull "$work/liver-mesh.h5"
run cut_edge "$work/liver-mesh.h5"
run grasp_then_cut "$work/liver-mesh.h5"
run cut_tumour "$work/block.h5"
run probe_tumour "$work/block.h5"
