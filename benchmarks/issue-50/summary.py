#!/usr/bin/env python3
"""Summarise an eval results.json along a camera path: per configuration, the median frame
time, and the mean and median of each metric over the views from `--from` on (default 0),
and the worst view's (each view's metric the mean over the repetitions).
Usage: summary.py RESULTS.json [--from N]"""
import json
import statistics
import sys

path = sys.argv[1]
start = int(sys.argv[sys.argv.index("--from") + 1]) if "--from" in sys.argv else 0
d = json.load(open(path))
rows = {}
for m in d["measurements"]:
    if m["view"] < start:
        continue
    r = rows.setdefault(m["configuration"], {"ms": [], "metrics": {}, "views": {}})
    r["ms"].append(m["ms"])
    for k, v in m["metrics"].items():
        r["metrics"].setdefault(k, []).append(v)
        r["views"].setdefault(k, {}).setdefault(m["view"], []).append(v)
metrics = sorted({k for r in rows.values() for k in r["metrics"]})
print(f"views from {start}; metric: mean (median) [worst view]")
print(f"{'configuration':28} {'ms':>8} " + " ".join(f"{k:>27}" for k in metrics))
for name, r in rows.items():
    cells = []
    for k in metrics:
        v = r["metrics"].get(k, [])
        if not v:
            cells.append(" " * 27)
            continue
        worst = max(statistics.mean(x) for x in r["views"][k].values())
        cells.append(f"{statistics.mean(v):8.4f} ({statistics.median(v):7.4f}) [{worst:7.4f}]")
    print(f"{name:28} {statistics.median(r['ms']):8.1f} " + " ".join(cells))
