#!/usr/bin/env python3
"""Chart of bench/liver/run.sh: time (x) against SLIVER07 score (left) and Dice (right) for each
input and each ablation variant of `lseg liver`."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = [r for r in csv.DictReader(open(sys.argv[1])) if r["status"] == "ok"]
inputs = sorted({r["input"] for r in rows}, key=lambda s: [r["input"] for r in rows].index(s))
variants = sorted({r["variant"] for r in rows}, key=lambda s: [r["variant"] for r in rows].index(s))
markers = "os^vD<>Px*"
# The default cycle's grey (its 8th colour) would read as the inputs' legend markers, drawn grey.
colours = [c for c in plt.rcParams["axes.prop_cycle"].by_key()["color"] if c != "#7f7f7f"] + ["#000080", "#8b4513", "#ff1493", "#00ced1", "#556b2f", "#b8860b", "#808000", "#4b0082", "#dc143c", "#2f4f4f", "#7fff00", "#bc8f8f", "#ff8c00", "#e9967a", "#9acd32"]
fig, axes = plt.subplots(1, 2, figsize=(15, 5.4))
for ax, key, label in ((axes[0], "score", "SLIVER07 score (0-100; human 75)"), (axes[1], "dice", "Dice")):
    for vi, v in enumerate(variants):
        for ii, name in enumerate(inputs):
            pts = [r for r in rows if r["variant"] == v and r["input"] == name]
            for r in pts:
                ax.scatter(float(r["seconds"]), float(r[key]), marker=markers[ii % len(markers)],
                           color=colours[vi % len(colours)], s=60 if v == "full" else 36,
                           edgecolors="black" if v == "full" else "none")
    ax.set_xscale("log")
    ax.set_xlabel("wall time of lseg liver [s] (log)")
    ax.set_ylabel(label)
    ax.grid(True, alpha=0.3)
handles = [plt.Line2D([], [], linestyle="", marker="o", color=colours[i % len(colours)], label=v)
           for i, v in enumerate(variants)]
handles += [plt.Line2D([], [], linestyle="", marker=markers[i % len(markers)], color="#7f7f7f", label=n)
            for i, n in enumerate(inputs)]
axes[1].legend(handles=handles, fontsize=8, loc="upper left", bbox_to_anchor=(1.01, 1.0))
fig.suptitle("lseg liver: each component switched off in turn (bench/liver/run.sh)")
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=90)
