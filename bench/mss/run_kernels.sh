#!/usr/bin/env bash
# The spring and volume kernels (issue 7, docs/benchmarks.md "Mass-spring step", "Kernels"):
# the explicit step with the scalar loops and with the AVX2 kernels, one and two threads, on
# the phantom's liver meshes, in one run. Needs build/tools (lphantom, lmesh) and the bench
# build's mss_scaling:
#   cmake --preset bench && cmake --build --preset bench --target mss_scaling
#   bash bench/mss/run_kernels.sh   -> docs/benchmarks/mss_kernels.{csv,png}
# Each row: the least wall time per step over REPEAT (default 3) runs of STEPS steps (default:
# 5000 to 300 by mesh size). MESHES=dir keeps the meshes (bench/mss/liver_meshes.sh).
set -euo pipefail
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
bin="${BIN:-$repo/build/tools}"
bench="${BENCH:-$repo/build-bench/bench}"
out="${OUT_DIR:-$repo/docs/benchmarks}"
mkdir -p "$out"
echo "machine: $(lscpu | sed -n 's/^Model name: *//p'), $(nproc --all) CPUs; load average $(cut -d' ' -f1-3 /proc/loadavg)" >&2
source "$repo/bench/mss/liver_meshes.sh"
csv="$out/mss_kernels.csv"
tmp="$csv.tmp"
echo "mesh,nodes,springs,config,kernel,threads,ms_per_step" > "$tmp"
# size:curvature factor:steps (about 1k, 10k, 12k, 47k and 107k nodes); SPECS overrides the list
for spec in ${SPECS:-12:3:5000 5.3:2:2000 5:2:2000 3:2:600 2.2:2:300}; do
  IFS=: read -r size cf steps <<< "$spec"
  mesh="$(liver_mesh "$size" "$cf")"
  for config in symplectic/van-gelder symplectic/havp; do
    for simd in 0 1; do
      for threads in 1 2; do
        best=""
        for _ in $(seq "${REPEAT:-3}"); do
          line="$(MSS_SIMD=$simd MSS_THREADS=$threads OMP_NUM_THREADS=$threads "$bench/mss_scaling" --single "$mesh" "$config" "${STEPS:-$steps}")"
          ms="$(sed -n 's/.*, \([0-9.]*\) ms per step/\1/p' <<< "$line")"
          best="$(python3 -c "print(min($ms, ${best:-$ms}))")"
        done
        counts="$(sed -n 's/.* steps, \([0-9]*\) nodes, \([0-9]*\) springs.*/\1,\2/p' <<< "$line")"
        kernel=$([ "$simd" = 1 ] && echo avx2 || echo scalar)
        echo "$(basename "$mesh" .h5),$counts,$config,$kernel,$threads,$best" | tee -a "$tmp" >&2
      done
    done
  done
done
mv "$tmp" "$csv"
/usr/bin/python3 "$repo/bench/mss/plot_kernels.py" "$csv" "$out/mss_kernels.png"
