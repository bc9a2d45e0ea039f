#!/usr/bin/env python3
"""Medians of goals.sh's output (read from a file or stdin): per configuration and build, the
median frame time, floor and frame/floor; the new build's median over the old one's (the
ratio of medians, and the median of the alternated pairs' ratios); and the stalls' lines."""
import collections
import statistics as st
import sys

frames = collections.defaultdict(lambda: collections.defaultdict(list))
stalls = []
for line in open(sys.argv[1]) if len(sys.argv) > 1 else sys.stdin:
    w = line.split()
    if w[:1] == ["frame"]:
        name = f"{w[1]} ({w[3]} threads)"
        ms = float(w[6])
        ratio = None if w[-1] == "None" else float(w[-1])
        floor = None if w[8] == "None" else float(w[8])
        frames[name][w[4]].append((ms, floor, ratio))
    elif w[:1] == ["stalls"]:
        stalls.append(line.rstrip())

for name, builds in frames.items():
    print(name)
    meds = {}
    for build, runs in builds.items():
        meds[build] = st.median(r[0] for r in runs)
        floors = [r[1] for r in runs if r[1] is not None]
        ratios = [r[2] for r in runs if r[2] is not None]
        extra = ""
        if floors:
            extra = f", floor {st.median(floors):.2f} ms, frame/floor {st.median(ratios):.2f}"
        runs_ms = " ".join(f"{r[0]:.1f}" for r in runs)
        print(f"  {build}: median {meds[build]:.2f} ms over {len(runs)} runs ({runs_ms}){extra}")
    if len(builds) == 2:
        (old, a), (new, b) = builds.items()
        pairs = [y[0] / x[0] for x, y in zip(a, b)]
        print(f"  new / old: {meds[new] / meds[old]:.3f} (pairs' median {st.median(pairs):.3f})")
for s in stalls:
    print(s)
