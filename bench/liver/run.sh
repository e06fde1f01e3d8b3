#!/usr/bin/env bash
# The liver pipeline's ablation benchmark: time against SLIVER07 score for `lseg liver` with each
# component switched off in turn, on phantoms and on the real scans of ../shared/data.
#   bash bench/liver/run.sh            -> docs/benchmarks/liver_ablation.{csv,png}
# BIN=dir uses the lseg/lphantom built there (default build/tools, `cmake --build --preset
# release`); OUT_DIR=dir writes elsewhere; DATA=dir points at the shared scans (skipped if absent).
# Each run's time is the wall time of the whole `lseg liver` command (reading included).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${BIN:-$repo/build/tools}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
data="${DATA:-$repo/../shared/data}"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
mkdir -p "$out"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2

# Inputs: name|image|reference|reference labels. The default phantom is the demo's; the second
# uses a spacing and noise seed the pipeline was not developed on.
"$bin/lphantom" "$work/ph-default" --quiet
"$bin/lphantom" "$work/ph-fine" --spacing 0.9,0.9,3 --seed 5 --quiet
inputs=("phantom-0.7x2.5|$work/ph-default/ct.mhd|$work/ph-default/labels.mhd|1,2,3,4"
        "phantom-0.9x3|$work/ph-fine/ct.mhd|$work/ph-fine/labels.mhd|1,2,3,4")
if [ -d "$data/ct-small" ]; then
  inputs+=("ct-small|$data/ct-small/ct.mhd|$data/ct-small/liver.mhd|1"
           "ct-dicom-jpeg2000|$data/ct-dicom-jpeg2000/dicom|$data/ct-dicom-jpeg2000/liver.mhd|1"
           "mr-small|$data/mr-small/mr.mhd|$data/mr-small/labels.mhd|5")
else
  echo "run.sh: $data not found: real scans skipped" >&2
fi

# The shape memory: trained on two other phantoms (as in the demo).
"$bin/lphantom" "$work/train-a" --spacing 1.4,1.4,5 --seed 7 --quiet
"$bin/lphantom" "$work/train-b" --spacing 1.0,1.0,2 --seed 9 --quiet
"$bin/lseg" train --quiet --image "$work/train-a/ct.mhd" --labels "$work/train-a/labels.mhd" \
  --image "$work/train-b/ct.mhd" --labels "$work/train-b/labels.mhd" --label 1,2,3,4 -o "$work/shape.h5"

variants=("full|--shape $work/shape.h5"
          "no shape memory|"
          "no rib cage|--shape $work/shape.h5 --no-rib-cage"
          "no competition|--shape $work/shape.h5 --no-competition"
          "competition's repeat as is|--shape $work/shape.h5 --no-repeat-trim"
          "no K-means|--shape $work/shape.h5 --no-kmeans"
          "no start slice|--shape $work/shape.h5 --no-start-slice"
          "no 3-D pass|--shape $work/shape.h5 --no-3d-pass"
          "no dome contact|--shape $work/shape.h5 --no-dome-contact"
          "no heart model|--shape $work/shape.h5 --no-heart-model"
          "no tissue stop|--shape $work/shape.h5 --no-tissue-stop"
          "no tissue trim|--shape $work/shape.h5 --no-tissue-trim"
          "no edge snap|--shape $work/shape.h5 --no-edge-snap"
          "no growing pieces|--shape $work/shape.h5 --no-piece-growth"
          "no vessel-cut pieces|--shape $work/shape.h5 --no-vessel-cut-pieces"
          "no vessel inlets|--shape $work/shape.h5 --no-vessel-inlets"
          "no dark rim|--shape $work/shape.h5 --no-dark-rim"
          "no surface lesions|--shape $work/shape.h5 --no-surface-lesions"
          "no wall margin|--shape $work/shape.h5 --no-wall-margin"
          "no seed-window widening|--shape $work/shape.h5 --no-seed-window-widening"
          "no iteration scaling|--shape $work/shape.h5 --no-iteration-scaling"
          "no layer clip|--shape $work/shape.h5 --layer-clip 0"
          "no snap scaling|--shape $work/shape.h5 --no-snap-scaling"
          "parenchyma convention|--shape $work/shape.h5 --convention parenchyma")

csv="$out/liver_ablation.csv"
echo "input,variant,seconds,dice,asd_mm,voe,abs_rvd,rmsd_mm,maxd_mm,score,status" > "$csv.tmp"
for in in "${inputs[@]}"; do
  IFS='|' read -r name image ref labels <<< "$in"
  for v in "${variants[@]}"; do
    IFS='|' read -r vname vargs <<< "$v"
    h5="$work/out.h5"
    rm -f "$h5"
    # shellcheck disable=SC2086
    t0=$(date +%s.%N)
    if "$bin/lseg" liver "$image" -o "$h5" --quiet $vargs 2> "$work/err"; then
      secs=$(echo "$(date +%s.%N) - $t0" | bc)
      "$bin/lseg" eval "$h5" "$ref" --seg-name liver --ref-label "$labels" --json --quiet > "$work/eval.json"
      /usr/bin/python3 - "$work/eval.json" "$name" "$vname" "$secs" >> "$csv.tmp" <<'PY'
import json, sys
e = json.load(open(sys.argv[1]))
print(",".join([sys.argv[2], sys.argv[3], "%.2f" % float(sys.argv[4]), "%.4f" % e["dice"], "%.3f" % e["asd_mm"],
                "%.2f" % e["voe_percent"], "%.2f" % e["abs_rvd_percent"], "%.3f" % e["rmsd_mm"],
                "%.2f" % e["maxd_mm"], "%.1f" % e["score"]["total"], "ok"]))
PY
    else
      echo "$name,$vname,nan,nan,nan,nan,nan,nan,nan,nan,\"$(tail -1 "$work/err" | tr ',' ';')\"" >> "$csv.tmp"
    fi
    echo "$name / $vname: $(tail -1 "$csv.tmp")" >&2
  done
done
mv "$csv.tmp" "$csv"
/usr/bin/python3 "$repo/bench/liver/plot_ablation.py" "$csv" "$out/liver_ablation.png"
echo "wrote $csv and $out/liver_ablation.png" >&2
