#!/usr/bin/python3
"""Merges repeated mss_scaling runs into one CSV (the shared machine's load changes by the minute).

    /usr/bin/python3 bench/mss/merge_runs.py OUT.csv RUN1.csv RUN2.csv ...

Single-simulation rows: the run with the least CPU time per step for each (mesh, config); a
failure (status column) only when every run failed. Two
simulations against one: both rows of the run in which the pair got the most CPU (cores_busy),
i.e. the quietest moment. A column `run` gives the run each row comes from (1-based).
"""
import csv
import sys


def cost(row):
    return float(row["cpu_us_best"]) if row["cpu_us_best"] else float("inf")


def main():
    out, runs = sys.argv[1], sys.argv[2:]
    tables, fields = [], []
    for k, path in enumerate(runs, 1):
        with open(path, newline="") as f:
            reader = csv.DictReader(f)
            fields += [name for name in reader.fieldnames if name not in fields]
            tables.append([dict(r, source_run=str(k)) for r in reader])
    order, best, pairs = [], {}, {}
    for rows in tables:
        for r in rows:
            key = (r["mesh"], r["config"], r["run"])
            if key not in order:
                order.append(key)
            if r["run"] == "single":  # a failed run (no time) is kept only if every run failed
                if key not in best or cost(r) < cost(best[key]):
                    best[key] = r
        for r in rows:
            if r["run"] == "concurrent" and r["threads"] == "2":
                key = (r["mesh"], r["config"], "concurrent")
                mate = [m for m in rows if m["run"] == "concurrent" and m["threads"] == "1" and
                        (m["mesh"], m["config"]) == key[:2]]
                if mate and (key not in pairs or float(r["cores_busy"]) > float(pairs[key][1]["cores_busy"])):
                    pairs[key] = (mate[0], r)
    with open(out, "w", newline="") as f:
        w = csv.DictWriter(f, fieldnames=fields + ["source_run"], restval="")
        w.writeheader()
        for key in order:
            if key[2] == "single":
                w.writerow(best[key])
            elif key in pairs:
                w.writerows(pairs[key])
    print("merged", len(runs), "runs into", out)


if __name__ == "__main__":
    main()
