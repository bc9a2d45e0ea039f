#!/usr/bin/env python3
"""Intel Open Image Denoise as a yardstick for pathlight's filters (seed 001), not a dependency.

    python3 -m venv oidn && oidn/bin/pip install pyoidn numpy OpenEXR
    pathlight render --spp 1 --aovs --out noisy.exr            # albedo and normal layers
    oidn/bin/python tools/oidn/denoise.py noisy.exr denoised.exr [--reference ref.exr]
        [--quality high|balanced|fast] [--no-aux] [--repeat N]

Denoises the RGB of NOISY (linear HDR) with its `albedo` and `normal` layers (OIDN's `RT`
filter, `hdr`), writes the result as OUT (linear RGB EXR) and prints one JSON line: the
denoising time (median of `--repeat` runs, milliseconds, OIDN on all cores), and with
`--reference` the relMSE of the noisy and the denoised image (pathlight eval's definition:
per pixel the squared error summed over channels over gray(reference)^2 + 0.001, averaged).
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
import time

import numpy as np
import OpenEXR
import pyoidn


def read(path: str, prefix: str = "") -> np.ndarray:
    """A three-channel layer of an EXR as float32 (H, W, 3): RGB, or `albedo`, `normal`."""
    channels = OpenEXR.File(path).channels()
    # The Python binding groups R, G, B (of a layer) into one channel: "RGB", "albedo".
    grouped = {"": "RGB", "albedo": "albedo"}.get(prefix)
    if grouped in channels:
        return np.ascontiguousarray(channels[grouped].pixels, dtype=np.float32)
    names = {"": ["R", "G", "B"], "albedo": ["albedo.R", "albedo.G", "albedo.B"],
             "normal": ["normal.X", "normal.Y", "normal.Z"]}[prefix]
    missing = [n for n in names if n not in channels]
    if missing:
        raise SystemExit(f"{path}: no {', '.join(missing)} (render with --aovs)")
    return np.ascontiguousarray(np.stack([channels[n].pixels for n in names], axis=-1),
                                dtype=np.float32)


def relmse(image: np.ndarray, reference: np.ndarray) -> float:
    gray = reference @ np.array([0.2126, 0.7152, 0.0722], dtype=np.float64)
    error = ((image.astype(np.float64) - reference) ** 2).sum(axis=-1)
    return float((error / (gray * gray + 0.001)).mean())


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("noisy")
    p.add_argument("out")
    p.add_argument("--reference")
    p.add_argument("--quality", default="high", choices=["high", "balanced", "fast"])
    p.add_argument("--no-aux", action="store_true", help="colour only (no albedo and normal)")
    p.add_argument("--repeat", type=int, default=3)
    a = p.parse_args(argv)
    color = np.maximum(read(a.noisy), 0.0)
    albedo = normal = None
    if not a.no_aux:
        albedo = np.clip(read(a.noisy, "albedo"), 0.0, 1.0)
        normal = np.clip(read(a.noisy, "normal"), -1.0, 1.0)
    times = []
    for _ in range(max(1, a.repeat)):
        start = time.perf_counter()
        out = pyoidn.denoise(color, albedo, normal, hdr=True, quality=a.quality)
        times.append((time.perf_counter() - start) * 1e3)
    out = np.asarray(out, dtype=np.float32)
    h, w, _ = out.shape
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    OpenEXR.File(header, {"RGB": out}).write(a.out)
    result = {"ms": statistics.median(times), "quality": a.quality, "aux": not a.no_aux,
              "width": w, "height": h}
    if a.reference:
        reference = read(a.reference).astype(np.float64)
        result["relmse_noisy"] = relmse(color, reference)
        result["relmse_denoised"] = relmse(out, reference)
    print(json.dumps(result))
    return 0


if __name__ == "__main__":
    sys.exit(main())
