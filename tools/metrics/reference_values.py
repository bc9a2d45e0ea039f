#!/usr/bin/env python3
"""Reference values for pathlight-eval's image metrics (crates/eval/src/metrics/).

Generates a few deterministic image pairs, evaluates them with independent reference
implementations (scikit-image SSIM/MSE/PSNR, NVIDIA's flip-evaluator, colour-science CIELUV)
and writes everything the Rust test `crates/eval/tests/metrics.rs` needs:

    <out>/<pair>_image.f32, <pair>_reference.f32   linear RGB, f32 little-endian, row-major,
                                                   row 0 at the top, channels interleaved
    <out>/<pair>_ssim_map.f32                      1 - SSIM per pixel (mean of the channels)
    <out>/<pair>_flip_map.f32                      FLIP error per pixel
    <out>/expected.json                            sizes, expected metric values, versions

Usage (from the repository root):
    python3 tools/metrics/reference_values.py [--out crates/eval/tests/data/metrics]
"""

import argparse
import json
import os
import sys
import warnings

import numpy as np

warnings.filterwarnings("ignore")  # colour-science warns about a missing matplotlib

import colour  # noqa: E402
import flip_evaluator  # noqa: E402
import scipy  # noqa: E402
import skimage  # noqa: E402
from skimage.metrics import (  # noqa: E402
    mean_squared_error,
    peak_signal_noise_ratio,
    structural_similarity,
)

try:
    from importlib.metadata import version as pkg_version
except ImportError:  # pragma: no cover
    pkg_version = None


# ---------------------------------------------------------------- image pairs


def gradient_pair(rng):
    """A smooth LDR gradient and a noisy version (some noisy values fall outside [0, 1])."""
    w, h = 48, 40
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    ref = np.stack(
        [x / (w - 1), y / (h - 1), 0.5 + 0.4 * np.sin(0.2 * x + 0.3 * y)], axis=-1
    )
    ref = 0.9 * ref + 0.02
    img = ref + rng.normal(0.0, 0.06, ref.shape)
    return img, ref


def checker_pair(rng):
    """A coloured 6-pixel checkerboard and the same board shifted by (2, 1) pixels."""
    w, h = 40, 32

    def board(dx, dy):
        y, x = np.mgrid[0:h, 0:w]
        c = (((x + dx) // 6 + (y + dy) // 6) % 2).astype(np.float64)
        a = np.array([0.8, 0.6, 0.1])
        b = np.array([0.05, 0.1, 0.3])
        return c[..., None] * a + (1.0 - c[..., None]) * b

    return board(2, 1), board(0, 0)


def hdr_pair(rng):
    """A 64x48 HDR pair: values up to ~20, a few small negative values, a black region."""
    w, h = 64, 48
    y, x = np.mgrid[0:h, 0:w].astype(np.float64)
    base = np.stack(
        [
            0.3 + 0.2 * np.cos(0.15 * x),
            0.25 + 0.2 * np.sin(0.11 * y),
            0.2 + 0.1 * np.cos(0.07 * (x + y)),
        ],
        axis=-1,
    )
    # A bright "light" blob (HDR) and a black corner.
    blob = np.exp(-((x - 40) ** 2 + (y - 14) ** 2) / 30.0)
    base = base + 20.0 * blob[..., None] * np.array([1.0, 0.8, 0.5])
    base[:8, :8] = 0.0
    ref = base
    # Test image: multiplicative noise like a Monte Carlo estimate, plus fireflies and a
    # few slightly negative values (as a reconstruction filter's negative lobes produce).
    img = ref * rng.gamma(4.0, 0.25, ref.shape)
    fireflies = rng.random((h, w)) < 0.01
    img[fireflies] += 15.0
    neg = rng.random((h, w, 3)) < 0.01
    img[neg] = -0.02
    return img, ref


def tiny_pair(rng):
    """An odd-sized 13x11 pair: just above SSIM's 11-pixel window, most pixels in the border."""
    w, h = 13, 11
    ref = rng.random((h, w, 3)) * 0.9
    img = np.clip(ref + rng.normal(0.0, 0.1, ref.shape), -0.1, 1.2)
    return img, ref


PAIRS = [
    ("gradient", gradient_pair),
    ("checker", checker_pair),
    ("hdr", hdr_pair),
    ("tiny", tiny_pair),
]


FLIP_PPD = 67.0

# ---------------------------------------------------------------- conversions


def srgb_encode(lin):
    """Linear -> sRGB encoding after clamping to [0, 1] (IEC 61966-2-1), in float64."""
    c = np.clip(lin, 0.0, 1.0)
    return np.where(c <= 0.0031308, 12.92 * c, 1.055 * np.power(c, 1.0 / 2.4) - 0.055)


def srgb8(lin):
    """8-bit sRGB codes, rounded to nearest, as pathlight_core::color::linear_to_srgb8."""
    return np.floor(srgb_encode(lin) * 255.0 + 0.5).astype(np.uint8)


def to_luv(lin):
    cs = colour.RGB_COLOURSPACES["sRGB"]  # Rec.709 primaries, D65, IEC 61966-2-1 matrix
    xyz = colour.RGB_to_XYZ(lin, cs, illuminant=None, apply_cctf_decoding=False)
    white_xyz = colour.RGB_to_XYZ(np.ones(3), cs, illuminant=None)
    white_xy = colour.XYZ_to_xy(white_xyz)  # XYZ_to_Luv rebuilds the white with Yn = 1
    return colour.XYZ_to_Luv(xyz, illuminant=white_xy)


# ---------------------------------------------------------------- metrics


def metrics_for(img, ref):
    srgb_i, srgb_r = srgb_encode(img), srgb_encode(ref)
    out = {}
    out["mse"] = float(mean_squared_error(ref, img))
    out["rmse"] = float(np.sqrt(out["mse"]))
    gray = 0.2126 * ref[..., 0] + 0.7152 * ref[..., 1] + 0.0722 * ref[..., 2]
    out["relmse"] = float(
        np.mean(np.sum((img - ref) ** 2, axis=-1) / (gray**2 + 0.001))
    )
    out["psnr"] = float(peak_signal_noise_ratio(srgb_r, srgb_i, data_range=1.0))

    ssim, smap = structural_similarity(
        srgb_i,
        srgb_r,
        gaussian_weights=True,
        sigma=1.5,
        use_sample_covariance=False,
        data_range=1.0,
        channel_axis=2,
        full=True,
    )
    out["ssim"] = float(ssim)
    ssim_err_map = 1.0 - smap.mean(axis=-1)

    ref8 = srgb8(ref).astype(np.float32) / 255.0
    img8 = srgb8(img).astype(np.float32) / 255.0
    # ppd 67.0 as nv_flip::DEFAULT_PIXELS_PER_DEGREE (flip-evaluator's own default is the
    # 67.02 that its viewing conditions 0.7 m, 3840 px, 0.7 m give).
    flip_map, flip_mean, _params = flip_evaluator.evaluate(
        ref8,
        img8,
        "LDR",
        inputsRGB=True,
        applyMagma=False,
        computeMeanError=True,
        parameters={"ppd": FLIP_PPD},
    )
    flip_map = np.asarray(flip_map, dtype=np.float64).reshape(ref.shape[:2])
    out["flip"] = float(flip_mean)
    out["flip_map_mean_f64"] = float(flip_map.mean())

    luv_i, luv_r = to_luv(img), to_luv(ref)
    out["luvmse"] = float(np.mean((luv_i - luv_r) ** 2))
    return out, ssim_err_map, flip_map


def write_f32(path, array):
    np.ascontiguousarray(array, dtype="<f4").tofile(path)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", default="crates/eval/tests/data/metrics")
    args = parser.parse_args()
    os.makedirs(args.out, exist_ok=True)

    rng = np.random.default_rng(20240607)
    expected = {
        "generator": "tools/metrics/reference_values.py",
        "versions": {
            "python": sys.version.split()[0],
            "numpy": np.__version__,
            "scipy": scipy.__version__,
            "scikit-image": skimage.__version__,
            "colour-science": colour.__version__,
            "flip-evaluator": pkg_version("flip-evaluator") if pkg_version else "?",
        },
        "pairs": {},
    }
    for name, make in PAIRS:
        img, ref = make(rng)
        # The metrics see f32 images: round first so Python and Rust read identical values.
        img = img.astype(np.float32).astype(np.float64)
        ref = ref.astype(np.float32).astype(np.float64)
        values, ssim_map, flip_map = metrics_for(img, ref)
        h, w = ref.shape[:2]
        write_f32(os.path.join(args.out, f"{name}_image.f32"), img)
        write_f32(os.path.join(args.out, f"{name}_reference.f32"), ref)
        write_f32(os.path.join(args.out, f"{name}_ssim_map.f32"), ssim_map)
        write_f32(os.path.join(args.out, f"{name}_flip_map.f32"), flip_map)
        expected["pairs"][name] = {"width": w, "height": h, "values": values}
        print(name, w, h, json.dumps(values))

    with open(os.path.join(args.out, "expected.json"), "w") as f:
        json.dump(expected, f, indent=2, sort_keys=True)
        f.write("\n")


if __name__ == "__main__":
    main()
