#!/usr/bin/env python3
"""Chart of bench/vessels/run.sh: time of the vessel stage (x) against vessel Dice (left) and the
centre-line recall of the 4th branch level (right), for each input and each variant with one stage
switched off."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

rows = list(csv.DictReader(open(sys.argv[1])))
inputs = list(dict.fromkeys(r["input"] for r in rows))
variants = list(dict.fromkeys(r["variant"] for r in rows))
markers = "os^vD<>Px*"
colours = plt.rcParams["axes.prop_cycle"].by_key()["color"]
fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
for ax, key, label in ((axes[0], "dice", "vessel Dice (portal + hepatic)"),
                       (axes[1], "recall_l4", "centre-line recall, 4th branch level")):
    for vi, v in enumerate(variants):
        for ii, name in enumerate(inputs):
            for r in (r for r in rows if r["variant"] == v and r["input"] == name):
                ax.scatter(float(r["seconds"]), float(r[key]), marker=markers[ii % len(markers)],
                           color=colours[vi % len(colours)], s=70 if v == "full" else 40,
                           edgecolors="black" if v == "full" else "none")
    ax.set_xscale("log")
    ax.set_xlabel("time of the vessel stage [s] (log; 2 threads)")
    ax.set_ylabel(label)
    ax.grid(True, alpha=0.3)
axes[0].axhline(0.71, color="grey", linestyle="--", linewidth=1)
axes[0].text(axes[0].get_xlim()[0], 0.715, " FC anchor 0.71 (SLIVER07 scans)", fontsize=8, color="grey")
handles = [plt.Line2D([], [], linestyle="", marker="o", color=colours[i % len(colours)], label=v)
           for i, v in enumerate(variants)]
handles += [plt.Line2D([], [], linestyle="", marker=markers[i % len(markers)], color="grey", label=n)
            for i, n in enumerate(inputs)]
axes[1].legend(handles=handles, fontsize=8, loc="lower left")
fig.suptitle("lseg vessels: each stage switched off in turn (bench/vessels/run.sh)")
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=90)
