#!/usr/bin/env python3
"""Render the McGuire Cornell box with Mitsuba 3 as an independent reference.

Usage (from the repo root):
    python3 tools/mitsuba/cornell.py [OBJ] --spp 4096 --seed 0 --out out.exr

The OBJ is parsed here (not by Mitsuba's obj plugin, which would load the
whole file as one shape with one BSDF): every `usemtl` material becomes its
own triangle mesh with a two-sided diffuse BSDF (reflectance = Kd), and the
material with a nonzero Ke additionally gets a one-sided `area` emitter with
radiance = Ke.  See README.md in this folder for the recorded reference run.
"""

import argparse
import os
import sys
import time

import mitsuba as mi

mi.set_variant('scalar_rgb')

DEFAULT_OBJ = os.path.join(
    os.path.dirname(os.path.abspath(__file__)),
    '..', '..', '..', 'shared', 'scenes', 'CornellBox',
    'CornellBox-Original.obj')


def parse_mtl(path):
    """Return {name: {'Kd': (r, g, b), 'Ke': (r, g, b)}} from an MTL file."""
    mats, cur = {}, None
    with open(path) as f:
        for line in f:
            tok = line.split('#', 1)[0].split()
            if not tok:
                continue
            if tok[0] == 'newmtl':
                cur = mats.setdefault(tok[1], {'Kd': (0.0, 0.0, 0.0),
                                               'Ke': (0.0, 0.0, 0.0)})
            elif tok[0] in ('Kd', 'Ke') and cur is not None:
                cur[tok[0]] = tuple(float(x) for x in tok[1:4])
    return mats


def parse_obj(path):
    """Return (mtllib or None, {material: [triangle, ...]}).

    A triangle is a tuple of three (x, y, z) positions.  Faces are assigned
    to the material that is current (last `usemtl`) when the `f` line is
    read; `g` lines are ignored.  Polygons are fan-triangulated from their
    first vertex, (0,1,2), (0,2,3), ..., keeping the file's winding.
    Indices may be 1-based or negative (relative to the vertices so far).
    """
    verts, groups, mtl, mtllib = [], {}, None, None
    with open(path) as f:
        for line in f:
            tok = line.split('#', 1)[0].split()
            if not tok:
                continue
            if tok[0] == 'v':
                verts.append(tuple(float(x) for x in tok[1:4]))
            elif tok[0] == 'usemtl':
                mtl = tok[1]
            elif tok[0] == 'mtllib':
                mtllib = tok[1]
            elif tok[0] == 'f':
                idx = []
                for t in tok[1:]:
                    i = int(t.split('/')[0])
                    idx.append(len(verts) + i if i < 0 else i - 1)
                poly = [verts[i] for i in idx]
                tris = groups.setdefault(mtl, [])
                for k in range(1, len(poly) - 1):
                    tris.append((poly[0], poly[k], poly[k + 1]))
    return mtllib, groups


def tri_normal(t):
    """Unnormalised geometric normal (p1-p0) x (p2-p0), as Mitsuba uses it;
    its length is twice the triangle's area."""
    (ax, ay, az), (bx, by, bz), (cx, cy, cz) = t
    ux, uy, uz = bx - ax, by - ay, bz - az
    vx, vy, vz = cx - ax, cy - ay, cz - az
    return (uy * vz - uz * vy, uz * vx - ux * vz, ux * vy - uy * vx)


def make_mesh(name, tris, bsdf, emitter=None):
    """Build a mi.Mesh with flat (face) normals from a triangle list."""
    props = mi.Properties()
    props['bsdf'] = bsdf
    if emitter is not None:
        props['emitter'] = emitter
    # No vertex normals: Mitsuba then shades with the geometric normal.
    mesh = mi.Mesh(name, 3 * len(tris), len(tris), props=props,
                   has_vertex_normals=False)
    params = mi.traverse(mesh)
    params['vertex_positions'] = [c for t in tris for p in t for c in p]
    params['faces'] = list(range(3 * len(tris)))
    params.update()
    return mesh


def build_scene(obj_path, spp, verbose=True, max_depth=-1):
    mtllib, groups = parse_obj(obj_path)
    mtl_path = os.path.join(os.path.dirname(obj_path),
                            mtllib or os.path.splitext(obj_path)[0] + '.mtl')
    mats = parse_mtl(mtl_path)

    scene = {
        'type': 'scene',
        'integrator': {
            'type': 'path',
            'max_depth': max_depth,   # -1: unlimited; rr_depth stays at 5
            'hide_emitters': False,
        },
        'sensor': {
            'type': 'perspective',
            'fov_axis': 'y',
            'fov': 40.107,
            'to_world': mi.ScalarTransform4f().look_at(
                origin=[0, 1, 3.5], target=[0, 1, 0], up=[0, 1, 0]),
            'sampler': {'type': 'independent', 'sample_count': spp},
            'film': {
                'type': 'hdrfilm',
                'width': 256,
                'height': 256,
                'rfilter': {'type': 'box'},   # default radius 0.5 = 1 pixel
                'pixel_format': 'rgb',
                'component_format': 'float32',
            },
        },
    }
    for name, tris in groups.items():
        m = mats[name]
        bsdf = mi.load_dict({
            'type': 'twosided',
            'material': {
                'type': 'diffuse',
                'reflectance': {'type': 'rgb', 'value': list(m['Kd'])},
            },
        })
        emitter = None
        if any(c > 0 for c in m['Ke']):
            # Mitsuba's area emitter is one-sided: it emits on the side of the
            # geometric normal (p1-p0) x (p2-p0).  The ceiling light must emit
            # downward (-y).  In CornellBox-Original.obj the light's winding
            # already gives -y, so nothing is flipped; if a file had it the
            # other way round we reverse the triangles, which is equivalent
            # to the obj/ply plugins' flip_normals=True.
            ny = sum(tri_normal(t)[1] for t in tris)
            if ny > 0:
                tris = [(a, c, b) for a, b, c in tris]
                if verbose:
                    print(f'emitter {name!r}: normal pointed up, flipped')
            elif verbose:
                print(f'emitter {name!r}: normal points down (-y), kept')
            emitter = mi.load_dict({
                'type': 'area',
                'radiance': {'type': 'rgb', 'value': list(m['Ke'])},
            })
        scene[name] = make_mesh(name, tris, bsdf, emitter)
    return mi.load_dict(scene)


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split('\n')[0])
    ap.add_argument('obj', nargs='?', default=DEFAULT_OBJ)
    ap.add_argument('--spp', type=int, default=64)
    ap.add_argument('--seed', type=int, default=0)
    ap.add_argument('--out', default='cornell-mitsuba-256.exr')
    ap.add_argument('--max-depth', type=int, default=-1,
                    help='Mitsuba path depth (-1 unlimited; 2 = direct light only)')
    args = ap.parse_args(argv)

    scene = build_scene(os.path.abspath(args.obj), args.spp,
                        max_depth=args.max_depth)
    t0 = time.perf_counter()
    img = mi.render(scene, spp=args.spp, seed=args.seed)
    dt = time.perf_counter() - t0

    bmp = mi.Bitmap(img, pixel_format=mi.Bitmap.PixelFormat.RGB)
    out = os.path.abspath(args.out)
    os.makedirs(os.path.dirname(out), exist_ok=True)
    tmp = os.path.join(os.path.dirname(out),
                       f'.{os.path.basename(out)}.{os.getpid()}.tmp.exr')
    bmp.write(tmp, mi.Bitmap.FileFormat.OpenEXR)
    os.replace(tmp, out)   # atomic on the same file system
    print(f'mitsuba {mi.__version__} scalar_rgb: {args.spp} spp, '
          f'seed {args.seed}, render {dt:.1f} s -> {out}')
    return 0


if __name__ == '__main__':
    sys.exit(main())
