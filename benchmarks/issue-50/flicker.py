#!/usr/bin/env python3
"""Flicker along an orbit against two independent reference sets, split by pixel class.

    python3 flicker.py SCENE_SUBSTRING REF2_DIR FIRST LAST FRAMES_DIR...
    python3 flicker.py render SCENE_SUBSTRING SCENE ENV FIRST LAST SEED REF2_DIR

The eval's references (R1) are read from `.pathlight-cache/references` (run from the
repository's root, after `pathlight eval` of the spec), those of the scene whose description
contains SCENE_SUBSTRING at 320x180, in the order they were rendered (the views' order);
REF2_DIR holds `ref-NNNNN.exr`, an independent render of view NNNNN (`pathlight render` of
that view's camera, from the reference's `.json`, with another `--seed`); FRAMES_DIR holds
`play --format exr` frames along the same views. For views FIRST..LAST it prints each
configuration's flicker (the mean over pixels and channels of |(s(I_v) - s(I_v-1)) -
(s(R_v) - s(R_v-1))|, s the clamped sRGB encoding, as `pathlight eval`'s `flicker`) against
R1, against the mean of both sets, extrapolated to noise-free references (the references'
noise adds in quadrature: sqrt(2 S_mean^2 - S_R1^2)), and against the mean by pixel class
(the sky; edges: a depth step over 3% or normals with a cosine under 0.9 in the 3x3
neighbourhood, in either view; flat: the rest). `render` makes REF2_DIR: views FIRST - 1 to
LAST at the references' settings (256 spp, two bounces) with seed SEED, through
target/release/pathlight. Needs numpy and OpenEXR (pip).
"""
import glob
import json
import os
import subprocess
import sys

import numpy as np
import OpenEXR


def channels(path):
    return OpenEXR.File(path).parts[0].channels


def rgb(path):
    return np.asarray(channels(path)["RGB"].pixels, float)


def srgb(x):
    x = np.clip(x, 0, 1)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def references(sub):
    out = []
    for j in glob.glob(".pathlight-cache/references/*.json"):
        d = json.load(open(j))
        c = d["config"]
        if sub in d["scene"] and (c["width"], c["height"]) == (320, 180):
            out.append((os.path.getmtime(d["path"]), d["path"]))
    return [p for _, p in sorted(out)]


def classes(path):
    ch = channels(path)
    d = np.asarray(ch["depth.Z"].pixels, float)
    n = np.stack([np.asarray(ch["normal." + c].pixels, float) for c in "XYZ"], -1)
    edge = np.zeros(d.shape, bool)
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            dd, nn = (np.roll(np.roll(a, dy, 0), dx, 1) for a in (d, n))
            cos = (nn * n).sum(-1)
            norms = np.linalg.norm(nn, axis=-1) * np.linalg.norm(n, axis=-1)
            edge |= (np.abs(dd - d) > 0.03 * np.maximum(d, 1e-3)) | (cos < 0.9 * norms)
    return np.where(d <= 1e-6, 0, np.where(edge, 1, 2))


def render(sub, scene, env, first, last, seed, out):
    os.makedirs(out, exist_ok=True)
    for v, path in enumerate(references(sub)):
        if not first - 1 <= v <= last:
            continue
        c = json.load(open(path[: -len(".exr")] + ".json"))["config"]
        cam = c["camera"]
        vec = lambda a: ",".join(map(str, a))
        subprocess.run(
            ["target/release/pathlight", "render", scene, "--env", env]
            + ["--width", "320", "--height", "180", "--spp", str(c["spp"]), "--seed", seed]
            + ["--max-bounces", str(c["max_bounces"]), "--fov-y", str(cam["fov_y"])]
            + ["--look-from", vec(cam["look_from"]), "--look-at", vec(cam["look_at"])]
            + ["--up", vec(cam["up"]), "--out", "%s/ref-%05d.exr" % (out, v)],
            check=True,
        )


def main():
    if sys.argv[1] == "render":
        a = sys.argv[2:]
        return render(a[0], a[1], a[2], int(a[3]), int(a[4]), a[5], a[6])
    sub, ref2, first, last = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
    views = range(first - 1, last + 1)
    r1_paths = references(sub)
    lin1 = {v: rgb(r1_paths[v]) for v in views}
    lin2 = {v: rgb("%s/ref-%05d.exr" % (ref2, v)) for v in views}
    r1 = {v: srgb(lin1[v]) for v in views}
    r2 = {v: srgb(lin2[v]) for v in views}
    mean = {v: srgb((lin1[v] + lin2[v]) / 2) for v in views}
    cls = {v: classes(r1_paths[v]) for v in views}

    def changes(frames, refs):
        return [
            np.abs((frames[v] - frames[v - 1]) - (refs[v] - refs[v - 1])).mean(-1)
            for v in views[1:]
        ]

    def report(name, frames):
        s1 = np.mean([m.mean() for m in changes(frames, r1)])
        by_mean = changes(frames, mean)
        sm = np.mean([m.mean() for m in by_mean])
        free = np.sqrt(max(2 * sm * sm - s1 * s1, 0.0))
        split = []
        for k, label in enumerate(["sky", "edges", "flat"]):
            total, count = 0.0, 0
            for v, m in zip(views[1:], by_mean):
                c = np.where(
                    (cls[v] == 0) & (cls[v - 1] == 0),
                    0,
                    np.where((cls[v] == 1) | (cls[v - 1] == 1), 1, 2),
                )
                total += m[c == k].sum()
                count += (c == k).sum()
            share = count / (len(by_mean) * by_mean[0].size)
            split.append("%s %.4f (%.0f%%)" % (label, total / max(count, 1), 100 * share))
        print("%-24s R1 %.4f  mean %.4f  noise-free %.4f | %s" % (name, s1, sm, free, ", ".join(split)))

    report("independent references", r2)
    for d in sys.argv[5:]:
        files = sorted(glob.glob(d + "/frame-*.exr"))
        report(os.path.basename(d.rstrip("/")), {v: srgb(rgb(files[v])) for v in views})


main()
