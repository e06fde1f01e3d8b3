#!/usr/bin/python3
"""Chart of run_kernels.sh's CSV: the explicit step with the scalar loops and the AVX2 kernels.

    /usr/bin/python3 bench/mss/plot_kernels.py [CSV [PNG]]

Defaults: docs/benchmarks/mss_kernels.csv -> docs/benchmarks/mss_kernels.png. Left: wall time per
step against nodes for Van Gelder and HAVP, scalar and AVX2, one and two threads, with the
issue's goals (0.3 ms at 10 k nodes on one core, 3.5 ms at 100 k). Right: the AVX2 kernels'
speed-up over the scalar loops and two threads' over one. Debian's python3-matplotlib only.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
COLOURS = {"symplectic/van-gelder": "tab:blue", "symplectic/havp": "tab:green"}
STYLES = {("scalar", "1"): ("--", "o"), ("avx2", "1"): ("-", "o"), ("avx2", "2"): ("-", "s")}


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs/benchmarks/mss_kernels.csv")
    dst = sys.argv[2] if len(sys.argv) > 2 else os.path.join(ROOT, "docs/benchmarks/mss_kernels.png")
    with open(src) as f:
        rows = list(csv.DictReader(f))
    # (config, kernel, threads) -> sorted [(nodes, ms)]
    series = {}
    for r in rows:
        series.setdefault((r["config"], r["kernel"], r["threads"]), []).append((int(r["nodes"]), float(r["ms_per_step"])))
    for v in series.values():
        v.sort()
    fig, (left, right) = plt.subplots(1, 2, figsize=(13, 5.2))
    for (config, kernel, threads), pts in sorted(series.items()):
        if (kernel, threads) not in STYLES:
            continue
        ls, marker = STYLES[(kernel, threads)]
        left.plot([p[0] for p in pts], [p[1] for p in pts], ls, marker=marker, color=COLOURS.get(config, "grey"),
                  label=f"{config.split('/')[1]}, {kernel}, {threads} thread{'s' if threads != '1' else ''}")
    left.plot([10000], [0.3], "r*", markersize=14, label="goal: 0.3 ms at 10 k (one core)")
    left.plot([100000], [3.5], "m*", markersize=14, label="goal: 3.5 ms at 100 k")
    left.set_xscale("log")
    left.set_yscale("log")
    left.set_xlabel("nodes (lmesh's liver)")
    left.set_ylabel("wall time per explicit step [ms]")
    left.grid(True, which="both", alpha=0.3)
    left.legend(fontsize=7.5)
    left.set_title("symplectic Euler step")
    for config in COLOURS:
        scalar = dict(series.get((config, "scalar", "1"), []))
        avx = dict(series.get((config, "avx2", "1"), []))
        two = dict(series.get((config, "avx2", "2"), []))
        xs = sorted(set(scalar) & set(avx))
        right.plot(xs, [scalar[x] / avx[x] for x in xs], "-o", color=COLOURS[config],
                   label=f"{config.split('/')[1]}: AVX2 over scalar (1 thread)")
        xs2 = sorted(x for x in set(avx) & set(two) if x > 20000)  # below 100 k springs both are serial
        right.plot(xs2, [avx[x] / two[x] for x in xs2], "--s", color=COLOURS[config],
                   label=f"{config.split('/')[1]}: 2 threads over 1 (AVX2)")
    right.axhline(1, color="grey", lw=0.8)
    right.set_xscale("log")
    right.set_xlabel("nodes")
    right.set_ylabel("speed-up")
    right.grid(True, which="both", alpha=0.3)
    right.legend(fontsize=8)
    right.set_title("what the kernels and the second core buy")
    fig.tight_layout()
    fig.savefig(dst, dpi=110)
    print(f"wrote {dst}")


if __name__ == "__main__":
    main()
