#!/usr/bin/python3
"""Chart of seg_bench's CSV: time (log scale) against Dice and against ASD.

    /usr/bin/python3 bench/seg/plot_speed_accuracy.py [CSV [PNG [TITLE]]]

Defaults: docs/benchmarks/seg_speed_accuracy.csv -> docs/benchmarks/seg_speed_accuracy.png.
One marker per method, one colour per input; only rows with a segmentation (Dice present) and
the 2-thread runs are drawn (the 1-thread rows of the scaling study would double every point).
GGVF's field-iteration sweep (methods GGVF-f<N>, the seeded starts) is drawn as small hollow
squares joined to the GGVF point of the same input by a dashed line.
Uses Debian's python3-matplotlib only (no pandas).
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
from matplotlib.lines import Line2D  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

MARKERS = {
    "CDSG": "*",
    "CDSG+template": "P",
    "GGVF": "s",
    "GAC": "^",
    "ITK-GAC": "o",
    "ITK-GAC-example": "x",
    "ITK-GVF-snake": "D",
}
FILLED = {"CDSG", "CDSG+template", "GGVF", "GAC"}  # lobe's methods filled, ITK's hollow


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "benchmarks", "seg_speed_accuracy.csv")
    dst = sys.argv[2] if len(sys.argv) > 2 else os.path.splitext(src)[0] + ".png"
    with open(src, newline="") as f:
        rows = [r for r in csv.DictReader(f) if r["dice"] and r["threads"] == "2"]
    if not rows:
        sys.exit("no rows with a Dice value in " + src)

    inputs = list(dict.fromkeys(r["input"] for r in rows))
    methods = [m for m in MARKERS if any(r["method"] == m for r in rows)]
    methods += [m for m in dict.fromkeys(r["method"] for r in rows)
                if m not in methods and not m.startswith("GGVF-f")]
    sweep_shown = any(r["method"].startswith("GGVF-f") for r in rows)
    cmap = plt.get_cmap("tab10")
    colour = {name: cmap(i % 10) for i, name in enumerate(inputs)}

    fig, axes = plt.subplots(1, 2, figsize=(15, 6.5))
    for ax, key, label in ((axes[0], "dice", "Dice (higher is better)"),
                           (axes[1], "asd_mm", "average symmetric surface distance [mm] (lower is better)")):
        for r in rows:
            if not r[key]:
                continue
            m = r["method"]
            c = colour[r["input"]]
            if m.startswith("GGVF-f"):
                ax.scatter(float(r["total_seconds"]), float(r[key]), s=30, marker="s", facecolors="none",
                           edgecolors=c, linewidths=1.0)
                continue
            marker = MARKERS.get(m, "v")
            size = 90 if marker == "*" else 55
            x, y = float(r["total_seconds"]), float(r[key])
            if marker in ("x", "+"):  # line markers have no face
                ax.scatter(x, y, s=size, marker=marker, color=c, linewidths=1.4)
            else:
                ax.scatter(x, y, s=size, marker=marker, facecolors=c if m in FILLED else "none", edgecolors=c,
                           linewidths=1.4)
        for i in inputs:  # GGVF's sweep, cheapest first
            sweep = sorted((float(r["total_seconds"]), float(r[key])) for r in rows
                           if r["input"] == i and r[key] and (r["method"] == "GGVF" or r["method"].startswith("GGVF-f")))
            if len(sweep) > 1:
                ax.plot([p[0] for p in sweep], [p[1] for p in sweep], linestyle="--", linewidth=0.8,
                        color=colour[i], alpha=0.7)
        ax.set_xscale("log")
        ax.set_xlabel("total time per run [s] (log scale; 2 threads)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)
    axes[1].set_yscale("log")

    method_handles = [Line2D([], [], linestyle="none", marker=MARKERS.get(m, "v"), color="black",
                             markerfacecolor="black" if m in FILLED else "none", markersize=8, label=m)
                      for m in methods]
    if sweep_shown:
        method_handles.append(Line2D([], [], linestyle="--", marker="s", color="black", markerfacecolor="none",
                                     markersize=6, linewidth=0.8, label="GGVF, more field iterations"))
    input_handles = [Line2D([], [], linestyle="none", marker="o", color=colour[i], markersize=8, label=i)
                     for i in inputs]
    axes[0].legend(handles=method_handles, title="method (filled: lobe, hollow: ITK)", loc="best",
                   fontsize=8)
    axes[1].legend(handles=input_handles, title="input", loc="best", fontsize=8)
    title = sys.argv[3] if len(sys.argv) > 3 else \
        "libseg active contours against ITK: speed and accuracy (same inputs, same initial mask)"
    fig.suptitle(title)
    fig.tight_layout()
    tmp = dst + ".tmp.png"
    fig.savefig(tmp, dpi=110)
    os.replace(tmp, dst)
    print("wrote", dst)


if __name__ == "__main__":
    main()
