#!/usr/bin/python3
"""Chart of mss_accuracy's CSV: static error against the cost of a step.

    /usr/bin/python3 bench/mss/plot_accuracy.py [CSV [PNG]]

Defaults: docs/benchmarks/mss_accuracy.csv -> docs/benchmarks/mss_accuracy.png. Columns: the
1 % compression of a clamped column (left) and the cantilever under its own weight (right). Top:
|error| against the analytic value (E A strain; Euler-Bernoulli) over the CPU time of one explicit
step; bottom: over the CPU time per simulated second (time per step / critical-policy step), since
the stiffer laws also need shorter steps. One line per law, through the resolutions (cells across
the section, labelled). Uses Debian's python3-matplotlib only.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
STYLE = {  # variant: (colour, marker, filled)
    "linear-fem": ("black", "s", True),
    "corotational-fem": ("grey", "D", False),
    "constant": ("tab:orange", "v", True),
    "inverse-length": ("tab:red", "^", True),
    "van-gelder": ("tab:blue", "o", True),
    "havp": ("tab:green", "*", True),
}
TITLES = {
    "compression": "1 % compression, clamped 20 x 20 x 80 mm column\n(error of the force against E A strain)",
    "cantilever": "cantilever 80 x 10 x 10 mm under its weight\n(error of the tip deflection against Euler-Bernoulli)",
}


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "benchmarks", "mss_accuracy.csv")
    dst = sys.argv[2] if len(sys.argv) > 2 else os.path.splitext(src)[0] + ".png"
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    problems = list(dict.fromkeys(r["problem"] for r in rows))
    fig, axes = plt.subplots(2, len(problems), figsize=(7.5 * len(problems), 11), squeeze=False)
    for col, problem in enumerate(problems):
        for row, (key, xlabel) in enumerate((
                ("step_us", "CPU time of one explicit step [µs] (log)"),
                ("cpu_per_simulated_second", "CPU time per simulated second [s] (log; step at 0.2 x critical)"))):
            ax = axes[row][col]
            for variant, (colour, marker, filled) in STYLE.items():
                pts = sorted((r for r in rows if r["problem"] == problem and r["variant"] == variant),
                             key=lambda r: int(r["cells_across"]))
                if not pts:
                    continue
                xs = [float(r[key]) for r in pts]
                ys = [abs(float(r["error_vs_analytic"])) * 100 for r in pts]
                ax.plot(xs, ys, color=colour, linewidth=1, alpha=0.7)
                ax.scatter(xs, ys, color=colour, marker=marker, s=70 if marker == "*" else 40,
                           facecolors=colour if filled else "none", label=variant, zorder=3)
                for x, y, r in zip(xs, ys, pts):
                    ax.annotate(r["cells_across"], (x, y), textcoords="offset points", xytext=(4, 4), fontsize=7,
                                color=colour)
            ax.set_xscale("log")
            ax.set_yscale("log")
            ax.set_xlabel(xlabel)
            ax.set_ylabel("|error| against the analytic value [%] (log)")
            ax.grid(True, which="both", alpha=0.3)
            if row == 0:
                ax.set_title(TITLES.get(problem, problem), fontsize=10)
        axes[0][col].legend(fontsize=8, loc="best", title="law (labels: cells across)")
    fig.suptitle("libmss: static error against cost per step, every stiffness law and the FEM (mss_accuracy)")
    fig.tight_layout()
    fig.savefig(dst, dpi=110)
    print("wrote", dst)


if __name__ == "__main__":
    main()
