#!/usr/bin/python3
"""Charts of mesh_bench's CSV: element count against time and against minimum quality.

    /usr/bin/python3 bench/mesh/plot_mesh_bench.py [CSV [PNG]]

Defaults: docs/benchmarks/mesh_scaling.csv -> docs/benchmarks/mesh_scaling.png. Only the sweep
rows (k > 0) are drawn: lobe at each resolution factor k and tetgen on the same surfaces. One
row of panels per scene: time [s], smallest dihedral angle [deg], smallest combined measure,
each against the number of tets (log scale). Uses Debian's python3-matplotlib only.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))

STYLE = {
    "lobe": dict(marker="o", color="tab:blue"),
    "tetgen -pq1.9AYQ": dict(marker="s", color="tab:orange"),
    "tetgen -pq1.414AYQ": dict(marker="^", color="tab:green"),
}
SCENES = {"cgal": "CGAL's labelled liver", "phantom": "lphantom's default volume"}


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "benchmarks", "mesh_scaling.csv")
    dst = sys.argv[2] if len(sys.argv) > 2 else os.path.splitext(src)[0] + ".png"
    with open(src, newline="") as f:
        rows = [r for r in csv.DictReader(f) if float(r["k"]) > 0]
    if not rows:
        sys.exit("no sweep rows in " + src)
    scenes = list(dict.fromkeys(r["scene"] for r in rows))
    panels = (("seconds", "time [s] (log)", True),
              ("min_dihedral_deg", "smallest dihedral angle [deg]", False),
              ("combined_min", "smallest combined measure (eq 6.16)", False))
    fig, axes = plt.subplots(len(scenes), len(panels), figsize=(16, 4.6 * len(scenes)), squeeze=False)
    for i, scene in enumerate(scenes):
        for j, (key, label, log) in enumerate(panels):
            ax = axes[i][j]
            for mesher in dict.fromkeys(r["mesher"] for r in rows):
                pts = sorted((int(r["tets"]), float(r[key])) for r in rows
                             if r["scene"] == scene and r["mesher"] == mesher)
                if not pts:
                    continue
                style = STYLE.get(mesher, dict(marker="x", color="grey"))
                ax.plot([p[0] for p in pts], [p[1] for p in pts], linestyle="-", label=mesher, **style)
            ax.set_xscale("log")
            if log:
                ax.set_yscale("log")
            if key == "min_dihedral_deg":
                ax.axhline(10, color="grey", linestyle=":", linewidth=1)
            if key == "combined_min":
                ax.axhline(0.3, color="grey", linestyle=":", linewidth=1)
            ax.set_xlabel("tets (log)")
            ax.set_ylabel(label)
            ax.set_title(SCENES.get(scene, scene))
            ax.grid(True, which="both", alpha=0.3)
            if j == 0:
                ax.legend(loc="upper left")
    fig.suptitle("mesh_bench sweep: lobe (CGAL Mesh_3, serial) at size 10k, vessels 3k, tumours 5k, curvature "
                 "factor 2k; tetgen on the same surfaces")
    fig.tight_layout()
    fig.savefig(dst, dpi=90)
    print("wrote " + dst)


if __name__ == "__main__":
    main()
