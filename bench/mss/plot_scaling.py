#!/usr/bin/python3
"""Chart of mss_scaling's CSV: the mass-spring step on liver meshes of 1k-200k nodes.

    /usr/bin/python3 bench/mss/plot_scaling.py [CSV [PNG]]

Defaults: docs/benchmarks/mss_scaling.csv -> docs/benchmarks/mss_scaling.png. Panels: CPU time
per step against nodes (with the issue's goals and its DRAM-bandwidth floor), ns per spring,
heap bytes per node (model + simulator with its solver), and the steps per second of two
independent simulations on two threads over one on one thread. Debian's python3-matplotlib only.
"""
import csv
import os
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(os.path.dirname(HERE))
COLOURS = {"constant": "tab:orange", "inverse-length": "tab:red", "van-gelder": "tab:blue", "havp": "tab:green",
           "linear-fem": "black", "corotational-fem": "grey"}
STYLES = {"symplectic": ("-", "o"), "verlet": (":", "s"), "implicit-cg": ("--", "^"), "implicit-cholmod": ("-.", "D")}


def family(mesh):
    """lmesh's liver as written, the same renumbered along a Morton curve, or mss_bench's cube."""
    return "cube" if mesh.startswith("cube:") else "morton" if mesh.endswith("+morton") else "liver"


def style(config):
    integrator, law = config.split("/")
    line, marker = STYLES[integrator]
    return dict(color=COLOURS[law], linestyle=line, marker=marker)


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else os.path.join(ROOT, "docs", "benchmarks", "mss_scaling.csv")
    dst = sys.argv[2] if len(sys.argv) > 2 else os.path.splitext(src)[0] + ".png"
    with open(src, newline="") as f:
        rows = list(csv.DictReader(f))
    single = [r for r in rows if r["run"] == "single" and r.get("status") in (None, "", "ok")]
    configs = list(dict.fromkeys(r["config"] for r in single))

    def series(config, key, fam="liver"):
        pts = sorted((r for r in single if r["config"] == config and r[key] and family(r["mesh"]) == fam),
                     key=lambda r: int(r["nodes"]))
        return [int(r["nodes"]) for r in pts], [float(r[key]) for r in pts]

    def others(ax, key, scale=1.0):
        """The renumbered liver meshes and the cubes, for the two explicit spring configurations."""
        for c in ("symplectic/van-gelder", "symplectic/havp"):
            st = style(c)
            for fam, line, label in (("morton", (0, (1, 1)), "Morton order"), ("cube", (0, (5, 1, 1, 1)), "cube")):
                x, y = series(c, key, fam)
                if x:
                    ax.plot(x, [v * scale for v in y], color=st["color"], linestyle=line, marker=st["marker"],
                            markerfacecolor="none", markersize=6, label="%s, %s" % (c, label))

    fig, axes = plt.subplots(2, 2, figsize=(15, 12))
    ax = axes[0][0]
    for c in configs:
        x, y = series(c, "cpu_us_best")
        ax.plot(x, [v / 1e3 for v in y], label=c, markersize=5, **style(c))
    others(ax, "cpu_us_best", 1e-3)
    nodes = sorted({int(r["nodes"]) for r in single})
    ax.plot(nodes, [n * 270 / 12e9 * 1e3 for n in nodes], color="purple", linewidth=2, alpha=0.4,
            label="DRAM floor: 270 B/node at 12 GB/s (issue)")
    ax.scatter([1e4, 1e5], [0.3, 3.5], marker="*", s=250, color="gold", edgecolors="black", zorder=5,
               label="goal: explicit step, 10k and 100k nodes")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("nodes (log)")
    ax.set_ylabel("CPU time per step [ms] (log; one thread)")
    ax.set_title("time per step (lmesh's node order; hollow: renumbered along a Morton curve, and cubes)",
                 fontsize=9)
    ax.legend(fontsize=7, ncol=2)

    ax = axes[0][1]
    for c in configs:
        if c.startswith("implicit"):
            continue
        x, y = series(c, "ns_per_spring")
        ax.plot(x, y, label=c, markersize=5, **style(c))
    others(ax, "ns_per_spring")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("nodes (log)")
    ax.set_ylabel("CPU ns per spring per step (log)")
    ax.set_title("explicit steps: cost per spring (flat = linear scaling)")
    ax.legend(fontsize=7, ncol=2)

    ax = axes[1][0]
    for c in configs:
        x, model = series(c, "model_bytes_per_node")
        _, sim = series(c, "simulator_bytes_per_node")
        ax.plot(x, [(a + b) / 1e3 for a, b in zip(model, sim)], label=c, markersize=5, **style(c))
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("nodes (log)")
    ax.set_ylabel("heap per node [kB] (model + simulator and solver; log)")
    ax.set_title("memory per node (glibc mallinfo2, after warm-up steps)")
    ax.legend(fontsize=7, ncol=2)

    ax = axes[1][1]
    conc = [r for r in rows if r["run"] == "concurrent" and family(r["mesh"]) == "liver"]
    for c in dict.fromkeys(r["config"] for r in conc):
        pts = {}
        for r in conc:
            if r["config"] == c:
                pts.setdefault(int(r["nodes"]), {})[r["threads"]] = r
        xs = sorted(n for n in pts if {"1", "2"} <= set(pts[n]))
        ys = [float(pts[n]["2"]["steps_per_second"]) / float(pts[n]["1"]["steps_per_second"]) for n in xs]
        ax.plot(xs, ys, label=c + " (wall)", markersize=6, **style(c))
        for n, y in zip(xs, ys):
            ax.annotate("%.1f cores" % float(pts[n]["2"]["cores_busy"]), (n, y), textcoords="offset points",
                        xytext=(3, -10), fontsize=6, color=COLOURS[c.split("/")[1]])
        # What two free cores would give: 2 x (CPU per step alone) / (CPU per step beside the other).
        est = [2 * float(pts[n]["1"]["cpu_us_best"]) / float(pts[n]["2"]["cpu_us_best"]) for n in xs]
        st = style(c)
        ax.plot(xs, est, color=st["color"], marker=st["marker"], linestyle="none", markerfacecolor="none",
                markersize=8, label=c + " (2 x CPU per step alone / beside)")
    ax.axhline(2, color="grey", linewidth=0.8, linestyle="--")
    ax.axhline(1, color="grey", linewidth=0.8)
    ax.set_xscale("log")
    ax.set_ylim(0, 2.3)
    ax.set_xlabel("nodes (log)")
    ax.set_ylabel("steps per second, 2 simulations on 2 threads / 1 on 1")
    ax.set_title("two independent simulations on two threads (the step itself is single-threaded)\n"
                 "filled: measured (labels: cores the pair got on the shared VM); hollow: with two free cores",
                 fontsize=9)
    ax.legend(fontsize=7)
    for a in axes.flat:
        a.grid(True, which="both", alpha=0.3)
    fig.suptitle("libmss step on lphantom liver meshes (lmesh), shared 2-core VM under load: CPU time, "
                 "least of repeated runs (mss_scaling)")
    fig.tight_layout()
    fig.savefig(dst, dpi=100)
    print("wrote", dst)


if __name__ == "__main__":
    main()
