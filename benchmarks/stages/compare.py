#!/usr/bin/env python3
"""Frame times of two `pathlight` binaries side by side (issue 49's "no slower" goal).

    python3 benchmarks/stages/compare.py BEFORE AFTER [--rounds 5] [--frames 30] [SCENE ARGS...]

Runs `pathlight bench frame --json` with the real-time preset, each technique alone and
ReSTIR, alternating the binaries round by round (the host's noise falls on both), and prints
per configuration the median frame time of each binary and the median of the per-round
ratios (after / before). Adaptive sampling and SVGF run with the settings that were their
defaults before issue 49 (`adaptive.toml`, `svgf.toml` here), which both binaries read the
same way. Run it from the repository's root.
"""
import json
import statistics
import subprocess
import sys

CONFIGS = [
    ("plain", []),
    ("preset", ["--config", "experiments/realtime.toml"]),
    ("adaptive", ["--config", "benchmarks/stages/adaptive.toml"]),
    ("reprojection", ["--reprojection"]),
    ("restir", ["--restir"]),
    ("data-driven", ["--filter", "data-driven", "--holes"]),
    ("svgf", ["--config", "benchmarks/stages/svgf.toml"]),
]


def plain(binary, args):
    """`--plain` for the configuration without arguments, where the binary has it (builds that
    choose a preset when given no configuration)."""
    if args:
        return []
    help_text = subprocess.run(
        [binary, "bench", "frame", "--help"], capture_output=True, text=True
    ).stdout
    return ["--plain"] if "--plain" in help_text else []


def frame_ms(binary, args, frames):
    out = subprocess.run(
        [binary, "bench", "frame", "--frames", str(frames), "--json", *args],
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out.strip().splitlines()[-1])["ms_per_frame"]


def main():
    argv = sys.argv[1:]
    before, after = argv[0], argv[1]
    rest = argv[2:]
    rounds, frames = 5, 30
    if "--rounds" in rest:
        i = rest.index("--rounds")
        rounds = int(rest[i + 1])
        del rest[i : i + 2]
    if "--frames" in rest:
        i = rest.index("--frames")
        frames = int(rest[i + 1])
        del rest[i : i + 2]
    print(f"{'configuration':14} {'before ms':>10} {'after ms':>10} {'ratio':>7}")
    for name, args in CONFIGS:
        b, a = [], []
        for r in range(rounds):
            order = [(before, b), (after, a)] if r % 2 == 0 else [(after, a), (before, b)]
            for binary, out in order:
                out.append(frame_ms(binary, args + plain(binary, args) + rest, frames))
        ratios = [y / x for x, y in zip(b, a)]
        print(
            f"{name:14} {statistics.median(b):10.2f} {statistics.median(a):10.2f} "
            f"{statistics.median(ratios):7.3f}",
            flush=True,
        )


if __name__ == "__main__":
    main()
