#!/usr/bin/env python3
"""Compare two linear RGB OpenEXR images (A = test, B = reference).

Usage: python3 tools/mitsuba/compare.py A.exr B.exr

Prints the per-channel means of both, the relative difference of the means
(mean_A_c - mean_B_c) / mean_B_c per channel, relMSE = mean over pixels and
channels of (A - B)^2 / (B^2 + 0.001), and the plain MSE.
"""

import argparse
import sys

import mitsuba as mi
import numpy as np

mi.set_variant('scalar_rgb')


def load_rgb(path):
    """Load an EXR as a float64 (H, W, 3) array (RGB, alpha dropped)."""
    bmp = mi.Bitmap(path)
    if bmp.pixel_format() not in (mi.Bitmap.PixelFormat.RGB,
                                  mi.Bitmap.PixelFormat.RGBA):
        bmp = bmp.convert(mi.Bitmap.PixelFormat.RGB,
                          mi.Struct.Type.Float32, srgb_gamma=False)
    return np.array(bmp, dtype=np.float64)[..., :3]


def compare(a, b):
    if a.shape != b.shape:
        raise ValueError(f'shape mismatch: {a.shape} vs {b.shape}')
    mean_a = a.mean(axis=(0, 1))
    mean_b = b.mean(axis=(0, 1))
    return {
        'mean_a': mean_a,
        'mean_b': mean_b,
        'rel_mean_diff': (mean_a - mean_b) / mean_b,
        'relmse': float(np.mean((a - b) ** 2 / (b ** 2 + 1e-3))),
        'mse': float(np.mean((a - b) ** 2)),
    }


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('a', help='test image A.exr')
    ap.add_argument('b', help='reference image B.exr')
    args = ap.parse_args(argv)

    r = compare(load_rgb(args.a), load_rgb(args.b))

    def rgb(v, fmt):
        return ' '.join(format(x, fmt) for x in v)

    print(f'mean A (RGB):         {rgb(r["mean_a"], ".6f")}')
    print(f'mean B (RGB):         {rgb(r["mean_b"], ".6f")}')
    print(f'rel mean diff (A-B)/B: {rgb(r["rel_mean_diff"], "+.4%")}')
    print(f'relMSE:               {r["relmse"]:.6g}')
    print(f'MSE:                  {r["mse"]:.6g}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
