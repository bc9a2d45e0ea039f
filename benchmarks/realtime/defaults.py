"""Summarises `pathlight eval experiments/060-defaults.toml --out DIR` as BENCHMARKS' table.

    python3 benchmarks/realtime/defaults.py DIR [--chosen SCENE=PRESET,...]

Per scene and configuration, over the views after the first (the camera moving; the first
frame is the cold one): mean relMSE, mean flicker and median frame time (ms); the best preset
is the one with the lowest relMSE x ms (the issue's "best relMSE x ms"); then the defaults'
relMSE and flicker over the best preset's, and over the lowest of any preset.

`--chosen` takes the defaults' row from a preset's instead of the `defaults` configuration's,
for results made before the rule last changed: a preset's configuration renders the same
frames as `preset = "auto"` choosing it (same seed, same settings).

Configurations other than the defaults and the presets (experiments/060-composition.toml's
compositions) get a second table: their relMSE @ ms and flicker, and their relMSE x ms over
the defaults' and over the best preset's (issue 60, part 2: one composition against choosing).
"""

import json
import statistics
import sys
from pathlib import Path

PRESETS = ["realtime", "realtime-many-lights", "realtime-sun"]


def summary(results):
    rows = {}
    for m in results["measurements"]:
        if m["view"] == 0:
            continue
        r = rows.setdefault(m["configuration"], {"relmse": [], "flicker": [], "ms": []})
        r["relmse"].append(m["metrics"]["relmse"])
        if "flicker" in m["metrics"]:
            r["flicker"].append(m["metrics"]["flicker"])
        r["ms"].append(m["ms"])
    return {
        c: {
            "relmse": statistics.mean(r["relmse"]),
            "flicker": statistics.mean(r["flicker"]) if r["flicker"] else float("nan"),
            "ms": statistics.median(r["ms"]),
        }
        for c, r in rows.items()
    }


def main():
    out = Path(sys.argv[1])
    chosen_by = {}
    if len(sys.argv) > 3 and sys.argv[2] == "--chosen":
        chosen_by = dict(kv.split("=") for kv in sys.argv[3].split(","))
    print("| scene | defaults (chosen) | realtime | realtime-many-lights | realtime-sun "
          "| defaults / best relMSE x ms preset: relMSE, flicker "
          "| defaults / any preset's lowest: relMSE, flicker |")
    print("|---|---|---|---|---|---|---|")
    extra, names = [], []
    for results_file in sorted(out.glob("*/results.json")):
        results = json.loads(results_file.read_text())
        s = summary(results)
        if "defaults" not in s:
            continue
        scene = results_file.parent.name
        if scene in chosen_by:
            s["defaults"] = s[chosen_by[scene]]
        d = s["defaults"]
        chosen = next(
            (p for p in PRESETS if p in s and s[p]["relmse"] == d["relmse"]), "plain?"
        )
        best = min((p for p in PRESETS if p in s), key=lambda p: s[p]["relmse"] * s[p]["ms"])
        lowest = min(s[p]["relmse"] for p in PRESETS if p in s)
        calm = min(s[p]["flicker"] for p in PRESETS if p in s)

        def cell(c):
            x = s[c]
            mark = "**" if c == best else ""
            return f"{mark}{x['relmse']:.3g} @ {x['ms']:.0f}{mark} (fl. {x['flicker']:.3g})"

        print(
            f"| {scene} | {d['relmse']:.3g} @ {d['ms']:.0f} ({chosen}) | "
            + " | ".join(cell(p) if p in s else "" for p in PRESETS)
            + f" | {d['relmse'] / s[best]['relmse']:.2f}x, "
            f"{d['flicker'] / s[best]['flicker']:.2f}x | {d['relmse'] / lowest:.2f}x, "
            f"{d['flicker'] / calm:.2f}x |"
        )
        others = [c for c in s if c != "defaults" and c not in PRESETS]
        if others:
            product = lambda c: s[c]["relmse"] * s[c]["ms"]
            extra.append(
                f"| {scene} | "
                + " | ".join(
                    f"{s[c]['relmse']:.3g} @ {s[c]['ms']:.0f} (fl. {s[c]['flicker']:.3g}): "
                    f"{product(c) / product('defaults'):.2f}x, {product(c) / product(best):.2f}x"
                    for c in others
                )
                + " |"
            )
            names = others
    if extra:
        print()
        print("| scene | " + " | ".join(f"{c}: relMSE @ ms (flicker): relMSE x ms over the defaults', "
                                       "over the best preset's" for c in names) + " |")
        print("|---|" + "---|" * len(names))
        print("\n".join(extra))


if __name__ == "__main__":
    main()
