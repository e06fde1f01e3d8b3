"""Step time over the course of a cut (bench/mss/run_instruments.sh): one line per mesh."""
import csv
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

series = {}
with open(sys.argv[1]) as f:
    for row in csv.DictReader(f):
        series.setdefault(row["mesh"], ([], []))
        series[row["mesh"]][0].append(float(row["time_s"]))
        series[row["mesh"]][1].append(float(row["step_us"]) / 1000)
fig, ax = plt.subplots(figsize=(8, 4))
for name, (t, ms) in series.items():
    # Each mesh's run takes its own simulated time (0.2 s, or 2000 steps if that is less) with
    # the blade covering the same path: plot against the fraction of that path.
    end = max(t)
    ax.plot([x / end for x in t], ms, lw=0.6, label=f"{name} nodes ({end:.3g} s simulated)")
ax.axhline(1.0, color="grey", ls="--", lw=0.8)
ax.text(0.005, 1.05, "1 kHz haptic rate", color="grey", fontsize=8)
ax.set_yscale("log")
ax.set_xlabel("fraction of the blade's path (it moves into the liver throughout)")
ax.set_ylabel("wall time of the step [ms]")
ax.set_title("Step time during a cut (spikes: topology updates every 2 ms)")
ax.legend()
fig.tight_layout()
fig.savefig(sys.argv[2], dpi=110)
