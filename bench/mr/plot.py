#!/usr/bin/python3
"""Chart of bias_bench's CSV: correction time (log scale) against field error and block spread.

    /usr/bin/python3 bench/mr/plot.py [CSV [PNG]]

Defaults: docs/benchmarks/bias_field.csv -> docs/benchmarks/bias_field.png.
Left: field error on the phantoms (the true field is known). Right: the liver's block spread of
the corrected image on every input (mr-small included), with each input's uncorrected value as a
dotted line. One marker per method (filled: lobe, hollow: ITK), one colour per input's field
(both phantom spacings share it). The "none" rows take no time and are not drawn as points.
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

MARKERS = {"lobe": "o", "lobe-deg1": "v", "lobe-k3": "^", "lobe-deg3": "s", "itk-n4": "D"}
SPACING_MARKER_SIZE = {"phantom-1.4x5": 60, "phantom-1.2x4": 35}


def field_of(name):
    """The field part of an input name ("phantom-1.4x5/linear-0.30" -> "linear-0.30")."""
    return name.split("/", 1)[1] if "/" in name else name


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "benchmarks", "bias_field.csv")
    dst = sys.argv[2] if len(sys.argv) > 2 else os.path.splitext(src)[0] + ".png"
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    if not rows:
        sys.exit("no rows in " + src)

    fields = list(dict.fromkeys(field_of(r["input"]) for r in rows))
    cmap = plt.get_cmap("tab10")
    colour = {name: ("black" if name == "mr-small" else cmap(i % 10)) for i, name in enumerate(fields)}
    methods = [m for m in MARKERS if any(r["method"] == m for r in rows)]

    fig, axes = plt.subplots(1, 2, figsize=(15, 6.5))
    for ax, key, label, phantoms_only in (
            (axes[0], "field_rms_percent", "field error: RMS of log b_est - log b_true over the liver [%]", True),
            (axes[1], "block_spread", "liver block spread of the corrected image (lower is better)", False)):
        for r in rows:
            if not r[key] or (phantoms_only and r["input"] == "mr-small"):
                continue
            c = colour[field_of(r["input"])]
            if r["method"] == "none":
                if not phantoms_only:  # the uncorrected level, for comparison
                    ax.axhline(float(r[key]), color=c, linestyle=":", linewidth=1, alpha=0.7)
                continue
            m = r["method"]
            size = SPACING_MARKER_SIZE.get(r["input"].split("/")[0], 60)
            ax.scatter(float(r["seconds"]), max(float(r[key]), 1e-3), s=size, marker=MARKERS.get(m, "x"),
                       facecolors="none" if m.startswith("itk") else c, edgecolors=c, linewidths=1.4)
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.set_xlabel("correction wall time [s] (log scale; 2 threads)")
        ax.set_ylabel(label)
        ax.grid(True, which="both", alpha=0.3)

    method_handles = [Line2D([], [], linestyle="none", marker=MARKERS[m], color="black",
                             markerfacecolor="none" if m.startswith("itk") else "black", markersize=8, label=m)
                      for m in methods]
    input_handles = [Line2D([], [], linestyle="none", marker="o", color=colour[f], markersize=8, label=f)
                     for f in fields]
    axes[0].legend(handles=method_handles, title="method (large: 1.4x5 mm, small: 1.2x4 mm)", loc="best",
                   fontsize=8)
    axes[1].legend(handles=input_handles, title="field (dotted: uncorrected)", loc="best", fontsize=8)
    fig.suptitle("MR bias-field correction: libseg correct_bias_field against ITK N4 (T1-like phantoms with a "
                 "known field; mr-small)")
    fig.tight_layout()
    fig.savefig(dst, dpi=110)
    print("wrote " + dst)


if __name__ == "__main__":
    main()
